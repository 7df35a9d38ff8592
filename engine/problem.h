// The problem interface of the adjoint engine: a first-order system z' = F(t, z, p) with an
// objective psi = integral_{t0}^{t1} G(t, z, p) dt + phi(z(t1), p).
//
// A problem is immutable during a solve (docs/design.md P 3): every method is const and writes
// only into its output arguments and into the ProblemWorkspace it created itself. The engine
// creates one workspace per solve, before the first step, so evaluations allocate nothing.
//
// Dimensions: z in R^n (stateSize()), p in R^np (parameterSize()). Derivatives are the partials
// the continuous and discrete adjoints need (docs/design.md §5): F_z (dense Jacobian or a
// vector-Jacobian product), (F_p)^T w, G_z, G_p, and the terminal term's gradients. Every
// derivative a problem supplies is tested against finite differences with GradientChecker.
#pragma once

#include <hindsight/engine/types.h>

#include <memory>
#include <string>

namespace hindsight {

/// Scratch buffers of a problem, created once per solve by Problem::createWorkspace().
class ProblemWorkspace {
 public:
  virtual ~ProblemWorkspace() = default;
};

/// Solves with the Newton matrix (I - alpha * F_z(t, z, p)) of an implicit stage and with its
/// transpose (needed by the discrete adjoint). A problem with a large sparse Jacobian supplies its
/// own; the default is a dense LU of the Jacobian.
class NewtonSolver {
 public:
  virtual ~NewtonSolver() = default;
  /// Forms and factorises I - alpha * F_z(t, z, p).
  virtual void factorize(double t, ConstVectorRef z, ConstVectorRef p, double alpha,
                         ProblemWorkspace* ws) = 0;
  /// x <- (I - alpha F_z)^{-1} x, in place.
  virtual void solve(VectorRef x) = 0;
  /// x <- (I - alpha F_z)^{-T} x, in place.
  virtual void solveTransposed(VectorRef x) = 0;
};

class Problem {
 public:
  virtual ~Problem() = default;

  virtual std::string name() const = 0;
  virtual int stateSize() const = 0;
  virtual int parameterSize() const = 0;
  virtual std::unique_ptr<ProblemWorkspace> createWorkspace() const { return nullptr; }
  /// A workspace for a solve at the fixed parameters p: the problem may keep products of p in it,
  /// computed once instead of at every call. Every call with this workspace must pass the same p
  /// (the integrators hold p for the whole solve); a caller that varies p uses createWorkspace().
  /// Default: createWorkspace().
  virtual std::unique_ptr<ProblemWorkspace> createWorkspaceFor(ConstVectorRef p) const;

  /// z(t0) = z0(p).
  virtual void initialState(ConstVectorRef p, VectorRef z0) const = 0;
  /// gradient += (d z0 / d p)^T lambda0. Default: z0 does not depend on p.
  virtual void addInitialStateVjp(ConstVectorRef p, ConstVectorRef lambda0, VectorRef gradient) const;

  /// f = F(t, z, p).
  virtual void rhs(double t, ConstVectorRef z, ConstVectorRef p, VectorRef f, ProblemWorkspace* ws) const = 0;
  /// True when rhsJacobian() gives the dense n x n Jacobian (the default). A problem with a large
  /// state returns false and supplies rhsStateVjp() and createNewtonSolver() instead.
  virtual bool hasDenseJacobian() const { return true; }
  /// jacobian = dF/dz (n x n).
  virtual void rhsJacobian(double t, ConstVectorRef z, ConstVectorRef p, MatrixRef jacobian,
                           ProblemWorkspace* ws) const;
  /// True when rhsStateVjp() is implemented (also for a problem with a dense Jacobian): explicit
  /// stages of the discrete adjoint then use it instead of forming the Jacobian.
  virtual bool hasStateVjp() const { return !hasDenseJacobian(); }
  /// out = (dF/dz)^T w. Called when hasDenseJacobian() is false or hasStateVjp() is true.
  virtual void rhsStateVjp(double t, ConstVectorRef z, ConstVectorRef p, ConstVectorRef w, VectorRef out,
                           ProblemWorkspace* ws) const;
  /// out += (dF/dp)^T w.
  virtual void addRhsParameterVjp(double t, ConstVectorRef z, ConstVectorRef p, ConstVectorRef w,
                                  VectorRef out, ProblemWorkspace* ws) const = 0;
  /// outState = (dF/dz)^T w and gradient += (dF/dp)^T w at one point, for an explicit adjoint stage
  /// (called only when hasStateVjp() is true). A problem that shares work between the two products
  /// overrides this; the default calls rhsStateVjp() and addRhsParameterVjp().
  virtual void rhsVjps(double t, ConstVectorRef z, ConstVectorRef p, ConstVectorRef w, VectorRef outState,
                       VectorRef gradient, ProblemWorkspace* ws) const;
  /// Doubles of what rhs() computes at a point besides F and the products at that point reuse (a
  /// SecondOrderProblem: the acceleration and the Cholesky factor of M); 0 (the default): none. An explicit
  /// Runge-Kutta method keeps them per stage with its stage values (Integrator::stepDataSize()), so that
  /// its adjoint stage evaluates nothing of the rhs again.
  virtual int rhsDataSize() const { return 0; }
  /// data <- what the last rhs() with `ws` computed (rhsDataSize() doubles, the bits it computed).
  virtual void saveRhsData(ProblemWorkspace* ws, VectorRef data) const;
  /// Leaves `ws` as rhs(t, z, p) leaves it, from the data saveRhsData() gave after that call: the products at
  /// (t, z) then give the bits they give after rhs(t, z, p). Called only with rhsDataSize() > 0.
  virtual void restoreRhsData(double t, ConstVectorRef z, ConstVectorRef p, ConstVectorRef data,
                              ProblemWorkspace* ws) const;
  /// A solver for I - alpha F_z; nullptr means the engine's dense LU of rhsJacobian().
  virtual std::unique_ptr<NewtonSolver> createNewtonSolver() const { return nullptr; }
  /// True when F is affine in z (F = A(t, p) z + b(t, p)) and the Newton solve (createNewtonSolver() or
  /// the dense LU) is exact to round-off: an implicit stage is then solved by its first Newton step, and
  /// the engine skips the second iteration that would only confirm it (one F evaluation and one solve
  /// per implicit stage). Default false: Newton iterates to options.newtonTolerance.
  virtual bool isLinearInState() const { return false; }

  /// The objective integrand G(t, z, p).
  virtual double integrand(double t, ConstVectorRef z, ConstVectorRef p, ProblemWorkspace* ws) const = 0;
  /// out += scale * dG/dz.
  virtual void addIntegrandStateGradient(double t, ConstVectorRef z, ConstVectorRef p, double scale,
                                         VectorRef out, ProblemWorkspace* ws) const = 0;
  /// out += scale * dG/dp.
  virtual void addIntegrandParameterGradient(double t, ConstVectorRef z, ConstVectorRef p, double scale,
                                             VectorRef out, ProblemWorkspace* ws) const = 0;

  /// Terminal term phi(z(t1), p); default 0.
  virtual double terminal(ConstVectorRef z, ConstVectorRef p) const;
  /// gz += dphi/dz, gp += dphi/dp.
  virtual void addTerminalGradient(ConstVectorRef z, ConstVectorRef p, VectorRef gz, VectorRef gp) const;
};

}  // namespace hindsight
