#include <hindsight/problems/rod/invariants.h>

#include <sstream>
#include <stdexcept>

namespace hindsight {
namespace rod {

InvariantLayout::InvariantLayout(int n) : modeCount(n) {
  c1 = 4;
  c2 = c1 + 2 * n;
  a0 = c2 + n;
  cTilde = a0 + n;
  mee = cTilde + n * n;
  kee = mee + n * n;
  b = kee + n * n;
  size = b + n;
}

Vector InertiaInvariants::pack() const {
  const int n = modeCount();
  const InvariantLayout layout(n);
  Vector packed(layout.size);
  packed(layout.mass) = mass;
  packed.segment<2>(layout.massTimesCenter) = massTimesCenter;
  packed(layout.polarMoment) = polarMoment;
  packed.segment(layout.c1, 2 * n) = Eigen::Map<const Vector>(c1.data(), 2 * n);
  packed.segment(layout.c2, n) = c2;
  packed.segment(layout.a0, n) = a0;
  packed.segment(layout.cTilde, n * n) = Eigen::Map<const Vector>(cTilde.data(), n * n);
  packed.segment(layout.mee, n * n) = Eigen::Map<const Vector>(mee.data(), n * n);
  packed.segment(layout.kee, n * n) = Eigen::Map<const Vector>(kee.data(), n * n);
  packed.segment(layout.b, n) = b;
  return packed;
}

InertiaInvariants InertiaInvariants::unpack(ConstVectorRef packed, int n) {
  if (n < 1)
    throw std::invalid_argument("InertiaInvariants::unpack: modeCount = " + std::to_string(n) +
                                " is outside the allowed range [1, inf)");
  const InvariantLayout layout(n);
  if (packed.size() != layout.size) {
    std::ostringstream message;
    message << "InertiaInvariants::unpack: packed vector has " << packed.size() << " entries, expected "
            << layout.size << " = 4 + 5 n + 3 n^2 for n = " << n;
    throw std::invalid_argument(message.str());
  }
  InertiaInvariants result;
  result.mass = packed(layout.mass);
  result.massTimesCenter = packed.segment<2>(layout.massTimesCenter);
  result.polarMoment = packed(layout.polarMoment);
  result.c1 = Eigen::Map<const Matrix>(packed.data() + layout.c1, 2, n);
  result.c2 = packed.segment(layout.c2, n);
  result.a0 = packed.segment(layout.a0, n);
  result.cTilde = Eigen::Map<const Matrix>(packed.data() + layout.cTilde, n, n);
  result.mee = Eigen::Map<const Matrix>(packed.data() + layout.mee, n, n);
  result.kee = Eigen::Map<const Matrix>(packed.data() + layout.kee, n, n);
  result.b = packed.segment(layout.b, n);
  return result;
}

InertiaInvariants computeInvariants(const FeModel& model, const ModalBasis& basis) {
  if (basis.modesFull.rows() != model.dofCount() || basis.modesFull.cols() != basis.columnCount()) {
    std::ostringstream message;
    message << "computeInvariants: basis.modesFull is " << basis.modesFull.rows() << " x "
            << basis.modesFull.cols() << ", expected dofCount() = " << model.dofCount() << " rows and "
            << basis.columnCount() << " columns";
    throw std::invalid_argument(message.str());
  }
  const SparseMatrix& mass = model.massFull();
  const Vector& ex = model.unitTranslationX();
  const Vector& ey = model.unitTranslationY();
  const Vector& coordinates = model.referenceCoordinates();
  const Matrix& modes = basis.modesFull;

  const Vector massEx = mass * ex;
  const Vector massEy = mass * ey;
  const Vector massX = mass * coordinates;
  const Matrix massModes = mass * modes;

  InertiaInvariants result;
  result.mass = ex.dot(massEx);
  result.massTimesCenter << ex.dot(massX), ey.dot(massX);
  result.polarMoment = coordinates.dot(massX);
  result.c1.resize(2, modes.cols());
  result.c1.row(0) = massEx.transpose() * modes;
  result.c1.row(1) = massEy.transpose() * modes;
  result.c2 = massModes.transpose() * coordinates;
  result.a0 = massModes.transpose() * rotateNodewise(coordinates);
  result.cTilde = massModes.transpose() * rotateNodewiseTransposedColumns(modes);
  result.mee = modes.transpose() * massModes;
  // Element by element: the plain product with the assembled K carries ~eps lambda_max absolute error,
  // 2e-10 relative in lambda_1 on a high-contrast design, which psi1 would see as noise
  // (modal_reduction.h, refinementSteps). The refinement has summed it already for the eigenvalues.
  const bool kept = basis.stiffnessForm.rows() == modes.cols() && basis.stiffnessForm.cols() == modes.cols();
  result.kee = kept ? basis.stiffnessForm : elementwiseStiffnessForm(model, modes);
  result.b = modes.row(model.jointBAxialDof()).transpose();
  return result;
}

}  // namespace rod
}  // namespace hindsight
