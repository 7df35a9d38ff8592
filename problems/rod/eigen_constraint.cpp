#include <hindsight/problems/rod/eigen_constraint.h>

#include <cmath>
#include <stdexcept>
#include <string>

namespace hindsight {
namespace rod {

Vector eigenvalueDesignGradient(const FeModel& model, double eigenvalue, ConstVectorRef modeFull) {
  if (modeFull.size() != model.dofCount()) {
    throw std::invalid_argument("eigenvalueDesignGradient: modeFull has " + std::to_string(modeFull.size()) +
                                " entries, expected dofCount = " + std::to_string(model.dofCount()));
  }
  Vector gradient(model.designCount());
  for (int d = 0; d < model.designCount(); ++d) {
    const double x = model.design()(d);
    const std::array<int, 8> dofs = model.elementDofs(model.designToElement(d));
    ElementVector phi;
    for (int a = 0; a < 8; ++a) phi(a) = modeFull(dofs[a]);
    gradient(d) = model.simp().stiffnessDerivative(x) * phi.dot(model.unitStiffness() * phi) -
                  eigenvalue * model.simp().densityDerivative(x) * phi.dot(model.unitMass() * phi);
  }
  return gradient;
}

FirstEigenvalue firstEigenvalue(const FeModel& model, ConstVectorRef eigenvalues, ConstMatrixRef modesFull,
                                double clusterTolerance) {
  if (eigenvalues.size() < 1 || modesFull.cols() < eigenvalues.size() || modesFull.rows() != model.dofCount())
    throw std::invalid_argument(
        "firstEigenvalue: need at least one eigenvalue and one mode column per "
        "eigenvalue on all " +
        std::to_string(model.dofCount()) + " DOFs");
  if (!(clusterTolerance >= 0.0 && std::isfinite(clusterTolerance)))
    throw std::invalid_argument("firstEigenvalue: clusterTolerance = " + std::to_string(clusterTolerance) +
                                " must be >= 0 and finite");
  FirstEigenvalue out;
  const double first = eigenvalues(0);
  int size = 1;
  while (size < eigenvalues.size() && eigenvalues(size) - first <= clusterTolerance * first) ++size;
  out.clusterSize = size;
  out.value = 0.0;
  out.gradient = Vector::Zero(model.designCount());
  for (int a = 0; a < size; ++a) {
    out.value += eigenvalues(a);
    out.gradient += eigenvalueDesignGradient(model, eigenvalues(a), modesFull.col(a));
  }
  out.value /= size;
  out.gradient /= size;
  return out;
}

}  // namespace rod
}  // namespace hindsight
