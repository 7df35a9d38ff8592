#include <hindsight/problems/rod/parallel.h>
#include <hindsight/problems/rod/subtree_ldlt.h>

#include <metis.h>

#include <algorithm>
#include <mutex>
#include <queue>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>

namespace hindsight {
namespace rod {

static_assert(sizeof(idx_t) == sizeof(int),
              "METIS must be built with 32-bit indices (Debian's IDXTYPEWIDTH 32)");

Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> metisOrdering(
    const Eigen::SparseMatrix<double>& lower) {
  if (lower.rows() != lower.cols()) throw std::invalid_argument("metisOrdering: the matrix is not square");
  // The adjacency graph of the symmetric pattern without the diagonal, each row's neighbours in
  // increasing order, as METIS_NodeND reads it (the METIS 5.1 manual's CSR graph). Eigen's own wrapper
  // (Eigen/MetisSupport) is not used: on a METIS error it prints a line and leaves the permutation
  // empty, which SimplicialLDLT takes for the natural ordering -- a silent change of every bit.
  const Eigen::SparseMatrix<double> full = lower.selfadjointView<Eigen::Lower>();
  idx_t n = static_cast<idx_t>(full.rows());
  std::vector<idx_t> start(static_cast<std::size_t>(n) + 1, 0), neighbours;
  neighbours.reserve(static_cast<std::size_t>(full.nonZeros()));
  for (idx_t j = 0; j < n; ++j) {
    for (Eigen::SparseMatrix<double>::InnerIterator it(full, j); it; ++it)
      if (it.row() != j) neighbours.push_back(static_cast<idx_t>(it.row()));
    start[static_cast<std::size_t>(j) + 1] = static_cast<idx_t>(neighbours.size());
  }
  Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> newToOld(n);
  if (n == 0) return newToOld;
  std::vector<idx_t> oldToNew(static_cast<std::size_t>(n));
  idx_t options[METIS_NOPTIONS];
  METIS_SetDefaultOptions(options);
  options[METIS_OPTION_NUMBERING] = 0;
  int status = METIS_OK;
  {
    // METIS draws its random choices from one generator of the process (Debian's libmetis imports the C
    // library's srand and rand), reseeded with its fixed seed at each call: two orderings at once share
    // one sequence and come out different (measured: two threads ordering a 200 x 13 x 9 grid graph at
    // once got another ordering than the serial call's in 20 of 20 calls). One at a time, each is a
    // function of its pattern. (Nothing else in hindsight calls rand.)
    static std::mutex metis;
    const std::lock_guard<std::mutex> lock(metis);
    status = METIS_NodeND(&n, start.data(), neighbours.data(), nullptr, options, newToOld.indices().data(),
                          oldToNew.data());
  }
  if (status != METIS_OK)
    throw std::runtime_error("metisOrdering: METIS_NodeND failed (status " + std::to_string(status) +
                             (status == METIS_ERROR_MEMORY ? ", out of memory)" : ")"));
  return newToOld;
}

SubtreeParallelLdlt::SubtreeParallelLdlt(const SparseMatrix& a, SubtreeSchedule options,
                                         FillOrdering ordering)
    : options_(options), ordering_(ordering) {
  compute(a);
}

void SubtreeParallelLdlt::analyzePattern(const SparseMatrix& a) {
  if (ordering_ == FillOrdering::Amd) {
    Eigen::SimplicialLDLT<SparseMatrix>::analyzePattern(a);
  } else {
    // Eigen's ordering step (SimplicialCholeskyBase::ordering) with METIS's permutation in place of
    // AMD's: the upper triangle of P A P^T is what Eigen's analysis and factorize() work on.
    eigen_assert(a.rows() == a.cols());
    m_Pinv = metisOrdering(a);
    m_P = m_Pinv.inverse();
    SparseMatrix permuted(a.rows(), a.cols());
    permuted.selfadjointView<Eigen::Upper>() = a.selfadjointView<Eigen::Lower>().twistedBy(m_P);
    analyzePattern_preordered(permuted, true);
  }
  groups_.clear();
  top_.clear();
  parallelShare_ = 0.0;
  const int n = static_cast<int>(m_parent.size());
  const int threads = options_.groups > 0 ? options_.groups : parallelConcurrency();
  if (threads < 2 || n < options_.smallest) return;  // no groups: the sweeps run serially
  // Work per row: the entries of its column of L (the analysis's counts) and one.
  const int* lp = m_matrix.outerIndexPtr();
  std::vector<double> work(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) work[i] = lp[i + 1] - lp[i] + 1.0;
  SubtreePartition partition =
      partitionSubtrees(std::vector<int>(m_parent.data(), m_parent.data() + n), work, threads);
  groups_ = std::move(partition.groups);
  top_ = std::move(partition.top);
  parallelShare_ = partition.parallelShare;
}

SubtreePartition partitionSubtrees(const std::vector<int>& parent, const std::vector<double>& work,
                                   int threads) {
  SubtreePartition result;
  const int n = static_cast<int>(parent.size());
  if (threads < 2 || n == 0) return result;
  std::vector<double> subtree(work);
  for (int i = 0; i < n; ++i)
    if (parent[i] >= 0) subtree[parent[i]] += subtree[i];
  std::vector<int> childStart(static_cast<std::size_t>(n) + 1, 0), children(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i)
    if (parent[i] >= 0) ++childStart[parent[i] + 1];
  for (int i = 0; i < n; ++i) childStart[i + 1] += childStart[i];
  {
    std::vector<int> fill(childStart.begin(), childStart.end() - 1);
    for (int i = 0; i < n; ++i)
      if (parent[i] >= 0) children[fill[parent[i]]++] = i;
  }
  // Split the heaviest subtree (its root joins the top) until every subtree holds at most 1/(8 T) of
  // the work, so that T groups can be balanced.
  using Entry = std::pair<double, int>;
  std::priority_queue<Entry> heap;
  double total = 0.0;
  for (int i = 0; i < n; ++i)
    if (parent[i] < 0) {
      heap.push({subtree[i], i});
      total += subtree[i];
    }
  const double largest = total / (8.0 * threads);
  std::vector<char> isTop(static_cast<std::size_t>(n), 0);
  while (!heap.empty() && heap.top().first > largest) {
    const int r = heap.top().second;
    heap.pop();
    isTop[r] = 1;
    for (int c = childStart[r]; c < childStart[r + 1]; ++c) heap.push({subtree[children[c]], children[c]});
  }
  // Longest processing time first onto T groups.
  std::vector<double> load(static_cast<std::size_t>(threads), 0.0);
  std::vector<int> owner(static_cast<std::size_t>(n), -1);
  double parallel = 0.0;
  for (; !heap.empty(); heap.pop()) {
    const auto [subtreeWork, r] = heap.top();
    const auto g = std::min_element(load.begin(), load.end()) - load.begin();
    load[g] += subtreeWork;
    owner[r] = static_cast<int>(g);
    parallel += subtreeWork;
  }
  // The other nodes of a subtree follow its root (parents have larger indices).
  for (int i = n - 1; i >= 0; --i)
    if (!isTop[i] && owner[i] < 0) owner[i] = owner[parent[i]];
  result.groups.assign(static_cast<std::size_t>(threads), {});
  for (int i = 0; i < n; ++i) {
    if (isTop[i])
      result.top.push_back(i);
    else
      result.groups[owner[i]].push_back(i);
  }
  result.groups.erase(
      std::remove_if(result.groups.begin(), result.groups.end(), [](const auto& g) { return g.empty(); }),
      result.groups.end());
  result.parallelShare = total > 0.0 ? parallel / total : 0.0;
  return result;
}

template <int Columns>
void SubtreeParallelLdlt::forward(double* x, Eigen::Index runtimeColumns) const {
  const Eigen::Index columns = Columns > 0 ? Columns : runtimeColumns;
  const int* outer = m_matrix.outerIndexPtr();
  const int* rows = m_matrix.innerIndexPtr();
  const double* values = m_matrix.valuePtr();
  // Eigen's column-oriented unit lower solve: x_r -= x_j L(r, j) for the entries of column j (L is
  // stored without its unit diagonal; rows never equal j, hence __restrict).
  const Eigen::Index n = m_matrix.outerSize();
  for (Eigen::Index j = 0; j < n; ++j) {
    const double* __restrict xj = x + j * columns;
    for (int p = outer[j]; p < outer[j + 1]; ++p) {
      double* __restrict xr = x + static_cast<Eigen::Index>(rows[p]) * columns;
      const double l = values[p];
      for (Eigen::Index c = 0; c < columns; ++c) xr[c] -= xj[c] * l;
    }
  }
}

template <int Columns>
void SubtreeParallelLdlt::backward(double* x, Eigen::Index runtimeColumns, bool parallel) const {
  const Eigen::Index columns = Columns > 0 ? Columns : runtimeColumns;
  const int* outer = m_matrix.outerIndexPtr();
  const int* rows = m_matrix.innerIndexPtr();
  const double* values = m_matrix.valuePtr();
  // Eigen's row-oriented unit upper solve with U = L^T: x_i -= L(r, i) x_r in storage order.
  const auto row = [&](int i) {
    double* __restrict xi = x + static_cast<Eigen::Index>(i) * columns;
    for (int p = outer[i]; p < outer[i + 1]; ++p) {
      const double* __restrict xr = x + static_cast<Eigen::Index>(rows[p]) * columns;
      const double l = values[p];
      for (Eigen::Index c = 0; c < columns; ++c) xi[c] -= l * xr[c];
    }
  };
  if (!parallel || groups_.empty()) {
    for (int i = static_cast<int>(m_matrix.outerSize()) - 1; i >= 0; --i) row(i);
    return;
  }
  for (auto i = top_.rbegin(); i != top_.rend(); ++i) row(*i);
  parallelFor(static_cast<int>(groups_.size()), [&](int g) {
    for (auto i = groups_[g].rbegin(); i != groups_[g].rend(); ++i) row(*i);
  });
}

void SubtreeParallelLdlt::forwardSweep(double* x, Eigen::Index columns) const {
  eigen_assert(m_factorizationIsOk && m_info == Eigen::Success);
  detail::byColumns(columns, [&](auto c) { forward<decltype(c)::value>(x, columns); });
}

void SubtreeParallelLdlt::backwardSweep(double* x, Eigen::Index columns, bool parallel) const {
  eigen_assert(m_factorizationIsOk && m_info == Eigen::Success);
  detail::byColumns(columns, [&](auto c) { backward<decltype(c)::value>(x, columns, parallel); });
}

}  // namespace rod
}  // namespace hindsight
