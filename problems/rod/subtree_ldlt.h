// Eigen's SimplicialLDLT (lower triangle; AMD's ordering or METIS's nested dissection) with its
// triangular sweeps on row-major blocks of right-hand sides, and the back-substitution L^-T run on
// independent subtrees of the elimination tree in parallel, bitwise equal to Eigen's serial sweep for any
// number of threads.
//
// Why by hand: the eigen-solve's Lanczos iteration solves with K's factor one vector at a time, and at
// production meshes (1600 x 96: a 300 MB factor) those sweeps are a serial step of every design. The
// back-substitution is a chain of dot products, each a sequence of dependent additions, so one core
// waits on the adder; no Debian package runs it on several cores with bits independent of the machine
// (CHOLMOD's supernodal solves call the run-time-selected BLAS, docs/guides/performance.md; PETSc's
// and SuperLU's threads change the order of the sums).
//
// Why the bits cannot change: in the elimination tree parent(i) is the first row below the diagonal of
// column i of L, so parent(i) > i and the rows of column i are ancestors of i. Eigen's L^T x = y runs
// row by row, x_i -= L(r, i) x_r over column i in storage order, so row i reads its ancestors only: the
// rows above a set of disjoint subtrees (the top) run first, in decreasing index, then each subtree on
// its own, in decreasing index. Every row computes the same sum of the same operands in the same order.
//
// The factorisation and the forward sweep stay serial: measured at 1600 x 96, the up-looking
// factorisation leaves 42 % of its work above the subtrees (AMD's elimination tree of a long strip
// ends in a long chain), and the forward sweep, column-oriented scatters, is bound by memory bandwidth
// that a second core shares; neither ran faster on two cores (bench/RESULTS.md).
#pragma once

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include <type_traits>
#include <vector>

namespace hindsight {
namespace rod {

/// The fill-reducing ordering of the factorisation. Both are deterministic functions of the pattern
/// (METIS with its fixed seed), so the bits of the factor do not depend on the machine; they differ from
/// each other, so a member's choice is part of its recorded bits (modal_reduction.h, stiffnessOrdering).
enum class FillOrdering {
  /// Eigen's approximate minimum degree (Eigen::AMDOrdering): Eigen's own SimplicialLDLT, bit for bit.
  Amd,
  /// METIS 5's nested dissection (METIS_NodeND, default options): on the slender 3-D bars of the solid
  /// member 28-35 % fewer nonzeros in L than AMD, and its separators split the elimination tree into
  /// large independent subtrees (bench/RESULTS.md, "The solid's gradient").
  Metis,
};

/// METIS_NodeND's ordering of the symmetric matrix whose lower triangle `lower` holds (the diagonal and
/// the upper triangle are not read), as Eigen's ordering functors return it: the permutation from the
/// new order to the old (row i of P A P^T is row indices()(i) of A). Throws std::runtime_error when
/// METIS fails (out of memory) rather than fall back to another ordering, which would change the bits.
Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> metisOrdering(
    const Eigen::SparseMatrix<double>& lower);

/// How the elimination tree is shared out for the parallel back-substitution. The partition decides
/// only which rows run at the same time, never a bit of the result.
struct SubtreeSchedule {
  /// Groups of subtrees run in parallel; 0: the threads hindsight::parallelFor may use at analysis time.
  int groups = 0;
  /// Below this order a sweep takes well under a millisecond and runs serially.
  int smallest = 16384;
};

/// Disjoint subtrees of a forest shared out over groups that run in parallel, and the nodes above them.
/// Used by the simplicial factor's back-substitution (rows) and by the supernodal factor (supernodes,
/// supernodal_ldlt.h): a node's descendants are in its own group or, for a top node, anywhere.
struct SubtreePartition {
  /// Nodes of each group in increasing index (non-empty groups only).
  std::vector<std::vector<int>> groups;
  /// The nodes above the subtrees, in increasing index.
  std::vector<int> top;
  /// Share of the work in the groups (0 when the forest was not split).
  double parallelShare = 0.0;
};

/// Splits the heaviest subtree (its root joins the top) until every subtree holds at most 1/(8 T) of the
/// total work, then shares the subtrees out onto T = `threads` groups, longest first. `parent[i]` > i or
/// -1 (a root); `work[i]` >= 0 is node i's own work. Ties go by index, so the partition is a function of
/// the forest, the work and T alone; it decides which nodes run at the same time, never a bit of a result.
SubtreePartition partitionSubtrees(const std::vector<int>& parent, const std::vector<double>& work,
                                   int threads);

namespace detail {

/// Calls call(std::integral_constant<int, C>()) with C = columns for 1..8 (so that loops over the
/// columns of a block of right-hand sides unroll: with a run-time count of 2-10 a loop's set-up costs more
/// than its arithmetic), C = 0 (run-time count) otherwise.
template <class Call>
void byColumns(Eigen::Index columns, Call&& call) {
  switch (columns) {
    case 1:
      return call(std::integral_constant<int, 1>());
    case 2:
      return call(std::integral_constant<int, 2>());
    case 3:
      return call(std::integral_constant<int, 3>());
    case 4:
      return call(std::integral_constant<int, 4>());
    case 5:
      return call(std::integral_constant<int, 5>());
    case 6:
      return call(std::integral_constant<int, 6>());
    case 7:
      return call(std::integral_constant<int, 7>());
    case 8:
      return call(std::integral_constant<int, 8>());
    default:
      return call(std::integral_constant<int, 0>());
  }
}

/// L D L^T's solve in place on right-hand sides stored by rows (one row per unknown, `scratch` sized to
/// `block`): x = P b; x = L^-1 x; x_i = (1 / d_i) x_i; x = L^-T x; b = P^-1 x -- Eigen's
/// SimplicialLDLT::solve column by column, bitwise, for a factor with Eigen's sweeps (SubtreeParallelLdlt),
/// and the same steps for the supernodal factor (supernodal_ldlt.h).
template <class Factor, class RowBlock>
void ldltSolveInPlace(const Factor& factor, RowBlock& block, RowBlock& scratch) {
  const Eigen::Index columns = block.cols();
  scratch.noalias() = factor.permutationP() * block;
  factor.forwardSweep(scratch.data(), columns);
  const auto& d = factor.vectorD();
  for (Eigen::Index i = 0; i < block.rows(); ++i) scratch.row(i) *= 1.0 / d(i);
  factor.backwardSweep(scratch.data(), columns, false);
  block.noalias() = factor.permutationPinv() * scratch;
}

}  // namespace detail

class SubtreeParallelLdlt : public Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> {
 public:
  using SparseMatrix = Eigen::SparseMatrix<double>;
  explicit SubtreeParallelLdlt(SubtreeSchedule options = {}, FillOrdering ordering = FillOrdering::Amd)
      : options_(options), ordering_(ordering) {}
  /// analyzePattern(a) and factorize(a) (Eigen's).
  explicit SubtreeParallelLdlt(const SparseMatrix& a, SubtreeSchedule options = {},
                               FillOrdering ordering = FillOrdering::Amd);
  /// The ordering and Eigen's symbolic analysis, then the schedule of the subtrees.
  void analyzePattern(const SparseMatrix& a);
  void compute(const SparseMatrix& a) {
    analyzePattern(a);
    factorize(a);
  }
  /// L^-1 (unit lower) in place on `columns` right-hand sides stored by rows (x[i * columns + c]):
  /// bitwise Eigen's matrixL().solveInPlace() on each column. Serial.
  void forwardSweep(double* x, Eigen::Index columns) const;
  /// L^-T (unit upper) in place, the same layout: bitwise Eigen's matrixU().solveInPlace() on each
  /// column. On the subtrees in parallel when `parallel` (callers already inside a parallel loop pass
  /// false).
  void backwardSweep(double* x, Eigen::Index columns, bool parallel) const;
  /// Share of the sweep's entries in the parallel subtrees (0 when the tree was not split: a small
  /// matrix or one thread): for the benchmarks and tests.
  double parallelShare() const { return parallelShare_; }
  FillOrdering ordering() const { return ordering_; }

 private:
  template <int Columns>
  void forward(double* x, Eigen::Index columns) const;
  template <int Columns>
  void backward(double* x, Eigen::Index columns, bool parallel) const;

  SubtreeSchedule options_;
  FillOrdering ordering_ = FillOrdering::Amd;
  // Rows of each group in increasing index (the groups run in parallel, each in decreasing index) and
  // the rows above them (run first, in decreasing index).
  std::vector<std::vector<int>> groups_;
  std::vector<int> top_;
  double parallelShare_ = 0.0;
};

}  // namespace rod
}  // namespace hindsight
