// The mechanism's objective psi1 = int q^T K_ee q dt and its partials in y and in the invariants p
// (docs/design.md §2; the same psi1 as the built-in model's). psi2, the equivalent-static-load surrogate,
// is evaluated after the motion by problems/rod/esl.h and needs nothing of the mechanism.
#include <hindsight/problems/mechanism/detail/member_invariants.h>
#include <hindsight/problems/mechanism/detail/system.h>

namespace hindsight::mechanism {

using namespace detail;

double MechanismProblem::integrand(double, ConstVectorRef y, ConstVectorRef, ConstVectorRef p,
                                   ProblemWorkspace*) const {
  const View P(modes_, p.data(), impl_->spatial);
  const int o = impl_->nFree;
  double s = 0.0;
  for (int i = 0; i < modes_; ++i) {
    for (int j = 0; j < modes_; ++j) s += y(o + i) * P.kee(i, j) * y(o + j);
  }
  return s;
}

void MechanismProblem::addIntegrandStateGradient(double, ConstVectorRef y, ConstVectorRef, ConstVectorRef p,
                                                 double scale, VectorRef gy, VectorRef,
                                                 ProblemWorkspace*) const {
  const View P(modes_, p.data(), impl_->spatial);
  const int o = impl_->nFree;
  for (int i = 0; i < modes_; ++i) {
    for (int j = 0; j < modes_; ++j) gy(o + i) += scale * (P.kee(i, j) + P.kee(j, i)) * y(o + j);
  }
}

void MechanismProblem::addIntegrandParameterGradient(double, ConstVectorRef y, ConstVectorRef,
                                                     ConstVectorRef p, double scale, VectorRef gp,
                                                     ProblemWorkspace*) const {
  const View P(modes_, p.data(), impl_->spatial);
  const int o = impl_->nFree;
  for (int j = 0; j < modes_; ++j) {
    for (int i = 0; i < modes_; ++i) gp(P.keeOffset() + i + modes_ * j) += scale * y(o + i) * y(o + j);
  }
}

}  // namespace hindsight::mechanism
