#include <hindsight/problems/topopt/mma.h>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace hindsight {
namespace {

// Fractions of the positive and negative parts of a derivative put into p and q (the 1.001 / 0.001
// split of the 2007 note), which makes every approximation strictly convex.
constexpr double kMainCurvature = 1.001;
constexpr double kMinorCurvature = 0.001;
// The interior-point step keeps every positive variable positive with this safety factor.
constexpr double kFractionToBoundary = 1.01;
// Halvings of the step before a Newton step is accepted without residual decrease.
constexpr int kMaxStepHalvings = 50;

bool Fail(std::string* error, const std::string& message) {
  if (error != nullptr) *error = message;
  return false;
}

std::string RangeMessage(const char* field, double value, const char* range) {
  std::ostringstream out;
  out << "MmaOptions::" << field << " = " << value << " must be " << range;
  return out.str();
}

[[noreturn]] void ThrowArgument(const std::string& message) { throw std::invalid_argument(message); }

void CheckSize(const char* name, Eigen::Index actual, Eigen::Index expected) {
  if (actual != expected) {
    std::ostringstream out;
    out << "Mma: " << name << " has length " << actual << ", expected " << expected;
    ThrowArgument(out.str());
  }
}

void CheckFinite(const char* name, ConstVectorRef v) {
  for (Eigen::Index j = 0; j < v.size(); ++j) {
    if (!std::isfinite(v(j))) {
      std::ostringstream out;
      out << "Mma: " << name << "(" << j << ") = " << v(j) << " is not finite";
      ThrowArgument(out.str());
    }
  }
}

}  // namespace

double kktResidual(ConstVectorRef x, ConstVectorRef objective_gradient, ConstVectorRef constraints,
                   ConstMatrixRef constraint_jacobian, ConstVectorRef lambda, ConstVectorRef xmin,
                   ConstVectorRef xmax) {
  const Eigen::Index n = x.size(), m = constraints.size();
  CheckSize("objective_gradient", objective_gradient.size(), n);
  CheckSize("xmin", xmin.size(), n);
  CheckSize("xmax", xmax.size(), n);
  CheckSize("lambda", lambda.size(), m);
  if (constraint_jacobian.rows() != m || constraint_jacobian.cols() != n) {
    ThrowArgument("kktResidual: constraint_jacobian is " + std::to_string(constraint_jacobian.rows()) +
                  " x " + std::to_string(constraint_jacobian.cols()) + ", expected " + std::to_string(m) +
                  " x " + std::to_string(n));
  }
  double residual = 0.0;
  for (Eigen::Index j = 0; j < n; ++j) {
    double g = objective_gradient(j);
    for (Eigen::Index i = 0; i < m; ++i) g += lambda(i) * constraint_jacobian(i, j);
    const double projected = std::min(std::max(x(j) - g, xmin(j)), xmax(j));
    residual = std::max(residual, std::abs(x(j) - projected));
  }
  for (Eigen::Index i = 0; i < m; ++i) {
    residual = std::max(residual, std::max(constraints(i), 0.0));
    residual = std::max(residual, std::abs(lambda(i) * constraints(i)));
  }
  return residual;
}

bool MmaOptions::IsValid(std::string* error) const {
  // Written as !(a && b) so that NaN fails every check.
  if (!(initial_asymptote_distance > 0.0 && initial_asymptote_distance <= 1.0))
    return Fail(error, RangeMessage("initial_asymptote_distance", initial_asymptote_distance, "in (0, 1]"));
  if (!(asymptote_expansion >= 1.0 && std::isfinite(asymptote_expansion)))
    return Fail(error, RangeMessage("asymptote_expansion", asymptote_expansion, ">= 1 and finite"));
  if (!(asymptote_contraction > 0.0 && asymptote_contraction <= 1.0))
    return Fail(error, RangeMessage("asymptote_contraction", asymptote_contraction, "in (0, 1]"));
  if (!(min_asymptote_distance > 0.0 && min_asymptote_distance <= initial_asymptote_distance))
    return Fail(error, RangeMessage("min_asymptote_distance", min_asymptote_distance,
                                    "in (0, initial_asymptote_distance]"));
  if (!(max_asymptote_distance >= initial_asymptote_distance && std::isfinite(max_asymptote_distance)))
    return Fail(error, RangeMessage("max_asymptote_distance", max_asymptote_distance,
                                    ">= initial_asymptote_distance and finite"));
  if (!(asymptote_margin > 0.0 && asymptote_margin < 1.0))
    return Fail(error, RangeMessage("asymptote_margin", asymptote_margin, "in (0, 1)"));
  if (!(move_limit > 0.0 && move_limit <= 1.0))
    return Fail(error, RangeMessage("move_limit", move_limit, "in (0, 1]"));
  if (!(move_limit_shrink > 0.0 && move_limit_shrink < 1.0))
    return Fail(error, RangeMessage("move_limit_shrink", move_limit_shrink, "in (0, 1)"));
  if (!(move_limit_growth >= 1.0 && std::isfinite(move_limit_growth)))
    return Fail(error, RangeMessage("move_limit_growth", move_limit_growth, ">= 1 and finite"));
  if (!(min_move_limit > 0.0 && min_move_limit <= move_limit))
    return Fail(error, RangeMessage("min_move_limit", min_move_limit, "in (0, move_limit]"));
  if (!(curvature_regularization > 0.0 && std::isfinite(curvature_regularization)))
    return Fail(error, RangeMessage("curvature_regularization", curvature_regularization, "> 0 and finite"));
  if (!(z_cost > 0.0 && std::isfinite(z_cost)))
    return Fail(error, RangeMessage("z_cost", z_cost, "> 0 and finite"));
  if (!(z_weight >= 0.0 && std::isfinite(z_weight)))
    return Fail(error, RangeMessage("z_weight", z_weight, ">= 0 and finite"));
  if (!(y_linear_cost >= 0.0 && std::isfinite(y_linear_cost)))
    return Fail(error, RangeMessage("y_linear_cost", y_linear_cost, ">= 0 and finite"));
  if (!(y_quadratic_cost >= 0.0 && std::isfinite(y_quadratic_cost)))
    return Fail(error, RangeMessage("y_quadratic_cost", y_quadratic_cost, ">= 0 and finite"));
  if (!(y_linear_cost + y_quadratic_cost > 0.0))
    return Fail(error, RangeMessage("y_linear_cost + y_quadratic_cost", y_linear_cost + y_quadratic_cost,
                                    "> 0 (otherwise the elastic variables are unbounded)"));
  if (!(subproblem_tolerance > 0.0 && subproblem_tolerance < 1.0))
    return Fail(error, RangeMessage("subproblem_tolerance", subproblem_tolerance, "in (0, 1)"));
  if (!(subproblem_max_newton_iterations >= 1))
    return Fail(error,
                RangeMessage("subproblem_max_newton_iterations", subproblem_max_newton_iterations, ">= 1"));
  return true;
}

Mma::Mma(int n, int m, const MmaOptions& options) : n_(n), m_(m), options_(options) {
  if (n < 1) ThrowArgument("Mma: n = " + std::to_string(n) + " must be >= 1");
  if (m < 0) ThrowArgument("Mma: m = " + std::to_string(m) + " must be >= 0");
  std::string error;
  if (!options.IsValid(&error)) ThrowArgument("Mma: options invalid: " + error);

  for (Vector* v : {&state_.xold1, &state_.xold2,  &state_.low,  &state_.upp, &sub_.xsi, &sub_.eta, &p0_,
                    &q0_,          &alpha_,        &beta_,       &xsub_,      &xOld_,    &xsiOld_,  &etaOld_,
                    &dx_,          &dxsi_,         &deta_,       &uxInv_,     &xlInv_,   &plam_,    &qlam_,
                    &deltaX_,      &inverseDiagX_, &toAlphaInv_, &toBetaInv_})
    v->setZero(n);
  for (Vector* v : {&sub_.lambda, &sub_.y, &b_, &mu_, &s_, &yOld_, &lambdaOld_, &muOld_, &sOld_, &dy_,
                    &dlambda_, &dmu_, &ds_, &gvec_, &deltaY_, &diagY_, &deltaLambda_})
    v->setZero(m);
  P_.setZero(m, n);
  Q_.setZero(m, n);
  gradG_.setZero(m, n);
  scaledGradG_.setZero(m, n);
  reducedMatrix_.setZero(m + 1, m + 1);
  reducedRhs_.setZero(m + 1);
  reducedSolution_.setZero(m + 1);
  reducedLu_ = Eigen::PartialPivLU<Matrix>(m + 1);
  uniformRegularization_ = Vector::Constant(m + 1, options_.curvature_regularization);
}

void Mma::restore(const MmaState& state) {
  if (state.iteration < 0)
    ThrowArgument("Mma::restore: state.iteration = " + std::to_string(state.iteration) + " must be >= 0");
  CheckSize("state.xold1", state.xold1.size(), n_);
  CheckSize("state.xold2", state.xold2.size(), n_);
  CheckSize("state.low", state.low.size(), n_);
  CheckSize("state.upp", state.upp.size(), n_);
  state_.iteration = state.iteration;
  state_.xold1 = state.xold1;
  state_.xold2 = state.xold2;
  state_.low = state.low;
  state_.upp = state.upp;
  state_.moveLimit = state.moveLimit;
  state_.objective = state.objective;
}

void Mma::checkInputs(double objective, ConstVectorRef objective_gradient, ConstVectorRef constraints,
                      ConstMatrixRef constraint_jacobian, ConstVectorRef xmin, ConstVectorRef xmax,
                      const Vector& x) const {
  CheckSize("x", x.size(), n_);
  CheckSize("objective_gradient", objective_gradient.size(), n_);
  CheckSize("constraints", constraints.size(), m_);
  CheckSize("xmin", xmin.size(), n_);
  CheckSize("xmax", xmax.size(), n_);
  if (constraint_jacobian.rows() != m_ || constraint_jacobian.cols() != n_) {
    std::ostringstream out;
    out << "Mma: constraint_jacobian is " << constraint_jacobian.rows() << " x " << constraint_jacobian.cols()
        << ", expected " << m_ << " x " << n_;
    ThrowArgument(out.str());
  }
  if (!std::isfinite(objective))
    ThrowArgument("Mma: objective = " + std::to_string(objective) + " is not finite");
  CheckFinite("x", x);
  CheckFinite("objective_gradient", objective_gradient);
  CheckFinite("constraints", constraints);
  CheckFinite("xmin", xmin);
  CheckFinite("xmax", xmax);
  if (!constraint_jacobian.allFinite()) ThrowArgument("Mma: constraint_jacobian has a non-finite entry");
  for (int j = 0; j < n_; ++j) {
    if (!(xmin(j) < xmax(j))) {
      std::ostringstream out;
      out << "Mma: xmin(" << j << ") = " << xmin(j) << " must be < xmax(" << j << ") = " << xmax(j);
      ThrowArgument(out.str());
    }
    if (!(xmin(j) <= x(j) && x(j) <= xmax(j))) {
      std::ostringstream out;
      out << "Mma: x(" << j << ") = " << x(j) << " must lie in [xmin, xmax] = [" << xmin(j) << ", " << xmax(j)
          << "]";
      ThrowArgument(out.str());
    }
  }
}

void Mma::update(double objective, ConstVectorRef objective_gradient, ConstVectorRef constraints,
                 ConstMatrixRef constraint_jacobian, ConstVectorRef xmin, ConstVectorRef xmax, Vector& x) {
  checkInputs(objective, objective_gradient, constraints, constraint_jacobian, xmin, xmax, x);
  adaptMoveLimit(objective, constraints);
  updateAsymptotes(xmin, xmax, x);
  buildApproximation(objective_gradient, constraints, constraint_jacobian, xmin, xmax, x,
                     uniformRegularization_);
  solveSubproblem();

  state_.iteration += 1;
  state_.xold2 = state_.xold1;
  state_.xold1 = x;
  // The interior point lies strictly inside [alpha, beta]; clamping only guards the last bit.
  x = xsub_.cwiseMax(xmin).cwiseMin(xmax);
}

void Mma::adaptMoveLimit(double objective, ConstVectorRef constraints) {
  const MmaOptions& o = options_;
  // The one place the move limit of an update is decided; updateAsymptotes() reads it from the state.
  double move = o.adaptive_move_limit && state_.moveLimit > 0.0 ? state_.moveLimit : o.move_limit;
  const bool feasible = m_ == 0 || constraints.maxCoeff() <= 0.0;
  if (o.adaptive_move_limit && feasible && std::isfinite(state_.objective)) {
    move = objective > state_.objective ? std::max(move * o.move_limit_shrink, o.min_move_limit)
                                        : std::min(move * o.move_limit_growth, o.move_limit);
  }
  state_.moveLimit = move;
  state_.objective = feasible ? objective : std::numeric_limits<double>::quiet_NaN();
}

void Mma::updateAsymptotes(ConstVectorRef xmin, ConstVectorRef xmax, const Vector& x) {
  const MmaOptions& o = options_;
  const int k = state_.iteration + 1;    // the number of this iteration, counted from 1 as in the note
  const double move = state_.moveLimit;  // set by adaptMoveLimit() just before
  Vector& low = state_.low;
  Vector& upp = state_.upp;

  for (int j = 0; j < n_; ++j) {
    const double range = xmax(j) - xmin(j);
    // Asymptotes: fixed distance in the first two iterations; afterwards they widen when x_j moved in
    // the same direction twice (the approximation was too conservative) and narrow when it
    // oscillated (too aggressive).
    if (k <= 2) {
      low(j) = x(j) - o.initial_asymptote_distance * range;
      upp(j) = x(j) + o.initial_asymptote_distance * range;
    } else {
      const double trend = (x(j) - state_.xold1(j)) * (state_.xold1(j) - state_.xold2(j));
      const double factor =
          trend > 0.0 ? o.asymptote_expansion : (trend < 0.0 ? o.asymptote_contraction : 1.0);
      low(j) = x(j) - factor * (state_.xold1(j) - low(j));
      upp(j) = x(j) + factor * (upp(j) - state_.xold1(j));
      low(j) = std::min(std::max(low(j), x(j) - o.max_asymptote_distance * range),
                        x(j) - o.min_asymptote_distance * range);
      upp(j) = std::max(std::min(upp(j), x(j) + o.max_asymptote_distance * range),
                        x(j) + o.min_asymptote_distance * range);
    }
    // Move limits of the subproblem: a margin away from the asymptotes, at most move * range.
    alpha_(j) = std::max({xmin(j), low(j) + o.asymptote_margin * (x(j) - low(j)), x(j) - move * range});
    beta_(j) = std::min({xmax(j), upp(j) - o.asymptote_margin * (upp(j) - x(j)), x(j) + move * range});
  }
}

void Mma::buildApproximation(ConstVectorRef objective_gradient, ConstVectorRef constraints,
                             ConstMatrixRef constraint_jacobian, ConstVectorRef xmin, ConstVectorRef xmax,
                             const Vector& x, ConstVectorRef regularization) {
  const Vector& low = state_.low;
  const Vector& upp = state_.upp;
  for (int j = 0; j < n_; ++j) {
    const double range = xmax(j) - xmin(j);
    // Coefficients of f(x) ~ r + sum_j p_j / (upp_j - x_j) + q_j / (x_j - low_j): the positive part of
    // the derivative goes into p, the negative part into q, with a small share of each in the other
    // and rho_i / range added to both so that the approximation is strictly convex (rho_i = raa0 for
    // MMA; GCMMA raises it per function until the approximation is conservative).
    const double ux = upp(j) - x(j);
    const double xl = x(j) - low(j);
    const double ux2 = ux * ux;
    const double xl2 = xl * xl;
    const double regularization0 = regularization(0) / range;
    const double g0 = objective_gradient(j);
    const double g0plus = std::max(g0, 0.0);
    const double g0minus = std::max(-g0, 0.0);
    p0_(j) = ux2 * (kMainCurvature * g0plus + kMinorCurvature * g0minus + regularization0);
    q0_(j) = xl2 * (kMinorCurvature * g0plus + kMainCurvature * g0minus + regularization0);
    for (int i = 0; i < m_; ++i) {
      const double regularizationI = regularization(i + 1) / range;
      const double g = constraint_jacobian(i, j);
      const double gplus = std::max(g, 0.0);
      const double gminus = std::max(-g, 0.0);
      P_(i, j) = ux2 * (kMainCurvature * gplus + kMinorCurvature * gminus + regularizationI);
      Q_(i, j) = xl2 * (kMinorCurvature * gplus + kMainCurvature * gminus + regularizationI);
    }
    uxInv_(j) = 1.0 / ux;
    xlInv_(j) = 1.0 / xl;
  }
  // The constraint of the subproblem is g_i(x) <= b_i with g_i the p/q terms and
  // b_i = g_i(x^k) - f_i(x^k), so that the approximation equals f_i at x^k.
  for (int i = 0; i < m_; ++i) b_(i) = P_.row(i).dot(uxInv_) + Q_.row(i).dot(xlInv_) - constraints(i);
}

void Mma::beginConservativeIteration(double objective, ConstVectorRef objective_gradient,
                                     ConstVectorRef constraints, ConstMatrixRef constraint_jacobian,
                                     ConstVectorRef xmin, ConstVectorRef xmax, const Vector& x) {
  checkInputs(objective, objective_gradient, constraints, constraint_jacobian, xmin, xmax, x);
  adaptMoveLimit(objective, constraints);
  updateAsymptotes(xmin, xmax, x);
}

void Mma::solveConservativeSubproblem(ConstVectorRef objective_gradient, ConstVectorRef constraints,
                                      ConstMatrixRef constraint_jacobian, ConstVectorRef xmin,
                                      ConstVectorRef xmax, const Vector& x, ConstVectorRef regularization,
                                      Vector& trial) {
  CheckSize("regularization", regularization.size(), m_ + 1);
  for (Eigen::Index i = 0; i < regularization.size(); ++i) {
    if (!(regularization(i) > 0.0 && std::isfinite(regularization(i)))) {
      std::ostringstream out;
      out << "Mma: regularization(" << i << ") = " << regularization(i) << " must be > 0 and finite";
      ThrowArgument(out.str());
    }
  }
  buildApproximation(objective_gradient, constraints, constraint_jacobian, xmin, xmax, x, regularization);
  solveSubproblem();
  trial = xsub_.cwiseMax(xmin).cwiseMin(xmax);
}

double Mma::approximationChange(int i, const Vector& x, const Vector& trial) const {
  // f~_i(trial) - f_i(x) = sum_j p_ij (1/(u_j - t_j) - 1/(u_j - x_j)) + q_ij (1/(t_j - l_j) - 1/(x_j - l_j)),
  // written with the differences factored out so that no large terms cancel.
  const Vector& low = state_.low;
  const Vector& upp = state_.upp;
  double sum = 0.0;
  for (int j = 0; j < n_; ++j) {
    const double p = i == 0 ? p0_(j) : P_(i - 1, j);
    const double q = i == 0 ? q0_(j) : Q_(i - 1, j);
    const double step = trial(j) - x(j);
    sum += p * step / ((upp(j) - trial(j)) * (upp(j) - x(j))) -
           q * step / ((trial(j) - low(j)) * (x(j) - low(j)));
  }
  return sum;
}

double Mma::conservativeDistance(const Vector& x, const Vector& trial, ConstVectorRef xmin,
                                 ConstVectorRef xmax) const {
  const Vector& low = state_.low;
  const Vector& upp = state_.upp;
  double sum = 0.0;
  for (int j = 0; j < n_; ++j) {
    const double step = trial(j) - x(j);
    sum +=
        (upp(j) - low(j)) * step * step / ((upp(j) - trial(j)) * (trial(j) - low(j)) * (xmax(j) - xmin(j)));
  }
  return sum;
}

void Mma::finishConservativeIteration(const Vector& x) {
  state_.iteration += 1;
  state_.xold2 = state_.xold1;
  state_.xold1 = x;
}

double Mma::subproblemResidual(double epsilon, double* max_abs) {
  const MmaOptions& o = options_;
  const Vector& low = state_.low;
  const Vector& upp = state_.upp;
  Vector& y = sub_.y;
  Vector& lambda = sub_.lambda;
  Vector& xsi = sub_.xsi;
  Vector& eta = sub_.eta;
  const double z = sub_.z;

  plam_ = p0_;
  qlam_ = q0_;
  for (int i = 0; i < m_; ++i) {
    plam_ += lambda(i) * P_.row(i).transpose();
    qlam_ += lambda(i) * Q_.row(i).transpose();
  }
  double sum = 0.0;
  double largest = 0.0;
  auto add = [&sum, &largest](double r) {
    sum += r * r;
    largest = std::max(largest, std::abs(r));
  };
  for (int j = 0; j < n_; ++j) {
    const double uxinv = 1.0 / (upp(j) - xsub_(j));
    const double xlinv = 1.0 / (xsub_(j) - low(j));
    uxInv_(j) = uxinv;
    xlInv_(j) = xlinv;
    // d/dx_j of the Lagrangian of the subproblem, minus the bound multipliers.
    add(plam_(j) * uxinv * uxinv - qlam_(j) * xlinv * xlinv - xsi(j) + eta(j));
    add(xsi(j) * (xsub_(j) - alpha_(j)) - epsilon);
    add(eta(j) * (beta_(j) - xsub_(j)) - epsilon);
  }
  double lambdaDotA = 0.0;
  for (int i = 0; i < m_; ++i) {
    const double g = P_.row(i).dot(uxInv_) + Q_.row(i).dot(xlInv_);
    add(o.y_linear_cost + o.y_quadratic_cost * y(i) - mu_(i) - lambda(i));
    add(g - o.z_weight * z - y(i) + s_(i) - b_(i));
    add(mu_(i) * y(i) - epsilon);
    add(lambda(i) * s_(i) - epsilon);
    lambdaDotA += o.z_weight * lambda(i);
  }
  add(o.z_cost - zeta_ - lambdaDotA);
  add(zeta_ * z - epsilon);
  *max_abs = largest;
  return std::sqrt(sum);
}

void Mma::solveSubproblem() {
  const MmaOptions& o = options_;
  const Vector& low = state_.low;
  const Vector& upp = state_.upp;
  Vector& y = sub_.y;
  Vector& lambda = sub_.lambda;
  Vector& xsi = sub_.xsi;
  Vector& eta = sub_.eta;
  double& z = sub_.z;

  // Starting point of the note: the middle of the box, unit slacks and multipliers, and bound
  // multipliers large enough to make the complementarity residuals moderate.
  xsub_ = 0.5 * (alpha_ + beta_);
  y.setOnes();
  z = 1.0;
  lambda.setOnes();
  s_.setOnes();
  for (int j = 0; j < n_; ++j) {
    xsi(j) = std::max(1.0, 1.0 / (xsub_(j) - alpha_(j)));
    eta(j) = std::max(1.0, 1.0 / (beta_(j) - xsub_(j)));
  }
  mu_.setConstant(std::max(1.0, 0.5 * o.y_linear_cost));
  zeta_ = 1.0;

  sub_.converged = true;
  sub_.newton_iterations = 0;
  double epsilon = 1.0;
  double residualNorm = 0.0;
  double residualMax = 0.0;
  while (epsilon > o.subproblem_tolerance) {
    residualNorm = subproblemResidual(epsilon, &residualMax);
    int newtonSteps = 0;
    while (residualMax > 0.9 * epsilon && newtonSteps < o.subproblem_max_newton_iterations) {
      ++newtonSteps;
      ++sub_.newton_iterations;

      // Newton step on the relaxed KKT conditions. Eliminating the bound multipliers, the slacks and
      // y leaves, with diagX = (second derivative of the Lagrangian) + xsi / (x - alpha)
      // + eta / (beta - x) and G = dg/dx of the constraint approximations (m x n),
      //   diag(diagX) dx + G^T dlambda = -deltaX                                   for x, and
      //   [ G diag(diagX)^-1 G^T + diag(s / lambda + 1 / diagY)   a       ] [dlambda]   [rhs   ]
      //   [ a^T                                                   -zeta/z ] [dz     ] = [deltaZ]
      // with rhs = deltaLambda + deltaY / diagY - G diag(diagX)^-1 deltaX, where the deltas are the
      // relaxed residuals with the complementarity conditions substituted. m is small, so the dense
      // (m+1) x (m+1) system is cheap for any n.
      plam_ = p0_;
      qlam_ = q0_;
      for (int i = 0; i < m_; ++i) {
        plam_ += lambda(i) * P_.row(i).transpose();
        qlam_ += lambda(i) * Q_.row(i).transpose();
      }
      for (int j = 0; j < n_; ++j) {
        const double uxinv = 1.0 / (upp(j) - xsub_(j));
        const double xlinv = 1.0 / (xsub_(j) - low(j));
        const double toAlphaInv = 1.0 / (xsub_(j) - alpha_(j));
        const double toBetaInv = 1.0 / (beta_(j) - xsub_(j));
        toAlphaInv_(j) = toAlphaInv;
        toBetaInv_(j) = toBetaInv;
        uxInv_(j) = uxinv;
        xlInv_(j) = xlinv;
        const double dpsidx = plam_(j) * uxinv * uxinv - qlam_(j) * xlinv * xlinv;
        deltaX_(j) = dpsidx - epsilon * toAlphaInv + epsilon * toBetaInv;
        inverseDiagX_(j) =
            1.0 / (2.0 * (plam_(j) * uxinv * uxinv * uxinv + qlam_(j) * xlinv * xlinv * xlinv) +
                   xsi(j) * toAlphaInv + eta(j) * toBetaInv);
      }
      double lambdaDotA = 0.0;
      for (int i = 0; i < m_; ++i) {
        for (int j = 0; j < n_; ++j) {
          const double g = P_(i, j) * uxInv_(j) * uxInv_(j) - Q_(i, j) * xlInv_(j) * xlInv_(j);
          gradG_(i, j) = g;
          scaledGradG_(i, j) = g * inverseDiagX_(j);
        }
        gvec_(i) = P_.row(i).dot(uxInv_) + Q_.row(i).dot(xlInv_);
        deltaY_(i) = o.y_linear_cost + o.y_quadratic_cost * y(i) - lambda(i) - epsilon / y(i);
        deltaLambda_(i) = gvec_(i) - o.z_weight * z - y(i) - b_(i) + epsilon / lambda(i);
        diagY_(i) = o.y_quadratic_cost + mu_(i) / y(i);
        lambdaDotA += o.z_weight * lambda(i);
      }
      const double deltaZ = o.z_cost - lambdaDotA - epsilon / z;

      for (int i = 0; i < m_; ++i) {
        for (int k = 0; k <= i; ++k) {
          const double entry = gradG_.row(i).dot(scaledGradG_.row(k));
          reducedMatrix_(i, k) = entry;
          reducedMatrix_(k, i) = entry;
        }
        reducedMatrix_(i, i) += s_(i) / lambda(i) + 1.0 / diagY_(i);
        reducedMatrix_(i, m_) = o.z_weight;
        reducedMatrix_(m_, i) = o.z_weight;
        reducedRhs_(i) = deltaLambda_(i) + deltaY_(i) / diagY_(i) - scaledGradG_.row(i).dot(deltaX_);
      }
      reducedMatrix_(m_, m_) = -zeta_ / z;
      reducedRhs_(m_) = deltaZ;
      reducedLu_.compute(reducedMatrix_);
      reducedSolution_ = reducedLu_.solve(reducedRhs_);
      dlambda_ = reducedSolution_.head(m_);
      dz_ = reducedSolution_(m_);

      // Back substitution for the eliminated unknowns.
      for (int j = 0; j < n_; ++j) {
        double gTdlambda = 0.0;
        for (int i = 0; i < m_; ++i) gTdlambda += gradG_(i, j) * dlambda_(i);
        dx_(j) = -(deltaX_(j) + gTdlambda) * inverseDiagX_(j);
        dxsi_(j) = -xsi(j) + (epsilon - xsi(j) * dx_(j)) * toAlphaInv_(j);
        deta_(j) = -eta(j) + (epsilon + eta(j) * dx_(j)) * toBetaInv_(j);
      }
      for (int i = 0; i < m_; ++i) {
        dy_(i) = (dlambda_(i) - deltaY_(i)) / diagY_(i);
        dmu_(i) = -mu_(i) + (epsilon - mu_(i) * dy_(i)) / y(i);
        ds_(i) = -s_(i) + (epsilon - s_(i) * dlambda_(i)) / lambda(i);
      }
      dzeta_ = -zeta_ + (epsilon - zeta_ * dz_) / z;

      // Longest step (times 1/1.01) that keeps x inside (alpha, beta) and every multiplier and slack
      // positive; never longer than the full Newton step.
      double inverseStep = 1.0;
      for (int j = 0; j < n_; ++j) {
        inverseStep = std::max(inverseStep, -kFractionToBoundary * dx_(j) * toAlphaInv_(j));
        inverseStep = std::max(inverseStep, kFractionToBoundary * dx_(j) * toBetaInv_(j));
        inverseStep = std::max(inverseStep, -kFractionToBoundary * dxsi_(j) / xsi(j));
        inverseStep = std::max(inverseStep, -kFractionToBoundary * deta_(j) / eta(j));
      }
      for (int i = 0; i < m_; ++i) {
        inverseStep = std::max(inverseStep, -kFractionToBoundary * dy_(i) / y(i));
        inverseStep = std::max(inverseStep, -kFractionToBoundary * dlambda_(i) / lambda(i));
        inverseStep = std::max(inverseStep, -kFractionToBoundary * dmu_(i) / mu_(i));
        inverseStep = std::max(inverseStep, -kFractionToBoundary * ds_(i) / s_(i));
      }
      inverseStep = std::max(inverseStep, -kFractionToBoundary * dz_ / z);
      inverseStep = std::max(inverseStep, -kFractionToBoundary * dzeta_ / zeta_);
      double step = 1.0 / inverseStep;

      xOld_ = xsub_;
      yOld_ = y;
      zOld_ = z;
      lambdaOld_ = lambda;
      xsiOld_ = xsi;
      etaOld_ = eta;
      muOld_ = mu_;
      zetaOld_ = zeta_;
      sOld_ = s_;

      // Backtracking until the residual norm decreases.
      double trialNorm = 2.0 * residualNorm;
      double trialMax = residualMax;
      for (int halving = 0; halving < kMaxStepHalvings && trialNorm > residualNorm; ++halving) {
        xsub_ = xOld_ + step * dx_;
        y = yOld_ + step * dy_;
        z = zOld_ + step * dz_;
        lambda = lambdaOld_ + step * dlambda_;
        xsi = xsiOld_ + step * dxsi_;
        eta = etaOld_ + step * deta_;
        mu_ = muOld_ + step * dmu_;
        zeta_ = zetaOld_ + step * dzeta_;
        s_ = sOld_ + step * ds_;
        trialNorm = subproblemResidual(epsilon, &trialMax);
        step *= 0.5;
      }
      residualNorm = trialNorm;
      residualMax = trialMax;
    }
    if (residualMax > 0.9 * epsilon) sub_.converged = false;
    epsilon *= 0.1;
  }
  sub_.residual_norm = residualNorm;
}

}  // namespace hindsight
