#include <hindsight/engine/generalized_alpha.h>

#include <hindsight/engine/step_controller.h>

#include <cmath>
#include <limits>

namespace hindsight {

GeneralizedAlphaIntegrator::Coefficients GeneralizedAlphaIntegrator::coefficients(IntegratorMethod method,
                                                                                  double rhoInfinity) {
  const double rho = rhoInfinity;
  Coefficients c;
  if (method == IntegratorMethod::GeneralizedAlpha) {
    c.alphaM = (2.0 * rho - 1.0) / (rho + 1.0);
    c.alphaF = rho / (rho + 1.0);
  } else if (method == IntegratorMethod::HhtAlpha) {
    c.alphaM = 0.0;
    c.alphaF = (1.0 - rho) / (1.0 + rho);
  } else {
    throw std::invalid_argument("IntegratorOptions.method = '" + toString(method) +
                                "' is not generalized-alpha or hht-alpha");
  }
  // Second order and unconditionally stable for linear problems (Chung & Hulbert, eqs. 17 and 20).
  c.gamma = 0.5 - c.alphaM + c.alphaF;
  const double shift = 1.0 - c.alphaM + c.alphaF;
  c.beta = 0.25 * shift * shift;
  return c;
}

GeneralizedAlphaIntegrator::GeneralizedAlphaIntegrator(const SecondOrderProblem& problem, ConstVectorRef p,
                                                       const IntegratorOptions& options)
    : problem_(problem), p_(p), options_(options) {
  method_ = checkedMethod(problem, p, options);
  coefficients_ = coefficients(method_, options.rhoInfinity);
  f_ = problem.coordinateCount();
  workspace_ = problem.createModelWorkspaceFor(p_);
  mass_.resize(f_, f_);
  ry_.resize(f_, f_);
  rv_.resize(f_, f_);
  iteration_.resize(f_, f_);
  lu_ = Eigen::PartialPivLU<Matrix>(f_);
  for (Vector* v : {&force_, &residual_, &delta_, &accel_, &yNext_, &vNext_, &aNext_, &adjointY_, &adjointV_,
                    &adjointA_, &mu_, &work_}) {
    v->resize(f_);
  }
}

GeneralizedAlphaIntegrator::~GeneralizedAlphaIntegrator() = default;

void GeneralizedAlphaIntegrator::stateDerivative(double, ConstVectorRef, VectorRef) {
  throw std::logic_error("generalized-alpha provides no state derivative (hasStateDerivative() is false)");
}

void GeneralizedAlphaIntegrator::factorizeIterationMatrix(double t, ConstVectorRef y, ConstVectorRef v,
                                                          ConstVectorRef accel, double betaPrime,
                                                          double gammaPrime) {
  problem_.massMatrix(t, y, p_, mass_, workspace_.get());
  problem_.residualJacobians(t, y, v, accel, p_, ry_, rv_, workspace_.get());
  ++counters_.jacobianEvaluations;
  iteration_ = mass_;
  if (betaPrime != 0.0) iteration_ += betaPrime * ry_;
  if (gammaPrime != 0.0) iteration_ += gammaPrime * rv_;
  lu_.compute(iteration_);
  ++counters_.factorizations;
}

void GeneralizedAlphaIntegrator::initialState(double t0, VectorRef x) {
  auto y = x.segment(0, f_), v = x.segment(f_, f_), d = x.segment(2 * f_, f_), a = x.segment(3 * f_, f_);
  problem_.initialCoordinates(p_, y, v);
  // d_0 = M^{-1} f(t0, y0, v0): r is affine in d, so one solve with r_d = M is exact.
  problem_.massMatrix(t0, y, p_, mass_, workspace_.get());
  problem_.force(t0, y, v, p_, force_, workspace_.get());
  ++counters_.rhsEvaluations;
  lu_.compute(mass_);
  ++counters_.factorizations;
  d.noalias() = lu_.solve(force_);
  a = d;
}

void GeneralizedAlphaIntegrator::addInitialStateVjp(double t0, ConstVectorRef x0, ConstVectorRef lambda,
                                                    VectorRef gradient) {
  const auto y = x0.segment(0, f_), v = x0.segment(f_, f_), d = x0.segment(2 * f_, f_);
  // d_0 and a_0 both equal the solution of r(t0, y0, v0, d) = 0: mu = M^{-T} (lambda_d + lambda_a).
  mu_ = lambda.segment(2 * f_, f_) + lambda.segment(3 * f_, f_);
  factorizeIterationMatrix(t0, y, v, d, 0.0, 0.0);
  solveTransposedInPlace(lu_, mu_, work_);
  adjointY_ = lambda.segment(0, f_);
  adjointV_ = lambda.segment(f_, f_);
  adjointY_.noalias() -= ry_.transpose() * mu_;
  adjointV_.noalias() -= rv_.transpose() * mu_;
  mu_ = -mu_;
  problem_.addResidualParameterVjp(t0, y, v, d, p_, mu_, gradient, workspace_.get());
  problem_.addInitialCoordinatesVjp(p_, adjointY_, adjointV_, gradient);
}

void GeneralizedAlphaIntegrator::kinematics(double h, ConstVectorRef x) {
  const Coefficients& c = coefficients_;
  const auto y = x.segment(0, f_), v = x.segment(f_, f_), d = x.segment(2 * f_, f_),
             a = x.segment(3 * f_, f_);
  const double scale = 1.0 / (1.0 - c.alphaM);
  aNext_ = (c.alphaF * scale) * d - (c.alphaM * scale) * a + ((1.0 - c.alphaF) * scale) * accel_;
  yNext_ = y + h * v + (h * h * (0.5 - c.beta)) * a + (h * h * c.beta) * aNext_;
  vNext_ = v + (h * (1.0 - c.gamma)) * a + (h * c.gamma) * aNext_;
}

void GeneralizedAlphaIntegrator::solveStep(double t, double h, ConstVectorRef x) {
  const Coefficients& c = coefficients_;
  const double tNext = t + h;
  const double ratio = (1.0 - c.alphaF) / (1.0 - c.alphaM);
  accel_ = x.segment(2 * f_, f_);  // predictor: the last acceleration
  double previous = std::numeric_limits<double>::infinity();
  for (int iteration = 0; iteration < options_.newtonMaxIterations; ++iteration) {
    kinematics(h, x);
    if (iteration == 0) {
      // Simplified Newton: one iteration matrix per step, at the predictor.
      factorizeIterationMatrix(tNext, yNext_, vNext_, accel_, h * h * c.beta * ratio, h * c.gamma * ratio);
      problem_.force(tNext, yNext_, vNext_, p_, force_, workspace_.get());
    } else {
      problem_.massMatrixAndForce(tNext, yNext_, vNext_, p_, mass_, force_, workspace_.get());
    }
    ++counters_.rhsEvaluations;
    residual_.noalias() = mass_ * accel_;
    residual_ -= force_;
    delta_.noalias() = lu_.solve(residual_);
    accel_ -= delta_;
    ++counters_.newtonIterations;
    const double change = infNorm(delta_);
    if (!std::isfinite(change))
      throw NewtonFailure("Newton iteration produced a non-finite acceleration", tNext);
    const double scale = infNorm(accel_) + options_.absoluteTolerance;
    // Converged, or stalled at the round-off floor (S can be ill-conditioned for stiff springs).
    if (change <= options_.newtonTolerance * scale ||
        (iteration >= 2 && change >= previous && change <= 1e3 * options_.newtonTolerance * scale)) {
      kinematics(h, x);
      return;
    }
    if (iteration >= 2 && change > previous) {
      throw NewtonFailure("Newton iteration for the generalized-alpha acceleration diverges", tNext);
    }
    previous = change;
  }
  throw NewtonFailure("Newton iteration for the generalized-alpha acceleration did not converge in " +
                          std::to_string(options_.newtonMaxIterations) + " iterations",
                      tNext);
}

double GeneralizedAlphaIntegrator::step(double t, double h, VectorRef x, double* errorNorm) {
  assert(x.size() == 4 * f_);
  assert(errorNorm == nullptr && "generalized-alpha has no error estimate");
  (void)errorNorm;
  const double start = problem_.integrand(t, x.segment(0, f_), x.segment(f_, f_), p_, workspace_.get());
  solveStep(t, h, x);
  x.segment(0, f_) = yNext_;
  x.segment(f_, f_) = vNext_;
  x.segment(2 * f_, f_) = accel_;
  x.segment(3 * f_, f_) = aNext_;
  const double end = problem_.integrand(t + h, yNext_, vNext_, p_, workspace_.get());
  const double increment = 0.5 * h * (start + end);
  if (!x.allFinite() || !std::isfinite(increment)) {
    throw NumericalError("the state or the objective became non-finite", t + h);
  }
  return increment;
}

void GeneralizedAlphaIntegrator::adjointStep(double t, double h, ConstVectorRef x, VectorRef lambda,
                                             VectorRef gradient) {
  assert(x.size() == 4 * f_ && lambda.size() == 4 * f_ && gradient.size() == p_.size());
  // The same code path as step(): the converged acceleration has the forward sweep's bits.
  solveStep(t, h, x);
  adjointAtSolution(t, h, x, lambda, gradient);
}

void GeneralizedAlphaIntegrator::adjointStepWithEnd(double t, double h, ConstVectorRef x, ConstVectorRef xEnd,
                                                    VectorRef lambda, VectorRef gradient) {
  assert(x.size() == 4 * f_ && xEnd.size() == 4 * f_);
  // step() stored accel_ as d_{n+1} and solveStep() ended with kinematics() from it: the same bits.
  accel_ = xEnd.segment(2 * f_, f_);
  kinematics(h, x);
  adjointAtSolution(t, h, x, lambda, gradient);
}

void GeneralizedAlphaIntegrator::adjointAtSolution(double t, double h, ConstVectorRef x, VectorRef lambda,
                                                   VectorRef gradient) {
  assert(x.size() == 4 * f_ && lambda.size() == 4 * f_ && gradient.size() == p_.size());
  const Coefficients& c = coefficients_;
  const double tNext = t + h;
  const double ratio = (1.0 - c.alphaF) / (1.0 - c.alphaM);
  const double betaPrime = h * h * c.beta, gammaPrime = h * c.gamma;
  // Adjoints of y_{n+1}, v_{n+1}, with the end point of the trapezoidal rule (notation of
  // docs/generalized_alpha.md: Q, V).
  adjointY_ = lambda.segment(0, f_);
  adjointV_ = lambda.segment(f_, f_);
  problem_.addIntegrandStateGradient(tNext, yNext_, vNext_, p_, 0.5 * h, adjointY_, adjointV_,
                                     workspace_.get());
  problem_.addIntegrandParameterGradient(tNext, yNext_, vNext_, p_, 0.5 * h, gradient, workspace_.get());
  // S^T mu = lambda_d + c (lambda_a + h^2 beta Q + h gamma V), with the exact S at the solution.
  mu_ = lambda.segment(2 * f_, f_);
  mu_ += ratio * lambda.segment(3 * f_, f_);
  mu_ += (ratio * betaPrime) * adjointY_;
  mu_ += (ratio * gammaPrime) * adjointV_;
  factorizeIterationMatrix(tNext, yNext_, vNext_, accel_, betaPrime * ratio, gammaPrime * ratio);
  solveTransposedInPlace(lu_, mu_, work_);
  // Through the residual at fixed d_{n+1}: Q -= r_y^T mu, V -= r_v^T mu, gradient -= r_p^T mu.
  adjointY_.noalias() -= ry_.transpose() * mu_;
  adjointV_.noalias() -= rv_.transpose() * mu_;
  mu_ = -mu_;
  problem_.addResidualParameterVjp(tNext, yNext_, vNext_, accel_, p_, mu_, gradient, workspace_.get());
  // A: the adjoint of a_{n+1} at fixed d_{n+1}.
  adjointA_ = lambda.segment(3 * f_, f_);
  adjointA_ += betaPrime * adjointY_;
  adjointA_ += gammaPrime * adjointV_;
  // Back to x_n, with the start point of the trapezoidal rule.
  const double scale = 1.0 / (1.0 - c.alphaM);
  auto ly = lambda.segment(0, f_), lv = lambda.segment(f_, f_), ld = lambda.segment(2 * f_, f_),
       la = lambda.segment(3 * f_, f_);
  const auto y = x.segment(0, f_), v = x.segment(f_, f_);
  ly = adjointY_;
  lv = h * adjointY_ + adjointV_;
  ld = (c.alphaF * scale) * adjointA_;
  la = (-c.alphaM * scale) * adjointA_ + (h * h * (0.5 - c.beta)) * adjointY_ +
       (h * (1.0 - c.gamma)) * adjointV_;
  problem_.addIntegrandStateGradient(t, y, v, p_, 0.5 * h, ly, lv, workspace_.get());
  problem_.addIntegrandParameterGradient(t, y, v, p_, 0.5 * h, gradient, workspace_.get());
}

}  // namespace hindsight
