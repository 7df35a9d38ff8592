#include <hindsight/problems/rod/eigen_constraint.h>

#include <hindsight/problems/rod/solid_member.h>

#include <cmath>
#include <stdexcept>
#include <string>

namespace hindsight {
namespace rod {

namespace {

template <class Member>
Vector eigenvalueDesignGradientOf(const Member& model, double eigenvalue, ConstVectorRef modeFull) {
  constexpr int kDofs = Member::kElementDofs;
  if (modeFull.size() != model.dofCount()) {
    throw std::invalid_argument("eigenvalueDesignGradient: modeFull has " + std::to_string(modeFull.size()) +
                                " entries, expected dofCount = " + std::to_string(model.dofCount()));
  }
  Vector gradient(model.designCount());
  for (int d = 0; d < model.designCount(); ++d) {
    const double x = model.design()(d);
    const std::array<int, kDofs> dofs = model.elementDofs(model.designToElement(d));
    typename Member::ElementVectorType phi;
    for (int a = 0; a < kDofs; ++a) phi(a) = modeFull(dofs[a]);
    gradient(d) = model.simp().stiffnessDerivative(x) * phi.dot(model.unitStiffness() * phi) -
                  eigenvalue * model.simp().densityDerivative(x) * phi.dot(model.unitMass() * phi);
  }
  return gradient;
}

template <class Member>
FirstEigenvalue firstEigenvalueOf(const Member& model, ConstVectorRef eigenvalues, ConstMatrixRef modesFull,
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
    out.gradient += eigenvalueDesignGradientOf(model, eigenvalues(a), modesFull.col(a));
  }
  out.value /= size;
  out.gradient /= size;
  return out;
}

}  // namespace

Vector eigenvalueDesignGradient(const FeModel& model, double eigenvalue, ConstVectorRef modeFull) {
  return eigenvalueDesignGradientOf(model, eigenvalue, modeFull);
}
Vector eigenvalueDesignGradient(const SolidMember& model, double eigenvalue, ConstVectorRef modeFull) {
  return eigenvalueDesignGradientOf(model, eigenvalue, modeFull);
}
FirstEigenvalue firstEigenvalue(const FeModel& model, ConstVectorRef eigenvalues, ConstMatrixRef modesFull,
                                double clusterTolerance) {
  return firstEigenvalueOf(model, eigenvalues, modesFull, clusterTolerance);
}
FirstEigenvalue firstEigenvalue(const SolidMember& model, ConstVectorRef eigenvalues,
                                ConstMatrixRef modesFull, double clusterTolerance) {
  return firstEigenvalueOf(model, eigenvalues, modesFull, clusterTolerance);
}

}  // namespace rod
}  // namespace hindsight
