#include <hindsight/problems/rod/full_order_rod.h>

#include <hindsight/engine/deterministic_math.h>

#include <hindsight/engine/runge_kutta.h>
#include <hindsight/engine/stopwatch.h>
#include <hindsight/storage/storage_factory.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

namespace hindsight {
namespace rod {

RigidFrameMotion rigidFrameMotion(const CrankMotion& crank, double length, double t) {
  double phi = 0.0, phiDot = 0.0, phiDdot = 0.0;
  crank.at(t, phi, phiDot, phiDdot);
  const double r = crank.radius;
  double sinPhi, cosPhi;
  dmath::sincos(phi, &sinPhi, &cosPhi);
  // beta = asin(s), s = -r sin(phi) / L.
  const double s = -r * sinPhi / length;
  const double sDot = -r * cosPhi * phiDot / length;
  const double sDdot = -r * (cosPhi * phiDdot - sinPhi * phiDot * phiDot) / length;
  const double c = std::sqrt(1.0 - s * s);
  RigidFrameMotion frame;
  frame.angle = dmath::asin(s);
  frame.rate = sDot / c;
  frame.acceleration = sDdot / c + s * sDot * sDot / (c * c * c);
  const double ax = r * (-sinPhi * phiDdot - cosPhi * phiDot * phiDot);
  const double ay = r * (cosPhi * phiDdot - sinPhi * phiDot * phiDot);
  double cb, sb;
  dmath::sincos(frame.angle, &sb, &cb);
  frame.pinAccelerationX = cb * ax + sb * ay;
  frame.pinAccelerationY = -sb * ax + cb * ay;
  return frame;
}

// ---- workspace ----

class FullOrderRodProblem::Workspace final : public ProblemWorkspace {
 public:
  Workspace(int free, int full)
      : force(free),
        product(free),
        multiplier(free),
        accelerationFree(free),
        uFull(full),
        vFull(full),
        aFull(full),
        muFull(full) {}
  Vector force, product, multiplier, accelerationFree;  // free DOFs
  Vector uFull, vFull, aFull, muFull;                   // all DOFs
};

FullOrderRodProblem::FullOrderRodProblem(const RodConfig& config, ConstVectorRef design, bool coupling)
    : FullOrderRodProblem(config, design, CrankMotion{config.crankRadius, config.crankSpeed, config.rampTime},
                          coupling) {}

FullOrderRodProblem::FullOrderRodProblem(const RodConfig& config, ConstVectorRef design,
                                         const CrankMotion& crank, bool coupling)
    : model_(config, design), crank_(crank), coupling_(coupling), n_(model_.freeDofCount()) {
  if (!(crank.radius > 0.0) || !(crank.radius < config.length)) {
    throw std::invalid_argument("crank radius = " + std::to_string(crank.radius) +
                                " must be in (0, rod length = " + std::to_string(config.length) + ")");
  }
  build();
}

FullOrderRodProblem::~FullOrderRodProblem() = default;

void FullOrderRodProblem::build() {
  const int full = model_.dofCount();
  const std::vector<int>& freeToFull = model_.freeToFull();
  // P: full x free embedding; S_n: node-wise rotation on all DOFs.
  SparseMatrix embedding(full, n_), rotation(full, full);
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(n_);
  for (int k = 0; k < n_; ++k) triplets.emplace_back(freeToFull[k], k, 1.0);
  embedding.setFromTriplets(triplets.begin(), triplets.end());
  triplets.clear();
  for (int node = 0; node < model_.nodeCount(); ++node) {
    triplets.emplace_back(2 * node, 2 * node + 1, -1.0);  // (S u)_x = -u_y
    triplets.emplace_back(2 * node + 1, 2 * node, 1.0);   // (S u)_y = u_x
  }
  rotation.setFromTriplets(triplets.begin(), triplets.end());
  const SparseMatrix massTimesRotation = model_.massFull() * rotation;
  rotatedMass_ = SparseMatrix(embedding.transpose() * massTimesRotation * embedding);
  rotatedMass_.makeCompressed();

  const SparseMatrix& massFull = model_.massFull();
  const Vector& X = model_.referenceCoordinates();
  loadX_ = model_.restrictToFree(massFull * model_.unitTranslationX());
  loadY_ = model_.restrictToFree(massFull * model_.unitTranslationY());
  loadRotated_ = model_.restrictToFree(massFull * rotateNodewise(X));
  loadPosition_ = model_.restrictToFree(massFull * X);

  massFactor_.compute(model_.mass());
  if (massFactor_.info() != Eigen::Success) {
    throw std::runtime_error(
        "full-order rod: the Cholesky factorisation of M failed (M not positive definite)");
  }
}

void FullOrderRodProblem::inertialLoad(double t, VectorRef f) const {
  const RigidFrameMotion frame = rigidFrameMotion(crank_, model_.config().length, t);
  // a_full = (R^T r_A'')_x e_x + (R^T r_A'')_y e_y + beta'' S X - beta'^2 X.
  f = frame.pinAccelerationX * loadX_ + frame.pinAccelerationY * loadY_ + frame.acceleration * loadRotated_ -
      (frame.rate * frame.rate) * loadPosition_;
}

void FullOrderRodProblem::solveMass(VectorRef x) const {
  massFactor_.matrixL().solveInPlace(x);
  massFactor_.matrixU().solveInPlace(x);
}

double FullOrderRodProblem::largestEigenvalue(int iterations) const {
  // Power iteration on M^{-1} K with the Rayleigh quotient x^T K x / x^T M x (a lower bound that
  // converges from below; 200 iterations give a few per cent on the rod meshes).
  Vector x = Vector::Ones(n_), y(n_);
  for (int k = 0; k < n_; ++k) x(k) = (k % 2 == 0 ? 1.0 : -1.0) * (1.0 + 0.1 * (k % 7));
  double lambda = 0.0;
  for (int i = 0; i < iterations; ++i) {
    y.noalias() = model_.stiffness() * x;
    lambda = x.dot(y) / x.dot(model_.mass() * x);
    solveMass(y);
    x = y / y.norm();
  }
  return lambda;
}

void FullOrderRodProblem::applyStiffnessOperator(const RigidFrameMotion& frame, ConstVectorRef x,
                                                 VectorRef out, bool transposed) const {
  out.noalias() = model_.stiffness() * x;  // K symmetric
  if (!coupling_) return;
  out.noalias() -= (frame.rate * frame.rate) * (model_.mass() * x);
  if (transposed) {
    out.noalias() += frame.acceleration * (rotatedMass_.transpose() * x);
  } else {
    out.noalias() += frame.acceleration * (rotatedMass_ * x);
  }
}

std::unique_ptr<ProblemWorkspace> FullOrderRodProblem::createWorkspace() const {
  return std::make_unique<Workspace>(n_, model_.dofCount());
}

void FullOrderRodProblem::initialState(ConstVectorRef p, VectorRef z0) const {
  if (p.size() != model_.designCount() || p != model_.design()) {
    throw std::invalid_argument(
        "full-order rod: the parameters passed to the engine must equal the design the problem was built for "
        "(build a new FullOrderRodProblem for every design)");
  }
  z0.setZero();  // at rest, undeformed
}

void FullOrderRodProblem::rhs(double t, ConstVectorRef z, ConstVectorRef, VectorRef f,
                              ProblemWorkspace* ws) const {
  auto& w = static_cast<Workspace&>(*ws);
  const RigidFrameMotion frame = rigidFrameMotion(crank_, model_.config().length, t);
  // u' = v, v' = -M^{-1} g.
  massSolvedForce(frame, z, w.force);
  f.head(n_) = z.tail(n_);
  f.tail(n_) = -w.force;
}

void FullOrderRodProblem::massSolvedForce(const RigidFrameMotion& frame, ConstVectorRef z,
                                          VectorRef out) const {
  // g = A u + C v + f(t).
  applyStiffnessOperator(frame, z.head(n_), out, false);
  if (coupling_) out.noalias() += (2.0 * frame.rate) * (rotatedMass_ * z.tail(n_));
  out += frame.pinAccelerationX * loadX_ + frame.pinAccelerationY * loadY_ +
         frame.acceleration * loadRotated_ - (frame.rate * frame.rate) * loadPosition_;
  solveMass(out);
}

void FullOrderRodProblem::rhsStateVjp(double t, ConstVectorRef, ConstVectorRef, ConstVectorRef w,
                                      VectorRef out, ProblemWorkspace* ws) const {
  auto& work = static_cast<Workspace&>(*ws);
  const RigidFrameMotion frame = rigidFrameMotion(crank_, model_.config().length, t);
  // F_z^T w = (-A^T mu, w_1 - C^T mu), mu = M^{-1} w_2 (M symmetric).
  work.multiplier = w.tail(n_);
  solveMass(work.multiplier);
  applyStiffnessOperator(frame, work.multiplier, work.product, true);
  out.tail(n_) = w.head(n_);
  if (coupling_) out.tail(n_).noalias() -= (2.0 * frame.rate) * (rotatedMass_.transpose() * work.multiplier);
  out.head(n_) = -work.product;
}

void FullOrderRodProblem::addRhsParameterVjp(double t, ConstVectorRef z, ConstVectorRef p, ConstVectorRef w,
                                             VectorRef out, ProblemWorkspace* ws) const {
  auto& work = static_cast<Workspace&>(*ws);
  const RigidFrameMotion frame = rigidFrameMotion(crank_, model_.config().length, t);
  // w_2^T dF_2/dx_e = -mu^T (dM/dx_e F_2 + dg/dx_e): with everything on all DOFs,
  //   -rho'(x_e) mu_e^T Me0 q_e - E'(x_e) mu_e^T Ke0 u_e,
  //   q = F_2 + a_full - beta'^2 u + beta'' S u + 2 beta' S v   (coupling terms only with coupling).
  const auto u = z.head(n_);
  const auto v = z.tail(n_);
  massSolvedForce(frame, z, work.force);  // = -F_2
  work.multiplier = w.tail(n_);
  solveMass(work.multiplier);

  const Vector& X = model_.referenceCoordinates();
  const std::vector<int>& freeToFull = model_.freeToFull();
  const int nodes = model_.nodeCount();
  work.uFull.setZero();
  work.vFull.setZero();
  work.muFull.setZero();
  for (int k = 0; k < n_; ++k) {
    work.uFull(freeToFull[k]) = u(k);
    work.vFull(freeToFull[k]) = v(k);
    work.muFull(freeToFull[k]) = work.multiplier(k);
  }
  // q on all DOFs, node by node: F_2 (zero at constrained DOFs) + a_full + relative terms.
  const double rate2 = frame.rate * frame.rate;
  for (int node = 0; node < nodes; ++node) {
    const int ix = 2 * node, iy = 2 * node + 1;
    double qx = frame.pinAccelerationX - frame.acceleration * X(iy) - rate2 * X(ix);
    double qy = frame.pinAccelerationY + frame.acceleration * X(ix) - rate2 * X(iy);
    if (coupling_) {
      qx += -rate2 * work.uFull(ix) - frame.acceleration * work.uFull(iy) - 2.0 * frame.rate * work.vFull(iy);
      qy += -rate2 * work.uFull(iy) + frame.acceleration * work.uFull(ix) + 2.0 * frame.rate * work.vFull(ix);
    }
    work.aFull(ix) = qx;
    work.aFull(iy) = qy;
  }
  for (int k = 0; k < n_; ++k) work.aFull(freeToFull[k]) -= work.force(k);  // + F_2

  const SimpLaw& simp = model_.simp();
  const ElementMatrix& Ke0 = model_.unitStiffness();
  const ElementMatrix& Me0 = model_.unitMass();
  ElementVector mu, q, ue;
  for (int d = 0; d < model_.designCount(); ++d) {
    const int element = model_.designToElement(d);
    const std::array<int, 8> dofs = model_.elementDofs(element);
    for (int i = 0; i < 8; ++i) {
      mu(i) = work.muFull(dofs[i]);
      q(i) = work.aFull(dofs[i]);
      ue(i) = work.uFull(dofs[i]);
    }
    const double x = p(d);
    out(d) -= simp.densityDerivative(x) * mu.dot(Me0 * q) + simp.stiffnessDerivative(x) * mu.dot(Ke0 * ue);
  }
}

double FullOrderRodProblem::integrand(double, ConstVectorRef z, ConstVectorRef, ProblemWorkspace* ws) const {
  auto& work = static_cast<Workspace&>(*ws);
  work.product.noalias() = model_.stiffness() * z.head(n_);
  return z.head(n_).dot(work.product);
}

void FullOrderRodProblem::addIntegrandStateGradient(double, ConstVectorRef z, ConstVectorRef, double scale,
                                                    VectorRef out, ProblemWorkspace*) const {
  out.head(n_).noalias() += (2.0 * scale) * (model_.stiffness() * z.head(n_));
}

void FullOrderRodProblem::addIntegrandParameterGradient(double, ConstVectorRef z, ConstVectorRef p,
                                                        double scale, VectorRef out,
                                                        ProblemWorkspace* ws) const {
  auto& work = static_cast<Workspace&>(*ws);
  const std::vector<int>& freeToFull = model_.freeToFull();
  work.uFull.setZero();
  for (int k = 0; k < n_; ++k) work.uFull(freeToFull[k]) = z(k);
  const ElementMatrix& Ke0 = model_.unitStiffness();
  ElementVector ue;
  for (int d = 0; d < model_.designCount(); ++d) {
    const std::array<int, 8> dofs = model_.elementDofs(model_.designToElement(d));
    for (int i = 0; i < 8; ++i) ue(i) = work.uFull(dofs[i]);
    out(d) += scale * model_.simp().stiffnessDerivative(p(d)) * ue.dot(Ke0 * ue);
  }
}

// ---- Newton solver ----

class FullOrderRodProblem::Newton final : public NewtonSolver {
 public:
  explicit Newton(const FullOrderRodProblem& problem)
      : problem_(problem),
        n_(problem.n_),
        rhs_(n_),
        solution_(n_),
        residual_(n_),
        correction_(n_),
        work_(n_) {
    // The pattern of M + alpha^2 K (K's pattern contains M's: same element connectivity).
    const SparseMatrix pattern = problem.model_.mass() + problem.model_.stiffness();
    factor_.analyzePattern(pattern);
    matrix_ = pattern;
  }

  void factorize(double t, ConstVectorRef, ConstVectorRef, double alpha, ProblemWorkspace*) override {
    frame_ = rigidFrameMotion(problem_.crank_, problem_.model_.config().length, t);
    time_ = t;
    alpha_ = alpha;
    // The preconditioner's alpha0 is alpha rounded to 20 mantissa bits: a fixed step whose size
    // varies in the last bits (t_{n+1} - t_n) then factorises once, and alpha0 depends on alpha only,
    // so a recomputation from a checkpoint reproduces the original bits whatever was factorised before.
    int exponent = 0;
    const double mantissa = std::frexp(alpha, &exponent);
    const double rounded = std::ldexp(std::round(std::ldexp(mantissa, 20)), exponent - 20);
    if (rounded != factoredAlpha_) {
      factoredAlpha_ = rounded;
      matrix_ = problem_.model_.mass() + (rounded * rounded) * problem_.model_.stiffness();
      factor_.factorize(matrix_);
      if (factor_.info() != Eigen::Success) {
        factoredAlpha_ = std::numeric_limits<double>::quiet_NaN();
        throw NewtonFailure("full-order rod: M + alpha^2 K is not positive definite", t);
      }
    }
  }

  // (I - alpha F_z) x = b: (M + alpha C + alpha^2 A) x_2 = M b_2 - alpha A b_1, x_1 = b_1 + alpha x_2.
  void solve(VectorRef x) override {
    problem_.applyStiffnessOperator(frame_, x.head(n_), work_, false);
    rhs_.noalias() = problem_.model_.mass() * x.tail(n_);
    rhs_ -= alpha_ * work_;
    solveSchur(false);
    x.head(n_) += alpha_ * solution_;
    x.tail(n_) = solution_;
  }

  // (I - alpha F_z)^T y = b: (M + alpha C^T + alpha^2 A^T) w = b_2 + alpha b_1, y_2 = M w,
  // y_1 = b_1 - alpha A^T w.
  void solveTransposed(VectorRef x) override {
    rhs_ = x.tail(n_) + alpha_ * x.head(n_);
    solveSchur(true);
    problem_.applyStiffnessOperator(frame_, solution_, work_, true);
    x.head(n_) -= alpha_ * work_;
    x.tail(n_).noalias() = problem_.model_.mass() * solution_;
  }

 private:
  // P x = rhs_ (or P^T x = rhs_) with P = M + alpha C + alpha^2 A
  //   = M + alpha^2 K + alpha (2 beta' + alpha beta'') M_S - alpha^2 beta'^2 M (last two with coupling),
  // by iterative refinement x <- x + P0^{-1} (rhs - P x) with the factor of P0 = M + alpha0^2 K.
  void solveSchur(bool transposed) {
    solution_ = rhs_;
    solveP0(solution_);
    const bool coupling = problem_.coupling_;
    if (!coupling && alpha_ == factoredAlpha_) return;  // P = P0 exactly
    const double rotated = coupling ? alpha_ * (2.0 * frame_.rate + alpha_ * frame_.acceleration) : 0.0;
    const double massScale = coupling ? 1.0 - alpha_ * alpha_ * frame_.rate * frame_.rate : 1.0;
    double previous = std::numeric_limits<double>::infinity();
    for (int iteration = 0; iteration < 100; ++iteration) {
      residual_.noalias() = problem_.model_.stiffness() * solution_;
      residual_ *= alpha_ * alpha_;
      correction_.noalias() = problem_.model_.mass() * solution_;
      residual_ += massScale * correction_;
      if (coupling) {
        if (transposed) {
          correction_.noalias() = problem_.rotatedMass_.transpose() * solution_;
        } else {
          correction_.noalias() = problem_.rotatedMass_ * solution_;
        }
        residual_ += rotated * correction_;
      }
      correction_ = rhs_ - residual_;
      solveP0(correction_);
      solution_ += correction_;
      const double change = correction_.lpNorm<Eigen::Infinity>();
      const double size = solution_.lpNorm<Eigen::Infinity>();
      if (!std::isfinite(change))
        throw NewtonFailure("full-order rod: refinement produced a non-finite value", time_);
      if (change <= 4.0 * std::numeric_limits<double>::epsilon() * size) return;
      if (change > 0.5 * previous) {
        // No more progress: fine at round-off level, a failure otherwise.
        if (change <= 1e-12 * size) return;
        throw NewtonFailure(
            "full-order rod: iterative refinement of the Newton matrix does not contract "
            "(alpha too large for the frame coupling terms)",
            time_);
      }
      previous = change;
    }
    throw NewtonFailure("full-order rod: iterative refinement did not converge in 100 iterations", time_);
  }

  void solveP0(VectorRef x) {
    factor_.matrixL().solveInPlace(x);
    factor_.matrixU().solveInPlace(x);
  }

  const FullOrderRodProblem& problem_;
  int n_;
  double alpha_ = std::numeric_limits<double>::quiet_NaN();
  double factoredAlpha_ = std::numeric_limits<double>::quiet_NaN();
  double time_ = 0.0;
  RigidFrameMotion frame_;
  SparseMatrix matrix_;
  Eigen::SimplicialLLT<SparseMatrix, Eigen::Lower, Eigen::NaturalOrdering<int>> factor_;
  Vector rhs_, solution_, residual_, correction_, work_;
};

std::unique_ptr<NewtonSolver> FullOrderRodProblem::createNewtonSolver() const {
  return std::make_unique<Newton>(*this);
}

}  // namespace rod
}  // namespace hindsight
