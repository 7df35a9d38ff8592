// A cooperative interruption point for long sweeps. A host that embeds hindsight (the Python module,
// python/module.cpp) installs a poll function while a computation runs; the forward and backward
// sweeps (engine/adjoint.cpp, engine/continuous_adjoint.cpp) call pollInterrupt() once per step. The
// poll function may throw to abandon the computation (the Python module throws the pending
// KeyboardInterrupt after Ctrl-C); the exception unwinds like any other failure, so storages release
// their memory and files as they do on a NumericalError.
//
// Nothing is installed by default: pollInterrupt() is then one atomic load, results and allocations
// are unchanged (the hot loops allocate nothing either way).
#pragma once

namespace hindsight {

/// A poll function: returns normally to continue, throws to abandon the computation.
using InterruptPoll = void (*)();

/// Installs `poll` for the whole process (nullptr: none) and returns the previous one.
InterruptPoll setInterruptPoll(InterruptPoll poll);

/// Calls the installed poll function, if any (it may throw).
void pollInterrupt();

}  // namespace hindsight
