// Compression along time on the slider-crank (synthetic flexible body, 6 modes, rk4, 4000 steps):
// disk's time codec restores every bit (gradient bitwise equal to full storage's) and lossy:target=T
// keeps the achieved relative gradient error below T with an estimate between the two. The real
// rod's figures (T = 3, 10, 100 s) are in docs/theory/storage.md, "Compression along time" and
// bench/RESULTS.md.
#include <hindsight/problems/rod/slider_crank.h>

#include <hindsight/engine/adjoint.h>
#include <hindsight/engine/full_storage.h>
#include <hindsight/storage/storage_factory.h>
#include "support/storage_fixtures.h"
#include "support/synthetic_rod.h"

#include <gtest/gtest.h>

namespace hindsight::rod {
namespace {

struct Crank {
  Crank() : body(6, 1.0, 7), problem(6, 1.0, CrankMotion{}), p(body.invariants()) {
    options.method = "rk4";
    options.t1 = 2.0;
    options.step = 5e-4;
  }
  testing::SyntheticRod body;
  SliderCrankProblem problem;
  Vector p;
  IntegratorOptions options;
};

TEST(RodCompression, DiskTimeCodecIsBitwiseAndLossyTargetHoldsItsBound) {
  Crank crank;
  FullStorage full;
  const GradientResult reference = computeGradient(crank.problem, crank.p, crank.options, full);
  testing::ScratchDirectory dir;
  auto disk = createStorage("disk:dir=" + dir.path());
  const GradientResult lossless = computeGradient(crank.problem, crank.p, crank.options, *disk);
  EXPECT_TRUE(testing::bitwiseEqual(lossless, reference));
  ::testing::Test::RecordProperty("disk_ratio", ::testing::PrintToString(lossless.summary.compressionRatio));
  EXPECT_GT(lossless.summary.compressionRatio, 1.5);
  for (double target : {1e-4, 1e-6, 1e-8}) {
    auto storage = createStorage("lossy:target=" + ::testing::PrintToString(target));
    const GradientResult result = computeGradient(crank.problem, crank.p, crank.options, *storage);
    const double error = (result.gradient - reference.gradient).norm() / reference.gradient.norm();
    ::testing::Test::RecordProperty("error_" + ::testing::PrintToString(target),
                                    ::testing::PrintToString(error));
    EXPECT_GT(error, 0.0) << target;
    EXPECT_LE(error, target) << target;
    EXPECT_GE(result.summary.gradientErrorEstimate, error) << target;
    EXPECT_LE(result.summary.gradientErrorEstimate, target) << target;
    EXPECT_GT(result.summary.compressionRatio, 3.0) << target;  // measured 4.7 at 1e-8
  }
}

}  // namespace
}  // namespace hindsight::rod
