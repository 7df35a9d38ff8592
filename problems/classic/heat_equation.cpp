#include <hindsight/problems/classic/heat_equation.h>

#include <hindsight/engine/deterministic_math.h>

#include <hindsight/engine/integrator.h>

#include <cmath>
#include <stdexcept>

namespace hindsight {

namespace {
constexpr double kPi = 3.14159265358979323846;
}  // namespace

// ---- TridiagonalLu ----

TridiagonalLu::TridiagonalLu(int size) : n_(size), lower_(size), pivot_(size), upper_(size) {
  if (size < 1)
    throw std::invalid_argument("TridiagonalLu: size = " + std::to_string(size) + " must be >= 1");
}

void TridiagonalLu::factorize(const Vector& sub, const Vector& diagonal, const Vector& super, double time) {
  assert(sub.size() == n_ && diagonal.size() == n_ && super.size() == n_);
  // A = L U with L unit lower bidiagonal and U upper bidiagonal: U(i, i+1) = A(i, i+1),
  // L(i, i-1) = A(i, i-1) / U(i-1, i-1), U(i, i) = A(i, i) - L(i, i-1) A(i-1, i).
  pivot_(0) = diagonal(0);
  lower_(0) = 0.0;
  for (int i = 0; i < n_; ++i) {
    if (i > 0) {
      lower_(i) = sub(i) / pivot_(i - 1);
      pivot_(i) = diagonal(i) - lower_(i) * super(i - 1);
    }
    upper_(i) = super(i);
    if (!std::isfinite(pivot_(i)) || std::abs(pivot_(i)) <= 1e-300) {
      throw NewtonFailure(
          "tridiagonal factorisation: pivot " + std::to_string(i) + " is " + std::to_string(pivot_(i)), time);
    }
  }
}

void TridiagonalLu::solve(VectorRef x) const {
  for (int i = 1; i < n_; ++i) x(i) -= lower_(i) * x(i - 1);
  x(n_ - 1) /= pivot_(n_ - 1);
  for (int i = n_ - 2; i >= 0; --i) x(i) = (x(i) - upper_(i) * x(i + 1)) / pivot_(i);
}

void TridiagonalLu::solveTransposed(VectorRef x) const {
  // A^T = U^T L^T: U^T is lower bidiagonal (diagonal pivot, U^T(i, i-1) = upper(i-1)), L^T unit upper.
  x(0) /= pivot_(0);
  for (int i = 1; i < n_; ++i) x(i) = (x(i) - upper_(i - 1) * x(i - 1)) / pivot_(i);
  for (int i = n_ - 2; i >= 0; --i) x(i) -= lower_(i + 1) * x(i + 1);
}

// ---- HeatEquation ----

namespace {

/// I - alpha F_z for the reaction-diffusion Jacobian, factorised by TridiagonalLu.
class ReactionDiffusionNewtonSolver final : public NewtonSolver {
 public:
  ReactionDiffusionNewtonSolver(int n, double h) : h_(h), lu_(n), sub_(n), diagonal_(n), super_(n) {}
  void factorize(double t, ConstVectorRef z, ConstVectorRef p, double alpha, ProblemWorkspace*) override {
    const double coupling = p(0) / (h_ * h_);
    const int n = static_cast<int>(z.size());
    for (int i = 0; i < n; ++i) {
      diagonal_(i) = 1.0 - alpha * (-2.0 * coupling + p(1) * (1.0 - 2.0 * z(i)));
      sub_(i) = i > 0 ? -alpha * coupling : 0.0;
      super_(i) = i + 1 < n ? -alpha * coupling : 0.0;
    }
    lu_.factorize(sub_, diagonal_, super_, t);
  }
  void solve(VectorRef x) override { lu_.solve(x); }
  void solveTransposed(VectorRef x) override { lu_.solveTransposed(x); }

 private:
  double h_;
  TridiagonalLu lu_;
  Vector sub_, diagonal_, super_;
};

}  // namespace

HeatEquation::HeatEquation(int gridPoints, int profileModes)
    : n_(gridPoints), modes_(profileModes), h_(1.0 / (gridPoints + 1.0)) {
  if (gridPoints < 1) {
    throw std::invalid_argument("HeatEquation: gridPoints = " + std::to_string(gridPoints) + " must be >= 1");
  }
  if (profileModes < 0) {
    throw std::invalid_argument("HeatEquation: profileModes = " + std::to_string(profileModes) +
                                " must be >= 0");
  }
}

Vector HeatEquation::nominalParameters() const {
  Vector p(parameterSize());
  p(0) = 1e-3;
  p(1) = 1.0;
  for (int j = 0; j < modes_; ++j) p(2 + j) = 0.5 / std::ldexp(1.0, j);
  return p;
}

void HeatEquation::initialState(ConstVectorRef p, VectorRef z0) const {
  for (int i = 0; i < n_; ++i) {
    const double x = (i + 1) * h_;
    double u = 0.0;
    for (int j = 0; j < modes_; ++j) u += p(2 + j) * dmath::sin((j + 1) * kPi * x);
    z0(i) = u;
  }
}

void HeatEquation::addInitialStateVjp(ConstVectorRef, ConstVectorRef lambda0, VectorRef gradient) const {
  for (int j = 0; j < modes_; ++j) {
    double sum = 0.0;
    for (int i = 0; i < n_; ++i) sum += lambda0(i) * dmath::sin((j + 1) * kPi * (i + 1) * h_);
    gradient(2 + j) += sum;
  }
}

void HeatEquation::rhs(double, ConstVectorRef z, ConstVectorRef p, VectorRef f, ProblemWorkspace*) const {
  const double coupling = p(0) / (h_ * h_);
  const double k = p(1);
  for (int i = 0; i < n_; ++i) {
    const double left = i > 0 ? z(i - 1) : 0.0;
    const double right = i + 1 < n_ ? z(i + 1) : 0.0;
    f(i) = coupling * (left - 2.0 * z(i) + right) + k * z(i) * (1.0 - z(i));
  }
}

void HeatEquation::rhsStateVjp(double, ConstVectorRef z, ConstVectorRef p, ConstVectorRef w, VectorRef out,
                               ProblemWorkspace*) const {
  // F_z is symmetric: (F_z^T w)_i = D/h^2 (w_{i-1} - 2 w_i + w_{i+1}) + k (1 - 2 u_i) w_i.
  const double coupling = p(0) / (h_ * h_);
  const double k = p(1);
  for (int i = 0; i < n_; ++i) {
    const double left = i > 0 ? w(i - 1) : 0.0;
    const double right = i + 1 < n_ ? w(i + 1) : 0.0;
    out(i) = coupling * (left - 2.0 * w(i) + right) + k * (1.0 - 2.0 * z(i)) * w(i);
  }
}

void HeatEquation::addRhsParameterVjp(double, ConstVectorRef z, ConstVectorRef, ConstVectorRef w,
                                      VectorRef out, ProblemWorkspace*) const {
  // dF/dD = (u_{i-1} - 2 u_i + u_{i+1}) / h^2, dF/dk = u_i (1 - u_i); F does not depend on a.
  double diffusion = 0.0, reaction = 0.0;
  for (int i = 0; i < n_; ++i) {
    const double left = i > 0 ? z(i - 1) : 0.0;
    const double right = i + 1 < n_ ? z(i + 1) : 0.0;
    diffusion += w(i) * (left - 2.0 * z(i) + right);
    reaction += w(i) * z(i) * (1.0 - z(i));
  }
  out(0) += diffusion / (h_ * h_);
  out(1) += reaction;
}

std::unique_ptr<NewtonSolver> HeatEquation::createNewtonSolver() const {
  return std::make_unique<ReactionDiffusionNewtonSolver>(n_, h_);
}

double HeatEquation::integrand(double, ConstVectorRef z, ConstVectorRef, ProblemWorkspace*) const {
  return h_ * z.squaredNorm();
}

void HeatEquation::addIntegrandStateGradient(double, ConstVectorRef z, ConstVectorRef, double scale,
                                             VectorRef out, ProblemWorkspace*) const {
  out += (2.0 * h_ * scale) * z;
}

void HeatEquation::addIntegrandParameterGradient(double, ConstVectorRef, ConstVectorRef, double, VectorRef,
                                                 ProblemWorkspace*) const {}

}  // namespace hindsight
