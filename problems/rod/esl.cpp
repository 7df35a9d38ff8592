#include <hindsight/problems/rod/esl.h>

#include <hindsight/problems/rod/parallel.h>
#include <hindsight/problems/rod/solid_member.h>

#include <algorithm>
#include <memory>

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace hindsight {
namespace rod {

Matrix equivalentStaticLoads(const FeModel& model, const ModalBasis& basis, ConstMatrixRef modalCoordinates) {
  if (basis.modesFree.rows() != model.freeDofCount())
    throw std::invalid_argument(
        "equivalentStaticLoads: the modal basis does not belong to this FeModel (sizes differ)");
  if (modalCoordinates.rows() != basis.columnCount()) {
    std::ostringstream message;
    message << "equivalentStaticLoads: modalCoordinates has " << modalCoordinates.rows()
            << " rows, expected basis.columnCount() = " << basis.columnCount();
    throw std::invalid_argument(message.str());
  }
  return model.stiffness() * (basis.modesFree * modalCoordinates);
}

namespace {

void checkEndTime(const char* function, double endTime) {
  if (!std::isfinite(endTime) || !(endTime > 0.0)) {
    std::ostringstream message;
    message << function << ": endTime = " << endTime << " is outside the allowed range (0, inf)";
    throw std::invalid_argument(message.str());
  }
}

void checkEslArguments(const FeModel& model, ConstMatrixRef loads, double endTime) {
  if (loads.rows() != model.freeDofCount() || loads.cols() < 1) {
    std::ostringstream message;
    message << "evaluateEsl: loads are " << loads.rows() << " x " << loads.cols()
            << ", expected freeDofCount() = " << model.freeDofCount() << " rows and at least one column";
    throw std::invalid_argument(message.str());
  }
  checkEndTime("evaluateEsl", endTime);
}

template <class Member>
Vector eslGradient(const Member& model, const Matrix& displacementsFull, double weight);

}  // namespace

EslResult evaluateEsl(const FeModel& model, ConstMatrixRef loads, double endTime) {
  checkEslArguments(model, loads, endTime);
  std::unique_ptr<StiffnessFactorization> factorization;
  try {
    factorization = std::make_unique<StiffnessFactorization>(model.stiffness(), stiffnessOrdering(model));
  } catch (const std::runtime_error&) {
    throw std::runtime_error("evaluateEsl: the constrained stiffness matrix is not positive definite");
  }
  return evaluateEsl(model, loads, endTime, *factorization, true);
}

EslResult evaluateEsl(const FeModel& model, ConstMatrixRef loads, double endTime,
                      const StiffnessFactorization& factorization, bool withGradient) {
  checkEslArguments(model, loads, endTime);
  if (factorization.size() != model.freeDofCount())
    throw std::invalid_argument("evaluateEsl: the stiffness factorisation does not belong to this model");
  const double weight = endTime / static_cast<double>(loads.cols());

  EslResult result;
  // The load cases are independent: blocks of columns are solved in parallel threads
  // (problems/rod/parallel.h). The sparse triangular solves treat every column on its own, so a
  // block's columns get the bits of the whole solve, for any thread count.
  result.displacements.resize(loads.rows(), loads.cols());
  const int columns = static_cast<int>(loads.cols());
  const int columnBlocks = std::min(columns, 8);
  parallelFor(columnBlocks, [&](int b) {
    const int begin = b * columns / columnBlocks;
    const int end = (b + 1) * columns / columnBlocks;
    result.displacements.middleCols(begin, end - begin) =
        factorization.solve(Matrix(loads.middleCols(begin, end - begin)));
  });
  result.value = weight * loads.cwiseProduct(result.displacements).sum();
  if (withGradient)
    result.gradient = eslGradient(model, model.extendColumnsToFull(result.displacements), weight);
  return result;
}

namespace {

template <class Member>
EslResult eslAtLoadDesign(const Member& model, const ModalBasis& basis, ConstMatrixRef kee,
                          ConstMatrixRef modalCoordinates, double endTime, bool withGradient) {
  const Eigen::Index n = basis.columnCount();
  if (basis.modesFull.rows() != model.dofCount() || kee.rows() != n || kee.cols() != n ||
      modalCoordinates.rows() != n || modalCoordinates.cols() < 1) {
    std::ostringstream message;
    message << "evaluateEslAtLoadDesign: kee is " << kee.rows() << " x " << kee.cols()
            << " and modalCoordinates " << modalCoordinates.rows() << " x " << modalCoordinates.cols()
            << ", expected " << n << " x " << n << " and " << n
            << " rows, at least one column, for a basis of this model";
    throw std::invalid_argument(message.str());
  }
  checkEndTime("evaluateEslAtLoadDesign", endTime);
  const double weight = endTime / static_cast<double>(modalCoordinates.cols());
  EslResult result;
  result.value = weight * (kee * modalCoordinates).cwiseProduct(modalCoordinates).sum();
  if (withGradient) result.gradient = eslGradient(model, basis.modesFull * modalCoordinates, weight);
  return result;
}

// -weight sum_k u_k^T (dK/dx_d) u_k for every design variable, u_k the columns of `displacementsFull`.
template <class Member>
Vector eslGradient(const Member& model, const Matrix& displacementsFull, double weight) {
  constexpr int kDofs = Member::kElementDofs;
  Vector gradient(model.designCount());
  // Every design variable's entry on its own: fixed blocks in parallel.
  const int designs = model.designCount();
  const int designBlocks = (designs + 255) / 256;
  parallelFor(designBlocks, [&](int b) {
    // Both blocks sized once per thread: the loop over the elements allocates nothing.
    Eigen::Matrix<double, kDofs, Eigen::Dynamic> local(kDofs, displacementsFull.cols()),
        product(kDofs, local.cols());
    for (int d = b * 256; d < std::min(designs, (b + 1) * 256); ++d) {
      const std::array<int, kDofs> dofs = model.elementDofs(model.designToElement(d));
      for (int a = 0; a < kDofs; ++a) local.row(a) = displacementsFull.row(dofs[a]);
      product.noalias() = model.unitStiffness() * local;
      const double energy = local.cwiseProduct(product).sum();
      gradient(d) = -weight * model.simp().stiffnessDerivative(model.design()(d)) * energy;
    }
  });
  return gradient;
}

}  // namespace

EslResult evaluateEslAtLoadDesign(const FeModel& model, const ModalBasis& basis, ConstMatrixRef kee,
                                  ConstMatrixRef modalCoordinates, double endTime, bool withGradient) {
  return eslAtLoadDesign(model, basis, kee, modalCoordinates, endTime, withGradient);
}
EslResult evaluateEslAtLoadDesign(const SolidMember& model, const ModalBasis& basis, ConstMatrixRef kee,
                                  ConstMatrixRef modalCoordinates, double endTime, bool withGradient) {
  return eslAtLoadDesign(model, basis, kee, modalCoordinates, endTime, withGradient);
}

}  // namespace rod
}  // namespace hindsight
