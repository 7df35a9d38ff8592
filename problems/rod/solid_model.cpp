#include <hindsight/problems/rod/solid_model.h>

#include <Spectra/MatOp/SparseSymMatProd.h>
#include <Spectra/SymGEigsShiftSolver.h>
#include <Eigen/Cholesky>
#include <Eigen/SparseCholesky>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace hindsight {
namespace rod {

void SolidMeshOptions::validate() const {
  if (elementsThroughThickness < 1) {
    throw std::invalid_argument("SolidMeshOptions: elementsThroughThickness = " +
                                std::to_string(elementsThroughThickness) + " must be >= 1");
  }
  if (formulation != HexFormulation::trilinear && formulation != HexFormulation::incompatibleModes) {
    throw std::invalid_argument("SolidMeshOptions: formulation must be trilinear or incompatibleModes");
  }
}

namespace {

// Local node corners in natural coordinates: the plate's counter-clockwise square at zeta = -1, then at +1.
constexpr double kCornerXi[8] = {-1.0, 1.0, 1.0, -1.0, -1.0, 1.0, 1.0, -1.0};
constexpr double kCornerEta[8] = {-1.0, -1.0, 1.0, 1.0, -1.0, -1.0, 1.0, 1.0};
constexpr double kCornerZeta[8] = {-1.0, -1.0, -1.0, -1.0, 1.0, 1.0, 1.0, 1.0};

void checkWidths(const char* function, double widthX, double widthY, double widthZ) {
  const double widths[3] = {widthX, widthY, widthZ};
  const char* names[3] = {"widthX", "widthY", "widthZ"};
  for (int a = 0; a < 3; ++a) {
    if (!(widths[a] > 0.0 && std::isfinite(widths[a]))) {
      std::ostringstream message;
      message << function << ": " << names[a] << " = " << widths[a] << " must be finite and > 0 [m]";
      throw std::invalid_argument(message.str());
    }
  }
}

// Isotropic elasticity for E = 1, engineering strains ordered (xx, yy, zz, xy, yz, zx).
Eigen::Matrix<double, 6, 6> isotropicElasticity(double nu) {
  const double lambda = nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
  const double mu = 0.5 / (1.0 + nu);
  Eigen::Matrix<double, 6, 6> d = Eigen::Matrix<double, 6, 6>::Zero();
  for (int a = 0; a < 3; ++a) {
    for (int b = 0; b < 3; ++b) d(a, b) = lambda;
    d(a, a) = lambda + 2.0 * mu;
    d(3 + a, 3 + a) = mu;
  }
  return d;
}

// Strain-displacement columns of a scalar field with Cartesian gradient g, for the 3 components.
void strainColumns(const Eigen::Vector3d& g, Eigen::Matrix<double, 6, 33>& strain, int firstColumn) {
  for (int c = 0; c < 3; ++c) strain.col(firstColumn + c).setZero();
  strain(0, firstColumn) = g(0);
  strain(1, firstColumn + 1) = g(1);
  strain(2, firstColumn + 2) = g(2);
  strain(3, firstColumn) = g(1);
  strain(3, firstColumn + 1) = g(0);
  strain(4, firstColumn + 1) = g(2);
  strain(4, firstColumn + 2) = g(1);
  strain(5, firstColumn) = g(2);
  strain(5, firstColumn + 2) = g(0);
}

}  // namespace

HexElementMatrix hexUnitStiffness(double widthX, double widthY, double widthZ, double poissonRatio,
                                  HexFormulation formulation) {
  checkWidths("hexUnitStiffness", widthX, widthY, widthZ);
  if (!(poissonRatio > -1.0 && poissonRatio < 0.5)) {
    std::ostringstream message;
    message << "hexUnitStiffness: poissonRatio = " << poissonRatio << " must lie in (-1, 0.5)";
    throw std::invalid_argument(message.str());
  }
  const Eigen::Matrix<double, 6, 6> elasticity = isotropicElasticity(poissonRatio);
  // A box: x = X0 + xi a/2, so d/dx = (2/a) d/dxi, and the Jacobian determinant is a b c / 8 everywhere.
  const Eigen::Vector3d scale(2.0 / widthX, 2.0 / widthY, 2.0 / widthZ);
  const double jacobianDeterminant = widthX * widthY * widthZ / 8.0;
  const double gauss = 1.0 / std::sqrt(3.0);
  // The 24 nodal columns, then the 9 incompatible ones: the bubble shapes 1 - xi^2, 1 - eta^2, 1 - zeta^2
  // (Wilson et al. 1973) for each displacement component.
  Eigen::Matrix<double, 33, 33> full = Eigen::Matrix<double, 33, 33>::Zero();
  Eigen::Matrix<double, 6, 33> strain = Eigen::Matrix<double, 6, 33>::Zero();
  for (double xi : {-gauss, gauss}) {
    for (double eta : {-gauss, gauss}) {
      for (double zeta : {-gauss, gauss}) {
        for (int a = 0; a < 8; ++a) {
          const double sx = 1.0 + xi * kCornerXi[a], sy = 1.0 + eta * kCornerEta[a],
                       sz = 1.0 + zeta * kCornerZeta[a];
          const Eigen::Vector3d g(0.125 * kCornerXi[a] * sy * sz * scale(0),
                                  0.125 * kCornerEta[a] * sx * sz * scale(1),
                                  0.125 * kCornerZeta[a] * sx * sy * scale(2));
          strainColumns(g, strain, 3 * a);
        }
        const double natural[3] = {xi, eta, zeta};
        for (int m = 0; m < 3; ++m) {
          Eigen::Vector3d g = Eigen::Vector3d::Zero();
          g(m) = -2.0 * natural[m] * scale(m);  // d(1 - s^2)/ds, constant Jacobian (Taylor et al. 1976)
          strainColumns(g, strain, 24 + 3 * m);
        }
        full += strain.transpose() * elasticity * strain * jacobianDeterminant;
      }
    }
  }
  HexElementMatrix stiffness = full.topLeftCorner<24, 24>();
  if (formulation == HexFormulation::incompatibleModes) {
    // Static condensation of the internal modes: K = Kcc - Kci Kii^-1 Kic (Kii is positive definite: the
    // bubbles' strains are linearly independent of each other).
    const Eigen::Matrix<double, 9, 9> internal = full.bottomRightCorner<9, 9>();
    const Eigen::Matrix<double, 9, 24> coupling = full.bottomLeftCorner<9, 24>();
    const Eigen::LLT<Eigen::Matrix<double, 9, 9>> factor(internal);
    assert(factor.info() == Eigen::Success);
    stiffness -= coupling.transpose() * factor.solve(coupling);
  }
  return 0.5 * (stiffness + stiffness.transpose());
}

HexElementMatrix hexUnitConsistentMass(double widthX, double widthY, double widthZ) {
  checkWidths("hexUnitConsistentMass", widthX, widthY, widthZ);
  const double jacobianDeterminant = widthX * widthY * widthZ / 8.0;
  const double gauss = 1.0 / std::sqrt(3.0);
  HexElementMatrix mass = HexElementMatrix::Zero();
  for (double xi : {-gauss, gauss}) {
    for (double eta : {-gauss, gauss}) {
      for (double zeta : {-gauss, gauss}) {
        Eigen::Matrix<double, 8, 1> shape;
        for (int a = 0; a < 8; ++a) {
          shape(a) =
              0.125 * (1.0 + xi * kCornerXi[a]) * (1.0 + eta * kCornerEta[a]) * (1.0 + zeta * kCornerZeta[a]);
        }
        const Eigen::Matrix<double, 8, 8> scalar = shape * shape.transpose() * jacobianDeterminant;
        for (int a = 0; a < 8; ++a) {
          for (int b = 0; b < 8; ++b) {
            for (int c = 0; c < 3; ++c) mass(3 * a + c, 3 * b + c) += scalar(a, b);
          }
        }
      }
    }
  }
  return 0.5 * (mass + mass.transpose());
}

int SolidModel::designCountOf(const RodConfig& config, const SolidMeshOptions& options) {
  return (config.elementsAlongLength - 2) * config.elementsThroughHeight * options.elementsThroughThickness;
}

SolidModel::SolidModel(const RodConfig& config, const SolidMeshOptions& options, ConstVectorRef design)
    : DesignedMesh(config), options_(options) {
  config_.validate();
  options_.validate();
  const int nx = config_.elementsAlongLength, ny = config_.elementsThroughHeight;
  const int nz = options_.elementsThroughThickness;
  const int expected = designCountOf(config_, options_);
  if (design.size() != expected) {
    std::ostringstream message;
    message << "SolidModel: design has " << design.size()
            << " entries, expected (nx - 2) * ny * nz = " << expected;
    throw std::invalid_argument(message.str());
  }
  requireDesignInRange("SolidModel", design, config_.designLowerBound);
  placeDesign(design, nz);
  nodeCount_ = (nx + 1) * (ny + 1) * (nz + 1);

  const double wx = elementWidthX(), wy = elementWidthY(), wz = elementWidthZ();
  unitStiffness_ = hexUnitStiffness(wx, wy, wz, config_.poissonRatio, options_.formulation);
  unitMass_ = hexUnitConsistentMass(wx, wy, wz);

  const double zStart = options_.midPlaneSymmetry ? 0.0 : -0.5 * config_.thickness;
  referenceCoordinates_.resize(dofCount());
  symmetryConstrainedDofs_.clear();
  for (int i = 0; i <= nx; ++i) {
    for (int j = 0; j <= ny; ++j) {
      for (int k = 0; k <= nz; ++k) {
        const int node = nodeIndex(i, j, k);
        referenceCoordinates_(3 * node) = i * wx;
        referenceCoordinates_(3 * node + 1) = -0.5 * config_.height + j * wy;
        referenceCoordinates_(3 * node + 2) = zStart + k * wz;
        if (options_.midPlaneSymmetry && k == 0) symmetryConstrainedDofs_.push_back(3 * node + 2);
      }
    }
  }
  std::sort(symmetryConstrainedDofs_.begin(), symmetryConstrainedDofs_.end());
  assemble();
}

double SolidModel::elementWidthX() const { return config_.length / config_.elementsAlongLength; }
double SolidModel::elementWidthY() const { return config_.height / config_.elementsThroughHeight; }
double SolidModel::elementWidthZ() const {
  const double modelled = options_.midPlaneSymmetry ? 0.5 * config_.thickness : config_.thickness;
  return modelled / options_.elementsThroughThickness;
}

std::array<int, 24> SolidModel::elementDofs(int element) const {
  const int ny = config_.elementsThroughHeight, nz = options_.elementsThroughThickness;
  const int k = element % nz, j = (element / nz) % ny, i = element / (nz * ny);
  const int nodes[8] = {nodeIndex(i, j, k),
                        nodeIndex(i + 1, j, k),
                        nodeIndex(i + 1, j + 1, k),
                        nodeIndex(i, j + 1, k),
                        nodeIndex(i, j, k + 1),
                        nodeIndex(i + 1, j, k + 1),
                        nodeIndex(i + 1, j + 1, k + 1),
                        nodeIndex(i, j + 1, k + 1)};
  std::array<int, 24> dofs{};
  for (int a = 0; a < 8; ++a) {
    for (int c = 0; c < 3; ++c) dofs[static_cast<std::size_t>(3 * a + c)] = 3 * nodes[a] + c;
  }
  return dofs;
}

std::vector<int> SolidModel::jointANodes() const {
  std::vector<int> nodes;
  for (int k = 0; k <= options_.elementsThroughThickness; ++k)
    nodes.push_back(nodeIndex(0, config_.elementsThroughHeight / 2, k));
  return nodes;
}

std::vector<int> SolidModel::jointBNodes() const {
  std::vector<int> nodes;
  for (int k = 0; k <= options_.elementsThroughThickness; ++k)
    nodes.push_back(nodeIndex(config_.elementsAlongLength, config_.elementsThroughHeight / 2, k));
  return nodes;
}

// Column by column into the pattern the box mesh fixes: node (i, j, k) couples with the nodes at most one
// step away in each direction (each such pair shares an element), listed in increasing node index, three
// rows each. Every entry sums its elements' contributions from 0 in increasing element order, as an
// element-by-element assembly through coeffRef does, so K and M are that assembly's bits (tested against
// it in tests/problems/rod/solid_model_test.cpp). Written out because coeffRef searches a column for each
// of the 2 x 576 entries an element touches: 2.1 s CPU at 51 200 elements (bench/RESULTS.md, "The solid's
// assembly and sparse products"); a triplet list would hold 2 x 29 million triplets (0.9 GB).
void SolidModel::assemble() {
  const int nx = config_.elementsAlongLength, ny = config_.elementsThroughHeight;
  const int nz = options_.elementsThroughThickness;
  const int dofs = dofCount();
  // Nodes within one step of i along an axis with n elements.
  const auto reach = [](int i, int n) { return (i > 0 ? 1 : 0) + 1 + (i < n ? 1 : 0); };
  std::vector<std::int64_t> starts(static_cast<std::size_t>(dofs) + 1, 0);
  for (int i = 0; i <= nx; ++i) {
    for (int j = 0; j <= ny; ++j) {
      for (int k = 0; k <= nz; ++k) {
        const std::int64_t rows = 3 * reach(i, nx) * reach(j, ny) * reach(k, nz);
        const std::size_t column = 3 * static_cast<std::size_t>(nodeIndex(i, j, k));
        for (std::size_t c = 0; c < 3; ++c) starts[column + c + 1] = rows;
      }
    }
  }
  for (std::size_t c = 0; c < starts.size() - 1; ++c) starts[c + 1] += starts[c];
  const std::int64_t nonZeros = starts.back();
  if (nonZeros > std::numeric_limits<int>::max())
    throw std::invalid_argument("SolidModel: K would have " + std::to_string(nonZeros) +
                                " nonzeros, more than a 32-bit sparse index can address");
  for (SparseMatrix* matrix : {&stiffness_, &mass_}) {
    matrix->resize(dofs, dofs);
    matrix->resizeNonZeros(static_cast<Eigen::Index>(nonZeros));
    for (int c = 0; c <= dofs; ++c)
      matrix->outerIndexPtr()[c] = static_cast<int>(starts[static_cast<std::size_t>(c)]);
  }
  int* rowIndices = stiffness_.innerIndexPtr();
  double* stiffnessValues = stiffness_.valuePtr();
  double* massValues = mass_.valuePtr();
  std::fill(stiffnessValues, stiffnessValues + nonZeros, 0.0);
  std::fill(massValues, massValues + nonZeros, 0.0);
  // The element's local nodes as offsets from its (i, j, k) corner, in elementDofs' order.
  static constexpr int kCorner[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                                        {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
  for (int i = 0; i <= nx; ++i) {
    for (int j = 0; j <= ny; ++j) {
      for (int k = 0; k <= nz; ++k) {
        const int node = nodeIndex(i, j, k);
        // Neighbour (i + di, j + dj, k + dk) -> its place in the column's rows (-1: outside the mesh).
        int slot[27];
        int neighbours = 0;
        for (int di = -1; di <= 1; ++di) {
          for (int dj = -1; dj <= 1; ++dj) {
            for (int dk = -1; dk <= 1; ++dk) {
              const bool inside =
                  i + di >= 0 && i + di <= nx && j + dj >= 0 && j + dj <= ny && k + dk >= 0 && k + dk <= nz;
              const int place = (di + 1) * 9 + (dj + 1) * 3 + (dk + 1);
              slot[place] = inside ? neighbours++ : -1;
              if (!inside) continue;
              const int neighbour = nodeIndex(i + di, j + dj, k + dk);
              for (int c = 0; c < 3; ++c) {
                int* rows =
                    rowIndices + starts[3 * static_cast<std::size_t>(node) + static_cast<std::size_t>(c)];
                for (int r = 0; r < 3; ++r) rows[3 * slot[place] + r] = 3 * neighbour + r;
              }
            }
          }
        }
        // The elements around the node in increasing element index.
        for (int ei = i - 1; ei <= i; ++ei) {
          for (int ej = j - 1; ej <= j; ++ej) {
            for (int ek = k - 1; ek <= k; ++ek) {
              if (ei < 0 || ei >= nx || ej < 0 || ej >= ny || ek < 0 || ek >= nz) continue;
              const double x = elementDesignValue(elementIndex(ei, ej, ek));
              const double elementStiffness = simp_.stiffness(x);
              const double elementDensity = simp_.density(x);
              int own = 0;  // the node's local index in the element
              while (kCorner[own][0] != i - ei || kCorner[own][1] != j - ej || kCorner[own][2] != k - ek)
                ++own;
              for (int a = 0; a < 8; ++a) {
                const int place = (ei + kCorner[a][0] - i + 1) * 9 + (ej + kCorner[a][1] - j + 1) * 3 +
                                  (ek + kCorner[a][2] - k + 1);
                for (int c = 0; c < 3; ++c) {
                  const std::int64_t at =
                      starts[3 * static_cast<std::size_t>(node) + static_cast<std::size_t>(c)] +
                      3 * slot[place];
                  for (int r = 0; r < 3; ++r) {
                    stiffnessValues[at + r] += elementStiffness * unitStiffness_(3 * a + r, 3 * own + c);
                    massValues[at + r] += elementDensity * unitMass_(3 * a + r, 3 * own + c);
                  }
                }
              }
            }
          }
        }
      }
    }
  }
  std::copy(rowIndices, rowIndices + nonZeros, mass_.innerIndexPtr());
}

HexElementMatrix SolidModel::stiffnessDerivative(int designIndex) const {
  if (designIndex < 0 || designIndex >= designCount()) {
    throw std::invalid_argument(
        "SolidModel::stiffnessDerivative: designIndex = " + std::to_string(designIndex) +
        " must lie in [0, " + std::to_string(designCount() - 1) + "]");
  }
  return simp_.stiffnessDerivative(design_(designIndex)) * unitStiffness_;
}

HexElementMatrix SolidModel::massDerivative(int designIndex) const {
  if (designIndex < 0 || designIndex >= designCount()) {
    throw std::invalid_argument("SolidModel::massDerivative: designIndex = " + std::to_string(designIndex) +
                                " must lie in [0, " + std::to_string(designCount() - 1) + "]");
  }
  return simp_.densityDerivative(design_(designIndex)) * unitMass_;
}

SparseMatrix removeDofs(const SparseMatrix& matrix, const std::vector<int>& fixedDofs) {
  if (matrix.rows() != matrix.cols()) throw std::invalid_argument("removeDofs: the matrix must be square");
  const int size = static_cast<int>(matrix.rows());
  std::vector<int> map(static_cast<std::size_t>(size), 0);
  for (int d : fixedDofs) {
    if (d < 0 || d >= size) {
      throw std::invalid_argument("removeDofs: fixed DOF " + std::to_string(d) + " is outside [0, " +
                                  std::to_string(size - 1) + "]");
    }
    map[static_cast<std::size_t>(d)] = -1;
  }
  int kept = 0;
  for (int& entry : map) entry = entry < 0 ? -1 : kept++;
  // Straight into compressed storage: the kept rows and columns keep their order, so each column stays
  // sorted (a triplet list sorted the same entries again: 0.7 s a matrix at 177 k DOFs).
  Eigen::Index nonZeros = 0;
  for (int column = 0; column < size; ++column) {
    if (map[static_cast<std::size_t>(column)] < 0) continue;
    for (SparseMatrix::InnerIterator it(matrix, column); it; ++it)
      nonZeros += map[static_cast<std::size_t>(it.row())] >= 0 ? 1 : 0;
  }
  SparseMatrix result(kept, kept);
  result.resizeNonZeros(nonZeros);
  Eigen::Index at = 0;
  result.outerIndexPtr()[0] = 0;
  for (int column = 0; column < size; ++column) {
    const int newColumn = map[static_cast<std::size_t>(column)];
    if (newColumn < 0) continue;
    for (SparseMatrix::InnerIterator it(matrix, column); it; ++it) {
      const int newRow = map[static_cast<std::size_t>(it.row())];
      if (newRow < 0) continue;
      result.innerIndexPtr()[at] = newRow;
      result.valuePtr()[at] = it.value();
      ++at;
    }
    result.outerIndexPtr()[newColumn + 1] = static_cast<int>(at);
  }
  return result;
}

namespace {

// (K - sigma M)^-1 x for Spectra's shift-and-invert mode, by a sparse LDL^T (K - sigma M is positive
// definite for sigma below the smallest eigenvalue, indefinite but factorable by LDL^T otherwise).
class ShiftInvertOperator {
 public:
  using Scalar = double;
  ShiftInvertOperator(const SparseMatrix& stiffness, const SparseMatrix& mass)
      : stiffness_(stiffness), mass_(mass) {}
  Eigen::Index rows() const { return stiffness_.rows(); }
  Eigen::Index cols() const { return stiffness_.cols(); }
  void set_shift(double sigma) {
    const SparseMatrix shifted = stiffness_ - sigma * mass_;
    factor_.compute(shifted);
    if (factor_.info() != Eigen::Success) {
      throw std::runtime_error("lowestEigenvalues: the LDL^T factorisation of K - shift M failed");
    }
  }
  void perform_op(const double* in, double* out) const {
    Eigen::Map<const Vector> x(in, rows());
    Eigen::Map<Vector> y(out, rows());
    y = factor_.solve(x);
  }

 private:
  const SparseMatrix& stiffness_;
  const SparseMatrix& mass_;
  Eigen::SimplicialLDLT<SparseMatrix> factor_;
};

}  // namespace

Vector lowestEigenvalues(const SparseMatrix& stiffness, const SparseMatrix& mass, int count, double shift) {
  const Eigen::Index n = stiffness.rows();
  if (stiffness.cols() != n || mass.rows() != n || mass.cols() != n) {
    throw std::invalid_argument("lowestEigenvalues: K and M must be square of the same size");
  }
  if (count < 1 || count > n - 1) {
    throw std::invalid_argument("lowestEigenvalues: count = " + std::to_string(count) + " must lie in [1, " +
                                std::to_string(n - 1) + "]");
  }
  ShiftInvertOperator op(stiffness, mass);
  Spectra::SparseSymMatProd<double> massProduct(mass);
  const Eigen::Index subspace = std::min<Eigen::Index>(n, std::max(2 * count + 1, count + 20));
  Spectra::SymGEigsShiftSolver<ShiftInvertOperator, Spectra::SparseSymMatProd<double>,
                               Spectra::GEigsMode::ShiftInvert>
      solver(op, massProduct, count, subspace, shift);
  solver.init();
  const Eigen::Index converged = solver.compute(Spectra::SortRule::LargestMagn, 1000, 1e-12);
  if (solver.info() != Spectra::CompInfo::Successful || converged < count) {
    throw std::runtime_error("lowestEigenvalues: Spectra converged " + std::to_string(converged) + " of " +
                             std::to_string(count) + " eigenvalues");
  }
  Vector values = solver.eigenvalues();
  std::sort(values.data(), values.data() + values.size());
  return values;
}

}  // namespace rod
}  // namespace hindsight
