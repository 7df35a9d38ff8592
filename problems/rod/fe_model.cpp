#include <hindsight/problems/rod/fe_model.h>

#include <hindsight/engine/deterministic_math.h>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

namespace hindsight {
namespace rod {

void requireDesignInRange(const char* who, ConstVectorRef design, double designLowerBound) {
  for (Eigen::Index d = 0; d < design.size(); ++d) {
    const double x = design(d);
    if (!std::isfinite(x) || x < designLowerBound || x > 1.0) {
      std::ostringstream message;
      message.precision(17);
      message << who << ": design[" << d << "] = " << x << " is outside the allowed range ["
              << designLowerBound << ", 1]";
      throw std::invalid_argument(message.str());
    }
  }
}

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

Vector rotateNodewise(ConstVectorRef full, int components) {
  assert(components == 2 || components == 3);
  assert(full.size() % components == 0);
  Vector result(full.size());
  for (Eigen::Index node = 0; node < full.size() / components; ++node) {
    result(components * node) = -full(components * node + 1);
    result(components * node + 1) = full(components * node);
    if (components == 3) result(3 * node + 2) = 0.0;
  }
  return result;
}

Vector rotateNodewiseTransposed(ConstVectorRef full, int components) {
  assert(components == 2 || components == 3);
  assert(full.size() % components == 0);
  Vector result(full.size());
  for (Eigen::Index node = 0; node < full.size() / components; ++node) {
    result(components * node) = full(components * node + 1);
    result(components * node + 1) = -full(components * node);
    if (components == 3) result(3 * node + 2) = 0.0;
  }
  return result;
}

Matrix rotateNodewiseColumns(ConstMatrixRef full, int components) {
  Matrix result(full.rows(), full.cols());
  for (Eigen::Index c = 0; c < full.cols(); ++c)
    result.col(c) = rotateNodewise(Vector(full.col(c)), components);
  return result;
}

Matrix rotateNodewiseTransposedColumns(ConstMatrixRef full, int components) {
  Matrix result(full.rows(), full.cols());
  for (Eigen::Index c = 0; c < full.cols(); ++c)
    result.col(c) = rotateNodewiseTransposed(Vector(full.col(c)), components);
  return result;
}

double DesignedMesh::elementDesignValue(int element) const {
  const int d = elementToDesign(element);
  return d < 0 ? 1.0 : design_(d);
}

void DesignedMesh::placeDesign(ConstVectorRef design, int layers) {
  const int nx = config_.elementsAlongLength, ny = config_.elementsThroughHeight;
  design_ = design;
  elementCount_ = nx * ny * layers;
  elementToDesign_.assign(static_cast<std::size_t>(elementCount_), -1);
  designToElement_.resize(static_cast<std::size_t>(design_.size()));
  for (int i = 1; i < nx - 1; ++i) {
    for (int j = 0; j < ny; ++j) {
      for (int k = 0; k < layers; ++k) {
        const int d = ((i - 1) * ny + j) * layers + k;
        const int e = (i * ny + j) * layers + k;
        designToElement_[static_cast<std::size_t>(d)] = e;
        elementToDesign_[static_cast<std::size_t>(e)] = d;
      }
    }
  }
}

double DesignedMesh::volumeFraction() const {
  const int solidElements = elementCount_ - designCount();
  return (solidElements + design_.sum()) / elementCount_;
}

Vector DesignedMesh::volumeFractionGradient() const {
  return Vector::Constant(designCount(), 1.0 / elementCount_);
}

FeModel::FeModel(const RodConfig& config, ConstVectorRef design) : DesignedMesh(config) {
  config_.validate();
  if (config_.isSolid())
    throw std::invalid_argument(
        "FeModel: RodConfig.elementsThroughThickness = " + std::to_string(config_.elementsThroughThickness) +
        " is outside the allowed range {0} (the plate; the solid is SolidMember)");
  const int nx = config_.elementsAlongLength;
  const int ny = config_.elementsThroughHeight;
  if (design.size() != config_.designCount()) {
    std::ostringstream message;
    message << "FeModel: design has " << design.size()
            << " entries, expected designCount() = " << config_.designCount() << " ((nx - 2) * ny)";
    throw std::invalid_argument(message.str());
  }
  requireDesignInRange("FeModel", design, config_.designLowerBound);
  placeDesign(design, 1);
  nodeCount_ = (nx + 1) * (ny + 1);

  const double width = config_.length / nx;
  const double height = config_.height / ny;
  unitStiffness_ = planeStressQuadUnitStiffness(width, height, config_.poissonRatio, config_.thickness);
  unitMass_ = quadUnitConsistentMass(width, height, config_.thickness);

  const int dofs = 2 * nodeCount_;
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
  static_cast<SupportedDofs&>(*this) = SupportedDofs(dofs, {pinX, pinY, rollerY});
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

int FeModel::jointANode() const { return nodeIndex(0, config_.elementsThroughHeight / 2); }
int FeModel::jointBNode() const {
  return nodeIndex(config_.elementsAlongLength, config_.elementsThroughHeight / 2);
}

namespace {

// The node-to-node coupling of the structured mesh as a compressed-column pattern over `dofs` DOFs: DOF
// c = 2 node + component couples with both DOFs of every node that shares an element with its node, the
// nodes (i + di, j + dj), |di|, |dj| <= 1; rows ascend within each column, as Eigen's setFromTriplets
// leaves them. `keep` maps a full DOF to its index in the pattern (-1: dropped, the constrained DOFs).
void couplingPattern(int nx, int ny, const std::vector<int>& keep, int size, std::vector<int>& outer,
                     std::vector<int>& inner) {
  outer.assign(static_cast<std::size_t>(size) + 1, 0);
  inner.clear();
  auto node = [ny](int i, int j) { return i * (ny + 1) + j; };
  for (int i = 0; i <= nx; ++i) {
    for (int j = 0; j <= ny; ++j) {
      for (int component = 0; component < 2; ++component) {
        const int column = keep[static_cast<std::size_t>(2 * node(i, j) + component)];
        if (column < 0) continue;
        for (int di = -1; di <= 1; ++di) {
          if (i + di < 0 || i + di > nx) continue;
          for (int dj = -1; dj <= 1; ++dj) {
            if (j + dj < 0 || j + dj > ny) continue;
            for (int rowComponent = 0; rowComponent < 2; ++rowComponent) {
              const int row = keep[static_cast<std::size_t>(2 * node(i + di, j + dj) + rowComponent)];
              if (row >= 0) inner.push_back(row);
            }
          }
        }
        outer[static_cast<std::size_t>(column) + 1] = static_cast<int>(inner.size());
      }
    }
  }
}

/// Makes `matrix` square with the given pattern and zero values, in place: assigning a returned
/// SparseMatrix would copy it (Eigen 3.4's SparseMatrix has no move assignment).
void setPattern(SparseMatrix& matrix, int size, const std::vector<int>& outer,
                const std::vector<int>& inner) {
  matrix.resize(size, size);
  matrix.resizeNonZeros(static_cast<Eigen::Index>(inner.size()));
  std::copy(outer.begin(), outer.end(), matrix.outerIndexPtr());
  std::copy(inner.begin(), inner.end(), matrix.innerIndexPtr());
  std::fill(matrix.valuePtr(), matrix.valuePtr() + inner.size(), 0.0);
}

/// Position of `row` in column `column` of the pattern (present by construction: at most 18 rows).
int slotOf(const std::vector<int>& outer, const std::vector<int>& inner, int row, int column) {
  const auto begin = inner.begin() + outer[static_cast<std::size_t>(column)];
  const auto end = inner.begin() + outer[static_cast<std::size_t>(column) + 1];
  const auto it = std::lower_bound(begin, end, row);
  assert(it != end && *it == row);
  return static_cast<int>(it - inner.begin());
}

}  // namespace

// Element by element into the mesh's pattern. Each entry takes its first element's contribution and
// adds the later ones in element order: bit for bit what setFromTriplets made of the element-ordered
// triplets this replaced (collapseDuplicates stores the first and adds the rest in insertion order),
// without their four lists of 64 triplets per element and the sort (10 MB at 200 x 12, 630 MB at
// 1600 x 96).
void FeModel::assemble() {
  const int nx = config_.elementsAlongLength, ny = config_.elementsThroughHeight;
  const int dofs = dofCount(), free = freeDofCount();
  std::vector<int> all(static_cast<std::size_t>(dofs));
  for (int d = 0; d < dofs; ++d) all[static_cast<std::size_t>(d)] = d;
  std::vector<int> fullOuter, fullInner, freeOuter, freeInner;
  couplingPattern(nx, ny, all, dofs, fullOuter, fullInner);
  couplingPattern(nx, ny, fullToFree(), free, freeOuter, freeInner);
  setPattern(stiffnessFull_, dofs, fullOuter, fullInner);
  setPattern(massFull_, dofs, fullOuter, fullInner);
  setPattern(stiffness_, free, freeOuter, freeInner);
  setPattern(mass_, free, freeOuter, freeInner);
  std::vector<char> fullSeen(fullInner.size(), 0), freeSeen(freeInner.size(), 0);
  auto add = [](SparseMatrix& stiffness, SparseMatrix& mass, std::vector<char>& seen, int slot, double k,
                double m) {
    if (seen[static_cast<std::size_t>(slot)]) {
      stiffness.valuePtr()[slot] += k;
      mass.valuePtr()[slot] += m;
    } else {
      stiffness.valuePtr()[slot] = k;
      mass.valuePtr()[slot] = m;
      seen[static_cast<std::size_t>(slot)] = 1;
    }
  };
  for (int e = 0; e < elementCount_; ++e) {
    const double x = elementDesignValue(e);
    const double elementStiffness = simp_.stiffness(x);
    const double elementDensity = simp_.density(x);
    const std::array<int, 8> elementDofs = this->elementDofs(e);
    for (int a = 0; a < 8; ++a) {
      for (int b = 0; b < 8; ++b) {
        const double k = elementStiffness * unitStiffness_(a, b);
        const double m = elementDensity * unitMass_(a, b);
        add(stiffnessFull_, massFull_, fullSeen, slotOf(fullOuter, fullInner, elementDofs[a], elementDofs[b]),
            k, m);
        const int fa = fullToFree()[elementDofs[a]], fb = fullToFree()[elementDofs[b]];
        if (fa >= 0 && fb >= 0) {
          add(stiffness_, mass_, freeSeen, slotOf(freeOuter, freeInner, fa, fb), k, m);
        }
      }
    }
  }
}

SupportedDofs::SupportedDofs(int dofCount, const std::vector<int>& constrained) {
  fullToFree_.assign(static_cast<std::size_t>(dofCount), 0);
  for (int d : constrained) {
    if (d < 0 || d >= dofCount)
      throw std::invalid_argument("SupportedDofs: constrained DOF " + std::to_string(d) +
                                  " is outside the allowed range [0, " + std::to_string(dofCount - 1) + "]");
    fullToFree_[static_cast<std::size_t>(d)] = -1;
  }
  for (int d = 0; d < dofCount; ++d) {
    if (fullToFree_[static_cast<std::size_t>(d)] < 0) continue;
    fullToFree_[static_cast<std::size_t>(d)] = static_cast<int>(freeToFull_.size());
    freeToFull_.push_back(d);
  }
}

Vector SupportedDofs::restrictToFree(ConstVectorRef full) const {
  assert(full.size() == dofCount());
  Vector result(freeDofCount());
  for (int k = 0; k < freeDofCount(); ++k) result(k) = full(freeToFull_[k]);
  return result;
}

Matrix SupportedDofs::restrictColumnsToFree(ConstMatrixRef full) const {
  assert(full.rows() == dofCount());
  Matrix result(freeDofCount(), full.cols());
  for (int k = 0; k < freeDofCount(); ++k) result.row(k) = full.row(freeToFull_[k]);
  return result;
}

Vector SupportedDofs::extendToFull(ConstVectorRef free) const {
  assert(free.size() == freeDofCount());
  Vector result = Vector::Zero(dofCount());
  for (int k = 0; k < freeDofCount(); ++k) result(freeToFull_[k]) = free(k);
  return result;
}

Matrix SupportedDofs::extendColumnsToFull(ConstMatrixRef free) const {
  assert(free.rows() == freeDofCount());
  Matrix result = Matrix::Zero(dofCount(), free.cols());
  for (int k = 0; k < freeDofCount(); ++k) result.row(freeToFull_[k]) = free.row(k);
  return result;
}

}  // namespace rod
}  // namespace hindsight
