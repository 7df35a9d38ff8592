// A large-state test problem for trajectory-storage experiments (docs/design.md §8): the 1-D
// reaction-diffusion (Fisher-KPP) equation u_t = D u_xx + k u (1 - u) on x in (0, 1), u = 0 at both
// ends, semi-discretised by second-order central differences on n interior points x_i = i h,
// h = 1 / (n + 1):
//     u_i' = D (u_{i-1} - 2 u_i + u_{i+1}) / h^2 + k u_i (1 - u_i),   i = 1..n,  u_0 = u_{n+1} = 0.
// Initial profile u(0, x) = sum_{j=1..m} a_j sin(j pi x). Objective psi = int_0^T h sum_i u_i^2 dt
// (the trapezoidal-free Riemann sum of int int u^2 dx dt on the grid).
// Parameters p = (D, k, a_1, ..., a_m), np = m + 2. Units are nondimensional.
//
// The Jacobian F_z = D/h^2 tridiag(1, -2, 1) + diag(k (1 - 2 u_i)) is symmetric tridiagonal; the problem
// reports hasDenseJacobian() == false, supplies (F_z)^T w in O(n) and a tridiagonal Newton solver
// (Thomas algorithm without pivoting, O(n) per factorisation and solve) for the implicit methods.
// Explicit methods are stable for h_t <~ 2.78 h^2 / (4 D) (RK4), so large n wants small D or an implicit
// method. Preconditions: n >= 1, m >= 0 (std::invalid_argument otherwise).
// Complexity: F, (F_z)^T w, (F_p)^T w and G in O(n) without allocation; one Newton factorisation and each
// solve O(n). Memory per state 8 n bytes (80 kB at n = 10^4), which is what makes storage matter.
// References: Fisher 1937 (Ann. Eugenics 7:355-369) and Kolmogorov, Petrovsky & Piskunov 1937 for the
// equation; Thomas algorithm e.g. Golub & Van Loan, Matrix Computations, 4th ed., section 4.3.
#pragma once

#include <hindsight/engine/problem.h>

#include <memory>
#include <vector>

namespace hindsight {

/// LU factorisation of a tridiagonal matrix without pivoting (Thomas algorithm), with solves by the
/// matrix and its transpose. Throws NewtonFailure (with the time given to factorize) when a pivot
/// vanishes or is not finite; stable for diagonally dominant matrices such as I - alpha F_z above.
class TridiagonalLu {
 public:
  explicit TridiagonalLu(int size);
  /// sub(i) = A(i, i-1) for i >= 1, diagonal(i) = A(i, i), super(i) = A(i, i+1) for i < n-1.
  void factorize(const Vector& sub, const Vector& diagonal, const Vector& super, double time);
  void solve(VectorRef x) const;            ///< x <- A^{-1} x
  void solveTransposed(VectorRef x) const;  ///< x <- A^{-T} x

 private:
  int n_;
  Vector lower_;  // L(i, i-1), unit lower bidiagonal L
  Vector pivot_;  // U(i, i)
  Vector upper_;  // U(i, i+1) = super(i)
};

class HeatEquation final : public Problem {
 public:
  /// n interior grid points and m sine modes in the initial profile.
  explicit HeatEquation(int gridPoints = 1000, int profileModes = 3);

  /// (D, k, a) = (1e-3, 1, 0.5, 0.25, 0.125, ...): a smooth bump that grows and spreads.
  Vector nominalParameters() const;

  std::string name() const override { return "reaction-diffusion"; }
  int stateSize() const override { return n_; }
  int parameterSize() const override { return modes_ + 2; }
  double gridSpacing() const { return h_; }

  void initialState(ConstVectorRef p, VectorRef z0) const override;
  void addInitialStateVjp(ConstVectorRef p, ConstVectorRef lambda0, VectorRef gradient) const override;
  void rhs(double t, ConstVectorRef z, ConstVectorRef p, VectorRef f, ProblemWorkspace* ws) const override;
  bool hasDenseJacobian() const override { return false; }
  void rhsStateVjp(double t, ConstVectorRef z, ConstVectorRef p, ConstVectorRef w, VectorRef out,
                   ProblemWorkspace* ws) const override;
  void addRhsParameterVjp(double t, ConstVectorRef z, ConstVectorRef p, ConstVectorRef w, VectorRef out,
                          ProblemWorkspace* ws) const override;
  std::unique_ptr<NewtonSolver> createNewtonSolver() const override;
  double integrand(double t, ConstVectorRef z, ConstVectorRef p, ProblemWorkspace* ws) const override;
  void addIntegrandStateGradient(double t, ConstVectorRef z, ConstVectorRef p, double scale, VectorRef out,
                                 ProblemWorkspace* ws) const override;
  void addIntegrandParameterGradient(double t, ConstVectorRef z, ConstVectorRef p, double scale,
                                     VectorRef out, ProblemWorkspace* ws) const override;

 private:
  int n_;
  int modes_;
  double h_;
};

}  // namespace hindsight
