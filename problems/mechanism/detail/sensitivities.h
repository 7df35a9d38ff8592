// The residual's products with the member's invariants, (r_p)^T mu: the design sensitivities of a
// described mechanism, which problems/rod/design_gradient.h chains through the modal basis (the adjoint
// Nelson solves) to the element densities (docs/design.md §4, §10). Defined in design_sensitivities.cpp.
// Internal to problems/mechanism/ (not installed).
#pragma once

#include <hindsight/problems/mechanism/detail/workspace.h>

namespace hindsight::mechanism::detail {

/// d(mu . r)/dp at fixed kinematics for the invariants other than b (r is linear in them): nu = R mu
/// on the member's coordinates (frame, q), the member's z, z', z'' (frame pointers of 3, modal of n).
void memberParameterProduct(const System& I, const View& P, const double* zf, const double* zdf,
                            const double* xf, const double* q, const double* qd, const double* qdd,
                            const Vector& nuv, VectorRef out);

/// out += (r_p)^T mu after chordKinematics() and modalProducts() (mom) at the point.
void parameterProduct(const System& I, const System& C, const View& P, double t, ConstVectorRef y,
                      ConstVectorRef v, ConstVectorRef a, ConstVectorRef mu, const double* mom, Work& w,
                      VectorRef out);

}  // namespace hindsight::mechanism::detail
