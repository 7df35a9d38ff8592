// The "hermite" strategy: O(H^4) interpolation (checked as an observed order against the
// oscillator's closed-form trajectory), exact kept points, a discrete-adjoint gradient that
// converges to the full-storage one as M shrinks, and a budget it never exceeds.
#include <hindsight/engine/adjoint.h>
#include <hindsight/engine/full_storage.h>
#include <hindsight/problems/classic/classic_problems.h>
#include <hindsight/storage/hermite_storage.h>
#include <hindsight/storage/lossy_storage.h>
#include <hindsight/storage/storage_factory.h>

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>

namespace hindsight {
namespace {

class NoRecomputation final : public StepRecomputer {
 public:
  void advance(std::int64_t, VectorRef) override { FAIL() << "hermite storage must not recompute"; }
};

/// The damped oscillator y'' + c y' + k y = 0, y(0) = a, y'(0) = 0, as z = (y, y') and z'.
struct ExactOscillator {
  double k = 4.0, c = 0.4, a = 0.8;
  Eigen::Vector2d state(double t) const {
    const double s = -c / 2.0, w = std::sqrt(k - c * c / 4.0), b = -s * a / w;
    const double e = std::exp(s * t), cs = std::cos(w * t), sn = std::sin(w * t);
    const double y = e * (a * cs + b * sn);
    const double v = s * y + e * (-a * w * sn + b * w * cs);
    return {y, v};
  }
  Eigen::Vector2d derivative(double t) const {
    const Eigen::Vector2d z = state(t);
    return {z(1), -k * z(0) - c * z(1)};
  }
};

/// Records the exact trajectory on a uniform grid of N steps over [0, T].
void recordExact(HermiteStorage& storage, NoRecomputation& recomputer, std::int64_t steps, double horizon,
                 bool announceSteps = true) {
  const ExactOscillator exact;
  TrajectoryInfo info;
  info.problemName = "oscillator";
  info.stateSize = 2;
  info.t0 = 0.0;
  info.t1 = horizon;
  info.stepCount = announceSteps ? steps : -1;
  storage.begin(info, recomputer);
  for (std::int64_t n = 0; n < steps; ++n) {
    const double t = horizon * static_cast<double>(n) / static_cast<double>(steps);
    storage.record(n, t, exact.state(t), exact.derivative(t));
  }
  storage.finish(steps, horizon, exact.state(horizon), exact.derivative(horizon));
}

/// Max state error over the restored grid points and over interpolate() at segment midpoints.
std::pair<double, double> maxErrors(std::int64_t every) {
  const ExactOscillator exact;
  const std::int64_t steps = 480;
  const double horizon = 3.0;
  HermiteStorage storage(every);
  NoRecomputation recomputer;
  recordExact(storage, recomputer, steps, horizon);
  double restoreError = 0.0;
  Vector z(2);
  for (std::int64_t n = steps - 1; n >= 0; --n) {
    storage.restore(n, z);
    const double t = horizon * static_cast<double>(n) / static_cast<double>(steps);
    restoreError = std::max(restoreError, (z - exact.state(t)).cwiseAbs().maxCoeff());
  }
  double interpolateError = 0.0;
  for (int i = 0; i < 2000; ++i) {
    const double t = horizon * (i + 0.5) / 2000.0;
    storage.interpolate(t, z);
    interpolateError = std::max(interpolateError, (z - exact.state(t)).cwiseAbs().maxCoeff());
  }
  return {restoreError, interpolateError};
}

TEST(HermiteStorage, InterpolationErrorIsFourthOrder) {
  // Halving M halves the spacing H of kept points: a cubic Hermite interpolant's error O(H^4)
  // drops by 16. Asymptotically exact; [12, 20] leaves room for the H^5 term at these spacings.
  const auto [restore16, interpolate16] = maxErrors(16);
  const auto [restore8, interpolate8] = maxErrors(8);
  const auto [restore4, interpolate4] = maxErrors(4);
  std::cout << "[ hermite ] max error, restore: M=16 " << restore16 << ", M=8 " << restore8 << ", M=4 "
            << restore4 << "; observed order " << std::log2(restore16 / restore8) << ", "
            << std::log2(restore8 / restore4) << "\n";
  std::cout << "[ hermite ] max error, interpolate: M=16 " << interpolate16 << ", M=8 " << interpolate8
            << ", M=4 " << interpolate4 << "; observed order " << std::log2(interpolate16 / interpolate8)
            << ", " << std::log2(interpolate8 / interpolate4) << "\n";
  for (double ratio : {restore16 / restore8, restore8 / restore4, interpolate16 / interpolate8,
                       interpolate8 / interpolate4}) {
    EXPECT_GT(ratio, 12.0);
    EXPECT_LT(ratio, 20.0);
  }
}

TEST(HermiteStorage, KeptPointsAreRestoredBitForBit) {
  const ExactOscillator exact;
  HermiteStorage storage(5);
  NoRecomputation recomputer;
  recordExact(storage, recomputer, 23, 3.0);  // 23 is not a multiple of 5: a short last segment
  Vector z(2);
  for (std::int64_t n = 22; n >= 0; --n) {
    storage.restore(n, z);
    const double t = 3.0 * static_cast<double>(n) / 23.0;
    if (n % 5 == 0) {
      EXPECT_EQ(hashState(z), hashState(exact.state(t))) << "step " << n;
    } else {
      EXPECT_LT((z - exact.state(t)).norm(), 2e-2) << "step " << n;  // H = 0.65: coarse
    }
  }
  storage.interpolate(3.0, z);
  EXPECT_EQ(hashState(z), hashState(exact.state(3.0)));
  // 0, 5, 10, 15, 20 and the final point.
  EXPECT_EQ(storage.counters().statesStored, 6);
  EXPECT_THROW(storage.interpolate(3.1, z), std::invalid_argument);
}

TEST(HermiteStorage, GradientErrorAgainstFullStorageShrinksWithM) {
  Pendulum problem;
  const Vector p = Eigen::Vector4d(1.5, 0.8, 0.3, 1.2);
  IntegratorOptions options;
  options.method = "rk4";
  options.t1 = 4.0;
  options.step = 2e-3;
  FullStorage full;
  const GradientResult reference = computeGradient(problem, p, options, full);
  double previous = 0.0;
  for (std::int64_t every : {32, 16, 8, 4}) {
    HermiteStorage storage(every);
    const GradientResult result = computeGradient(problem, p, options, storage);
    const double error = (result.gradient - reference.gradient).norm() / reference.gradient.norm();
    std::cout << "[ hermite ] pendulum gradient error vs full, M = " << every << ": " << error;
    if (previous > 0.0) std::cout << " (ratio " << previous / error << ")";
    std::cout << "\n";
    EXPECT_EQ(result.objective, reference.objective);  // the forward sweep is the same
    // N = 2000 known in advance: one exact allocation of N + 1 times and K = ceil(N/M) + 1 kept
    // points of (2n + 1) doubles, n = 2. (With n = 2 the grid times dominate; for the large states
    // hermite is meant for, the kept points do.)
    // Plus one state (n = 2 doubles): the mid-interval sample of the error estimate.
    const std::int64_t kept = (2000 + every - 1) / every + 1;
    EXPECT_EQ(storage.counters().peakBytesInMemory, (2001 + kept * 5 + 2) * 8);
    EXPECT_EQ(storage.counters().statesStored, kept);
    // O(H^4) in the restored states: at least 8x per halving of M (16x asymptotically).
    if (previous > 0.0) EXPECT_GT(previous / error, 8.0) << "M = " << every;
    previous = error;
  }
  EXPECT_LT(previous, 1e-6);
}

// The error estimate: measured mid-interval in the forward sweep, reported as a gradient error
// estimate that is at least the gradient's actual error; an interval too long for a cubic (every = N:
// one cubic over the whole run) is refused instead of giving a gradient off by orders of magnitude.
TEST(HermiteStorage, ErrorEstimateCoversTheGradientErrorAndTooLongIntervalsAreRefused) {
  Pendulum problem;
  const Vector p = Eigen::Vector4d(1.5, 0.8, 0.3, 1.2);
  IntegratorOptions options;
  options.method = "rk4";
  options.t1 = 4.0;
  options.step = 2e-3;  // N = 2000
  FullStorage full;
  const GradientResult reference = computeGradient(problem, p, options, full);
  for (std::int64_t every : {100, 64, 32, 16, 4, 1}) {
    HermiteStorage storage(every, HermiteStorage::kDefaultBudget, 1.0);
    const GradientResult result = computeGradient(problem, p, options, storage);
    const double error = (result.gradient - reference.gradient).norm() / reference.gradient.norm();
    std::cout << "[ hermite ] M = " << every << ": gradient error " << error << ", estimate "
              << result.summary.gradientErrorEstimate << " (state error " << storage.stateErrorEstimate()
              << ")\n";
    EXPECT_GE(result.summary.gradientErrorEstimate, error) << "M = " << every;
    EXPECT_EQ(result.summary.gradientErrorEstimate,
              LossyStorage::kGradientSensitivity * storage.stateErrorEstimate());
    if (every == 1) EXPECT_EQ(result.summary.gradientErrorEstimate, 0.0);
    if (every == 4) EXPECT_LT(result.summary.gradientErrorEstimate, 1e-5);
  }
  for (const std::string spec : {"hermite:every=2000", "hermite:every=1000", "hermite:every=1999"}) {
    auto storage = createStorage(spec);
    try {
      computeGradient(problem, p, options, *storage);
      ADD_FAILURE() << spec << " was accepted";
    } catch (const std::invalid_argument& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find("hermite.every = " + spec.substr(14) + " is too long"), std::string::npos)
          << message;
      EXPECT_NE(message.find("hermite.tolerance = 0.01"), std::string::npos) << message;
    }
  }
  // Unknown N (adaptive steps): the same check.
  IntegratorOptions adaptive = options;
  adaptive.adaptive = true;
  adaptive.method = "dopri5";
  adaptive.relativeTolerance = 1e-8;
  adaptive.absoluteTolerance = 1e-10;
  HermiteStorage tooLong(1'000'000);
  EXPECT_THROW(computeGradient(problem, p, adaptive, tooLong), std::invalid_argument);
  EXPECT_EQ(createStorage("hermite:every=4,tolerance=0.5")->spec(), "hermite:every=4,tolerance=0.5");
  EXPECT_THROW(createStorage("hermite:tolerance=0"), std::invalid_argument);
  EXPECT_THROW(createStorage("hermite:tolerance=2"), std::invalid_argument);
}

TEST(HermiteStorage, BudgetIsNeverExceeded) {
  // 480 steps, M = 4: 121 kept points of (2 + 2) doubles + 1 time, and 481 grid times. With N
  // announced that is allocated once; with N unknown the buffers grow geometrically, and the
  // capacity (up to twice the content) is what is charged; plus the mid-interval sample (2 doubles).
  const std::int64_t needed = (121 * 5 + 481 + 2) * 8;
  for (bool announceSteps : {true, false}) {
    NoRecomputation recomputer;
    HermiteStorage enough(4, announceSteps ? needed : 2 * needed);
    recordExact(enough, recomputer, 480, 3.0, announceSteps);
    EXPECT_LE(enough.counters().peakBytesInMemory, enough.budgetBytes()) << announceSteps;
    EXPECT_GE(enough.counters().peakBytesInMemory, needed) << announceSteps;
    HermiteStorage tooSmall(4, needed / 2);
    EXPECT_THROW(recordExact(tooSmall, recomputer, 480, 3.0, announceSteps), StorageError) << announceSteps;
    EXPECT_LE(tooSmall.counters().peakBytesInMemory, tooSmall.budgetBytes()) << announceSteps;
  }
}

TEST(HermiteStorage, FactoryParsesTheSpecAndRejectsBadValues) {
  const auto storage = createStorage("hermite:every=7,budget=1MiB");
  EXPECT_EQ(storage->spec(), "hermite:every=7,budget=1048576");
  EXPECT_FALSE(storage->isExact());
  EXPECT_TRUE(storage->needsDerivative());
  EXPECT_TRUE(storage->canInterpolate());
  EXPECT_EQ(createStorage("hermite")->spec(), "hermite:every=10");
  try {
    createStorage("hermite:every=0");
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("hermite.every"), std::string::npos) << e.what();
  }
  EXPECT_THROW(createStorage("hermite:stride=2"), std::invalid_argument);
}

TEST(HermiteStorage, StrategiesWithoutDenseOutputSayTheyCannotInterpolate) {
  FullStorage full;
  EXPECT_FALSE(full.canInterpolate());
  Vector z(2);
  try {
    full.interpolate(0.5, z);
    FAIL() << "no exception";
  } catch (const std::logic_error& e) {
    EXPECT_NE(std::string(e.what()).find("strategy full cannot interpolate"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace hindsight
