// The one error norm and the one step-size controller of the engine, shared by the adaptive forward
// sweep (engine/adjoint.cpp), the Runge-Kutta error estimate (engine/runge_kutta.cpp) and the
// backward integrators of the continuous adjoint (engine/continuous_adjoint.cpp), so that every
// adaptive loop accepts, rejects and resizes steps by the same rule.
//
// Error norm: the weighted RMS norm ||e|| = sqrt(mean_i (e_i / (atol + rtol max(|y0_i|, |y1_i|)))^2)
// of an error estimate e over a step from y0 to y1 (Hairer, Norsett & Wanner, Solving ODEs I, II.4);
// a step is acceptable when ||e|| <= 1. The tolerances are scalars or, as in CVODES
// (CVodeSVtolerances), per component: a component whose magnitude differs by orders from the others
// (Robertson's y2 ~ 1e-5 beside y1, y3 ~ 1) needs its own atol_i, and a quadrature appended to a
// state (the continuous adjoint's mu beside lambda) its own rtol and atol.
//
// Controller: the elementary (I-) controller h_new = h * 0.9 ||e||^(-1/(q+1)) for an estimate of
// O(h^(q+1)), the factor clamped to [0.2, 5] after an accepted step and to [0.1, 0.9] after a rejected
// one; a failed Newton iteration (or a non-finite trial state) quarters the step.
#pragma once

#include <hindsight/engine/types.h>

#include <string>
#include <vector>

namespace hindsight {

/// The weighted RMS norm above; error, y0 and y1 have the same size (> 0).
double weightedRmsNorm(ConstVectorRef error, ConstVectorRef y0, ConstVectorRef y1, double relativeTolerance,
                       double absoluteTolerance);
/// The same with per-component tolerances: scale_i = atol_i + rtol_i max(|y0_i|, |y1_i|). With every
/// rtol_i and atol_i equal to scalars it gives the scalar version's bits (same operations, same order).
double weightedRmsNorm(ConstVectorRef error, ConstVectorRef y0, ConstVectorRef y1,
                       ConstVectorRef relativeTolerances, ConstVectorRef absoluteTolerances);
/// max_i |v_i| (0 for an empty vector): the measure of the implicit integrators' Newton corrections
/// (engine/runge_kutta.cpp, engine/generalized_alpha.cpp).
double infNorm(ConstVectorRef v);

/// Per-component tolerances as options give them (an empty vector: use the scalar). The first entry
/// that is not positive and finite, as "FIELD[i] = value must be positive and finite"; empty when all
/// are. One check for every options struct that takes such a vector (integrator, continuous adjoint,
/// CVODES).
std::string invalidToleranceEntry(const std::vector<double>& tolerances, const std::string& field);
/// Throws std::invalid_argument "FIELD has N entries, problem 'NAME' has M states (MEANING)" when a
/// non-empty `tolerances` does not have one entry per state.
void requireOneTolerancePerState(const std::vector<double>& tolerances, const std::string& field,
                                 const std::string& problemName, int stateSize, const std::string& meaning);

class StepSizeController {
 public:
  /// errorOrder q: the error estimate is O(h^(q+1)) (min of the two orders of an embedded pair).
  explicit StepSizeController(int errorOrder) : exponent_(-1.0 / (errorOrder + 1.0)) {}

  /// The next step after an accepted step of size h with error norm `norm` (<= 1).
  double afterAccepted(double h, double norm) const;
  /// The retry after a step of size h rejected with error norm `norm` (> 1).
  double afterRejected(double h, double norm) const;
  /// The retry after a step of size h whose Newton iteration failed.
  double afterFailed(double h) const { return 0.25 * h; }

 private:
  double exponent_;
};

}  // namespace hindsight
