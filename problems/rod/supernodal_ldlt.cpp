#include <hindsight/problems/rod/parallel.h>
#include <hindsight/problems/rod/supernodal_ldlt.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace hindsight {
namespace rod {

namespace {

// Columns of the unblocked panels of a supernode's dense LDL^T; the rest of the block is updated by one
// product per panel. A fixed number: it decides where the sums are rounded.
constexpr int kSupernodalPanel = 32;

using ConstSupernodeBlock = Eigen::Map<const Eigen::MatrixXd, 0, Eigen::OuterStride<>>;

// The general products of the numeric factorisation, dst = lhs rhs or dst -= lhs rhs (column-major,
// strided), by Eigen's own dispatch for `dst.noalias() = / -= lhs * rhs` (Eigen 3.4,
// Eigen/src/Core/products/GeneralMatrixMatrix.h: the coefficient-based product for tiny sizes, the
// matrix-vector product for one row or column, else the blocked product with the blocking Eigen computes
// from the pinned cache sizes), except that the blocked product packs into `packA` and `packB` (sized by
// analyzePattern) instead of buffers Eigen would take from the heap above 128 KB. The same kernels and
// blocking: no bit depends on where the buffers are.
using SupernodeBlocking =
    Eigen::internal::gemm_blocking_space<Eigen::ColMajor, double, double, Eigen::Dynamic, Eigen::Dynamic,
                                         Eigen::Dynamic, 1, false>;

bool supernodeProductIsBlocked(Eigen::Index rows, Eigen::Index cols, Eigen::Index depth) {
  return rows > 1 && cols > 1 && depth > 0 && depth + rows + cols >= EIGEN_GEMM_TO_COEFFBASED_THRESHOLD;
}

struct PreallocatedBlocking : SupernodeBlocking {
  PreallocatedBlocking(Eigen::Index rows, Eigen::Index cols, Eigen::Index depth, double* packA, double* packB)
      : SupernodeBlocking(rows, cols, depth, 1, true) {
    this->m_blockA = packA;
    this->m_blockB = packB;
  }
  ~PreallocatedBlocking() {
    this->m_blockA = nullptr;  // the workspace's: not for Eigen's destructor to free
    this->m_blockB = nullptr;
  }
  PreallocatedBlocking(const PreallocatedBlocking&) = delete;
  PreallocatedBlocking& operator=(const PreallocatedBlocking&) = delete;
};

void supernodeProduct(Eigen::Index rows, Eigen::Index cols, Eigen::Index depth, const double* lhs,
                      Eigen::Index lhsStride, const double* rhs, Eigen::Index rhsStride, double* dst,
                      Eigen::Index dstStride, bool subtract, double* packA, double* packB) {
  using Strided = Eigen::OuterStride<>;
  Eigen::Map<Eigen::MatrixXd, 0, Strided> out(dst, rows, cols, Strided(dstStride));
  if (!supernodeProductIsBlocked(rows, cols, depth)) {
    const Eigen::Map<const Eigen::MatrixXd, 0, Strided> left(lhs, rows, depth, Strided(lhsStride));
    const Eigen::Map<const Eigen::MatrixXd, 0, Strided> right(rhs, depth, cols, Strided(rhsStride));
    if (subtract)
      out.noalias() -= left * right;
    else
      out.noalias() = left * right;
    return;
  }
  if (!subtract) out.setZero();
  PreallocatedBlocking blocking(rows, cols, depth, packA, packB);
  Eigen::internal::general_matrix_matrix_product<Eigen::Index, double, Eigen::ColMajor, false, double,
                                                 Eigen::ColMajor, false, Eigen::ColMajor,
                                                 1>::run(rows, cols, depth, lhs, lhsStride, rhs, rhsStride,
                                                         dst, 1, dstStride, subtract ? -1.0 : 1.0, blocking,
                                                         nullptr);
}

// Entries of the lower trapezoid of a dense supernode block.
std::int64_t supernodeTrapezoid(std::int64_t columns, std::int64_t rows) {
  return columns * rows - columns * (columns - 1) / 2;
}

}  // namespace

void SupernodalLdlt::analyzePattern(const SparseMatrix& a) {
  if (a.rows() != a.cols()) throw std::invalid_argument("SupernodalLdlt: the matrix is not square");
  if (!a.isCompressed()) throw std::invalid_argument("SupernodalLdlt: the matrix is not compressed");
  info_ = Eigen::InvalidInput;
  const int n = static_cast<int>(a.rows());
  n_ = n;
  pinv_ = metisOrdering(a);
  p_ = pinv_.inverse();
  const int* newOf = p_.indices().data();
  const int* outer = a.outerIndexPtr();
  const int* inner = a.innerIndexPtr();
  outer_.assign(outer, outer + n + 1);
  inner_.assign(inner, inner + a.nonZeros());

  // The strict upper triangle of P A P^T by columns (column k: rows i < k), from A's lower triangle.
  std::vector<int> upperStart(static_cast<std::size_t>(n) + 1, 0);
  for (int c = 0; c < n; ++c)
    for (int p = outer[c]; p < outer[c + 1]; ++p)
      if (inner[p] > c) ++upperStart[std::max(newOf[inner[p]], newOf[c]) + 1];
  for (int k = 0; k < n; ++k) upperStart[k + 1] += upperStart[k];
  std::vector<int> upperRows(static_cast<std::size_t>(upperStart[n]));
  {
    std::vector<int> fill(upperStart.begin(), upperStart.end() - 1);
    for (int c = 0; c < n; ++c)
      for (int p = outer[c]; p < outer[c + 1]; ++p)
        if (inner[p] > c) {
          const int i = newOf[inner[p]], j = newOf[c];
          upperRows[fill[std::max(i, j)]++] = std::min(i, j);
        }
  }
  // The elimination tree (Liu's algorithm with path compression) and the column counts of L without the
  // diagonal (each row's subtree walked once: O(nnz(L))), Davis 2006 ch. 4.
  std::vector<int> parent(static_cast<std::size_t>(n), -1), ancestor(static_cast<std::size_t>(n), -1);
  for (int k = 0; k < n; ++k)
    for (int p = upperStart[k]; p < upperStart[k + 1]; ++p)
      for (int i = upperRows[p]; i != -1 && i < k;) {
        const int next = ancestor[i];
        ancestor[i] = k;
        if (next == -1) parent[i] = k;
        i = next;
      }
  std::vector<std::int64_t> count(static_cast<std::size_t>(n), 0);
  {
    std::vector<int> flag(static_cast<std::size_t>(n), -1);
    for (int k = 0; k < n; ++k) {
      flag[k] = k;
      for (int p = upperStart[k]; p < upperStart[k + 1]; ++p)
        for (int i = upperRows[p]; flag[i] != k; i = parent[i]) {
          ++count[i];
          flag[i] = k;
        }
    }
  }
  // Fundamental supernodes (column j joins j - 1's when it is j - 1's parent with j - 1's structure less
  // itself), then relaxed amalgamation of each supernode into the next when that one is its parent: the
  // merged block has the child's columns and the parent's rows, so its extra zeros are known from the
  // counts alone.
  first_.clear();
  {
    std::vector<int> fundamental;
    for (int j = 0; j < n; ++j)
      if (j == 0 || !(parent[j - 1] == j && count[j - 1] == count[j] + 1)) fundamental.push_back(j);
    fundamental.push_back(n);
    std::int64_t openRows = 0, openZeros = 0;
    for (std::size_t f = 0; f + 1 < fundamental.size(); ++f) {
      const int begin = fundamental[f], end = fundamental[f + 1];
      const std::int64_t columns = end - begin, rows = count[begin] + 1;
      if (!first_.empty()) {
        const int openBegin = first_.back();
        const int last = begin - 1;  // the open supernode's last column
        if (parent[last] >= begin && parent[last] < end) {
          const std::int64_t openColumns = begin - openBegin;
          const std::int64_t mergedColumns = openColumns + columns, mergedRows = openColumns + rows;
          const std::int64_t zeros = openZeros + supernodeTrapezoid(mergedColumns, mergedRows) -
                                     supernodeTrapezoid(openColumns, openRows) -
                                     supernodeTrapezoid(columns, rows);
          if (zeros <= options_.relaxedZeros ||
              (mergedColumns <= options_.relaxedColumns &&
               static_cast<double>(zeros) <=
                   options_.relaxedShare * supernodeTrapezoid(mergedColumns, mergedRows))) {
            openRows = mergedRows;
            openZeros = zeros;
            continue;
          }
        }
      }
      first_.push_back(begin);
      openRows = rows;
      openZeros = 0;
    }
    first_.push_back(n);
  }
  const int supernodes = static_cast<int>(first_.size()) - 1;
  std::vector<int> superOf(static_cast<std::size_t>(n));
  for (int s = 0; s < supernodes; ++s)
    std::fill(superOf.begin() + first_[s], superOf.begin() + first_[s + 1], s);
  parent_.assign(static_cast<std::size_t>(supernodes), -1);
  for (int s = 0; s < supernodes; ++s) {
    const int up = parent[first_[s + 1] - 1];
    if (up >= 0) parent_[s] = superOf[up];
  }
  // Rows of each supernode: its columns, then the union of A's rows below its columns and its children's
  // rows below its columns, increasing.
  std::vector<int> childStart(static_cast<std::size_t>(supernodes) + 1, 0), children;
  for (int s = 0; s < supernodes; ++s)
    if (parent_[s] >= 0) ++childStart[parent_[s] + 1];
  for (int s = 0; s < supernodes; ++s) childStart[s + 1] += childStart[s];
  children.resize(static_cast<std::size_t>(childStart[supernodes]));
  {
    std::vector<int> fill(childStart.begin(), childStart.end() - 1);
    for (int s = 0; s < supernodes; ++s)
      if (parent_[s] >= 0) children[fill[parent_[s]]++] = s;
  }
  // The lower triangle of P A P^T by columns is the upper one by rows: row i of column k above.
  std::vector<int> lowerStart(static_cast<std::size_t>(n) + 1, 0);
  for (int k = 0; k < n; ++k)
    for (int p = upperStart[k]; p < upperStart[k + 1]; ++p) ++lowerStart[upperRows[p] + 1];
  for (int j = 0; j < n; ++j) lowerStart[j + 1] += lowerStart[j];
  std::vector<int> lowerRows(static_cast<std::size_t>(lowerStart[n]));
  {
    std::vector<int> fill(lowerStart.begin(), lowerStart.end() - 1);
    for (int k = 0; k < n; ++k)
      for (int p = upperStart[k]; p < upperStart[k + 1]; ++p) lowerRows[fill[upperRows[p]]++] = k;
  }
  rowStart_.assign(1, 0);
  rows_.clear();
  {
    std::vector<int> mark(static_cast<std::size_t>(n), -1), below;
    for (int s = 0; s < supernodes; ++s) {
      const int begin = first_[s], end = first_[s + 1];
      below.clear();
      const auto add = [&](int row) {
        if (row >= end && mark[row] != s) {
          mark[row] = s;
          below.push_back(row);
        }
      };
      for (int j = begin; j < end; ++j)
        for (int p = lowerStart[j]; p < lowerStart[j + 1]; ++p) add(lowerRows[p]);
      for (int c = childStart[s]; c < childStart[s + 1]; ++c) {
        const int child = children[c];
        for (int p = rowStart_[child]; p < rowStart_[child + 1]; ++p) add(rows_[p]);
      }
      std::sort(below.begin(), below.end());
      for (int j = begin; j < end; ++j) rows_.push_back(j);
      rows_.insert(rows_.end(), below.begin(), below.end());
      rowStart_.push_back(static_cast<int>(rows_.size()));
    }
  }
  blockStart_.assign(1, 0);
  for (int s = 0; s < supernodes; ++s)
    blockStart_.push_back(blockStart_.back() + static_cast<std::int64_t>(first_[s + 1] - first_[s]) *
                                                   (rowStart_[s + 1] - rowStart_[s]));
  values_.resize(blockStart_.back());
  d_.resize(n);

  // Where each entry of A's lower triangle goes, grouped by supernode (in A's storage order within one).
  {
    std::vector<int> position(static_cast<std::size_t>(n), -1);
    std::vector<std::int64_t> perSupernode(static_cast<std::size_t>(supernodes) + 1, 0);
    for (int c = 0; c < n; ++c)
      for (int p = outer[c]; p < outer[c + 1]; ++p)
        if (inner[p] >= c) ++perSupernode[superOf[std::min(newOf[inner[p]], newOf[c])] + 1];
    for (int s = 0; s < supernodes; ++s) perSupernode[s + 1] += perSupernode[s];
    assemblyStart_ = perSupernode;
    assemblyTarget_.assign(static_cast<std::size_t>(perSupernode[supernodes]), 0);
    assemblySource_.assign(static_cast<std::size_t>(perSupernode[supernodes]), 0);
    std::vector<std::int64_t> fill(perSupernode.begin(), perSupernode.end() - 1);
    // Supernode by supernode so that `position` holds one supernode's rows at a time: collect the entries
    // of each supernode first.
    std::vector<int> entryColumn(static_cast<std::size_t>(perSupernode[supernodes]));
    for (int c = 0; c < n; ++c)
      for (int p = outer[c]; p < outer[c + 1]; ++p)
        if (inner[p] >= c) {
          const std::int64_t k = fill[superOf[std::min(newOf[inner[p]], newOf[c])]]++;
          assemblySource_[k] = p;
          entryColumn[k] = c;
        }
    for (int s = 0; s < supernodes; ++s) {
      const int rows = rowStart_[s + 1] - rowStart_[s];
      for (int q = 0; q < rows; ++q) position[rows_[rowStart_[s] + q]] = q;
      for (std::int64_t k = assemblyStart_[s]; k < assemblyStart_[s + 1]; ++k) {
        const int i = newOf[inner[assemblySource_[k]]], j = newOf[entryColumn[k]];
        const int row = std::max(i, j), column = std::min(i, j);
        assemblyTarget_[k] = static_cast<std::int64_t>(column - first_[s]) * rows + position[row];
      }
    }
  }

  // The updates each supernode receives: descendant d reaches supernode t through its rows in t's columns,
  // a contiguous run of d's sorted rows. Filled in increasing d, so each list is in increasing d.
  std::int64_t scaledSize = static_cast<std::int64_t>(kSupernodalPanel) * n, productSize = 0;
  // The blocked products' packing buffers: the largest Eigen's blocking asks for over all products.
  std::int64_t packASize = 0, packBSize = 0;
  const auto packSize = [&](Eigen::Index rows, Eigen::Index cols, Eigen::Index depth) {
    if (!supernodeProductIsBlocked(rows, cols, depth)) return;
    const SupernodeBlocking blocking(rows, cols, depth, 1, true);
    packASize = std::max<std::int64_t>(packASize, blocking.mc() * blocking.kc());
    packBSize = std::max<std::int64_t>(packBSize, blocking.kc() * blocking.nc());
  };
  for (int s = 0; s < supernodes; ++s) {
    const int columns = first_[s + 1] - first_[s], rows = rowStart_[s + 1] - rowStart_[s];
    for (int panel = 0; panel + kSupernodalPanel < columns; panel += kSupernodalPanel) {
      const int panelEnd = panel + kSupernodalPanel;
      packSize(rows - panelEnd, columns - panelEnd, panelEnd - panel);
    }
  }
  {
    std::vector<std::int64_t> perTarget(static_cast<std::size_t>(supernodes) + 1, 0);
    int widest = 0;
    for (int d = 0; d < supernodes; ++d) {
      widest = std::max(widest, first_[d + 1] - first_[d]);
      const int own = first_[d + 1] - first_[d];
      for (int p = rowStart_[d] + own; p < rowStart_[d + 1];) {
        const int t = superOf[rows_[p]];
        ++perTarget[t + 1];
        while (p < rowStart_[d + 1] && superOf[rows_[p]] == t) ++p;
      }
    }
    scaledSize = static_cast<std::int64_t>(kSupernodalPanel) * widest;
    for (int s = 0; s < supernodes; ++s) perTarget[s + 1] += perTarget[s];
    updateStart_ = perTarget;
    updates_.assign(static_cast<std::size_t>(perTarget[supernodes]), Update{});
    std::vector<std::int64_t> fill(perTarget.begin(), perTarget.end() - 1);
    for (int d = 0; d < supernodes; ++d) {
      const int own = first_[d + 1] - first_[d];
      for (int p = rowStart_[d] + own; p < rowStart_[d + 1];) {
        const int t = superOf[rows_[p]], begin = p - rowStart_[d];
        while (p < rowStart_[d + 1] && superOf[rows_[p]] == t) ++p;
        const int end = p - rowStart_[d];
        updates_[fill[t]++] = Update{d, begin, end};
        const std::int64_t width = end - begin, height = rowStart_[d + 1] - rowStart_[d] - begin;
        scaledSize = std::max(scaledSize, own * width);
        productSize = std::max(productSize, height * width);
        packSize(height, width, own);
      }
    }
  }

  // The subtrees factorised in parallel; a supernode's work is about its columns' updates to others,
  // sum over its columns of the squared column count.
  const int threads = options_.groups > 0 ? options_.groups : parallelConcurrency();
  partition_ = SubtreePartition{};
  if (threads >= 2 && n >= options_.smallest) {
    std::vector<double> work(static_cast<std::size_t>(supernodes), 0.0);
    for (int s = 0; s < supernodes; ++s) {
      const double rows = rowStart_[s + 1] - rowStart_[s];
      for (int j = 0; j < first_[s + 1] - first_[s]; ++j) work[s] += (rows - j) * (rows - j);
    }
    partition_ = partitionSubtrees(parent_, work, threads);
  }
  if (partition_.groups.empty()) {
    partition_.top.resize(static_cast<std::size_t>(supernodes));
    for (int s = 0; s < supernodes; ++s) partition_.top[s] = s;
  }
  workspaces_.assign(partition_.groups.size() + 1, Workspace{});
  int tallest = 0;
  for (int s = 0; s < supernodes; ++s) tallest = std::max(tallest, rowStart_[s + 1] - rowStart_[s]);
  for (Workspace& work : workspaces_) {
    work.position.assign(static_cast<std::size_t>(n), 0);
    work.relative.assign(static_cast<std::size_t>(tallest), 0);
    work.scaled.resize(scaledSize);
    work.product.resize(productSize);
    work.packA.resize(packASize);
    work.packB.resize(packBSize);
  }
}

void SupernodalLdlt::factorizeSupernode(int s, const double* values, Workspace& work) {
  const int begin = first_[s], columns = first_[s + 1] - begin;
  const int rows = rowStart_[s + 1] - rowStart_[s];
  const int* rowList = rows_.data() + rowStart_[s];
  double* block = values_.data() + blockStart_[s];
  // Assemble A's entries.
  std::fill(block, block + static_cast<std::int64_t>(columns) * rows, 0.0);
  for (std::int64_t k = assemblyStart_[s]; k < assemblyStart_[s + 1]; ++k)
    block[assemblyTarget_[k]] = values[assemblySource_[k]];
  // The descendants' updates, in increasing descendant.
  for (int q = 0; q < rows; ++q) work.position[rowList[q]] = q;
  for (std::int64_t u = updateStart_[s]; u < updateStart_[s + 1]; ++u) {
    const Update& update = updates_[u];
    const int d = update.descendant, dColumns = first_[d + 1] - first_[d];
    const int dRows = rowStart_[d + 1] - rowStart_[d];
    const int* dRowList = rows_.data() + rowStart_[d];
    const int width = update.end - update.begin, height = dRows - update.begin;
    const double* dBlock = values_.data() + blockStart_[d];
    // scaled = D_d L_d(rows in s)^T (dColumns x width), product = L_d(rows from s on) scaled.
    Eigen::Map<Eigen::MatrixXd> scaled(work.scaled.data(), dColumns, width);
    const ConstSupernodeBlock reach(dBlock + update.begin, width, dColumns, Eigen::OuterStride<>(dRows));
    scaled.noalias() = d_.segment(first_[d], dColumns).asDiagonal() * reach.transpose();
    supernodeProduct(height, width, dColumns, dBlock + update.begin, dRows, work.scaled.data(), dColumns,
                     work.product.data(), height, false, work.packA.data(), work.packB.data());
    for (int q = 0; q < height; ++q) work.relative[q] = work.position[dRowList[update.begin + q]];
    for (int c = 0; c < width; ++c) {
      double* target = block + static_cast<std::int64_t>(dRowList[update.begin + c] - begin) * rows;
      const double* source = work.product.data() + static_cast<std::int64_t>(c) * height;
      for (int q = c; q < height; ++q) target[work.relative[q]] -= source[q];
    }
  }
  // The dense LDL^T of the block, by panels.
  double* diagonal = d_.data() + begin;
  for (int panel = 0; panel < columns; panel += kSupernodalPanel) {
    const int panelEnd = std::min(columns, panel + kSupernodalPanel);
    for (int j = panel; j < panelEnd; ++j) {
      double* column = block + static_cast<std::int64_t>(j) * rows;
      const double pivot = column[j];
      if (!(pivot != 0.0 && std::isfinite(pivot))) work.failed = true;
      diagonal[j] = pivot;
      // The panel's later columns, with column j unscaled: a(i, c) -= a(i, j) l(c, j).
      for (int c = j + 1; c < panelEnd; ++c) {
        const double l = column[c] / pivot;
        double* __restrict target = block + static_cast<std::int64_t>(c) * rows;
        const double* __restrict source = column;
        for (int i = c; i < rows; ++i) target[i] -= source[i] * l;
      }
      for (int i = j + 1; i < rows; ++i) column[i] /= pivot;
    }
    if (panelEnd == columns) break;
    // The block's columns right of the panel: A22 -= L21 D L(right columns, panel)^T.
    const int right = columns - panelEnd, width = panelEnd - panel;
    Eigen::Map<Eigen::MatrixXd> scaled(work.scaled.data(), width, right);
    const ConstSupernodeBlock reach(block + static_cast<std::int64_t>(panel) * rows + panelEnd, right, width,
                                    Eigen::OuterStride<>(rows));
    scaled.noalias() = d_.segment(begin + panel, width).asDiagonal() * reach.transpose();
    supernodeProduct(rows - panelEnd, right, width,
                     block + static_cast<std::int64_t>(panel) * rows + panelEnd, rows, work.scaled.data(),
                     width, block + static_cast<std::int64_t>(panelEnd) * rows + panelEnd, rows, true,
                     work.packA.data(), work.packB.data());
  }
}

void SupernodalLdlt::factorizeRange(const std::vector<int>& supernodes, const double* values,
                                    Workspace& work) {
  for (const int s : supernodes) factorizeSupernode(s, values, work);
}

void SupernodalLdlt::factorize(const SparseMatrix& a) {
  if (!a.isCompressed() || a.rows() != n_ || a.cols() != n_ ||
      static_cast<std::size_t>(a.nonZeros()) != inner_.size() ||
      !std::equal(outer_.begin(), outer_.end(), a.outerIndexPtr()) ||
      !std::equal(inner_.begin(), inner_.end(), a.innerIndexPtr()))
    throw std::invalid_argument(
        "SupernodalLdlt::factorize: the matrix has another sparsity pattern than the analysed one");
  const double* values = a.valuePtr();
  for (Workspace& work : workspaces_) work.failed = false;
  const int groups = static_cast<int>(partition_.groups.size());
  if (groups > 0)
    parallelFor(groups, [&](int g) { factorizeRange(partition_.groups[g], values, workspaces_[g]); });
  factorizeRange(partition_.top, values, workspaces_.back());
  info_ = Eigen::Success;
  for (const Workspace& work : workspaces_)
    if (work.failed) info_ = Eigen::NumericalIssue;
}

template <int Columns>
void SupernodalLdlt::forward(double* x, Eigen::Index runtimeColumns) const {
  const Eigen::Index columns = Columns > 0 ? Columns : runtimeColumns;
  const int supernodes = supernodeCount();
  for (int s = 0; s < supernodes; ++s) {
    const int begin = first_[s], width = first_[s + 1] - begin;
    const int rows = rowStart_[s + 1] - rowStart_[s];
    const int* rowList = rows_.data() + rowStart_[s];
    const double* block = values_.data() + blockStart_[s];
    // Column by column: x_r -= L(r, j) x_j for the rows r below j, the supernode's own rows (contiguous)
    // and those below it (scattered).
    for (int j = 0; j < width; ++j) {
      const double* __restrict column = block + static_cast<std::int64_t>(j) * rows;
      const double* __restrict xj = x + static_cast<Eigen::Index>(begin + j) * columns;
      for (int q = j + 1; q < rows; ++q) {
        double* __restrict xr = x + static_cast<Eigen::Index>(rowList[q]) * columns;
        const double l = column[q];
        for (Eigen::Index c = 0; c < columns; ++c) xr[c] -= xj[c] * l;
      }
    }
  }
}

template <int Columns>
void SupernodalLdlt::backwardSupernode(int s, double* x, Eigen::Index runtimeColumns) const {
  const Eigen::Index columns = Columns > 0 ? Columns : runtimeColumns;
  const int begin = first_[s], width = first_[s + 1] - begin;
  const int rows = rowStart_[s + 1] - rowStart_[s];
  const int* rowList = rows_.data() + rowStart_[s];
  const double* block = values_.data() + blockStart_[s];
  // Row j of L^T from the last column back: x_j -= L(r, j) x_r over the rows r below j, increasing.
  for (int j = width - 1; j >= 0; --j) {
    const double* __restrict column = block + static_cast<std::int64_t>(j) * rows;
    double* __restrict xj = x + static_cast<Eigen::Index>(begin + j) * columns;
    for (int q = j + 1; q < rows; ++q) {
      const double* __restrict xr = x + static_cast<Eigen::Index>(rowList[q]) * columns;
      const double l = column[q];
      for (Eigen::Index c = 0; c < columns; ++c) xj[c] -= l * xr[c];
    }
  }
}

void SupernodalLdlt::forwardSweep(double* x, Eigen::Index columns) const {
  eigen_assert(info_ == Eigen::Success);
  detail::byColumns(columns, [&](auto c) { forward<decltype(c)::value>(x, columns); });
}

void SupernodalLdlt::backwardSweep(double* x, Eigen::Index columns, bool parallel) const {
  eigen_assert(info_ == Eigen::Success);
  detail::byColumns(columns, [&](auto c) {
    constexpr int kColumns = decltype(c)::value;
    // The top first (it reads nothing below it), then each group's subtrees from their roots down.
    for (auto s = partition_.top.rbegin(); s != partition_.top.rend(); ++s)
      backwardSupernode<kColumns>(*s, x, columns);
    const auto group = [&](int g) {
      for (auto s = partition_.groups[g].rbegin(); s != partition_.groups[g].rend(); ++s)
        backwardSupernode<kColumns>(*s, x, columns);
    };
    const int groups = static_cast<int>(partition_.groups.size());
    if (parallel && groups > 1)
      parallelFor(groups, group);
    else
      for (int g = 0; g < groups; ++g) group(g);
  });
}

Eigen::MatrixXd SupernodalLdlt::solve(const Eigen::Ref<const Eigen::MatrixXd>& b) const {
  using RowBlock = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  RowBlock block = b, scratch(b.rows(), b.cols());
  detail::ldltSolveInPlace(*this, block, scratch);
  return block;
}

std::int64_t SupernodalLdlt::storedNonZeros() const {
  std::int64_t total = 0;
  for (int s = 0; s < supernodeCount(); ++s)
    total += supernodeTrapezoid(first_[s + 1] - first_[s], rowStart_[s + 1] - rowStart_[s]);
  return total;
}

}  // namespace rod
}  // namespace hindsight
