// A numerical failure in the backward sweep names the sweep, the storage and the time: with an
// approximate storage whose restored states are far from the recorded ones, the implicit adjoint step
// of a stiff problem (Robertson, TR-BDF2) fails, and the message must point at the storage rather than
// at the model. The storage here is a test double: every state kept, one of them restored perturbed.
#include <hindsight/engine/adjoint.h>
#include <hindsight/engine/continuous_adjoint.h>
#include <hindsight/problems/classic/classic_problems.h>

#include <gtest/gtest.h>

#include <vector>

namespace hindsight {
namespace {

class PerturbingStorage final : public TrajectoryStorage {
 public:
  explicit PerturbingStorage(double factor) : TrajectoryStorage(kUnlimitedBytes), factor_(factor) {}
  std::string spec() const override { return "perturbing-test-double"; }
  bool isExact() const override { return false; }

 private:
  void doBegin() override { states_.clear(); }
  void doRecord(std::int64_t, double, ConstVectorRef z, ConstVectorRef) override { states_.emplace_back(z); }
  void doFinish(double, ConstVectorRef z, ConstVectorRef) override { states_.emplace_back(z); }
  void doRestore(std::int64_t step, VectorRef z) override {
    z = states_[static_cast<std::size_t>(step)];
    if (step == static_cast<std::int64_t>(states_.size()) / 2) z *= factor_;  // one state far off
  }
  double factor_;
  std::vector<Vector> states_;
};

TEST(BackwardSweepFailure, NamesTheSweepTheStorageAndTheTime) {
  Robertson problem(10.0);
  const Vector p = Robertson::nominalParameters();
  IntegratorOptions options;
  options.method = "trbdf2";
  options.t1 = 10.0;
  options.adaptive = true;
  options.step = 1e-6;
  options.relativeTolerance = 1e-6;
  options.absoluteTolerance = 1e-12;
  PerturbingStorage storage(1e200);
  try {
    const GradientResult result = computeGradient(problem, p, options, storage);
    // Without a failure the gradient must at least not be silently non-finite.
    ADD_FAILURE() << "no failure; gradient finite: " << result.gradient.allFinite();
  } catch (const NumericalError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("backward sweep (discrete adjoint, step "), std::string::npos) << message;
    EXPECT_NE(message.find("with storage 'perturbing-test-double'"), std::string::npos) << message;
    EXPECT_NE(message.find("the storage is approximate"), std::string::npos) << message;
    EXPECT_NE(message.find("(at t = "), std::string::npos) << message;
    EXPECT_EQ(message.find("(at t = "), message.rfind("(at t = ")) << "the time once: " << message;
    EXPECT_GT(e.time(), 0.0);
    EXPECT_LT(e.time(), 10.0);
  }
}

}  // namespace
}  // namespace hindsight
