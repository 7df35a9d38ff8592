// Strategy "lossy": every restored value within the tolerance (absolute for zfp, relative for
// round), gradient errors that fall with the tolerance and stay below C * tolerance, compression
// ratios above 1 that grow with the tolerance, the byte budget, and the spec strings.
#include <hindsight/storage/lossy_storage.h>
#include <hindsight/storage/storage_factory.h>
#include "support/storage_fixtures.h"

#include <cmath>
#include <random>

namespace hindsight {
namespace {

using testing::fixedStepRk4;
using testing::fullReference;
using testing::pendulumParameters;

LossyStorage::Options lossyOptions(LossyStorage::Codec codec, double tolerance) {
  LossyStorage::Options options;
  options.codec = codec;
  options.tolerance = tolerance;
  return options;
}

// A smooth trajectory of 7 components spanning magnitudes 1e-3..1e3, with one exact zero and noise
// in the last component so that not everything is trivially compressible.
Vector syntheticState(std::int64_t step, std::mt19937_64& random) {
  std::uniform_real_distribution<double> noise(-1.0, 1.0);
  Vector z(7);
  const double t = 0.01 * static_cast<double>(step);
  z << std::sin(t), 1e3 * std::cos(0.5 * t), 1e-3 * std::exp(-t), 0.0, -42.0 + t, 7.5 * std::sin(3 * t + 1),
      noise(random);
  return z;
}

class EveryCodec : public ::testing::TestWithParam<LossyStorage::Codec> {};

INSTANTIATE_TEST_SUITE_P(Codecs, EveryCodec,
                         ::testing::Values(LossyStorage::Codec::kZfp, LossyStorage::Codec::kRound),
                         [](const auto& info) {
                           return info.param == LossyStorage::Codec::kZfp ? "zfp" : "round";
                         });

TEST_P(EveryCodec, RestoredStatesAreWithinTheTolerance) {
  const LossyStorage::Codec codec = GetParam();
  for (double tolerance : {1e-2, 1e-4, 1e-7, 1e-10, 1e-14}) {
    for (std::int64_t block : {0, 1, 13}) {
      LossyStorage::Options options = lossyOptions(codec, tolerance);
      options.blockStates = block;
      LossyStorage storage(options);
      TrajectoryInfo info;
      info.stateSize = 7;
      info.t1 = 1.0;  // N unknown
      testing::ForbiddenRecomputer recomputer;
      storage.begin(info, recomputer);
      const std::int64_t steps = 301;
      std::mt19937_64 random(7);
      std::vector<Vector> recorded;
      for (std::int64_t step = 0; step < steps; ++step) {
        recorded.push_back(syntheticState(step, random));
        storage.record(step, 0.001 * step, recorded.back(), recorded.back());
      }
      storage.finish(steps, 1.0, recorded.back(), recorded.back());
      double worst = 0.0;  // error in units of the allowed error
      bool anyDifference = false;
      Vector z(7);
      for (std::int64_t step = steps - 1; step >= 0; --step) {
        storage.restore(step, z);
        const Vector& x = recorded[static_cast<std::size_t>(step)];
        for (Eigen::Index i = 0; i < 7; ++i) {
          const double allowed = codec == LossyStorage::Codec::kZfp ? tolerance : tolerance * std::abs(x(i));
          const double error = std::abs(z(i) - x(i));
          anyDifference = anyDifference || error > 0.0;
          if (error > 0.0) worst = std::max(worst, allowed > 0.0 ? error / allowed : HUGE_VAL);
        }
      }
      EXPECT_LE(worst, 1.0) << "tolerance " << tolerance << ", block " << block;
      if (tolerance >= 1e-7)
        EXPECT_TRUE(anyDifference) << "a lossy codec at " << tolerance << " should lose something";
      // Every compressed block is freed once decoded: only the work buffers remain.
      EXPECT_EQ(storage.counters().bytesInMemory,
                storage.counters().peakBytesInMemory - storage.counters().compressedBytes);
      EXPECT_EQ(storage.counters().uncompressedBytes, steps * 7 * 8);
    }
  }
}

// Gradient error against full storage, relative to |dpsi/dp|, on the pendulum (rk4, 2000 steps).
// Measured (T = 1e-4, 1e-6, 1e-8, 1e-10): zfp 1.4e-6, 1.3e-8, 7.7e-11, 4.6e-13 and round 1.6e-7,
// 9.1e-9, 1.1e-10, 5.6e-13, i.e. at most 0.015 T: both codecs' errors mostly cancel over the
// 2000 steps. C = 0.05 leaves a margin of 3 and still fails if states lost ~T relative to the
// gradient's sensitivity in a systematic way.
TEST_P(EveryCodec, GradientErrorFallsWithTheToleranceAndStaysBelowCTimesIt) {
  const LossyStorage::Codec codec = GetParam();
  const double constant = 0.05;
  Pendulum problem;
  const GradientResult reference = fullReference(problem, pendulumParameters(), fixedStepRk4());
  double previous = HUGE_VAL;
  for (double tolerance : {1e-4, 1e-6, 1e-8, 1e-10}) {
    LossyStorage storage(lossyOptions(codec, tolerance));
    const GradientResult result = computeGradient(problem, pendulumParameters(), fixedStepRk4(), storage);
    EXPECT_EQ(result.objective, reference.objective) << "the forward sweep is not affected";
    const double error = (result.gradient - reference.gradient).norm() / reference.gradient.norm();
    ::testing::Test::RecordProperty("error_" + std::to_string(static_cast<int>(-std::log10(tolerance))),
                                    ::testing::PrintToString(error));
    EXPECT_GT(error, 0.0) << "tolerance " << tolerance;
    EXPECT_LT(error, constant * tolerance) << "tolerance " << tolerance;
    EXPECT_LT(error, previous) << "tolerance " << tolerance;
    previous = error;
  }
}

TEST_P(EveryCodec, CompressionRatioAboveOneAndGrowingWithTheTolerance) {
  Pendulum problem;
  double previous = HUGE_VAL;
  for (double tolerance : {1e-3, 1e-6, 1e-9, 1e-12}) {
    LossyStorage storage(lossyOptions(GetParam(), tolerance));
    const GradientResult result = computeGradient(problem, pendulumParameters(), fixedStepRk4(), storage);
    EXPECT_GT(result.summary.compressionRatio, 1.0) << tolerance;
    EXPECT_LT(result.summary.compressionRatio, previous) << tolerance;
    EXPECT_EQ(storage.counters().uncompressedBytes, result.summary.steps * 16);
    EXPECT_EQ(storage.counters().bytesInMemory,
              storage.counters().peakBytesInMemory - storage.counters().compressedBytes);
    previous = result.summary.compressionRatio;
  }
}

TEST_P(EveryCodec, NeverExceedsItsBudget) {
  Pendulum problem;
  LossyStorage::Options options = lossyOptions(GetParam(), 1e-6);
  options.blockStates = 100;
  options.budgetBytes = 20000;  // the full trajectory is 32000 bytes; three work buffers ~ 5 KiB
  LossyStorage storage(options);
  const GradientResult result = computeGradient(problem, pendulumParameters(), fixedStepRk4(), storage);
  EXPECT_LE(storage.counters().peakBytesInMemory, 20000);
  EXPECT_GT(storage.counters().peakBytesInMemory, 10000);
  options.budgetBytes = 6000;
  LossyStorage tooSmall(options);
  EXPECT_THROW(computeGradient(problem, pendulumParameters(), fixedStepRk4(), tooSmall), StorageError);
  EXPECT_LE(tooSmall.counters().peakBytesInMemory, 6000);
}

TEST(LossyStorage, MantissaRoundingIsToNearestTiesToEvenWithinItsBound) {
  EXPECT_EQ(LossyStorage::keptMantissaBits(0.5), 0);
  EXPECT_EQ(LossyStorage::keptMantissaBits(std::ldexp(1.0, -10)), 9);
  EXPECT_EQ(LossyStorage::keptMantissaBits(1e-4), 13);
  EXPECT_EQ(LossyStorage::keptMantissaBits(1e-30), 52);
  double ties[] = {1.5, 2.5, 1.25, 1.75, -1.75, 0.0, 3.0};
  LossyStorage::roundMantissas(ties, 2, 0);      // 1.1b -> 10b; 10.1b -> 10b (even)
  LossyStorage::roundMantissas(ties + 2, 5, 1);  // 1.01b -> 1.0b; 1.11b -> 10.0b
  EXPECT_EQ(ties[0], 2.0);
  EXPECT_EQ(ties[1], 2.0);
  EXPECT_EQ(ties[2], 1.0);
  EXPECT_EQ(ties[3], 2.0);
  EXPECT_EQ(ties[4], -2.0);
  EXPECT_EQ(ties[5], 0.0);
  EXPECT_EQ(ties[6], 3.0);
  std::mt19937_64 random(3);
  std::uniform_real_distribution<double> exponent(-300.0, 300.0), sign(-1.0, 1.0);
  for (int bits : {0, 5, 23, 40, 51}) {
    for (int i = 0; i < 2000; ++i) {
      const double x = std::copysign(std::pow(10.0, exponent(random)), sign(random));
      double y = x;
      LossyStorage::roundMantissas(&y, 1, bits);
      EXPECT_LE(std::abs(y - x), std::ldexp(std::abs(x), -(bits + 1))) << x << " with " << bits << " bits";
    }
  }
  double special[] = {HUGE_VAL, -HUGE_VAL, std::numeric_limits<double>::max()};
  LossyStorage::roundMantissas(special, 3, 3);
  EXPECT_EQ(special[0], HUGE_VAL);
  EXPECT_EQ(special[1], -HUGE_VAL);
  EXPECT_EQ(special[2], std::numeric_limits<double>::max()) << "rounding must not overflow to infinity";
}

// lossy:target=T on the pendulum (rk4, 2000 steps): the achieved gradient error stays below T, the
// reported estimate is at most T and at least the error made, and the ratio grows with T.
// Measured: see tests/problems/classic/lossy_target_test.cpp and docs/theory/storage.md, "Compression along
// time".
TEST(LossyTarget, AchievedGradientErrorStaysBelowTheTargetOnThePendulum) {
  Pendulum problem;
  const GradientResult reference = fullReference(problem, pendulumParameters(), fixedStepRk4());
  double previousRatio = HUGE_VAL;
  for (double target : {1e-3, 1e-5, 1e-7, 1e-9}) {
    auto storage = createStorage("lossy:target=" + ::testing::PrintToString(target));
    const GradientResult result = computeGradient(problem, pendulumParameters(), fixedStepRk4(), *storage);
    EXPECT_EQ(result.objective, reference.objective) << "the forward sweep is not affected";
    const double error = (result.gradient - reference.gradient).norm() / reference.gradient.norm();
    ::testing::Test::RecordProperty("error_" + ::testing::PrintToString(target),
                                    ::testing::PrintToString(error));
    EXPECT_GT(error, 0.0) << target;
    EXPECT_LE(error, target) << target;
    EXPECT_LE(result.summary.gradientErrorEstimate, target) << target;
    EXPECT_GE(result.summary.gradientErrorEstimate, error) << target;
    EXPECT_GT(result.summary.compressionRatio, 1.0) << target;
    EXPECT_LT(result.summary.compressionRatio, previousRatio) << target;
    previousRatio = result.summary.compressionRatio;
  }
}

// codec=time restores every value within tolerance x max|component| over its block, whatever the
// block size, and restores blocks in the backward sweep's order; its blocks are freed once decoded.
TEST(LossyTarget, TimeCodecKeepsEveryValueWithinItsComponentsBlockScale) {
  for (double tolerance : {1e-2, 1e-6, 1e-12}) {
    for (std::int64_t block : {0, 1, 13}) {
      LossyStorage::Options options = lossyOptions(LossyStorage::Codec::kTime, tolerance);
      options.blockStates = block;
      LossyStorage storage(options);
      TrajectoryInfo info;
      info.stateSize = 7;
      info.t1 = 1.0;
      testing::ForbiddenRecomputer recomputer;
      storage.begin(info, recomputer);
      const std::int64_t steps = 301;
      std::mt19937_64 random(7);
      std::vector<Vector> recorded;
      for (std::int64_t step = 0; step < steps; ++step) {
        recorded.push_back(syntheticState(step, random));
        storage.record(step, 0.001 * step, recorded.back(), recorded.back());
      }
      storage.finish(steps, 1.0, recorded.back(), recorded.back());
      const std::int64_t blockStates =
          block == 0 ? steps : block;  // 301 states of 56 bytes fit one default block
      Vector z(7);
      for (std::int64_t step = steps - 1; step >= 0; --step) {
        storage.restore(step, z);
        const std::int64_t first = step / blockStates * blockStates;
        const std::int64_t last = std::min(steps, first + blockStates);
        for (Eigen::Index i = 0; i < 7; ++i) {
          double scale = 0.0;
          for (std::int64_t k = first; k < last; ++k)
            scale = std::max(scale, std::abs(recorded[static_cast<std::size_t>(k)](i)));
          EXPECT_LE(std::abs(z(i) - recorded[static_cast<std::size_t>(step)](i)), tolerance * scale)
              << "step " << step << ", component " << i << ", block " << block;
        }
      }
      EXPECT_LE(storage.counters().gradientErrorEstimate, LossyStorage::kGradientSensitivity * tolerance);
      EXPECT_EQ(storage.counters().uncompressedBytes, steps * 7 * 8);
      EXPECT_EQ(storage.counters().bytesInMemory,
                storage.counters().peakBytesInMemory - storage.counters().compressedBytes);
    }
  }
}

TEST(LossyStorage, SpecStringsRoundTripThroughTheFactory) {
  for (const std::string spec : {"lossy:codec=zfp,tolerance=1e-06", "lossy:codec=round,tolerance=0.0001",
                                 "lossy:codec=round,tolerance=1e-10,budget=1048576,block=64",
                                 "lossy:target=1e-06", "lossy:target=0.001,block=100",
                                 "lossy:codec=time,tolerance=1e-05", "lossy:target=1e-06,sensitivity=0.3"}) {
    EXPECT_EQ(createStorage(spec)->spec(), spec);
    EXPECT_FALSE(createStorage(spec)->isExact());
  }
  EXPECT_THROW(createStorage("lossy:codec=zfp"), std::invalid_argument);
  EXPECT_THROW(createStorage("lossy:tolerance=1e-6"), std::invalid_argument);
  EXPECT_THROW(createStorage("lossy:codec=gzip,tolerance=1e-6"), std::invalid_argument);
  EXPECT_THROW(createStorage("lossy:codec=round,tolerance=0.7"), std::invalid_argument);
  EXPECT_THROW(createStorage("lossy:codec=zfp,tolerance=-1"), std::invalid_argument);
  EXPECT_THROW(createStorage("lossy:codec=zfp,tolerance=0"), std::invalid_argument);
  EXPECT_THROW(createStorage("lossy:target=0.5"), std::invalid_argument);
  EXPECT_THROW(createStorage("lossy:target=0"), std::invalid_argument);
  EXPECT_THROW(createStorage("lossy:target=1e-6,codec=zfp"), std::invalid_argument);
  EXPECT_THROW(createStorage("lossy:target=1e-6,tolerance=1e-3"), std::invalid_argument);
  EXPECT_THROW(createStorage("lossy:codec=time,tolerance=0.6"), std::invalid_argument);
  EXPECT_THROW(createStorage("lossy:target=1e-6,sensitivity=0"), std::invalid_argument);
  EXPECT_THROW(createStorage("lossy:target=1e-6,sensitivity=2000"), std::invalid_argument);
  EXPECT_THROW(createStorage("lossy:codec=time,tolerance=1e-5,sensitivity=1"), std::invalid_argument);
  try {
    createStorage("lossy:target=2");
    ADD_FAILURE() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("lossy.target"), std::string::npos) << e.what();
  }
}

TEST(LossyStorage, CalibratedSensitivitySetsTheTargetsToleranceAndTheSpecSaysIt) {
  // target=T codes with tolerance T / S (S = 0.5: bounds 20 times those of the default S = 10); the spec's
  // own sensitivity= wins over an application's calibration, which the expert codecs ignore.
  auto plain = createStorage("lossy:target=1e-6");
  auto& lossy = dynamic_cast<LossyStorage&>(*plain);
  EXPECT_EQ(lossy.sensitivity(), LossyStorage::kGradientSensitivity);
  lossy.calibrate(0.5);
  EXPECT_EQ(lossy.sensitivity(), 0.5);
  EXPECT_EQ(lossy.spec(), "lossy:target=1e-06,sensitivity=0.5");
  auto given = createStorage("lossy:target=1e-6,sensitivity=2");
  dynamic_cast<LossyStorage&>(*given).calibrate(0.5);
  EXPECT_EQ(dynamic_cast<LossyStorage&>(*given).sensitivity(), 2.0);
  auto expert = createStorage("lossy:codec=time,tolerance=1e-5");
  dynamic_cast<LossyStorage&>(*expert).calibrate(0.5);
  EXPECT_EQ(expert->spec(), "lossy:codec=time,tolerance=1e-05");
  EXPECT_THROW(lossy.calibrate(0.0), std::invalid_argument);

  // On the pendulum the estimate is S x the relative state error made, and a looser S compresses more.
  Pendulum problem;
  auto strict = createStorage("lossy:target=1e-6");
  auto loose = createStorage("lossy:target=1e-6,sensitivity=0.5");
  const GradientResult a = computeGradient(problem, pendulumParameters(), fixedStepRk4(), *strict);
  const GradientResult b = computeGradient(problem, pendulumParameters(), fixedStepRk4(), *loose);
  EXPECT_GT(b.summary.compressionRatio, a.summary.compressionRatio);
  EXPECT_LE(b.summary.gradientErrorEstimate, 1e-6);
  EXPECT_GT(b.summary.gradientErrorEstimate, 0.0);
}

}  // namespace
}  // namespace hindsight
