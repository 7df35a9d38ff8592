#include <hindsight/problems/rod/design_gradient.h>

#include <hindsight/problems/rod/invariants.h>

#include <gtest/gtest.h>

#include "support/random_design.h"

#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <random>
#include <tuple>

namespace hindsight {
namespace rod {
namespace {

constexpr int kModes = 4;

RodConfig coarseConfig() {
  RodConfig config;
  config.elementsAlongLength = 20;
  config.elementsThroughHeight = 4;
  config.modeCount = kModes;
  return config;
}

// Seeded random design with values on both sides of the density-law threshold 0.1, at least 2e-3 away
// from it, so that central differences never straddle the kink.
Vector randomDesign(const RodConfig& config, unsigned seed) { return testing::randomRodDesign(config, seed); }

Vector packedInvariants(const RodConfig& config, const Vector& design) {
  const FeModel model(config, design);
  return computeInvariants(model, computeModalBasis(model, ModalReductionOptions::fromConfig(config))).pack();
}

// p(x) and p(x +- h_i e_i) for every design variable, h_i = cbrt(eps) max(1, |x_i|), computed once per
// design and shared by the functionals below (every test functional is a function of p alone).
struct PerturbedInvariants {
  Vector design, center;
  std::vector<Vector> plus, minus;
  std::vector<double> steps;
};

const PerturbedInvariants& perturbedInvariants(const Vector& design) {
  static std::map<std::vector<double>, PerturbedInvariants> cache;
  const std::vector<double> key(design.data(), design.data() + design.size());
  auto found = cache.find(key);
  if (found != cache.end()) return found->second;
  const RodConfig config = coarseConfig();
  PerturbedInvariants result;
  result.design = design;
  result.center = packedInvariants(config, design);
  const double root = std::cbrt(std::numeric_limits<double>::epsilon());
  for (Eigen::Index i = 0; i < design.size(); ++i) {
    Vector plus = design, minus = design;
    const double h = root * std::max(1.0, std::abs(design(i)));
    plus(i) += h;
    minus(i) -= h;
    result.plus.push_back(packedInvariants(config, plus));
    result.minus.push_back(packedInvariants(config, minus));
    result.steps.push_back(plus(i) - minus(i));
  }
  return cache.emplace(key, std::move(result)).first->second;
}

const InvariantLayout kLayout(kModes);
const int kBlockStarts[] = {
    0,           1,           3,         kLayout.c1,  kLayout.c2, kLayout.a0, kLayout.cTilde,
    kLayout.mee, kLayout.kee, kLayout.b, kLayout.size};
const char* const kBlockNames[] = {"m", "m c", "J0", "C1", "C2", "a0", "Ctilde", "Mee", "Kee", "b"};
constexpr int kBlockCount = 10;

// psi = w^T p + 1/2 sum_j s_j (w_j p_j)^2 (s = 0: linear). w_j = r_j / rms(block of p_j) so that every
// invariant block contributes comparably.
struct Functional {
  Vector w, s;
  double value(const Vector& p) const {
    return w.dot(p) + 0.5 * (s.array() * (w.array() * p.array()).square()).sum();
  }
  Vector gradient(const Vector& p) const { return w + Vector(s.array() * w.array().square() * p.array()); }
};

Functional makeFunctional(const Vector& p, unsigned seed, bool quadratic) {
  std::mt19937 generator(seed);
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> uniform(0.5, 1.5);
  Functional f;
  f.w.resize(p.size());
  f.s = Vector::Zero(p.size());
  for (int block = 0; block < kBlockCount; ++block) {
    const int begin = kBlockStarts[block], count = kBlockStarts[block + 1] - begin;
    const double rms = p.segment(begin, count).norm() / std::sqrt(static_cast<double>(count));
    for (int j = begin; j < begin + count; ++j) f.w(j) = normal(generator) / rms;
  }
  if (quadratic)
    for (auto& s : f.s) s = uniform(generator);
  return f;
}

struct ChainCheck {
  double normError, componentError;
  Vector analytic, finiteDifference;
};

// Finite-difference check of the whole chain x -> (K, M) -> Phi -> p -> psi for every design variable.
// The error of a component is taken relative to max(|fd_i|, ||fd||_inf): the finite-difference noise is
// absolute (psi is evaluated to ~1e-12 relative through the ill-conditioned eigenproblem, divided by
// 2h = 1.2e-5), so components 1e-4 below the largest carry relative noise ~1e-3 and cannot be checked on
// their own scale.
ChainCheck checkChain(const Vector& design, const Functional& functional,
                      EigenvectorSensitivityMethod method) {
  const RodConfig config = coarseConfig();
  const FeModel model(config, design);
  const ModalBasis basis = computeModalBasis(model, ModalReductionOptions::fromConfig(config));
  EXPECT_TRUE(basis.warning.empty()) << basis.warning;
  const PerturbedInvariants& perturbed = perturbedInvariants(design);
  DesignGradientOptions options;
  options.method = method;
  ChainCheck check;
  check.analytic =
      computeDesignGradient(model, basis, functional.gradient(perturbed.center), options).gradient;
  check.finiteDifference.resize(design.size());
  for (Eigen::Index i = 0; i < design.size(); ++i)
    check.finiteDifference(i) =
        (functional.value(perturbed.plus[i]) - functional.value(perturbed.minus[i])) / perturbed.steps[i];
  const Vector& fd = check.finiteDifference;
  check.normError = (fd - check.analytic).norm() / fd.norm();
  check.componentError = (fd - check.analytic).cwiseAbs().maxCoeff() / fd.cwiseAbs().maxCoeff();
  return check;
}

void expectChainMatches(const Vector& design, bool quadratic, unsigned seed, const char* label) {
  const Functional functional = makeFunctional(perturbedInvariants(design).center, seed, quadratic);
  for (auto method :
       {EigenvectorSensitivityMethod::AdjointNelson, EigenvectorSensitivityMethod::NelsonPerVariable}) {
    const ChainCheck check = checkChain(design, functional, method);
    std::printf(
        "[%s, %s] ||fd - an|| / ||fd|| = %.2e, max_i |fd_i - an_i| / ||fd||_inf = %.2e\n", label,
        method == EigenvectorSensitivityMethod::AdjointNelson ? "adjoint Nelson" : "Nelson per variable",
        check.normError, check.componentError);
    EXPECT_LT(check.normError, 3e-6) << label;
    EXPECT_LT(check.componentError, 3e-6) << label;
  }
}

TEST(DesignGradient, LinearFunctionalAtUniformDesign) {
  expectChainMatches(Vector::Constant(coarseConfig().designCount(), 0.5), false, 1, "linear, x0 = 0.5");
}

TEST(DesignGradient, LinearFunctionalAtRandomDesign) {
  expectChainMatches(randomDesign(coarseConfig(), 3), false, 2, "linear, random x");
}

TEST(DesignGradient, QuadraticFunctionalAtUniformDesign) {
  expectChainMatches(Vector::Constant(coarseConfig().designCount(), 0.5), true, 4, "quadratic, x0 = 0.5");
}

TEST(DesignGradient, QuadraticFunctionalAtRandomDesign) {
  expectChainMatches(randomDesign(coarseConfig(), 3), true, 6, "quadratic, random x");
}

// Each invariant block alone, so that a wrong term cannot hide behind a larger one. The error is taken
// relative to the gradient norm of the whole functional (the common noise scale). M_ee = Phi^T M Phi = I
// identically, so its exact derivative is zero and the chain must return (nearly) zero.
TEST(DesignGradient, EveryInvariantBlockSeparately) {
  const Vector design = randomDesign(coarseConfig(), 3);
  const Functional all = makeFunctional(perturbedInvariants(design).center, 9, false);
  const double scale =
      checkChain(design, all, EigenvectorSensitivityMethod::AdjointNelson).finiteDifference.norm();
  for (int block = 0; block < kBlockCount; ++block) {
    Functional one = all;
    for (Eigen::Index j = 0; j < one.w.size(); ++j)
      if (j < kBlockStarts[block] || j >= kBlockStarts[block + 1]) one.w(j) = 0.0;
    const ChainCheck check = checkChain(design, one, EigenvectorSensitivityMethod::AdjointNelson);
    const double error = (check.finiteDifference - check.analytic).norm();
    std::printf("  block %-6s ||an|| / scale = %.2e, ||fd - an|| / scale = %.2e\n", kBlockNames[block],
                check.analytic.norm() / scale, error / scale);
    EXPECT_LT(error, 3e-6 * scale) << kBlockNames[block];
    if (block != 7) EXPECT_LT(error, 1e-4 * check.finiteDifference.norm()) << kBlockNames[block];
  }
}

TEST(DesignGradient, AdjointNelsonAgreesWithNelsonPerVariable) {
  for (const auto& [nx, ny, modes] : {std::tuple<int, int, int>{20, 4, 4}, {50, 6, 8}}) {
    RodConfig config;
    config.elementsAlongLength = nx;
    config.elementsThroughHeight = ny;
    config.modeCount = modes;
    const Vector design = randomDesign(config, 12);
    const FeModel model(config, design);
    const ModalBasis basis = computeModalBasis(model, ModalReductionOptions::fromConfig(config));
    std::mt19937 generator(13);
    std::normal_distribution<double> normal;
    Vector weights(InertiaInvariants::packedSize(modes));
    for (auto& w : weights) w = normal(generator);
    DesignGradientExtras extras;
    extras.eigenvalueGradient = Vector::Constant(modes, 1e-4);
    DesignGradientOptions options;
    const DesignGradientResult adjoint = computeDesignGradient(model, basis, weights, options, extras);
    options.method = EigenvectorSensitivityMethod::NelsonPerVariable;
    const DesignGradientResult perVariable = computeDesignGradient(model, basis, weights, options, extras);
    EXPECT_LT((adjoint.gradient - perVariable.gradient).norm(), 1e-9 * perVariable.gradient.norm()) << nx;
    EXPECT_LT((adjoint.gradient - perVariable.gradient).cwiseAbs().maxCoeff(),
              1e-9 * perVariable.gradient.cwiseAbs().maxCoeff())
        << nx;
    // The adjoint route's deflated conjugate gradients converge here (gap > 1.2) without factorising
    // K - lambda M; each mode takes a few dozen iterations at most (the bound follows from the gap).
    EXPECT_EQ(adjoint.factorizations, 0);
    EXPECT_GT(adjoint.linearSolves, 2 * modes);
    EXPECT_LT(adjoint.linearSolves, 40 * modes);
    EXPECT_EQ(perVariable.linearSolves, modes * model.designCount());
    EXPECT_EQ(perVariable.factorizations, modes);
    // A mode that does not converge within the limit is solved with Nelson's factorised operator: with
    // the limit 0 every mode is, and the gradient is the same to the solves' round-off.
    DesignGradientOptions direct;
    direct.adjointIterationLimit = 0;
    const DesignGradientResult factorised = computeDesignGradient(model, basis, weights, direct, extras);
    EXPECT_EQ(factorised.factorizations, modes);
    EXPECT_EQ(factorised.linearSolves, modes);
    EXPECT_LT((factorised.gradient - adjoint.gradient).cwiseAbs().maxCoeff(),
              1e-9 * factorised.gradient.cwiseAbs().maxCoeff())
        << nx;
    direct.adjointIterationLimit = -1;
    EXPECT_THROW(computeDesignGradient(model, basis, weights, direct, extras), std::invalid_argument);
    // A mode whose eigenvalue lies above the first discarded one makes K - lambda M indefinite on the
    // complement of the kept modes: the iteration meets non-positive curvature or does not converge, and
    // the mode goes to the factorised operator (the others keep iterating).
    ModalBasis shifted = basis;
    shifted.eigenvalues(modes - 1) = 3.0 * basis.firstDiscardedEigenvalue;
    const DesignGradientResult fallback =
        computeDesignGradient(model, shifted, weights, DesignGradientOptions{}, extras);
    EXPECT_EQ(fallback.factorizations, 1) << nx;
    EXPECT_TRUE(fallback.gradient.allFinite()) << nx;
  }
}

// lambda' and phi' of Nelson's method against finite differences of the modal solver itself. Eigenvalues
// carry ~1e-11 relative round-off (K has entries ~1e6 times lambda_1 M), so this check uses
// Richardson-extrapolated central differences with h = 1e-4 (truncation O(h^4)) instead of the cbrt(eps)
// step; the noise left is ~1e-11 lambda / 1e-4 = 1e-7 lambda, hence the absolute term.
TEST(DesignGradient, EigenpairDerivativeMatchesFiniteDifferences) {
  const RodConfig config = coarseConfig();
  const Vector design = randomDesign(config, 21);
  const FeModel model(config, design);
  const ModalBasis basis = computeModalBasis(model, ModalReductionOptions::fromConfig(config));
  auto centralDifference = [&](int designIndex, double h) {
    Vector plus = design, minus = design;
    plus(designIndex) += h;
    minus(designIndex) -= h;
    const ModalBasis basisPlus =
        computeModalBasis(FeModel(config, plus), ModalReductionOptions::fromConfig(config));
    const ModalBasis basisMinus =
        computeModalBasis(FeModel(config, minus), ModalReductionOptions::fromConfig(config));
    return std::make_pair(Vector((basisPlus.eigenvalues - basisMinus.eigenvalues) / (2 * h)),
                          Matrix((basisPlus.modesFree - basisMinus.modesFree) / (2 * h)));
  };
  for (int designIndex : {0, 17, 40, model.designCount() - 1}) {
    const double h = 1e-4;
    const auto [valuesH, modesH] = centralDifference(designIndex, h);
    const auto [values2H, modes2H] = centralDifference(designIndex, 2 * h);
    const Vector fdValues = (4 * valuesH - values2H) / 3;
    const Matrix fdModes = (4 * modesH - modes2H) / 3;
    for (int mode = 0; mode < kModes; ++mode) {
      const EigenpairDerivative derivative = computeEigenpairDerivative(model, basis, mode, designIndex);
      EXPECT_NEAR(derivative.eigenvalue, fdValues(mode),
                  1e-6 * std::abs(fdValues(mode)) + 2e-7 * basis.eigenvalues(mode))
          << "mode " << mode << " design " << designIndex;
      EXPECT_LT((derivative.modeFree - fdModes.col(mode)).norm(),
                1e-6 * fdModes.col(mode).norm() + 2e-7 * basis.modesFree.col(mode).norm())
          << "mode " << mode << " design " << designIndex;
    }
  }
}

TEST(DesignGradient, ExtrasAreAddedAndBadInputThrows) {
  const RodConfig config = coarseConfig();
  const FeModel model(config, Vector::Constant(config.designCount(), 0.5));
  const ModalBasis basis = computeModalBasis(model, ModalReductionOptions::fromConfig(config));
  const Vector zero = Vector::Zero(InertiaInvariants::packedSize(kModes));
  DesignGradientExtras extras;
  extras.explicitDesignGradient = Vector::LinSpaced(model.designCount(), 1.0, 2.0);
  EXPECT_EQ(computeDesignGradient(model, basis, zero, {}, extras).gradient, extras.explicitDesignGradient);
  // dpsi/dlambda_0 = 1 alone gives lambda_0' for every element.
  extras = {};
  extras.eigenvalueGradient = Vector::Unit(kModes, 0);
  const Vector gradient = computeDesignGradient(model, basis, zero, {}, extras).gradient;
  EXPECT_NEAR(gradient(10), computeEigenpairDerivative(model, basis, 0, 10).eigenvalue,
              1e-12 * std::abs(gradient(10)));
  EXPECT_THROW(computeDesignGradient(model, basis, Vector::Zero(3)), std::invalid_argument);
  extras.eigenvalueGradient = Vector::Zero(kModes + 1);
  EXPECT_THROW(computeDesignGradient(model, basis, zero, {}, extras), std::invalid_argument);
  ModalReductionOptions relief = ModalReductionOptions::fromConfig(config);
  relief.inertiaReliefModes = true;
  const ModalBasis reliefBasis = computeModalBasis(model, relief);
  EXPECT_THROW(
      computeDesignGradient(model, reliefBasis, Vector::Zero(InertiaInvariants::packedSize(kModes + 3))),
      std::invalid_argument);
}

}  // namespace
}  // namespace rod
}  // namespace hindsight
