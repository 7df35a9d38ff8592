#include <hindsight/problems/rod/parallel.h>
#include <hindsight/problems/rod/supernodal_ldlt.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <type_traits>

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

// A counting sort into compressed storage: `items(emit)` calls emit(bucket, item) for every item, the
// same items in the same order each time it is called (twice: to count, then to place). On return
// items of bucket b are out[start[b] .. start[b + 1]) in the order emitted.
template <class Start, class Item, class Items>
void bucketSort(int buckets, Items&& items, std::vector<Start>& start, std::vector<Item>& out) {
  start.assign(static_cast<std::size_t>(buckets) + 1, 0);
  items([&](int bucket, const Item&) { ++start[bucket + 1]; });
  for (int b = 0; b < buckets; ++b) start[b + 1] += start[b];
  out.resize(static_cast<std::size_t>(start[buckets]));
  std::vector<Start> fill(start.begin(), start.end() - 1);
  items([&](int bucket, const Item& item) { out[fill[bucket]++] = item; });
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
  std::vector<int> upperStart, upperRows;
  bucketSort(
      n,
      [&](auto&& emit) {
        for (int c = 0; c < n; ++c)
          for (int p = outer[c]; p < outer[c + 1]; ++p)
            if (inner[p] > c) {
              const int i = newOf[inner[p]], j = newOf[c];
              emit(std::max(i, j), std::min(i, j));
            }
      },
      upperStart, upperRows);
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
  std::vector<int> childStart, children;
  bucketSort(
      supernodes,
      [&](auto&& emit) {
        for (int s = 0; s < supernodes; ++s)
          if (parent_[s] >= 0) emit(parent_[s], s);
      },
      childStart, children);
  // The lower triangle of P A P^T by columns is the upper one by rows: row i of column k above.
  std::vector<int> lowerStart, lowerRows;
  bucketSort(
      n,
      [&](auto&& emit) {
        for (int k = 0; k < n; ++k)
          for (int p = upperStart[k]; p < upperStart[k + 1]; ++p) emit(upperRows[p], k);
      },
      lowerStart, lowerRows);
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

  // Where each entry of A's lower triangle goes, grouped by supernode (in A's storage order within one),
  // supernode by supernode so that `position` holds one supernode's rows at a time.
  {
    struct Entry {
      int source, column;  // A's value index, and its column in A
    };
    std::vector<Entry> entries;
    bucketSort(
        supernodes,
        [&](auto&& emit) {
          for (int c = 0; c < n; ++c)
            for (int p = outer[c]; p < outer[c + 1]; ++p)
              if (inner[p] >= c) emit(superOf[std::min(newOf[inner[p]], newOf[c])], Entry{p, c});
        },
        assemblyStart_, entries);
    assemblySource_.resize(entries.size());
    assemblyTarget_.resize(entries.size());
    std::vector<int> position(static_cast<std::size_t>(n), -1);
    for (int s = 0; s < supernodes; ++s) {
      const int rows = rowStart_[s + 1] - rowStart_[s];
      for (int q = 0; q < rows; ++q) position[rows_[rowStart_[s] + q]] = q;
      for (std::int64_t k = assemblyStart_[s]; k < assemblyStart_[s + 1]; ++k) {
        assemblySource_[k] = entries[k].source;
        const int i = newOf[inner[entries[k].source]], j = newOf[entries[k].column];
        const int row = std::max(i, j), column = std::min(i, j);
        assemblyTarget_[k] = static_cast<std::int64_t>(column - first_[s]) * rows + position[row];
      }
    }
  }

  // The updates each supernode receives: descendant d reaches supernode t through its rows in t's columns,
  // a contiguous run of d's sorted rows. Filled in increasing d, so each list is in increasing d.
  std::int64_t productSize = 0;
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
  bucketSort(
      supernodes,
      [&](auto&& emit) {
        for (int d = 0; d < supernodes; ++d) {
          const int own = first_[d + 1] - first_[d];
          for (int p = rowStart_[d] + own; p < rowStart_[d + 1];) {
            const int t = superOf[rows_[p]], begin = p - rowStart_[d];
            while (p < rowStart_[d + 1] && superOf[rows_[p]] == t) ++p;
            emit(t, Update{d, begin, p - rowStart_[d]});
          }
        }
      },
      updateStart_, updates_);
  int widest = 0;
  for (int d = 0; d < supernodes; ++d) widest = std::max(widest, first_[d + 1] - first_[d]);
  std::int64_t scaledSize = static_cast<std::int64_t>(kSupernodalPanel) * widest;
  for (const Update& update : updates_) {
    const int d = update.descendant, own = first_[d + 1] - first_[d];
    const std::int64_t width = update.end - update.begin,
                       height = rowStart_[d + 1] - rowStart_[d] - update.begin;
    scaledSize = std::max(scaledSize, own * width);
    productSize = std::max(productSize, height * width);
    packSize(height, width, own);
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
  const auto [begin, columns, rows, rowList, blockStart] = geometry(s);
  double* block = values_.data() + blockStart;
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

namespace {

// The sweeps' kernels, on a strip of C <= kSweepStrip right-hand sides stored by rows with row stride
// `stride` (x[i * stride + c]; Packed: stride == C, known to the compiler). Each column's arithmetic is
// fixed by the loops below whatever C, the strip and the chunk of rows (a block solve is bitwise the
// one-column solve), and is a sequence of SSE2 operations without contraction (CMakeLists.txt,
// -ffp-contract=off): the same bits on every x86-64 CPU. The loops run over rows or columns, so the
// compiler vectorises them without reordering a sum.
constexpr int kSweepStrip = 8;
// The buffer of the rows below a supernode (kSupernodalSweepChunk rows) is on the stack, not in the factor,
// because several threads may solve with one factor at once (design_gradient.cpp, esl.cpp).
constexpr int kSweepChunk = kSupernodalSweepChunk;

template <int C, bool Packed>
Eigen::Index sweepStride(Eigen::Index stride) {
  return Packed ? C : stride;
}

// out[c] -= sum_q l[q] g[q * stride + c] for q < n, in four partial sums over q = k mod 4 (increasing q),
// added as (s0 + s1) + (s2 + s3): four independent chains instead of one, in an order fixed by the code.
template <int C, bool Packed>
inline void subtractDot(const double* __restrict l, const double* __restrict g, Eigen::Index runtimeStride,
                        int n, double* __restrict out) {
  const Eigen::Index stride = sweepStride<C, Packed>(runtimeStride);
  double s0[C] = {}, s1[C] = {}, s2[C] = {}, s3[C] = {};
  int q = 0;
  for (; q + 4 <= n; q += 4) {
    const double* g0 = g + q * stride;
    for (int c = 0; c < C; ++c) {
      s0[c] += l[q] * g0[c];
      s1[c] += l[q + 1] * g0[stride + c];
      s2[c] += l[q + 2] * g0[2 * stride + c];
      s3[c] += l[q + 3] * g0[3 * stride + c];
    }
  }
  double* tail[3] = {s0, s1, s2};
  for (int k = 0; q < n; ++q, ++k)
    for (int c = 0; c < C; ++c) tail[k][c] += l[q] * g[q * stride + c];
  for (int c = 0; c < C; ++c) out[c] -= (s0[c] + s1[c]) + (s2[c] + s3[c]);
}

}  // namespace

template <int C, bool Packed>
void SupernodalLdlt::forwardSupernode(int s, double* x, Eigen::Index runtimeStride) const {
  const Eigen::Index stride = sweepStride<C, Packed>(runtimeStride);
  const auto [begin, width, rows, rowList, blockStart] = geometry(s);
  const double* block = values_.data() + blockStart;
  double* __restrict own = x + begin * stride;
  // The unit lower triangle on the supernode's own rows (contiguous), column by column:
  // x_q -= L(q, j) x_j for q > j.
  for (int j = 0; j < width; ++j) {
    const double* __restrict column = block + static_cast<std::int64_t>(j) * rows;
    const double* xj = own + j * stride;
    double xjc[C];
    for (int c = 0; c < C; ++c) xjc[c] = xj[c];
    for (int q = j + 1; q < width; ++q)
      for (int c = 0; c < C; ++c) own[q * stride + c] -= column[q] * xjc[c];
  }
  // The rows below, a chunk at a time: y = L21 x_own (y_q = L(q, 0) x_0 + L(q, 1) x_1 + ..., in
  // increasing column, four columns per pass over the chunk), then x_r -= y_r scattered once.
  alignas(16) double y[kSweepChunk * C];
  for (int first = width; first < rows; first += kSweepChunk) {
    const int n = std::min(kSweepChunk, rows - first);
    std::fill(y, y + n * C, 0.0);
    int j = 0;
    for (; j + 4 <= width; j += 4) {
      const double* __restrict l0 = block + static_cast<std::int64_t>(j) * rows + first;
      const double* __restrict l1 = l0 + rows, * __restrict l2 = l1 + rows, * __restrict l3 = l2 + rows;
      double x0[C], x1[C], x2[C], x3[C];
      for (int c = 0; c < C; ++c) {
        x0[c] = own[j * stride + c];
        x1[c] = own[(j + 1) * stride + c];
        x2[c] = own[(j + 2) * stride + c];
        x3[c] = own[(j + 3) * stride + c];
      }
      for (int q = 0; q < n; ++q)
        for (int c = 0; c < C; ++c)
          y[q * C + c] = (((y[q * C + c] + l0[q] * x0[c]) + l1[q] * x1[c]) + l2[q] * x2[c]) + l3[q] * x3[c];
    }
    for (; j < width; ++j) {
      const double* __restrict l0 = block + static_cast<std::int64_t>(j) * rows + first;
      double x0[C];
      for (int c = 0; c < C; ++c) x0[c] = own[j * stride + c];
      for (int q = 0; q < n; ++q)
        for (int c = 0; c < C; ++c) y[q * C + c] += l0[q] * x0[c];
    }
    for (int q = 0; q < n; ++q) {
      double* __restrict xr = x + static_cast<Eigen::Index>(rowList[first + q]) * stride;
      for (int c = 0; c < C; ++c) xr[c] -= y[q * C + c];
    }
  }
}

template <int C, bool Packed>
void SupernodalLdlt::backwardSupernode(int s, double* x, Eigen::Index runtimeStride) const {
  const Eigen::Index stride = sweepStride<C, Packed>(runtimeStride);
  const auto [begin, width, rows, rowList, blockStart] = geometry(s);
  const double* block = values_.data() + blockStart;
  double* own = x + begin * stride;
  // The rows below, a chunk at a time: gathered once, then x_j -= L(chunk, j)^T x_chunk for every column j.
  alignas(16) double g[kSweepChunk * C];
  for (int first = width; first < rows; first += kSweepChunk) {
    const int n = std::min(kSweepChunk, rows - first);
    for (int q = 0; q < n; ++q) {
      const double* xr = x + static_cast<Eigen::Index>(rowList[first + q]) * stride;
      for (int c = 0; c < C; ++c) g[q * C + c] = xr[c];
    }
    for (int j = 0; j < width; ++j)
      subtractDot<C, true>(block + static_cast<std::int64_t>(j) * rows + first, g, C, n, own + j * stride);
  }
  // The unit upper triangle L11^T on the own rows (contiguous), from the last row back.
  for (int j = width - 2; j >= 0; --j)
    subtractDot<C, Packed>(block + static_cast<std::int64_t>(j) * rows + j + 1, own + (j + 1) * stride,
                           stride, width - j - 1, own + j * stride);
}

namespace {

// call(std::integral_constant<int, C>, std::bool_constant<Packed>, first column) on strips of at most
// kSweepStrip columns: one packed strip for up to kSweepStrip right-hand sides, else strips of the rows.
template <class Call>
void bySweepStrips(Eigen::Index columns, Call&& call) {
  for (Eigen::Index first = 0; first < columns; first += kSweepStrip) {
    const Eigen::Index width = std::min<Eigen::Index>(kSweepStrip, columns - first);
    detail::byColumns(width, [&](auto c) {
      constexpr int kC = decltype(c)::value;
      if constexpr (kC > 0) {
        if (columns <= kSweepStrip)
          call(c, std::true_type(), first);
        else
          call(c, std::false_type(), first);
      }
    });
  }
}

}  // namespace

void SupernodalLdlt::forwardSweep(double* x, Eigen::Index columns) const {
  eigen_assert(info_ == Eigen::Success);
  // Serial: a supernode scatters into its ancestors, which may be in any group.
  bySweepStrips(columns, [&](auto c, auto packed, Eigen::Index first) {
    for (int s = 0; s < supernodeCount(); ++s)
      forwardSupernode<decltype(c)::value, decltype(packed)::value>(s, x + first, columns);
  });
}

void SupernodalLdlt::backwardSweep(double* x, Eigen::Index columns, bool parallel) const {
  eigen_assert(info_ == Eigen::Success);
  bySweepStrips(columns, [&](auto c, auto packed, Eigen::Index first) {
    constexpr int kC = decltype(c)::value;
    constexpr bool kPacked = decltype(packed)::value;
    double* strip = x + first;
    // The top first (it reads nothing below it), then each group's subtrees from their roots down.
    for (auto s = partition_.top.rbegin(); s != partition_.top.rend(); ++s)
      backwardSupernode<kC, kPacked>(*s, strip, columns);
    const auto group = [&](int g) {
      for (auto s = partition_.groups[g].rbegin(); s != partition_.groups[g].rend(); ++s)
        backwardSupernode<kC, kPacked>(*s, strip, columns);
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

int SupernodalLdlt::tallestBelow() const {
  int tallest = 0;
  for (int s = 0; s < supernodeCount(); ++s)
    tallest = std::max(tallest, rowStart_[s + 1] - rowStart_[s] - (first_[s + 1] - first_[s]));
  return tallest;
}

std::int64_t SupernodalLdlt::storedNonZeros() const {
  std::int64_t total = 0;
  for (int s = 0; s < supernodeCount(); ++s)
    total += supernodeTrapezoid(first_[s + 1] - first_[s], rowStart_[s + 1] - rowStart_[s]);
  return total;
}

}  // namespace rod
}  // namespace hindsight
