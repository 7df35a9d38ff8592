// Adapter from the second-order mechanical form M(t, y, p) y'' = f(t, y, y', p) (docs/design.md §5,
// the paper's eq. 3) to the first-order interface with state z = (y, v), v = y'.
//
// The model supplies the mass matrix, the force vector and the Jacobians of the residual
// r(t, y, v, a, p) = M(t, y, p) a - f(t, y, v, p) at the current acceleration a. The adapter derives
//   F = (v, a),  a = M^{-1} f,
//   F_z = [[0, I], [-M^{-1} r_y, -M^{-1} r_v]],
//   (F_p)^T (w_y, w_v) = -(r_p)^T M^{-T} w_v,
// so the model never forms M^{-1}. Sizes: f coordinates, state size 2f. The mass matrix must be
// symmetric positive definite; a failed Cholesky factorisation throws NumericalError with the time.
#pragma once

#include <hindsight/engine/problem.h>

namespace hindsight {

class SecondOrderProblem : public Problem {
 public:
  /// Number f of generalised coordinates y.
  virtual int coordinateCount() const = 0;
  /// Scratch buffers of the model; created once per solve.
  virtual std::unique_ptr<ProblemWorkspace> createModelWorkspace() const { return nullptr; }
  /// Scratch buffers for a solve at the fixed p (Problem::createWorkspaceFor): the model may keep
  /// products of p in them. Default: createModelWorkspace().
  virtual std::unique_ptr<ProblemWorkspace> createModelWorkspaceFor(ConstVectorRef p) const;

  virtual void initialCoordinates(ConstVectorRef p, VectorRef y0, VectorRef v0) const = 0;
  /// gradient += (dy0/dp)^T lambdaY + (dv0/dp)^T lambdaV. Default: independent of p.
  virtual void addInitialCoordinatesVjp(ConstVectorRef p, ConstVectorRef lambdaY, ConstVectorRef lambdaV,
                                        VectorRef gradient) const;

  virtual void massMatrix(double t, ConstVectorRef y, ConstVectorRef p, MatrixRef mass,
                          ProblemWorkspace* ws) const = 0;
  virtual void force(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef p, VectorRef f,
                     ProblemWorkspace* ws) const = 0;
  /// mass = M(t, y, p) and f = f(t, y, v, p) at one point. A model that shares work between the two
  /// (kinematics, products of y) overrides this; the default calls massMatrix() and force().
  virtual void massMatrixAndForce(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef p,
                                  MatrixRef mass, VectorRef f, ProblemWorkspace* ws) const;
  /// dr/dy and dr/dv of r = M(t, y, p) a - f(t, y, v, p), at the given a.
  virtual void residualJacobians(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef a,
                                 ConstVectorRef p, MatrixRef ry, MatrixRef rv,
                                 ProblemWorkspace* ws) const = 0;
  /// out += (dr/dp)^T mu at the given a.
  virtual void addResidualParameterVjp(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef a,
                                       ConstVectorRef p, ConstVectorRef mu, VectorRef out,
                                       ProblemWorkspace* ws) const = 0;

  /// True when residualStateVjp() is implemented; the adapter then offers rhsStateVjp() so that
  /// explicit adjoint stages need no Jacobian.
  virtual bool hasResidualStateVjp() const { return false; }
  /// outY = (dr/dy)^T mu, outV = (dr/dv)^T mu at the given a.
  virtual void residualStateVjp(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef a,
                                ConstVectorRef p, ConstVectorRef mu, VectorRef outY, VectorRef outV,
                                ProblemWorkspace* ws) const;

  /// outY = (dr/dy)^T mu, outV = (dr/dv)^T mu and gradient += (dr/dp)^T mu at one point (an explicit
  /// adjoint stage needs all three). Default: residualStateVjp() and addResidualParameterVjp().
  virtual void residualVjps(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef a, ConstVectorRef p,
                            ConstVectorRef mu, VectorRef outY, VectorRef outV, VectorRef gradient,
                            ProblemWorkspace* ws) const;

  /// The integrand G(t, y, v, p) and its gradients (gy, gv, gp += scale * ...): the same concept and
  /// name as Problem::integrand, stated in the coordinates; the first-order overloads below call these.
  /// A subclass that overrides these hides the first-order overloads in its own scope (C++ name
  /// hiding): call those through a `const Problem&`, as the engine does.
  virtual double integrand(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef p,
                           ProblemWorkspace* ws) const = 0;
  virtual void addIntegrandStateGradient(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef p,
                                         double scale, VectorRef gy, VectorRef gv,
                                         ProblemWorkspace* ws) const = 0;
  virtual void addIntegrandParameterGradient(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef p,
                                             double scale, VectorRef gp, ProblemWorkspace* ws) const = 0;

  // ---- The first-order interface, derived from the above. ----
  int stateSize() const final { return 2 * coordinateCount(); }
  std::unique_ptr<ProblemWorkspace> createWorkspace() const final;
  std::unique_ptr<ProblemWorkspace> createWorkspaceFor(ConstVectorRef p) const final;
  void initialState(ConstVectorRef p, VectorRef z0) const final;
  void addInitialStateVjp(ConstVectorRef p, ConstVectorRef lambda0, VectorRef gradient) const final;
  void rhs(double t, ConstVectorRef z, ConstVectorRef p, VectorRef f, ProblemWorkspace* ws) const final;
  void rhsJacobian(double t, ConstVectorRef z, ConstVectorRef p, MatrixRef jacobian,
                   ProblemWorkspace* ws) const final;
  void addRhsParameterVjp(double t, ConstVectorRef z, ConstVectorRef p, ConstVectorRef w, VectorRef out,
                          ProblemWorkspace* ws) const final;
  /// The acceleration a and the lower triangle of M's Cholesky factor, f + f (f + 1) / 2 doubles: restored,
  /// the products at the point solve with M without forming or factorising it again. The model's own
  /// products (residualVjps() and the others) must therefore not read what massMatrixAndForce() left in
  /// the model workspace.
  int rhsDataSize() const override;
  void saveRhsData(ProblemWorkspace* ws, VectorRef data) const final;
  void restoreRhsData(double t, ConstVectorRef z, ConstVectorRef p, ConstVectorRef data,
                      ProblemWorkspace* ws) const final;
  bool hasStateVjp() const final { return hasResidualStateVjp(); }
  /// F_z^T w = (-r_y^T mu, w_y - r_v^T mu) with mu = M^{-1} w_v.
  void rhsStateVjp(double t, ConstVectorRef z, ConstVectorRef p, ConstVectorRef w, VectorRef out,
                   ProblemWorkspace* ws) const final;
  /// One factorisation of M and one mu = M^{-1} w_v for both products (residualVjps()).
  void rhsVjps(double t, ConstVectorRef z, ConstVectorRef p, ConstVectorRef w, VectorRef outState,
               VectorRef gradient, ProblemWorkspace* ws) const final;
  double integrand(double t, ConstVectorRef z, ConstVectorRef p, ProblemWorkspace* ws) const final;
  void addIntegrandStateGradient(double t, ConstVectorRef z, ConstVectorRef p, double scale, VectorRef out,
                                 ProblemWorkspace* ws) const final;
  void addIntegrandParameterGradient(double t, ConstVectorRef z, ConstVectorRef p, double scale,
                                     VectorRef out, ProblemWorkspace* ws) const final;
};

}  // namespace hindsight
