#include <hindsight/problems/rod/esl.h>

#include <Eigen/SparseCholesky>

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

EslResult evaluateEsl(const FeModel& model, ConstMatrixRef loads, double endTime) {
  if (loads.rows() != model.freeDofCount() || loads.cols() < 1) {
    std::ostringstream message;
    message << "evaluateEsl: loads are " << loads.rows() << " x " << loads.cols()
            << ", expected freeDofCount() = " << model.freeDofCount() << " rows and at least one column";
    throw std::invalid_argument(message.str());
  }
  if (!std::isfinite(endTime) || !(endTime > 0.0)) {
    std::ostringstream message;
    message << "evaluateEsl: endTime = " << endTime << " is outside the allowed range (0, inf)";
    throw std::invalid_argument(message.str());
  }
  Eigen::SimplicialLLT<SparseMatrix> factorization(model.stiffness());
  if (factorization.info() != Eigen::Success)
    throw std::runtime_error("evaluateEsl: the constrained stiffness matrix is not positive definite");
  const double weight = endTime / static_cast<double>(loads.cols());

  EslResult result;
  result.displacements = factorization.solve(Matrix(loads));
  result.value = weight * loads.cwiseProduct(result.displacements).sum();
  const Matrix displacementsFull = model.extendColumnsToFull(result.displacements);
  result.gradient.resize(model.designCount());
  for (int d = 0; d < model.designCount(); ++d) {
    const std::array<int, 8> dofs = model.elementDofs(model.designToElement(d));
    Eigen::Matrix<double, 8, Eigen::Dynamic> local(8, displacementsFull.cols());
    for (int a = 0; a < 8; ++a) local.row(a) = displacementsFull.row(dofs[a]);
    const double energy = local.cwiseProduct(model.unitStiffness() * local).sum();
    result.gradient(d) = -weight * model.simp().stiffnessDerivative(model.design()(d)) * energy;
  }
  return result;
}

}  // namespace rod
}  // namespace hindsight
