// An interrupt poll (engine/interrupt.h) that counts its calls and, once `throwAfter` >= 0 of them have
// passed, throws Stop: the tests that interrupt a run at every point it polls install it with
// setInterruptPoll(&countingPoll) and reset both counters first.
#pragma once

namespace hindsight::testing {

inline int polls = 0;
inline int throwAfter = -1;

struct Stop {};

inline void countingPoll() {
  ++polls;
  if (throwAfter >= 0 && polls > throwAfter) throw Stop{};
}

}  // namespace hindsight::testing
