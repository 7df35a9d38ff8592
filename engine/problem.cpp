#include <hindsight/engine/problem.h>

namespace hindsight {

void Problem::addInitialStateVjp(ConstVectorRef, ConstVectorRef, VectorRef) const {}

void Problem::rhsJacobian(double, ConstVectorRef, ConstVectorRef, MatrixRef, ProblemWorkspace*) const {
  throw std::logic_error("Problem '" + name() +
                         "' declares a dense Jacobian but does not implement rhsJacobian()");
}

void Problem::rhsStateVjp(double, ConstVectorRef, ConstVectorRef, ConstVectorRef, VectorRef,
                          ProblemWorkspace*) const {
  throw std::logic_error("Problem '" + name() +
                         "' has no dense Jacobian but does not implement rhsStateVjp()");
}

double Problem::terminal(ConstVectorRef, ConstVectorRef) const { return 0.0; }

void Problem::addTerminalGradient(ConstVectorRef, ConstVectorRef, VectorRef, VectorRef) const {}

}  // namespace hindsight
