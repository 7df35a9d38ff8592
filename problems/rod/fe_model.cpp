#include <hindsight/problems/rod/fe_model.h>

#include <hindsight/engine/deterministic_math.h>

#include <cassert>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace hindsight {
namespace rod {

SimpLaw::SimpLaw(const RodConfig& config)
    : youngsModulus_(config.youngsModulus),
      density_(config.density),
      penalty_(config.stiffnessPenalty),
      factor_(config.massLawFactor),
      exponent_(config.massLawExponent),
      threshold_(config.massLawThreshold) {}

double SimpLaw::stiffness(double x) const { return dmath::pow(x, penalty_) * youngsModulus_; }

double SimpLaw::stiffnessDerivative(double x) const {
  return penalty_ * dmath::pow(x, penalty_ - 1.0) * youngsModulus_;
}

double SimpLaw::density(double x) const {
  return x < threshold_ ? factor_ * dmath::pow(x, exponent_) * density_ : x * density_;
}

double SimpLaw::densityDerivative(double x) const {
  return x < threshold_ ? factor_ * exponent_ * dmath::pow(x, exponent_ - 1.0) * density_ : density_;
}

namespace {

// Local node corners in natural coordinates, counter-clockwise from (-1, -1).
constexpr double kCornerXi[4] = {-1.0, 1.0, 1.0, -1.0};
constexpr double kCornerEta[4] = {-1.0, -1.0, 1.0, 1.0};

}  // namespace

ElementMatrix planeStressQuadUnitStiffness(double width, double height, double poissonRatio,
                                           double thickness) {
  const double nu = poissonRatio;
  Eigen::Matrix3d elasticity;
  elasticity << 1.0, nu, 0.0, nu, 1.0, 0.0, 0.0, 0.0, 0.5 * (1.0 - nu);
  elasticity /= (1.0 - nu * nu);
  const double gauss = 1.0 / std::sqrt(3.0);
  const double jacobianDeterminant = 0.25 * width * height;
  ElementMatrix stiffness = ElementMatrix::Zero();
  for (double xi : {-gauss, gauss}) {
    for (double eta : {-gauss, gauss}) {
      Eigen::Matrix<double, 3, 8> strain = Eigen::Matrix<double, 3, 8>::Zero();
      for (int a = 0; a < 4; ++a) {
        const double dNdx = 0.25 * kCornerXi[a] * (1.0 + eta * kCornerEta[a]) * 2.0 / width;
        const double dNdy = 0.25 * kCornerEta[a] * (1.0 + xi * kCornerXi[a]) * 2.0 / height;
        strain(0, 2 * a) = dNdx;
        strain(1, 2 * a + 1) = dNdy;
        strain(2, 2 * a) = dNdy;
        strain(2, 2 * a + 1) = dNdx;
      }
      stiffness += strain.transpose() * elasticity * strain * (jacobianDeterminant * thickness);
    }
  }
  return 0.5 * (stiffness + stiffness.transpose());
}

ElementMatrix quadUnitConsistentMass(double width, double height, double thickness) {
  const double gauss = 1.0 / std::sqrt(3.0);
  const double jacobianDeterminant = 0.25 * width * height;
  ElementMatrix mass = ElementMatrix::Zero();
  for (double xi : {-gauss, gauss}) {
    for (double eta : {-gauss, gauss}) {
      Eigen::Matrix<double, 2, 8> shape = Eigen::Matrix<double, 2, 8>::Zero();
      for (int a = 0; a < 4; ++a) {
        const double value = 0.25 * (1.0 + xi * kCornerXi[a]) * (1.0 + eta * kCornerEta[a]);
        shape(0, 2 * a) = value;
        shape(1, 2 * a + 1) = value;
      }
      mass += shape.transpose() * shape * (jacobianDeterminant * thickness);
    }
  }
  return 0.5 * (mass + mass.transpose());
}

Vector rotateNodewise(ConstVectorRef full) {
  assert(full.size() % 2 == 0);
  Vector result(full.size());
  for (Eigen::Index node = 0; node < full.size() / 2; ++node) {
    result(2 * node) = -full(2 * node + 1);
    result(2 * node + 1) = full(2 * node);
  }
  return result;
}

Vector rotateNodewiseTransposed(ConstVectorRef full) {
  assert(full.size() % 2 == 0);
  Vector result(full.size());
  for (Eigen::Index node = 0; node < full.size() / 2; ++node) {
    result(2 * node) = full(2 * node + 1);
    result(2 * node + 1) = -full(2 * node);
  }
  return result;
}

Matrix rotateNodewiseColumns(ConstMatrixRef full) {
  Matrix result(full.rows(), full.cols());
  for (Eigen::Index c = 0; c < full.cols(); ++c) result.col(c) = rotateNodewise(Vector(full.col(c)));
  return result;
}

Matrix rotateNodewiseTransposedColumns(ConstMatrixRef full) {
  Matrix result(full.rows(), full.cols());
  for (Eigen::Index c = 0; c < full.cols(); ++c)
    result.col(c) = rotateNodewiseTransposed(Vector(full.col(c)));
  return result;
}

FeModel::FeModel(const RodConfig& config, ConstVectorRef design) : config_(config), simp_(config) {
  config_.validate();
  const int nx = config_.elementsAlongLength;
  const int ny = config_.elementsThroughHeight;
  if (design.size() != config_.designCount()) {
    std::ostringstream message;
    message << "FeModel: design has " << design.size()
            << " entries, expected designCount() = " << config_.designCount() << " ((nx - 2) * ny)";
    throw std::invalid_argument(message.str());
  }
  for (Eigen::Index d = 0; d < design.size(); ++d) {
    const double x = design(d);
    if (!std::isfinite(x) || x < config_.designLowerBound || x > 1.0) {
      std::ostringstream message;
      message.precision(17);
      message << "FeModel: design[" << d << "] = " << x << " is outside the allowed range ["
              << config_.designLowerBound << ", 1]";
      throw std::invalid_argument(message.str());
    }
  }
  design_ = design;
  nodeCount_ = (nx + 1) * (ny + 1);
  elementCount_ = nx * ny;

  elementToDesign_.assign(elementCount_, -1);
  designToElement_.resize(design_.size());
  for (int i = 1; i < nx - 1; ++i) {
    for (int j = 0; j < ny; ++j) {
      const int d = (i - 1) * ny + j;
      const int e = i * ny + j;
      designToElement_[d] = e;
      elementToDesign_[e] = d;
    }
  }

  const double width = config_.length / nx;
  const double height = config_.height / ny;
  unitStiffness_ = planeStressQuadUnitStiffness(width, height, config_.poissonRatio, config_.thickness);
  unitMass_ = quadUnitConsistentMass(width, height, config_.thickness);

  const int dofs = dofCount();
  referenceCoordinates_.resize(dofs);
  unitTranslationX_ = Vector::Zero(dofs);
  unitTranslationY_ = Vector::Zero(dofs);
  for (int i = 0; i <= nx; ++i) {
    for (int j = 0; j <= ny; ++j) {
      const int node = nodeIndex(i, j);
      referenceCoordinates_(2 * node) = i * width;
      referenceCoordinates_(2 * node + 1) = -0.5 * config_.height + j * height;
      unitTranslationX_(2 * node) = 1.0;
      unitTranslationY_(2 * node + 1) = 1.0;
    }
  }

  const int pinX = 2 * jointANode(), pinY = 2 * jointANode() + 1, rollerY = 2 * jointBNode() + 1;
  fullToFree_.assign(dofs, -1);
  freeToFull_.clear();
  for (int d = 0; d < dofs; ++d) {
    if (d == pinX || d == pinY || d == rollerY) continue;
    fullToFree_[d] = static_cast<int>(freeToFull_.size());
    freeToFull_.push_back(d);
  }
  assemble();
}

std::array<int, 8> FeModel::elementDofs(int element) const {
  const int ny = config_.elementsThroughHeight;
  const int i = element / ny, j = element % ny;
  const int nodes[4] = {nodeIndex(i, j), nodeIndex(i + 1, j), nodeIndex(i + 1, j + 1), nodeIndex(i, j + 1)};
  std::array<int, 8> dofs{};
  for (int a = 0; a < 4; ++a) {
    dofs[2 * a] = 2 * nodes[a];
    dofs[2 * a + 1] = 2 * nodes[a] + 1;
  }
  return dofs;
}

double FeModel::elementDesignValue(int element) const {
  const int d = elementToDesign_[element];
  return d < 0 ? 1.0 : design_(d);
}

int FeModel::jointANode() const { return nodeIndex(0, config_.elementsThroughHeight / 2); }
int FeModel::jointBNode() const {
  return nodeIndex(config_.elementsAlongLength, config_.elementsThroughHeight / 2);
}

void FeModel::assemble() {
  using Triplet = Eigen::Triplet<double>;
  std::vector<Triplet> stiffnessFull, massFull, stiffnessFree, massFree;
  stiffnessFull.reserve(64 * elementCount_);
  massFull.reserve(64 * elementCount_);
  stiffnessFree.reserve(64 * elementCount_);
  massFree.reserve(64 * elementCount_);
  for (int e = 0; e < elementCount_; ++e) {
    const double x = elementDesignValue(e);
    const double elementStiffness = simp_.stiffness(x);
    const double elementDensity = simp_.density(x);
    const std::array<int, 8> dofs = elementDofs(e);
    for (int a = 0; a < 8; ++a) {
      for (int b = 0; b < 8; ++b) {
        const double k = elementStiffness * unitStiffness_(a, b);
        const double m = elementDensity * unitMass_(a, b);
        stiffnessFull.emplace_back(dofs[a], dofs[b], k);
        massFull.emplace_back(dofs[a], dofs[b], m);
        const int fa = fullToFree_[dofs[a]], fb = fullToFree_[dofs[b]];
        if (fa >= 0 && fb >= 0) {
          stiffnessFree.emplace_back(fa, fb, k);
          massFree.emplace_back(fa, fb, m);
        }
      }
    }
  }
  const int dofs = dofCount(), free = freeDofCount();
  stiffnessFull_.resize(dofs, dofs);
  stiffnessFull_.setFromTriplets(stiffnessFull.begin(), stiffnessFull.end());
  massFull_.resize(dofs, dofs);
  massFull_.setFromTriplets(massFull.begin(), massFull.end());
  stiffness_.resize(free, free);
  stiffness_.setFromTriplets(stiffnessFree.begin(), stiffnessFree.end());
  mass_.resize(free, free);
  mass_.setFromTriplets(massFree.begin(), massFree.end());
}

Vector FeModel::restrictToFree(ConstVectorRef full) const {
  assert(full.size() == dofCount());
  Vector result(freeDofCount());
  for (int k = 0; k < freeDofCount(); ++k) result(k) = full(freeToFull_[k]);
  return result;
}

Matrix FeModel::restrictColumnsToFree(ConstMatrixRef full) const {
  assert(full.rows() == dofCount());
  Matrix result(freeDofCount(), full.cols());
  for (int k = 0; k < freeDofCount(); ++k) result.row(k) = full.row(freeToFull_[k]);
  return result;
}

Vector FeModel::extendToFull(ConstVectorRef free) const {
  assert(free.size() == freeDofCount());
  Vector result = Vector::Zero(dofCount());
  for (int k = 0; k < freeDofCount(); ++k) result(freeToFull_[k]) = free(k);
  return result;
}

Matrix FeModel::extendColumnsToFull(ConstMatrixRef free) const {
  assert(free.rows() == freeDofCount());
  Matrix result = Matrix::Zero(dofCount(), free.cols());
  for (int k = 0; k < freeDofCount(); ++k) result.row(freeToFull_[k]) = free.row(k);
  return result;
}

double FeModel::volumeFraction() const {
  const int solidElements = elementCount_ - designCount();
  return (solidElements + design_.sum()) / elementCount_;
}

Vector FeModel::volumeFractionGradient() const {
  return Vector::Constant(designCount(), 1.0 / elementCount_);
}

}  // namespace rod
}  // namespace hindsight
