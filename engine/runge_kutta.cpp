#include <hindsight/engine/runge_kutta.h>
#include <hindsight/engine/step_controller.h>

#include <cmath>
#include <limits>
#include <sstream>

namespace hindsight {
namespace {

ButcherTableau makeTableau(const std::string& name, std::initializer_list<std::initializer_list<double>> a,
                           std::initializer_list<double> b, std::initializer_list<double> c,
                           std::initializer_list<double> bEmbedded, int order, int embeddedOrder) {
  ButcherTableau t;
  t.name = name;
  const int s = static_cast<int>(b.size());
  t.a = Matrix::Zero(s, s);
  int i = 0;
  for (const auto& row : a) {
    int j = 0;
    for (double v : row) t.a(i, j++) = v;
    ++i;
  }
  t.b = Eigen::Map<const Vector>(b.begin(), s);
  t.c = Eigen::Map<const Vector>(c.begin(), s);
  if (bEmbedded.size() != 0) t.bEmbedded = Eigen::Map<const Vector>(bEmbedded.begin(), s);
  t.order = order;
  t.embeddedOrder = embeddedOrder;
  return t;
}

}  // namespace

bool ButcherTableau::isExplicit() const {
  for (int i = 0; i < a.rows(); ++i) {
    if (a(i, i) != 0.0) return false;
  }
  return true;
}

std::vector<std::string> ButcherTableau::names() {
  std::vector<std::string> names;
  for (const auto& name : integratorMethodNames()) {
    if (isRungeKutta(parseIntegratorMethod(name))) names.push_back(name);
  }
  return names;
}

ButcherTableau ButcherTableau::byName(const std::string& name) {
  const IntegratorMethod method = parseIntegratorMethod(name);
  if (!isRungeKutta(method)) {
    std::string known;
    for (const auto& n : names()) known += (known.empty() ? "" : ", ") + n;
    throw std::invalid_argument("IntegratorOptions.method = '" + name +
                                "' is not a Runge-Kutta method; Runge-Kutta methods: " + known);
  }
  return byMethod(method);
}

ButcherTableau ButcherTableau::byMethod(IntegratorMethod method) {
  const std::string name = toString(method);
  if (method == IntegratorMethod::Rk4) {
    return makeTableau(name, {{0, 0, 0, 0}, {0.5, 0, 0, 0}, {0, 0.5, 0, 0}, {0, 0, 1, 0}},
                       {1.0 / 6, 1.0 / 3, 1.0 / 3, 1.0 / 6}, {0, 0.5, 0.5, 1}, {}, 4, 0);
  }
  if (method == IntegratorMethod::Dopri5) {
    // Dormand & Prince (1980), the 5th-order solution propagated, 4th-order embedded.
    return makeTableau(
        name,
        {{0, 0, 0, 0, 0, 0, 0},
         {1.0 / 5, 0, 0, 0, 0, 0, 0},
         {3.0 / 40, 9.0 / 40, 0, 0, 0, 0, 0},
         {44.0 / 45, -56.0 / 15, 32.0 / 9, 0, 0, 0, 0},
         {19372.0 / 6561, -25360.0 / 2187, 64448.0 / 6561, -212.0 / 729, 0, 0, 0},
         {9017.0 / 3168, -355.0 / 33, 46732.0 / 5247, 49.0 / 176, -5103.0 / 18656, 0, 0},
         {35.0 / 384, 0, 500.0 / 1113, 125.0 / 192, -2187.0 / 6784, 11.0 / 84, 0}},
        {35.0 / 384, 0, 500.0 / 1113, 125.0 / 192, -2187.0 / 6784, 11.0 / 84, 0},
        {0, 0.2, 0.3, 0.8, 8.0 / 9, 1, 1},
        {5179.0 / 57600, 0, 7571.0 / 16695, 393.0 / 640, -92097.0 / 339200, 187.0 / 2100, 1.0 / 40}, 5, 4);
  }
  if (method == IntegratorMethod::TrBdf2) {
    // TR-BDF2 written as an ESDIRK (Hosea & Shampine 1996): gamma = 2 - sqrt(2), d = gamma/2,
    // w = sqrt(2)/4; stiffly accurate and L-stable; the embedded weights give order 3.
    const double gamma = 2.0 - std::sqrt(2.0);
    const double d = gamma / 2.0;
    const double w = std::sqrt(2.0) / 4.0;
    return makeTableau(name, {{0, 0, 0}, {d, d, 0}, {w, w, d}}, {w, w, d}, {0, gamma, 1},
                       {(1.0 - w) / 3.0, (3.0 * w + 1.0) / 3.0, d / 3.0}, 2, 3);
  }
  if (method == IntegratorMethod::Sdirk2) {
    // Alexander (1977): gamma = 1 - 1/sqrt(2), L-stable, stiffly accurate.
    const double gamma = 1.0 - 1.0 / std::sqrt(2.0);
    return makeTableau(name, {{gamma, 0}, {1.0 - gamma, gamma}}, {1.0 - gamma, gamma}, {gamma, 1.0}, {}, 2,
                       0);
  }
  if (method == IntegratorMethod::Midpoint) {
    return makeTableau(name, {{0.5}}, {1.0}, {0.5}, {}, 2, 0);
  }
  throw std::invalid_argument("IntegratorOptions.method = '" + name + "' is not a Runge-Kutta method");
}

RungeKuttaIntegrator::RungeKuttaIntegrator(const Problem& problem, ConstVectorRef p,
                                           const IntegratorOptions& options)
    : problem_(problem), p_(p), options_(options) {
  method_ = checkedMethod(problem, p, options);
  tableau_ = ButcherTableau::byMethod(method_);
  n_ = problem.stateSize();
  stages_ = static_cast<int>(tableau_.b.size());
  workspace_ = problem.createWorkspaceFor(p_);
  stageSlopes_.resize(n_, stages_);
  stageStates_.resize(n_, stages_);
  stageAdjoints_.resize(n_, stages_);
  if (tableau_.isExplicit()) rhsDataSize_ = problem.rhsDataSize();
  stageRhsData_.resize(rhsDataSize_, stages_);
  base_.resize(n_);
  residual_.resize(n_);
  delta_.resize(n_);
  work_.resize(n_);
  rhsWork_.resize(n_);
  zStart_.resize(n_);
  linearInState_ = problem.isLinearInState();
  newtonAbsoluteTolerance_ = options.absoluteTolerance;
  if (options.adaptive && !options.absoluteTolerances.empty()) {
    absoluteTolerances_ = Eigen::Map<const Vector>(options.absoluteTolerances.data(), n_);
    relativeTolerances_ = Vector::Constant(n_, options.relativeTolerance);
    newtonAbsoluteTolerance_ = absoluteTolerances_.minCoeff();
  }
  if (problem.hasDenseJacobian()) {
    jacobian_.resize(n_, n_);
    newtonMatrix_.resize(n_, n_);
    lu_ = Eigen::PartialPivLU<Matrix>(n_);
  } else if (!tableau_.isExplicit()) {
    newtonSolver_ = problem.createNewtonSolver();
    if (!newtonSolver_) {
      throw std::invalid_argument("problem '" + problem.name() +
                                  "' has no dense Jacobian and no Newton solver; implicit method '" +
                                  options.method + "' needs one");
    }
  }
}

RungeKuttaIntegrator::~RungeKuttaIntegrator() = default;

bool RungeKuttaIntegrator::firstStageIsRhs() const { return tableau_.c(0) == 0.0 && tableau_.a(0, 0) == 0.0; }

Eigen::Ref<const Vector> RungeKuttaIntegrator::lastFirstStage() const { return stageSlopes_.col(0); }

void RungeKuttaIntegrator::initialState(double, VectorRef z) { problem_.initialState(p_, z); }

void RungeKuttaIntegrator::addInitialStateVjp(double, ConstVectorRef, ConstVectorRef lambda,
                                              VectorRef gradient) {
  problem_.addInitialStateVjp(p_, lambda, gradient);
}

void RungeKuttaIntegrator::stateDerivative(double t, ConstVectorRef z, VectorRef f) {
  problem_.rhs(t, z, p_, f, workspace_.get());
  ++counters_.rhsEvaluations;
}

void RungeKuttaIntegrator::solveImplicitStage(int i, double t, double h) {
  const double ti = t + tableau_.c(i) * h;
  const double alpha = h * tableau_.a(i, i);
  auto K = stageSlopes_.col(i);
  auto Z = stageStates_.col(i);
  // Initial guess: the previous stage's slope, or F at the explicit part.
  if (i > 0) {
    K = stageSlopes_.col(i - 1);
  } else {
    problem_.rhs(ti, base_, p_, rhsWork_, workspace_.get());
    ++counters_.rhsEvaluations;
    K = rhsWork_;
  }
  double previous = std::numeric_limits<double>::infinity();
  for (int iteration = 0; iteration < options_.newtonMaxIterations; ++iteration) {
    Z = base_ + alpha * K;
    problem_.rhs(ti, Z, p_, rhsWork_, workspace_.get());
    ++counters_.rhsEvaluations;
    residual_ = K - rhsWork_;
    if (iteration == 0) {
      // Simplified Newton: one Jacobian and factorisation per stage.
      if (newtonSolver_) {
        newtonSolver_->factorize(ti, Z, p_, alpha, workspace_.get());
      } else {
        problem_.rhsJacobian(ti, Z, p_, jacobian_, workspace_.get());
        newtonMatrix_.noalias() = -alpha * jacobian_;
        newtonMatrix_.diagonal().array() += 1.0;
        lu_.compute(newtonMatrix_);
      }
      ++counters_.jacobianEvaluations;
      ++counters_.factorizations;
    }
    if (newtonSolver_) {
      delta_ = residual_;
      newtonSolver_->solve(delta_);
    } else {
      delta_.noalias() = lu_.solve(residual_);
    }
    K -= delta_;
    ++counters_.newtonIterations;
    const double change = alpha * infNorm(delta_);
    if (!std::isfinite(change)) throw NewtonFailure("Newton iteration produced a non-finite stage", ti);
    // An affine F with an exact solve: the first step solves the stage (Problem::isLinearInState).
    if (linearInState_ || change <= options_.newtonTolerance * (infNorm(Z) + newtonAbsoluteTolerance_)) {
      Z = base_ + alpha * K;
      return;
    }
    if (iteration >= 2 && change > previous && change > 1e3 * options_.newtonTolerance * (infNorm(Z) + 1.0)) {
      throw NewtonFailure("Newton iteration diverges in stage " + std::to_string(i), ti);
    }
    previous = change;
  }
  throw NewtonFailure("Newton iteration did not converge in " + std::to_string(options_.newtonMaxIterations) +
                          " iterations (stage " + std::to_string(i) + ")",
                      ti);
}

void RungeKuttaIntegrator::computeStages(double t, double h, ConstVectorRef z) {
  for (int i = 0; i < stages_; ++i) {
    base_ = z;
    for (int j = 0; j < i; ++j) {
      if (tableau_.a(i, j) != 0.0) base_ += (h * tableau_.a(i, j)) * stageSlopes_.col(j);
    }
    if (tableau_.a(i, i) == 0.0) {
      stageStates_.col(i) = base_;
      problem_.rhs(t + tableau_.c(i) * h, base_, p_, stageSlopes_.col(i), workspace_.get());
      ++counters_.rhsEvaluations;
      if (savesRhsData_) problem_.saveRhsData(workspace_.get(), stageRhsData_.col(i));
    } else {
      solveImplicitStage(i, t, h);
    }
  }
}

double RungeKuttaIntegrator::step(double t, double h, VectorRef z, double* errorNorm) {
  assert(z.size() == n_);
  zStart_ = z;
  computeStages(t, h, zStart_);
  double increment = 0.0;
  for (int i = 0; i < stages_; ++i) {
    if (tableau_.b(i) == 0.0) continue;
    z += (h * tableau_.b(i)) * stageSlopes_.col(i);
    increment += h * tableau_.b(i) *
                 problem_.integrand(t + tableau_.c(i) * h, stageStates_.col(i), p_, workspace_.get());
  }
  if (!z.allFinite() || !std::isfinite(increment)) {
    throw NumericalError("the state or the objective became non-finite", t + h);
  }
  if (errorNorm != nullptr) {
    assert(tableau_.bEmbedded.size() == stages_);
    work_.setZero();
    for (int i = 0; i < stages_; ++i) {
      const double weight = tableau_.b(i) - tableau_.bEmbedded(i);
      if (weight != 0.0) work_ += (h * weight) * stageSlopes_.col(i);
    }
    *errorNorm =
        absoluteTolerances_.size() > 0
            ? weightedRmsNorm(work_, zStart_, z, relativeTolerances_, absoluteTolerances_)
            : weightedRmsNorm(work_, zStart_, z, options_.relativeTolerance, options_.absoluteTolerance);
  }
  return increment;
}

void RungeKuttaIntegrator::jacobianTransposeProduct(double t, ConstVectorRef z, ConstVectorRef w,
                                                    VectorRef out, bool needDenseJacobian) {
  if (newtonSolver_ || !problem_.hasDenseJacobian() || (!needDenseJacobian && problem_.hasStateVjp())) {
    problem_.rhsStateVjp(t, z, p_, w, out, workspace_.get());
  } else {
    problem_.rhsJacobian(t, z, p_, jacobian_, workspace_.get());
    out.noalias() = jacobian_.transpose() * w;
  }
  ++counters_.jacobianEvaluations;
}

void RungeKuttaIntegrator::adjointStep(double t, double h, ConstVectorRef z, VectorRef lambda,
                                       VectorRef gradient) {
  assert(z.size() == n_ && lambda.size() == n_ && gradient.size() == p_.size());
  computeStages(t, h, z);
  adjointFromStages(t, h, lambda, gradient);
}

std::int64_t RungeKuttaIntegrator::stepDataSize() const {
  return static_cast<std::int64_t>(n_) * (stages_ - firstDataStage());
}

void RungeKuttaIntegrator::saveStepData(VectorRef data) const {
  assert(data.size() == stepDataSize() + (savesRhsData_ ? stepRhsDataSize() : 0));
  const int first = firstDataStage();
  const Eigen::Index states = static_cast<Eigen::Index>(stages_ - first) * n_;
  for (int i = first; i < stages_; ++i)
    data.segment(static_cast<Eigen::Index>(i - first) * n_, n_) = stageStates_.col(i);
  if (savesRhsData_) {
    data.segment(states, static_cast<Eigen::Index>(rhsDataSize_) * stages_) =
        Eigen::Map<const Vector>(stageRhsData_.data(), stageRhsData_.size());
  }
}

void RungeKuttaIntegrator::adjointStepFromData(double t, double h, ConstVectorRef z, ConstVectorRef data,
                                               VectorRef lambda, VectorRef gradient) {
  const bool withRhsData = rhsDataSize_ > 0 && data.size() == stepDataSize() + stepRhsDataSize();
  assert(z.size() == n_ && (withRhsData || data.size() == stepDataSize()) && lambda.size() == n_ &&
         gradient.size() == p_.size());
  const int first = firstDataStage();
  // With a_11 = 0 the first stage state is z_n: computeStages() copies it bit for bit, and so does this.
  if (first == 1) stageStates_.col(0) = z;
  for (int i = first; i < stages_; ++i)
    stageStates_.col(i) = data.segment(static_cast<Eigen::Index>(i - first) * n_, n_);
  adjointFromStages(t, h, lambda, gradient,
                    withRhsData ? data.data() + static_cast<Eigen::Index>(stages_ - first) * n_ : nullptr);
}

void RungeKuttaIntegrator::adjointFromStages(double t, double h, VectorRef lambda, VectorRef gradient,
                                             const double* rhsData) {
  for (int i = stages_ - 1; i >= 0; --i) {
    const double ti = t + tableau_.c(i) * h;
    const double alpha = h * tableau_.a(i, i);
    // r_i = h b_i lambda + h sum_{j>i} a_ji Zbar_j, kept in base_.
    base_ = (h * tableau_.b(i)) * lambda;
    for (int j = i + 1; j < stages_; ++j) {
      if (tableau_.a(j, i) != 0.0) base_ += (h * tableau_.a(j, i)) * stageAdjoints_.col(j);
    }
    auto Zbar = stageAdjoints_.col(i);
    auto Zi = stageStates_.col(i);
    // What the forward rhs computed at Z_i (explicit stages only): the products below reuse it.
    if (rhsData != nullptr) {
      problem_.restoreRhsData(
          ti, Zi, p_,
          Eigen::Map<const Vector>(rhsData + static_cast<std::ptrdiff_t>(i) * rhsDataSize_, rhsDataSize_),
          workspace_.get());
    }
    // An explicit stage takes both products at one point with one w (shared work, rhsVjps); an
    // implicit stage factorises I - alpha F_z below, so it needs the dense Jacobian anyway.
    const bool sharedProducts = alpha == 0.0 && !newtonSolver_ && problem_.hasStateVjp();
    if (sharedProducts) {
      problem_.rhsVjps(ti, Zi, p_, base_, Zbar, gradient, workspace_.get());
      ++counters_.jacobianEvaluations;
    } else {
      jacobianTransposeProduct(ti, Zi, base_, Zbar, alpha != 0.0 && !newtonSolver_);
    }
    if (tableau_.b(i) != 0.0) {
      problem_.addIntegrandStateGradient(ti, Zi, p_, h * tableau_.b(i), Zbar, workspace_.get());
    }
    if (alpha != 0.0) {
      if (newtonSolver_) {
        newtonSolver_->factorize(ti, Zi, p_, alpha, workspace_.get());
        newtonSolver_->solveTransposed(Zbar);
      } else {
        // jacobian_ holds F_z(Z_i) from jacobianTransposeProduct.
        newtonMatrix_.noalias() = -alpha * jacobian_;
        newtonMatrix_.diagonal().array() += 1.0;
        lu_.compute(newtonMatrix_);
        solveTransposedInPlace(lu_, Zbar, residual_);
      }
      ++counters_.factorizations;
    }
    // Kbar_i = r_i + h a_ii Zbar_i.
    if (alpha != 0.0) base_ += alpha * Zbar;
    if (!sharedProducts) problem_.addRhsParameterVjp(ti, Zi, p_, base_, gradient, workspace_.get());
    if (tableau_.b(i) != 0.0) {
      problem_.addIntegrandParameterGradient(ti, Zi, p_, h * tableau_.b(i), gradient, workspace_.get());
    }
  }
  for (int i = 0; i < stages_; ++i) lambda += stageAdjoints_.col(i);
}

}  // namespace hindsight
