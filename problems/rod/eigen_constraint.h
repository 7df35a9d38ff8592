// The first eigenvalue of the pinned-roller rod and its exact design derivative: the quantity of the
// optimizer's guard against mechanisms, lambda_1(x) >= (2 pi f_min)^2 (optimization.minFirstFrequency).
//
// For a simple eigenvalue lambda with mass-normalised mode phi (phi^T M phi = 1),
//   d lambda / dx_d = phi^T (dK/dx_d - lambda dM/dx_d) phi = E'(x_d) phi_e^T Ke0 phi_e - lambda rho'(x_d)
//   phi_e^T Me0 phi_e
// on the element e of design variable d (dK/dx_d = E'(x_d) Ke0, dM/dx_d = rho'(x_d) Me0; fe_model.h).
//
// Repeated eigenvalue: a multiple lambda_1 is not differentiable (its derivative depends on the
// direction of the design change). What we do: the eigenvalues within a relative distance
// clusterTolerance of lambda_1 form a cluster of size J, and the guarded quantity is the cluster mean
// (1/J) sum_a lambda_a, whose derivative (1/J) sum_a phi_a^T (K' - lambda_a M') phi_a is the trace of the
// cluster's projected derivative: independent of which basis of the eigenspace the solver returned, so
// it is well defined. The mean exceeds lambda_1 by at most clusterTolerance lambda_1. For a simple
// lambda_1 (J = 1, the usual case) it is lambda_1 and its derivative exactly.
#pragma once

#include <hindsight/engine/types.h>
#include <hindsight/problems/rod/fe_model.h>

namespace hindsight {
namespace rod {

class SolidMember;

/// d lambda / dx_d for every design variable of `model`, for the eigenvalue `eigenvalue` with
/// mass-normalised mode `modeFull` on all DOFs (zeros at the constrained ones). Throws
/// std::invalid_argument when modeFull has not model.dofCount() entries.
Vector eigenvalueDesignGradient(const FeModel& model, double eigenvalue, ConstVectorRef modeFull);
Vector eigenvalueDesignGradient(const SolidMember& model, double eigenvalue, ConstVectorRef modeFull);

struct FirstEigenvalue {
  double value = 0.0;   ///< lambda_1, or the mean of its cluster [1/s^2]
  int clusterSize = 1;  ///< J: eigenvalues within clusterTolerance lambda_1 of lambda_1
  Vector gradient;      ///< d value / dx_d, model.designCount() entries
};

/// The guarded first eigenvalue and its gradient from ascending eigenvalues and their mass-normalised
/// modes (columns of modesFull, all DOFs), e.g. ModalBasis or PistonRodEvaluation. Throws
/// std::invalid_argument for empty or mismatched inputs or a clusterTolerance that is negative or not finite.
FirstEigenvalue firstEigenvalue(const FeModel& model, ConstVectorRef eigenvalues, ConstMatrixRef modesFull,
                                double clusterTolerance = 1e-6);
FirstEigenvalue firstEigenvalue(const SolidMember& model, ConstVectorRef eigenvalues,
                                ConstMatrixRef modesFull, double clusterTolerance = 1e-6);

}  // namespace rod
}  // namespace hindsight
