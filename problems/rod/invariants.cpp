#include <hindsight/problems/rod/invariants.h>

#include <hindsight/problems/rod/solid_member.h>
#include <hindsight/problems/rod/sparse_products.h>

#include <sstream>
#include <stdexcept>

namespace hindsight {
namespace rod {

InvariantLayout::InvariantLayout(int n, bool isSpatial) : modeCount(n), spatial(isSpatial) {
  c1 = 4;
  c2 = c1 + 2 * n;
  a0 = c2 + n;
  cTilde = a0 + n;
  mee = cTilde + n * n;
  kee = mee + n * n;
  b = kee + n * n;
  meeRotation = spatial ? b + n : -1;
  size = b + n + (spatial ? n * n : 0);
}

Vector InertiaInvariants::pack() const {
  const int n = modeCount();
  const InvariantLayout layout(n, spatial());
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
  if (layout.spatial)
    packed.segment(layout.meeRotation, n * n) = Eigen::Map<const Vector>(meeRotation.data(), n * n);
  return packed;
}

InertiaInvariants InertiaInvariants::unpack(ConstVectorRef packed, int n) {
  if (n < 1)
    throw std::invalid_argument("InertiaInvariants::unpack: modeCount = " + std::to_string(n) +
                                " is outside the allowed range [1, inf)");
  const InvariantLayout layout(n, packed.size() == InvariantLayout(n, true).size);
  if (packed.size() != layout.size) {
    std::ostringstream message;
    message << "InertiaInvariants::unpack: packed vector has " << packed.size() << " entries, expected "
            << layout.size << " = 4 + 5 n + 3 n^2 (the plate) or 4 + 5 n + 4 n^2 (the solid) for n = " << n;
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
  if (layout.spatial) result.meeRotation = Eigen::Map<const Matrix>(packed.data() + layout.meeRotation, n, n);
  return result;
}

Matrix planarComponents(ConstMatrixRef full, int components) {
  Matrix result = full;
  if (components == 3) {
    for (Eigen::Index row = 2; row < result.rows(); row += 3) result.row(row).setZero();
  }
  return result;
}

namespace {

template <class Member>
InertiaInvariants computeInvariantsOf(const Member& model, const ModalBasis& basis) {
  constexpr int kComponents = Member::kComponents;
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
  const Matrix massModes = sparseTimesDense(mass, modes);

  InertiaInvariants result;
  result.mass = ex.dot(massEx);
  result.massTimesCenter << ex.dot(massX), ey.dot(massX);
  result.polarMoment = coordinates.dot(massX);
  result.c1.resize(2, modes.cols());
  result.c1.row(0) = massEx.transpose() * modes;
  result.c1.row(1) = massEy.transpose() * modes;
  result.c2 = massModes.transpose() * coordinates;
  result.a0 = massModes.transpose() * rotateNodewise(coordinates, kComponents);
  result.cTilde = massModes.transpose() * rotateNodewiseTransposedColumns(modes, kComponents);
  result.mee = modes.transpose() * massModes;
  // Element by element: the plain product with the assembled K carries ~eps lambda_max absolute error,
  // 2e-10 relative in lambda_1 on a high-contrast design, which psi1 would see as noise
  // (modal_reduction.h, refinementSteps). The refinement has summed it already for the eigenvalues.
  const bool kept = basis.stiffnessForm.rows() == modes.cols() && basis.stiffnessForm.cols() == modes.cols();
  result.kee = kept ? basis.stiffnessForm : elementwiseStiffnessForm(model, modes);
  if constexpr (kComponents == 2) {
    result.b = modes.row(model.jointBAxialDof()).transpose();
  } else {
    // The mean u_x of B's axis, and the rotation's modal mass Phi_xy^T M Phi_xy = Phi^T M Phi_xy.
    const std::vector<int> axis = model.jointBAxialDofs();
    result.b = Vector::Zero(modes.cols());
    for (int dof : axis) result.b += modes.row(dof).transpose();
    result.b /= static_cast<double>(axis.size());
    const Matrix planar = planarComponents(modes, kComponents);
    // Written out as ((M Phi_xy)^T Phi_xy)^T: the nested Phi_xy^T (M Phi_xy) that gave the recorded psi1
    // of the solid is, in this library's build, bitwise this transposed product, while a small program
    // with the same types evaluates it as Phi_xy^T T (measured); the two GEMMs handle the edge rows and
    // columns (n mod 4) in another order (bench/RESULTS.md, "The solid's assembly and sparse products").
    const Matrix massPlanar = sparseTimesDense(mass, planar);
    const Matrix transposedProduct = massPlanar.transpose() * planar;
    result.meeRotation = transposedProduct.transpose();
  }
  return result;
}

}  // namespace

InertiaInvariants computeInvariants(const FeModel& model, const ModalBasis& basis) {
  return computeInvariantsOf(model, basis);
}
InertiaInvariants computeInvariants(const SolidMember& model, const ModalBasis& basis) {
  return computeInvariantsOf(model, basis);
}

}  // namespace rod
}  // namespace hindsight
