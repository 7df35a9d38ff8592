#include <hindsight/engine/second_order_problem.h>

#include <Eigen/Cholesky>

#include <cstring>

namespace hindsight {
namespace {

struct SecondOrderWorkspace final : ProblemWorkspace {
  explicit SecondOrderWorkspace(int f)
      : mass(f, f),
        cholesky(f),
        restoredFactor(f, f),
        force(f),
        acceleration(f),
        mu(f),
        ry(f, f),
        rv(f, f),
        cachedState(2 * f) {}
  std::unique_ptr<ProblemWorkspace> model;
  Matrix mass;
  Eigen::LLT<Matrix> cholesky;
  // The Cholesky factor of the cached point when it came from restoreRhsData() (lower triangle; the
  // upper one is not read), in place of `cholesky`'s.
  Matrix restoredFactor;
  bool factorRestored = false;
  Vector force, acceleration, mu;
  Matrix ry, rv;
  // The acceleration of the last (t, y, v, p): rhs, Jacobian and parameter products at one stage
  // share it instead of refactorising M. Compared bit for bit, so results do not change. A workspace
  // made for a fixed p (createWorkspaceFor) compares (t, y, v) only.
  bool cacheValid = false;
  bool parametersFixed = false;
  double cachedTime = 0.0;
  Vector cachedState, cachedParameters;
};

SecondOrderWorkspace& workspaceOf(ProblemWorkspace* ws) {
  assert(ws != nullptr && "SecondOrderProblem needs the workspace it created");
  return static_cast<SecondOrderWorkspace&>(*ws);
}

// x <- M^{-1} x at the cached point: LLT::solveInPlace, or for a restored factor the same two triangular
// solves (Eigen's LLT<Matrix, Lower>::solveInPlace: L, then L^T) on a matrix of the same type and layout,
// so both give the same bits.
template <typename Derived>
void solveMass(const SecondOrderWorkspace& w, const Eigen::MatrixBase<Derived>& x) {
  if (!w.factorRestored) {
    w.cholesky.solveInPlace(x);
    return;
  }
  w.restoredFactor.triangularView<Eigen::Lower>().solveInPlace(x);
  w.restoredFactor.adjoint().triangularView<Eigen::Upper>().solveInPlace(x);
}

// a = M^{-1} f at (t, y, v); leaves the factorisation of M in the workspace.
void solveAcceleration(const SecondOrderProblem& problem, double t, ConstVectorRef y, ConstVectorRef v,
                       ConstVectorRef p, SecondOrderWorkspace& w) {
  const Eigen::Index f = y.size();
  assert(!w.parametersFixed || w.cachedParameters == p);
  if (w.cacheValid && t == w.cachedTime && w.cachedState.head(f) == y && w.cachedState.tail(f) == v &&
      (w.parametersFixed || w.cachedParameters == p)) {
    return;
  }
  w.cacheValid = false;
  w.factorRestored = false;
  problem.massMatrixAndForce(t, y, v, p, w.mass, w.force, w.model.get());
  w.cholesky.compute(w.mass);
  if (w.cholesky.info() != Eigen::Success) {
    throw NumericalError("mass matrix of '" + problem.name() + "' is not positive definite", t);
  }
  w.acceleration = w.force;
  w.cholesky.solveInPlace(w.acceleration);
  w.cachedTime = t;
  w.cachedState.head(f) = y;
  w.cachedState.tail(f) = v;
  if (!w.parametersFixed) w.cachedParameters = p;
  w.cacheValid = true;
}

}  // namespace

void SecondOrderProblem::addInitialCoordinatesVjp(ConstVectorRef, ConstVectorRef, ConstVectorRef,
                                                  VectorRef) const {}

std::unique_ptr<ProblemWorkspace> SecondOrderProblem::createModelWorkspaceFor(ConstVectorRef) const {
  return createModelWorkspace();
}

void SecondOrderProblem::massMatrixAndForce(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef p,
                                            MatrixRef mass, VectorRef f, ProblemWorkspace* ws) const {
  massMatrix(t, y, p, mass, ws);
  force(t, y, v, p, f, ws);
}

void SecondOrderProblem::residualVjps(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef a,
                                      ConstVectorRef p, ConstVectorRef mu, VectorRef outY, VectorRef outV,
                                      VectorRef gradient, ProblemWorkspace* ws) const {
  residualStateVjp(t, y, v, a, p, mu, outY, outV, ws);
  addResidualParameterVjp(t, y, v, a, p, mu, gradient, ws);
}

std::unique_ptr<ProblemWorkspace> SecondOrderProblem::createWorkspace() const {
  auto ws = std::make_unique<SecondOrderWorkspace>(coordinateCount());
  ws->cachedParameters.resize(parameterSize());
  ws->model = createModelWorkspace();
  return ws;
}

std::unique_ptr<ProblemWorkspace> SecondOrderProblem::createWorkspaceFor(ConstVectorRef p) const {
  auto ws = std::make_unique<SecondOrderWorkspace>(coordinateCount());
  // Kept for the debug check that every call passes this p (Problem::createWorkspaceFor).
  ws->cachedParameters = p;
  ws->parametersFixed = true;
  ws->model = createModelWorkspaceFor(p);
  return ws;
}

void SecondOrderProblem::initialState(ConstVectorRef p, VectorRef z0) const {
  const int f = coordinateCount();
  initialCoordinates(p, z0.head(f), z0.tail(f));
}

void SecondOrderProblem::addInitialStateVjp(ConstVectorRef p, ConstVectorRef lambda0,
                                            VectorRef gradient) const {
  const int f = coordinateCount();
  addInitialCoordinatesVjp(p, lambda0.head(f), lambda0.tail(f), gradient);
}

void SecondOrderProblem::rhs(double t, ConstVectorRef z, ConstVectorRef p, VectorRef out,
                             ProblemWorkspace* ws) const {
  const int f = coordinateCount();
  auto& w = workspaceOf(ws);
  solveAcceleration(*this, t, z.head(f), z.tail(f), p, w);
  out.head(f) = z.tail(f);
  out.tail(f) = w.acceleration;
}

void SecondOrderProblem::rhsJacobian(double t, ConstVectorRef z, ConstVectorRef p, MatrixRef jacobian,
                                     ProblemWorkspace* ws) const {
  const int f = coordinateCount();
  auto& w = workspaceOf(ws);
  solveAcceleration(*this, t, z.head(f), z.tail(f), p, w);
  residualJacobians(t, z.head(f), z.tail(f), w.acceleration, p, w.ry, w.rv, w.model.get());
  solveMass(w, w.ry);
  solveMass(w, w.rv);
  jacobian.topLeftCorner(f, f).setZero();
  jacobian.topRightCorner(f, f).setIdentity();
  jacobian.bottomLeftCorner(f, f) = -w.ry;
  jacobian.bottomRightCorner(f, f) = -w.rv;
}

int SecondOrderProblem::rhsDataSize() const {
  const int f = coordinateCount();
  return f + f * (f + 1) / 2;
}

void SecondOrderProblem::saveRhsData(ProblemWorkspace* ws, VectorRef data) const {
  const int f = coordinateCount();
  const auto& w = workspaceOf(ws);
  assert(w.cacheValid && data.size() == rhsDataSize());
  const Matrix& factor = w.factorRestored ? w.restoredFactor : w.cholesky.matrixLLT();
  double* out = data.data();
  std::memcpy(out, w.acceleration.data(), sizeof(double) * static_cast<std::size_t>(f));
  out += f;
  // Column j of the lower triangle: rows j..f-1.
  for (int j = 0; j < f; ++j) {
    std::memcpy(out, factor.data() + static_cast<std::ptrdiff_t>(j) * f + j,
                sizeof(double) * static_cast<std::size_t>(f - j));
    out += f - j;
  }
}

void SecondOrderProblem::restoreRhsData(double t, ConstVectorRef z, ConstVectorRef p, ConstVectorRef data,
                                        ProblemWorkspace* ws) const {
  const int f = coordinateCount();
  auto& w = workspaceOf(ws);
  assert(data.size() == rhsDataSize() && z.size() == 2 * f);
  assert(!w.parametersFixed || w.cachedParameters == p);
  const double* in = data.data();
  std::memcpy(w.acceleration.data(), in, sizeof(double) * static_cast<std::size_t>(f));
  in += f;
  for (int j = 0; j < f; ++j) {
    std::memcpy(w.restoredFactor.data() + static_cast<std::ptrdiff_t>(j) * f + j, in,
                sizeof(double) * static_cast<std::size_t>(f - j));
    in += f - j;
  }
  w.factorRestored = true;
  w.cachedTime = t;
  std::memcpy(w.cachedState.data(), z.data(), sizeof(double) * static_cast<std::size_t>(2 * f));
  if (!w.parametersFixed) w.cachedParameters = p;
  w.cacheValid = true;
}

void SecondOrderProblem::addRhsParameterVjp(double t, ConstVectorRef z, ConstVectorRef p, ConstVectorRef wIn,
                                            VectorRef out, ProblemWorkspace* ws) const {
  const int f = coordinateCount();
  auto& w = workspaceOf(ws);
  solveAcceleration(*this, t, z.head(f), z.tail(f), p, w);
  // M is symmetric, so M^{-T} = M^{-1}; the minus sign goes into mu.
  w.mu = -wIn.tail(f);
  solveMass(w, w.mu);
  addResidualParameterVjp(t, z.head(f), z.tail(f), w.acceleration, p, w.mu, out, w.model.get());
}

void SecondOrderProblem::residualStateVjp(double, ConstVectorRef, ConstVectorRef, ConstVectorRef,
                                          ConstVectorRef, ConstVectorRef, VectorRef, VectorRef,
                                          ProblemWorkspace*) const {
  throw std::logic_error("Problem '" + name() + "' does not implement residualStateVjp()");
}

void SecondOrderProblem::rhsStateVjp(double t, ConstVectorRef z, ConstVectorRef p, ConstVectorRef wIn,
                                     VectorRef out, ProblemWorkspace* ws) const {
  const int f = coordinateCount();
  auto& w = workspaceOf(ws);
  solveAcceleration(*this, t, z.head(f), z.tail(f), p, w);
  // a = M^{-1} f with r(y, v, a) = 0: da/dy = -M^{-1} r_y, da/dv = -M^{-1} r_v (M symmetric).
  w.mu = -wIn.tail(f);
  solveMass(w, w.mu);
  residualStateVjp(t, z.head(f), z.tail(f), w.acceleration, p, w.mu, out.head(f), out.tail(f), w.model.get());
  out.tail(f) += wIn.head(f);
}

void SecondOrderProblem::rhsVjps(double t, ConstVectorRef z, ConstVectorRef p, ConstVectorRef wIn,
                                 VectorRef outState, VectorRef gradient, ProblemWorkspace* ws) const {
  const int f = coordinateCount();
  auto& w = workspaceOf(ws);
  solveAcceleration(*this, t, z.head(f), z.tail(f), p, w);
  w.mu = -wIn.tail(f);
  solveMass(w, w.mu);
  residualVjps(t, z.head(f), z.tail(f), w.acceleration, p, w.mu, outState.head(f), outState.tail(f), gradient,
               w.model.get());
  outState.tail(f) += wIn.head(f);
}

double SecondOrderProblem::integrand(double t, ConstVectorRef z, ConstVectorRef p,
                                     ProblemWorkspace* ws) const {
  const int f = coordinateCount();
  return integrand(t, z.head(f), z.tail(f), p, workspaceOf(ws).model.get());
}

void SecondOrderProblem::addIntegrandStateGradient(double t, ConstVectorRef z, ConstVectorRef p, double scale,
                                                   VectorRef out, ProblemWorkspace* ws) const {
  const int f = coordinateCount();
  addIntegrandStateGradient(t, z.head(f), z.tail(f), p, scale, out.head(f), out.tail(f),
                            workspaceOf(ws).model.get());
}

void SecondOrderProblem::addIntegrandParameterGradient(double t, ConstVectorRef z, ConstVectorRef p,
                                                       double scale, VectorRef out,
                                                       ProblemWorkspace* ws) const {
  const int f = coordinateCount();
  addIntegrandParameterGradient(t, z.head(f), z.tail(f), p, scale, out, workspaceOf(ws).model.get());
}

}  // namespace hindsight
