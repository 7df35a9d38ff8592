// engine/interrupt.h: the sweeps call the installed poll once per step (forward and backward), a poll
// that throws abandons the run with its exception, and a run after it (poll removed) gives the same
// bits as one that was never interrupted.
#include <hindsight/engine/adjoint.h>
#include <hindsight/engine/continuous_adjoint.h>
#include <hindsight/engine/full_storage.h>
#include <hindsight/engine/interrupt.h>
#include <hindsight/problems/classic/classic_problems.h>

#include "support/counting_poll.h"

#include <gtest/gtest.h>

namespace hindsight {
namespace {

using testing::countingPoll;
using testing::polls;
using testing::Stop;
using testing::throwAfter;

class Interrupt : public ::testing::Test {
 protected:
  void SetUp() override {
    polls = 0;
    throwAfter = -1;
  }
  void TearDown() override { setInterruptPoll(nullptr); }
  const ExponentialDecay problem;
  const Vector p = Eigen::Vector2d(0.7, 1.3);
  IntegratorOptions options = [] {
    IntegratorOptions o;
    o.t1 = 2.0;
    o.step = 0.01;  // 200 steps
    return o;
  }();
};

TEST_F(Interrupt, NothingInstalledByDefault) {
  EXPECT_EQ(setInterruptPoll(nullptr), nullptr);
  pollInterrupt();  // no effect
}

TEST_F(Interrupt, PolledOncePerForwardAndBackwardStep) {
  FullStorage plain;
  const GradientResult reference = computeGradient(problem, p, options, plain);
  EXPECT_EQ(setInterruptPoll(&countingPoll), nullptr);
  FullStorage storage;
  const GradientResult result = computeGradient(problem, p, options, storage);
  EXPECT_EQ(polls, 2 * 200);
  EXPECT_EQ(setInterruptPoll(nullptr), &countingPoll);
  // Polling changes nothing.
  EXPECT_EQ(result.objective, reference.objective);
  EXPECT_EQ(result.gradient, reference.gradient);
  polls = 0;
  simulate(problem, p, options);
  EXPECT_EQ(polls, 0);
}

TEST_F(Interrupt, AThrowingPollAbandonsTheRunAndTheNextRunIsUnchanged) {
  FullStorage plain;
  const GradientResult reference = computeGradient(problem, p, options, plain);
  for (const int after : {0, 57, 200, 311}) {  // in the forward sweep, at its end, in the backward sweep
    polls = 0;
    throwAfter = after;
    setInterruptPoll(&countingPoll);
    FullStorage storage;
    EXPECT_THROW(computeGradient(problem, p, options, storage), Stop) << after;
    EXPECT_EQ(polls, after + 1);
    setInterruptPoll(nullptr);
    // The same storage object serves the next run.
    const GradientResult again = computeGradient(problem, p, options, storage);
    EXPECT_EQ(again.gradient, reference.gradient) << after;
  }
}

TEST_F(Interrupt, TheContinuousAdjointPollsItsBackwardSteps) {
  options.method = "dopri5";
  options.adaptive = true;
  setInterruptPoll(&countingPoll);
  FullStorage storage;
  const GradientResult result = computeGradientContinuous(problem, p, options, storage);
  EXPECT_GT(polls, result.summary.steps);  // forward steps plus at least one backward step
  polls = 0;
  throwAfter = result.summary.steps + 1;  // during the backward integration
  FullStorage again;
  EXPECT_THROW(computeGradientContinuous(problem, p, options, again), Stop);
}

}  // namespace
}  // namespace hindsight
