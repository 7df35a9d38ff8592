// lossy:target=T on classic problems with exact references (full storage of the same run): the
// reaction-diffusion equation (200 grid points, trbdf2); the pendulum is in
// tests/storage/lossy_storage_test.cpp, the rod in tests/problems/rod/lossy_target_test.cpp. Not
// covered: trajectories whose components fall by decades within a block (Robertson): the bound is
// relative to the component's largest magnitude in the block, so small late values lose all their
// digits (docs/theory/storage.md, "Compression along time"). The achieved relative gradient error stays
// below T (LossyStorage::kGradientSensitivity = 1 is the documented factor between the relative state
// error made and the gradient error estimated) and the summary's estimate is at least the error made.
#include <hindsight/engine/adjoint.h>
#include <hindsight/engine/full_storage.h>
#include <hindsight/problems/classic/heat_equation.h>
#include <hindsight/storage/storage_factory.h>

#include <gtest/gtest.h>

namespace hindsight {
namespace {

void expectWithinTarget(const Problem& problem, const Vector& p, const IntegratorOptions& options,
                        const std::string& label) {
  FullStorage full;
  const GradientResult reference = computeGradient(problem, p, options, full);
  for (double target : {1e-3, 1e-5, 1e-7}) {
    auto storage = createStorage("lossy:target=" + ::testing::PrintToString(target));
    const GradientResult result = computeGradient(problem, p, options, *storage);
    const double error = (result.gradient - reference.gradient).norm() / reference.gradient.norm();
    ::testing::Test::RecordProperty(label + "_error_" + ::testing::PrintToString(target),
                                    ::testing::PrintToString(error));
    EXPECT_LE(error, target) << label << " at target " << target;
    EXPECT_GE(result.summary.gradientErrorEstimate, error) << label << " at target " << target;
    EXPECT_LE(result.summary.gradientErrorEstimate, target) << label << " at target " << target;
    EXPECT_GT(result.summary.compressionRatio, 1.0) << label << " at target " << target;
  }
}

TEST(LossyTarget, ReactionDiffusionGradientWithinTheTarget) {
  HeatEquation problem(200, 3);
  IntegratorOptions options;
  options.method = "trbdf2";
  options.t1 = 1.0;
  options.step = 2e-3;
  expectWithinTarget(problem, problem.nominalParameters(), options, "heat");
}

}  // namespace
}  // namespace hindsight
