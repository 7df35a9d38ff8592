#include <hindsight/engine/continuous_adjoint.h>
#include <hindsight/engine/deterministic_math.h>
#include <hindsight/engine/grid_recomputer.h>
#include <hindsight/engine/interrupt.h>
#include <hindsight/engine/runge_kutta.h>
#include <hindsight/engine/step_controller.h>
#include <hindsight/engine/stopwatch.h>

#include <Eigen/LU>

#include <cmath>
#include <limits>
#include <sstream>

namespace hindsight {
namespace {

/// What to loosen when the backward steps cannot shrink further (see the header, "Stiff adjoints").
std::string toleranceAdvice(const ContinuousAdjointOptions& options) {
  std::ostringstream msg;
  msg << "; the backward error test (ContinuousAdjointOptions.relativeTolerance = "
      << options.relativeTolerance << ", absoluteTolerance" << (options.absoluteTolerances.empty() ? "" : "s")
      << ") asks to resolve a layer"
      << " of the adjoint narrower than that, typically the terminal layer of a stiff adjoint whose"
      << " lambda(t1) = dphi/dz is off its slow manifold; loosen the backward tolerances, or use the discrete"
      << " adjoint or CVODES";
  return msg.str();
}

/// Throws NumericalError (with the time) when a backward integrator has used up its steps or its
/// step size has underflowed; shared by the explicit and the implicit backward integrators.
void checkBackwardStep(std::int64_t attempts, const ContinuousAdjointOptions& options, double t, double h) {
  if (attempts >= options.maxSteps) {
    throw NumericalError(
        "continuous adjoint: more than maxSteps = " + std::to_string(options.maxSteps) + " backward steps",
        t);
  }
  if (h < options.minStep * std::max(1.0, std::abs(t))) {
    std::ostringstream msg;
    msg << "continuous adjoint: backward step size underflow, h = " << h
        << " < ContinuousAdjointOptions.minStep * max(1, |t|) = "
        << options.minStep * std::max(1.0, std::abs(t)) << toleranceAdvice(options);
    throw NumericalError(msg.str(), t);
  }
}

/// Where a backward step from t asking for size h ends: t - h, or t0 when that is (nearly) reached.
/// Near a large |t| the times are spaced by ulp(t) (7.5e-9 at t = 4e7), so a step is a whole number
/// of ulps; a retry 0.1 to 0.9 times a rejected step of a few ulps can round back onto the end just
/// rejected (rejectedEnd) and would be retried unchanged until maxSteps. Such a retry ends one
/// representable time closer to t instead; when the rejected step was a single ulp there is no
/// smaller step, and the backward sweep stops at once with the reason. Elsewhere the retry ends
/// above rejectedEnd anyway, so this changes no step that converged before.
double backwardStepEnd(double t, double h, double t0, double rejectedEnd,
                       const ContinuousAdjointOptions& options) {
  double tNext = (t - h <= t0 || (t - h) - t0 < 1e-12 * h) ? t0 : t - h;
  // A step below half an ulp rounds onto t itself: a step of zero length, accepted with a zero error,
  // would set h = 0 and fail; the smallest step is one ulp.
  if (tNext >= t) tNext = std::nextafter(t, t0);
  if (tNext <= rejectedEnd) {
    tNext = std::nextafter(rejectedEnd, t);
    if (tNext >= t) {
      std::ostringstream msg;
      msg << "continuous adjoint: a backward step of one unit in the last place of t (h = " << t - rejectedEnd
          << ", the resolution of the time at t) was rejected" << toleranceAdvice(options);
      throw NumericalError(msg.str(), t);
    }
  }
  return tNext;
}

/// The first backward step: `h` from the options or the heuristic, but not below the underflow bound.
/// The heuristic scales by atol where y(t1) has zeros (mu(t1) = 0, most of lambda(t1)), and with a
/// steep adjoint slope there (a stiff terminal layer) it returns steps far below minStep * |t1|;
/// starting at 100 times that bound lets the controller find the step the layer needs. Only a start
/// that would have failed at once is changed.
double firstBackwardStep(double h, double t1, double t0, const ContinuousAdjointOptions& options) {
  const double bound = options.minStep * std::max(1.0, std::abs(t1));
  return h < bound ? std::min(100.0 * bound, t1 - t0) : h;
}

/// Where the backward sweep gets z(t).
class ForwardStates {
 public:
  virtual ~ForwardStates() = default;
  /// z <- z(t) for t at or below the last accepted backward time.
  virtual void at(double t, VectorRef z) = 0;
  /// The backward sweep has accepted a step down to t; nothing above t is asked for again.
  virtual void release(double t) { (void)t; }
};

class InterpolatedStates final : public ForwardStates {
 public:
  explicit InterpolatedStates(TrajectoryStorage& storage) : storage_(storage) {}
  void at(double t, VectorRef z) override { storage_.interpolate(t, z); }

 private:
  TrajectoryStorage& storage_;
};

/// Cubic Hermite dense output over the grid points restored in reverse order (see the header).
class RestoredWindowStates final : public ForwardStates {
 public:
  RestoredWindowStates(const Problem& problem, ConstVectorRef p, ProblemWorkspace* workspace,
                       TrajectoryStorage& storage, const std::vector<double>& times,
                       ConstVectorRef finalState, std::int64_t& rhsEvaluations)
      : problem_(problem),
        p_(p),
        workspace_(workspace),
        storage_(storage),
        times_(times),
        rhsEvaluations_(rhsEvaluations) {
    points_.reserve(64);
    spare_.reserve(64);
    nextIndex_ = static_cast<std::int64_t>(times.size()) - 1;
    push([&](VectorRef z) { z = finalState; });
  }

  void at(double t, VectorRef z) override {
    while (points_.back().t > t && nextIndex_ >= 0) {
      push([&](VectorRef zn) { storage_.restore(nextIndex_, zn); });
    }
    // The segment [lower, upper] containing t, searched from the low end where t usually is.
    std::size_t upper = points_.size() >= 2 ? points_.size() - 2 : 0;
    while (upper > 0 && points_[upper].t < t) --upper;
    if (points_.size() < 2) {
      z = points_.front().z;
      return;
    }
    const Point& b = points_[upper];
    const Point& a = points_[upper + 1];
    const double span = b.t - a.t;
    const double s = (t - a.t) / span;
    const double s2 = s * s, s3 = s2 * s;
    z = (2.0 * s3 - 3.0 * s2 + 1.0) * a.z + ((s3 - 2.0 * s2 + s) * span) * a.f +
        (-2.0 * s3 + 3.0 * s2) * b.z + ((s3 - s2) * span) * b.f;
  }

  void release(double t) override {
    std::size_t drop = 0;
    while (points_.size() - drop >= 2 && points_[drop + 1].t >= t) ++drop;
    for (std::size_t i = 0; i < drop; ++i) spare_.push_back(std::move(points_[i]));
    points_.erase(points_.begin(), points_.begin() + static_cast<std::ptrdiff_t>(drop));
  }

 private:
  struct Point {
    double t;
    Vector z, f;
  };

  template <typename Fill>
  void push(Fill&& fill) {
    Point point;
    if (!spare_.empty()) {
      point = std::move(spare_.back());
      spare_.pop_back();
    } else {
      point.z.resize(problem_.stateSize());
      point.f.resize(problem_.stateSize());
    }
    point.t = times_[static_cast<std::size_t>(nextIndex_)];
    fill(point.z);
    problem_.rhs(point.t, point.z, p_, point.f, workspace_);
    ++rhsEvaluations_;
    points_.push_back(std::move(point));
    --nextIndex_;
  }

  const Problem& problem_;
  ConstVectorRef p_;
  ProblemWorkspace* workspace_;
  TrajectoryStorage& storage_;
  const std::vector<double>& times_;
  std::int64_t& rhsEvaluations_;
  std::int64_t nextIndex_;
  // Descending t. Dropped points are recycled through spare_, so that once the window has reached its
  // largest size the backward sweep allocates nothing.
  std::vector<Point> points_;
  std::vector<Point> spare_;
};

/// The augmented backward system y = (lambda, mu), dy/dt = f(t, y).
class AdjointSystem {
 public:
  AdjointSystem(const Problem& problem, ConstVectorRef p, ProblemWorkspace* workspace, ForwardStates& states)
      : problem_(problem),
        p_(p),
        workspace_(workspace),
        states_(states),
        n_(problem.stateSize()),
        np_(problem.parameterSize()),
        z_(n_),
        vjp_(n_) {
    if (problem.hasDenseJacobian()) jacobian_ = Matrix::Zero(n_, n_);
  }

  void evaluate(double t, ConstVectorRef y, VectorRef out) {
    ++evaluations;
    states_.at(t, z_);
    const auto lambda = y.head(n_);
    auto lambdaDot = out.head(n_);
    auto muDot = out.tail(np_);
    if (problem_.hasDenseJacobian()) {
      problem_.rhsJacobian(t, z_, p_, jacobian_, workspace_);
      lambdaDot.noalias() = jacobian_.transpose() * lambda;
      lambdaDot = -lambdaDot;
    } else {
      problem_.rhsStateVjp(t, z_, p_, lambda, vjp_, workspace_);
      lambdaDot = -vjp_;
    }
    problem_.addIntegrandStateGradient(t, z_, p_, -1.0, lambdaDot, workspace_);
    muDot.setZero();
    problem_.addRhsParameterVjp(t, z_, p_, lambda, muDot, workspace_);
    problem_.addIntegrandParameterGradient(t, z_, p_, 1.0, muDot, workspace_);
    muDot = -muDot;
  }

  /// For the implicit method: z(t), F_z(t, z(t)) into jacobian() and G_z^T into stateGradient().
  void linearize(double t) {
    ++evaluations;
    states_.at(t, z_);
    problem_.rhsJacobian(t, z_, p_, jacobian_, workspace_);
    stateGradient_.setZero();
    problem_.addIntegrandStateGradient(t, z_, p_, 1.0, stateGradient_, workspace_);
    linearizedAt_ = t;
  }
  const Matrix& jacobian() const { return jacobian_; }
  const Vector& stateGradient() const { return stateGradient_; }
  /// out = (G_p + lambda^T F_p)^T at the time of the last linearize().
  void parameterRate(ConstVectorRef lambda, VectorRef out) {
    out.setZero();
    problem_.addRhsParameterVjp(linearizedAt_, z_, p_, lambda, out, workspace_);
    problem_.addIntegrandParameterGradient(linearizedAt_, z_, p_, 1.0, out, workspace_);
  }

  std::int64_t evaluations = 0;

 private:
  const Problem& problem_;
  ConstVectorRef p_;
  ProblemWorkspace* workspace_;
  ForwardStates& states_;
  int n_, np_;
  Vector z_, vjp_;
  Matrix jacobian_;
  Vector stateGradient_ = Vector::Zero(n_);
  double linearizedAt_ = 0.0;
};

/// The backward error test's per-component rtol and atol over y = (lambda, mu), from the options.
struct BackwardTolerances {
  BackwardTolerances(const ContinuousAdjointOptions& options, int n, int np)
      : relative(n + np), absolute(n + np) {
    relative.head(n).setConstant(options.relativeTolerance);
    if (options.absoluteTolerances.empty()) {
      absolute.head(n).setConstant(options.absoluteTolerance);
    } else {
      absolute.head(n) = Eigen::Map<const Vector>(options.absoluteTolerances.data(), n);
    }
    relative.tail(np).setConstant(options.quadratureRelativeTolerance > 0.0
                                      ? options.quadratureRelativeTolerance
                                      : options.relativeTolerance);
    absolute.tail(np).setConstant(options.quadratureAbsoluteTolerance > 0.0
                                      ? options.quadratureAbsoluteTolerance
                                      : options.absoluteTolerance);
  }
  Vector relative, absolute;
};

struct BackwardStatistics {
  std::int64_t steps = 0;
  std::int64_t rejected = 0;
  std::int64_t factorizations = 0;
};

/// Hairer, Norsett & Wanner, Solving ODEs I, section II.4: a starting step for a method of `order`,
/// from y(t1) and its slope f1 = f(t1, y).
double initialStep(AdjointSystem& system, double t0, double t1, ConstVectorRef y, ConstVectorRef f1,
                   int order, const BackwardTolerances& tolerances) {
  const Vector& rtol = tolerances.relative;
  const Vector& atol = tolerances.absolute;
  const double span = t1 - t0;
  const double d0 = weightedRmsNorm(y, y, y, rtol, atol);
  const double d1 = weightedRmsNorm(f1, y, y, rtol, atol);
  const double h0 = std::min((d0 < 1e-5 || d1 < 1e-5) ? 1e-6 * span : 0.01 * d0 / d1, span);
  const Vector trial = y - h0 * f1;
  Vector f2(y.size());
  system.evaluate(t1 - h0, trial, f2);
  const double d2 = weightedRmsNorm(f2 - f1, y, y, rtol, atol) / h0;
  const double dmax = std::max(d1, d2);
  const double h1 =
      dmax <= 1e-15 ? std::max(1e-6 * span, h0 * 1e-3) : dmath::pow(0.01 / dmax, 1.0 / (order + 1.0));
  return std::min({100.0 * h0, h1, span});
}

/// Dormand-Prince 5(4) from t1 down to t0; y holds y(t1) on entry and y(t0) on exit.
BackwardStatistics integrateBackward(AdjointSystem& system, ForwardStates& states, double t0, double t1,
                                     VectorRef y, const ContinuousAdjointOptions& options,
                                     const BackwardTolerances& tolerances) {
  static const ButcherTableau tableau = ButcherTableau::byMethod(IntegratorMethod::Dopri5);
  const Eigen::Index m = y.size();
  const int stages = static_cast<int>(tableau.b.size());
  const Vector& rtol = tolerances.relative;
  const Vector& atol = tolerances.absolute;
  Matrix k(m, stages);
  Vector stage(m), error(m);
  const Vector weightDifference = tableau.b - tableau.bEmbedded;
  BackwardStatistics statistics;
  double t = t1;
  system.evaluate(t, y, k.col(0));

  double h =
      firstBackwardStep(options.initialStep > 0.0 ? options.initialStep
                                                  : initialStep(system, t0, t1, y, k.col(0), 5, tolerances),
                        t1, t0, options);
  const StepSizeController controller(std::min(tableau.order, tableau.embeddedOrder));
  double rejectedEnd = -std::numeric_limits<double>::infinity();
  while (t > t0) {
    pollInterrupt();
    checkBackwardStep(statistics.steps + statistics.rejected, options, t, h);
    const double tNext = backwardStepEnd(t, h, t0, rejectedEnd, options);
    const double hTaken = t - tNext;
    for (int i = 1; i < stages; ++i) {
      stage = y;
      for (int j = 0; j < i; ++j) {
        if (tableau.a(i, j) != 0.0) stage.noalias() -= (hTaken * tableau.a(i, j)) * k.col(j);
      }
      system.evaluate(t - tableau.c(i) * hTaken, stage, k.col(i));
    }
    // The last stage is the new solution (FSAL: a_7j = b_j, c_7 = 1).
    error.noalias() = k * weightDifference;
    error *= -hTaken;
    double norm = weightedRmsNorm(error, y, stage, rtol, atol);
    if (!std::isfinite(norm) || !stage.allFinite()) norm = 1e10;
    if (norm <= 1.0) {
      y = stage;
      t = tNext;
      k.col(0) = k.col(stages - 1);
      states.release(t);
      ++statistics.steps;
      h = controller.afterAccepted(hTaken, norm);
      rejectedEnd = -std::numeric_limits<double>::infinity();
    } else {
      ++statistics.rejected;
      h = controller.afterRejected(hTaken, norm);
      rejectedEnd = tNext;
    }
  }
  if (!y.allFinite()) throw NumericalError("continuous adjoint: non-finite adjoint state", t0);
  return statistics;
}

/// TR-BDF2 (the ESDIRK of engine/integrator.h) from t1 down to t0, in the backward time
/// s = t1 - t: d(lambda)/ds = F_z^T lambda + G_z^T is linear, so each implicit stage is one LU
/// solve with I - h a_ii F_z^T; d(mu)/ds = G_p + F_p^T lambda is a quadrature with the same
/// weights. The error estimate (b - b_hat) covers lambda and mu; L-stable, so stiff adjoints take
/// steps set by accuracy, not stability.
BackwardStatistics integrateBackwardImplicit(AdjointSystem& system, double t0, double t1, VectorRef y, int n,
                                             const ContinuousAdjointOptions& options,
                                             const BackwardTolerances& tolerances) {
  static const ButcherTableau tableau = ButcherTableau::byMethod(IntegratorMethod::TrBdf2);
  const int stages = static_cast<int>(tableau.b.size());
  const Eigen::Index np = y.size() - n;
  const Vector& rtol = tolerances.relative;
  const Vector& atol = tolerances.absolute;
  Matrix k(n, stages), q(np, stages), newton(n, n);
  Vector stage(n), rhs(n), error(y.size()), next(y.size()), slope(y.size());
  const Vector weightDifference = tableau.b - tableau.bEmbedded;
  Eigen::PartialPivLU<Matrix> lu(n);
  BackwardStatistics statistics;
  double t = t1;
  // First stage (c = 0, explicit); later steps reuse the last stage (stiffly accurate: FSAL).
  system.linearize(t);
  k.col(0).noalias() = system.jacobian().transpose() * y.head(n);
  k.col(0) += system.stateGradient();
  system.parameterRate(y.head(n), q.col(0));
  // The starting step from the slope in t, dy/dt = -(k_1, q_1).
  slope << -k.col(0), -q.col(0);
  double h = firstBackwardStep(
      options.initialStep > 0.0 ? options.initialStep : initialStep(system, t0, t1, y, slope, 2, tolerances),
      t1, t0, options);
  const StepSizeController controller(std::min(tableau.order, tableau.embeddedOrder));
  double rejectedEnd = -std::numeric_limits<double>::infinity();
  while (t > t0) {
    pollInterrupt();
    checkBackwardStep(statistics.steps + statistics.rejected, options, t, h);
    const double tNext = backwardStepEnd(t, h, t0, rejectedEnd, options);
    const double hTaken = t - tNext;
    for (int i = 1; i < stages; ++i) {
      const double ti = t - tableau.c(i) * hTaken;
      system.linearize(ti);
      rhs = y.head(n);
      for (int j = 0; j < i; ++j) rhs.noalias() += (hTaken * tableau.a(i, j)) * k.col(j);
      rhs += (hTaken * tableau.a(i, i)) * system.stateGradient();
      newton.noalias() = -(hTaken * tableau.a(i, i)) * system.jacobian().transpose();
      newton.diagonal().array() += 1.0;
      lu.compute(newton);
      ++statistics.factorizations;
      stage.noalias() = lu.solve(rhs);
      k.col(i).noalias() = system.jacobian().transpose() * stage;
      k.col(i) += system.stateGradient();
      system.parameterRate(stage, q.col(i));
    }
    next.head(n) = stage;  // stiffly accurate: the last stage is the new lambda
    next.tail(np) = y.tail(np);
    next.tail(np).noalias() += hTaken * (q * tableau.b);
    error.head(n).noalias() = k * weightDifference;
    error.tail(np).noalias() = q * weightDifference;
    error *= hTaken;
    if (options.filterErrorEstimate) {
      // Shampine's filter: (I - h gamma F_z^T)^{-1} e, with the last stage's factorisation. It leaves
      // the non-stiff components' estimate as it was and divides the stiff ones by ~h gamma |eig|,
      // where the raw estimate is round-off in k_i = F_z^T lambda_i amplified by h ||F_z||.
      error.head(n) = lu.solve(error.head(n));
    }
    double norm = weightedRmsNorm(error, y, next, rtol, atol);
    if (!std::isfinite(norm) || !next.allFinite()) norm = 1e10;
    if (norm <= 1.0) {
      y = next;
      t = tNext;
      k.col(0) = k.col(stages - 1);
      q.col(0) = q.col(stages - 1);
      ++statistics.steps;
      h = controller.afterAccepted(hTaken, norm);
      rejectedEnd = -std::numeric_limits<double>::infinity();
    } else {
      ++statistics.rejected;
      h = controller.afterRejected(hTaken, norm);
      rejectedEnd = tNext;
    }
  }
  return statistics;
}

}  // namespace

BackwardMethod parseBackwardMethod(const std::string& name) {
  if (name == "dopri5") return BackwardMethod::Dopri5;
  if (name == "trbdf2") return BackwardMethod::TrBdf2;
  throw std::invalid_argument("ContinuousAdjointOptions.method = '" + name +
                              "' is unknown; valid: dopri5, trbdf2");
}

bool ContinuousAdjointOptions::IsValid(std::string* error) const {
  std::ostringstream msg;
  const auto fail = [&]() {
    if (error != nullptr) *error = msg.str();
    return false;
  };
  if (!(relativeTolerance >= 1e-14 && relativeTolerance < 1.0)) {
    msg << "ContinuousAdjointOptions.relativeTolerance = " << relativeTolerance << " must be in [1e-14, 1)";
    return fail();
  }
  if (!(absoluteTolerance > 0.0) || !std::isfinite(absoluteTolerance)) {
    msg << "ContinuousAdjointOptions.absoluteTolerance = " << absoluteTolerance
        << " must be positive and finite";
    return fail();
  }
  if (const std::string entry =
          invalidToleranceEntry(absoluteTolerances, "ContinuousAdjointOptions.absoluteTolerances");
      !entry.empty()) {
    msg << entry;
    return fail();
  }
  if (quadratureRelativeTolerance != 0.0 &&
      !(quadratureRelativeTolerance >= 1e-14 && quadratureRelativeTolerance < 1.0)) {
    msg << "ContinuousAdjointOptions.quadratureRelativeTolerance = " << quadratureRelativeTolerance
        << " must be 0 (use relativeTolerance) or in [1e-14, 1)";
    return fail();
  }
  if (quadratureAbsoluteTolerance != 0.0 &&
      (!(quadratureAbsoluteTolerance > 0.0) || !std::isfinite(quadratureAbsoluteTolerance))) {
    msg << "ContinuousAdjointOptions.quadratureAbsoluteTolerance = " << quadratureAbsoluteTolerance
        << " must be 0 (use absoluteTolerance) or positive and finite";
    return fail();
  }
  if (!(initialStep >= 0.0) || !std::isfinite(initialStep)) {
    msg << "ContinuousAdjointOptions.initialStep = " << initialStep << " must be in [0, t1 - t0]";
    return fail();
  }
  if (!(minStep > 0.0 && minStep <= 1e-3)) {
    msg << "ContinuousAdjointOptions.minStep = " << minStep << " must be in (0, 1e-3]";
    return fail();
  }
  if (maxSteps < 1 || maxSteps > 1'000'000'000'000) {
    msg << "ContinuousAdjointOptions.maxSteps = " << maxSteps << " must be in [1, 1e12]";
    return fail();
  }
  try {
    parseBackwardMethod(method);
  } catch (const std::invalid_argument& e) {
    msg << e.what();
    return fail();
  }
  return true;
}

void ContinuousAdjointOptions::validate() const {
  std::string error;
  if (!IsValid(&error)) throw std::invalid_argument(error);
}

GradientResult computeGradientContinuous(const Problem& problem, ConstVectorRef p,
                                         const IntegratorOptions& forward, TrajectoryStorage& storage,
                                         const ContinuousAdjointOptions& options) {
  options.validate();
  forward.validate();
  const BackwardMethod backwardMethod = parseBackwardMethod(options.method);
  if (backwardMethod == BackwardMethod::TrBdf2 && !problem.hasDenseJacobian()) {
    throw std::invalid_argument(
        "ContinuousAdjointOptions.method = 'trbdf2' needs a dense Jacobian, but problem '" + problem.name() +
        "' has hasDenseJacobian() == false; use 'dopri5'");
  }
  requireOneTolerancePerState(options.absoluteTolerances, "ContinuousAdjointOptions.absoluteTolerances",
                              problem.name(), problem.stateSize(),
                              "one atol per adjoint component, or empty");
  if (options.initialStep > forward.t1 - forward.t0) {
    std::ostringstream msg;
    msg << "ContinuousAdjointOptions.initialStep = " << options.initialStep
        << " must be in [0, t1 - t0 = " << forward.t1 - forward.t0 << "]";
    throw std::invalid_argument(msg.str());
  }
  const Stopwatch forwardTimer;
  const int n = problem.stateSize();
  // The integrator that recomputes steps for checkpointing strategies (same options, same bits).
  const std::unique_ptr<Integrator> recomputeIntegrator = createIntegrator(problem, p, forward);
  if (recomputeIntegrator->stateSize() != n) {
    // The storage below records the problem state z that the observer sees; a method that carries
    // more than z between steps could not be recomputed from it.
    throw std::invalid_argument(
        "the continuous adjoint needs a forward method whose state is the problem state; '" + forward.method +
        "' carries " + std::to_string(recomputeIntegrator->stateSize()) + " values per step for " +
        std::to_string(n) + " states; use the discrete adjoint");
  }
  std::vector<double> times;
  GridRecomputer recomputer(*recomputeIntegrator, times);
  std::unique_ptr<ProblemWorkspace> workspace = problem.createWorkspace();

  TrajectoryInfo info;
  info.problemName = problem.name();
  info.stateSize = n;
  info.t0 = forward.t0;
  info.t1 = forward.t1;
  info.stepCount = -1;  // unknown until the forward sweep ends
  storage.begin(info, recomputer);

  // The forward sweep hands each grid point to the storage one point late, so that the last one
  // goes to finish() with N.
  const bool needDerivative = storage.needsDerivative();
  std::int64_t rhsEvaluations = 0;
  Vector pendingZ(n), pendingF = Vector::Zero(n);
  double pendingT = forward.t0;
  const auto observer = [&](std::int64_t step, double t, ConstVectorRef z) {
    if (step > 0) storage.record(step - 1, pendingT, pendingZ, pendingF);
    times.push_back(t);
    pendingT = t;
    pendingZ = z;
    if (needDerivative) {
      problem.rhs(t, z, p, pendingF, workspace.get());
      ++rhsEvaluations;
    }
  };
  ForwardResult forwardResult = simulate(problem, p, forward, observer);
  storage.finish(forwardResult.summary.steps, pendingT, pendingZ, pendingF);

  GradientResult result;
  result.summary = forwardResult.summary;
  result.summary.adjoint = "continuous";
  result.summary.storage = storage.spec();
  result.summary.forwardSeconds = forwardTimer.seconds();

  const Stopwatch backwardTimer;
  const int np = problem.parameterSize();
  Vector y = Vector::Zero(n + np);
  Vector gradient = Vector::Zero(np);
  {
    auto lambda = y.head(n);
    problem.addTerminalGradient(forwardResult.finalState, p, lambda, gradient);
  }
  std::unique_ptr<ForwardStates> states;
  if (storage.canInterpolate()) {
    states = std::make_unique<InterpolatedStates>(storage);
  } else {
    states = std::make_unique<RestoredWindowStates>(problem, p, workspace.get(), storage, times,
                                                    forwardResult.finalState, rhsEvaluations);
  }
  AdjointSystem system(problem, p, workspace.get(), *states);
  const BackwardTolerances tolerances(options, n, np);
  BackwardStatistics backward;
  try {
    backward = backwardMethod == BackwardMethod::TrBdf2
                   ? integrateBackwardImplicit(system, forward.t0, forward.t1, y, n, options, tolerances)
                   : integrateBackward(system, *states, forward.t0, forward.t1, y, options, tolerances);
  } catch (const NumericalError& e) {
    throwBackwardSweepFailure(e, storage, "continuous adjoint");
  }
  gradient += y.tail(np);
  problem.addInitialStateVjp(p, y.head(n), gradient);
  result.summary.backwardSeconds = backwardTimer.seconds();

  const StorageCounters& counters = storage.counters();
  result.summary.rejectedSteps += backward.rejected;
  result.summary.factorizations += backward.factorizations;
  result.summary.rhsEvaluations += rhsEvaluations + recomputeIntegrator->counters().rhsEvaluations;
  result.summary.jacobianEvaluations += system.evaluations;
  result.summary.addStorageCounters(counters, times.size());
  result.objective = forwardResult.objective;
  result.gradient = std::move(gradient);
  result.times = std::move(times);
  return result;
}

}  // namespace hindsight
