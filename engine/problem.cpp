#include <hindsight/engine/problem.h>

namespace hindsight {

void Problem::addInitialStateVjp(ConstVectorRef, ConstVectorRef, VectorRef) const {}

std::unique_ptr<ProblemWorkspace> Problem::createWorkspaceFor(ConstVectorRef) const {
  return createWorkspace();
}

void Problem::rhsVjps(double t, ConstVectorRef z, ConstVectorRef p, ConstVectorRef w, VectorRef outState,
                      VectorRef gradient, ProblemWorkspace* ws) const {
  rhsStateVjp(t, z, p, w, outState, ws);
  addRhsParameterVjp(t, z, p, w, gradient, ws);
}

void Problem::rhsJacobian(double, ConstVectorRef, ConstVectorRef, MatrixRef, ProblemWorkspace*) const {
  throw std::logic_error("Problem '" + name() +
                         "' declares a dense Jacobian but does not implement rhsJacobian()");
}

void Problem::rhsStateVjp(double, ConstVectorRef, ConstVectorRef, ConstVectorRef, VectorRef,
                          ProblemWorkspace*) const {
  throw std::logic_error("Problem '" + name() +
                         "' has no dense Jacobian but does not implement rhsStateVjp()");
}

void Problem::saveRhsData(ProblemWorkspace*, VectorRef) const {
  throw std::logic_error("Problem '" + name() + "' keeps no rhs data (rhsDataSize() = 0)");
}

void Problem::restoreRhsData(double, ConstVectorRef, ConstVectorRef, ConstVectorRef,
                             ProblemWorkspace*) const {
  throw std::logic_error("Problem '" + name() + "' keeps no rhs data (rhsDataSize() = 0)");
}

double Problem::terminal(ConstVectorRef, ConstVectorRef) const { return 0.0; }

void Problem::addTerminalGradient(ConstVectorRef, ConstVectorRef, VectorRef, VectorRef) const {}

}  // namespace hindsight
