// A supernodal LDL^T factorisation P A P^T = L D L^T of a symmetric positive definite sparse matrix in
// METIS's nested-dissection ordering, with the same bits on every x86-64 CPU and for any thread count: the
// solid member's stiffness factor (modal_reduction.h, stiffnessOrdering).
//
// Why by hand: the solid's K (177 k DOFs at a 400 x 16 x 8 half mesh, 76 M nonzeros in L) took 68 s CPU
// in Eigen's up-looking SimplicialLDLT, which does scalar work one column at a time (bench/RESULTS.md, "The
// solid's gradient"). Supernodal factorisations do the same work as dense block products, 3-5 x faster,
// but no Debian package has one whose bits do not depend on the machine: CHOLMOD, MUMPS, PaStiX and
// SuperLU send their dense blocks to the BLAS that Debian's alternatives select at run time (reference,
// OpenBLAS, BLIS round differently; docs/guides/reproducibility.md), and their threads change the order of
// the sums. Here the dense blocks go through Eigen's own products, whose blocking is pinned at start-up
// (engine/dense_blocking.h) and whose kernels are fixed at compile time (SSE2 packets, no FMA): the same
// operands in the same order on every CPU.
//
// The method (Ng and Peyton 1993, "Block sparse Cholesky algorithms on advanced uniprocessor computers",
// SIAM J. Sci. Comput. 14(5); Davis 2006, "Direct Methods for Sparse Linear Systems", ch. 4 and 9):
// - Symbolic: METIS's ordering (metisOrdering), the elimination tree and the column counts of L (Liu's
//   algorithm, the row-subtree count), fundamental supernodes (column j + 1 joins j when it is j's parent
//   and has j's structure less j), then relaxed amalgamation: a supernode is merged into its parent while
//   the explicit zeros that adds stay below a fixed share (SupernodalOptions; fixed numbers, so the
//   structure is a function of the pattern). Each supernode is a dense column-major block of its rows
//   (its own columns first, then the rows below, increasing).
// - Numeric, left-looking: supernode s is assembled from A, then updated by each descendant d whose rows
//   reach s's columns, in increasing d (a list made by the symbolic phase, so the order is fixed):
//   C = L_d(rows >= s) D_d L_d(rows in s)^T by one Eigen product, subtracted from s's block through the
//   rows' positions; then the block is factorised in place by a blocked dense LDL^T without pivoting
//   (unblocked panels of kSupernodalPanel columns, the rest of the block updated by one product per panel).
// - Each supernode's arithmetic reads only finished descendants and writes only its own block, so
//   independent subtrees of the supernodal tree are factorised in parallel (partitionSubtrees) and the
//   bits do not depend on the partition, hence not on the thread count. The back-substitution runs on the
//   subtrees too; the forward substitution scatters into ancestors and runs serially.
// - Solves on blocks of right-hand sides stored by rows, supernode by supernode: the unit triangle on the
//   supernode's own rows (contiguous), and its rows below through a contiguous buffer, gathered or
//   scattered once (forward: y = L21 x_own, then x_below -= y; backward: x_own -= L21^T x_below, each dot
//   in four partial sums, then the triangle). Plain loops over rows and columns that the compiler
//   vectorises without reordering a sum, each column's arithmetic the same whatever the number of columns
//   (no product whose blocking depends on the block's width), so a block solve is bitwise the
//   column-by-column one. The column-by-column sweeps before them loaded and stored each x_r once per
//   column of L and ran the back-substitution as one chain of dependent subtractions; these take a solve
//   at 200 x 12 x 8 from 0.15 to 0.09 s CPU (bench/RESULTS.md, "Supernodal sweeps").
//
// The numeric phase allocates nothing: the blocks, the assembly map and the per-group workspaces (with the
// packing buffers of the blocked products, which Eigen would take from the heap above 128 KB) are made by
// analyzePattern.
#pragma once

#include <hindsight/problems/rod/subtree_ldlt.h>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <cstdint>
#include <vector>

namespace hindsight {
namespace rod {

/// The fixed numbers of the supernodal symbolic analysis (they decide the factor's bits: change them and
/// the solid's recorded results change).
struct SupernodalOptions {
  /// Relaxed amalgamation: a child supernode is merged into its parent when the merged block has at most
  /// `relaxedZeros` explicit zeros, or at most `relaxedShare` of its lower-triangle entries are zeros and
  /// the merged supernode has at most `relaxedColumns` columns.
  int relaxedZeros = 64;
  double relaxedShare = 0.1;
  int relaxedColumns = 96;
  /// Groups of subtrees factorised and back-substituted in parallel; 0: the threads hindsight::parallelFor
  /// may use at analysis time. Below `smallest` columns everything runs serially.
  int groups = 0;
  int smallest = 16384;
};

/// Rows below a supernode go through the sweeps' buffer (on the stack) in chunks of this many rows: a fixed
/// number, since the back-substitution's sums are rounded at the chunks' boundaries.
inline constexpr int kSupernodalSweepChunk = 256;

class SupernodalLdlt {
 public:
  using SparseMatrix = Eigen::SparseMatrix<double>;
  using Permutation = Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int>;

  explicit SupernodalLdlt(SupernodalOptions options = {}) : options_(options) {}
  /// METIS's ordering of the lower triangle of `a` (the rest is not read) and the symbolic analysis;
  /// allocates the factor and the workspaces. Throws std::invalid_argument for a non-square matrix and
  /// std::runtime_error when METIS fails.
  void analyzePattern(const SparseMatrix& a);
  /// The numeric factorisation of a matrix with the analysed pattern (compressed, the same outer starts and
  /// row indices). info() is Eigen::NumericalIssue on a zero or non-finite pivot.
  void factorize(const SparseMatrix& a);
  void compute(const SparseMatrix& a) {
    analyzePattern(a);
    factorize(a);
  }
  Eigen::ComputationInfo info() const { return info_; }
  Eigen::Index rows() const { return n_; }
  Eigen::Index cols() const { return n_; }

  /// P (old to new: (P b)_{P(i)} = b_i) and P^-1, as Eigen's SimplicialLDLT names them.
  const Permutation& permutationP() const { return p_; }
  const Permutation& permutationPinv() const { return pinv_; }
  /// D of L D L^T.
  const Eigen::VectorXd& vectorD() const { return d_; }

  /// L^-1 (unit lower) in place on `columns` right-hand sides stored by rows (x[i * columns + c]), in the
  /// permuted order. Serial. Each column bitwise the one-column sweep.
  void forwardSweep(double* x, Eigen::Index columns) const;
  /// L^-T (unit upper) in place, the same layout. On the subtrees in parallel when `parallel` (callers
  /// already inside a parallel loop pass false); the same bits either way.
  void backwardSweep(double* x, Eigen::Index columns, bool parallel) const;
  /// A^-1 B (detail::ldltSolveInPlace: P, L^-1, D^-1, L^-T, P^-1), bitwise the block solves' columns.
  Eigen::MatrixXd solve(const Eigen::Ref<const Eigen::MatrixXd>& b) const;

  /// Nonzeros of L as stored (the dense blocks' lower trapezoids, unit diagonal included), supernodes,
  /// and the share of the factorisation's work in the parallel subtrees: for benchmarks and tests.
  std::int64_t storedNonZeros() const;
  int supernodeCount() const { return static_cast<int>(first_.size()) - 1; }
  double parallelShare() const { return partition_.parallelShare; }
  /// The most rows below one supernode's columns: for tests that the sweeps' chunks are exercised.
  int tallestBelow() const;

 private:
  struct Update {
    int descendant;  // supernode d
    int begin, end;  // d's rows in the target's columns: positions [begin, end) of d's row list
  };
  // Supernode s as its kernels read it: its first column, its column count (width), its rows (its own
  // columns first) and its column-major block, whose leading dimension is `rows`.
  struct Geometry {
    int begin, width, rows;
    const int* rowList;
    std::int64_t blockStart;
  };
  Geometry geometry(int s) const {
    return Geometry{first_[s], first_[s + 1] - first_[s], rowStart_[s + 1] - rowStart_[s],
                    rows_.data() + rowStart_[s], blockStart_[s]};
  }
  struct Workspace {
    std::vector<int> position;        // row -> position in the current supernode's rows
    std::vector<int> relative;        // a descendant's rows -> positions in the current supernode's block
    Eigen::VectorXd scaled, product;  // D L^T of a panel or a descendant, and a descendant's update
    Eigen::VectorXd packA, packB;     // the blocked products' packing buffers (Eigen's blocking)
    bool failed = false;
  };
  void factorizeSupernode(int s, const double* values, Workspace& work);
  void factorizeRange(const std::vector<int>& supernodes, const double* values, Workspace& work);
  // One supernode of L^-1 or L^-T on a strip of C right-hand sides (supernodal_ldlt.cpp).
  template <int C, bool Packed>
  void forwardSupernode(int s, double* x, Eigen::Index stride) const;
  template <int C, bool Packed>
  void backwardSupernode(int s, double* x, Eigen::Index stride) const;

  SupernodalOptions options_;
  Eigen::Index n_ = 0;
  Permutation p_, pinv_;
  Eigen::VectorXd d_;
  // Supernode s: columns [first_[s], first_[s + 1]), rows rows_[rowStart_[s] .. rowStart_[s + 1]) (its own
  // columns first), block values_[blockStart_[s] ..] column-major with leading dimension its row count.
  std::vector<int> first_, rowStart_, rows_, parent_;
  std::vector<std::int64_t> blockStart_;
  Eigen::VectorXd values_;
  // Assembly: the entries of A's lower triangle go to supernode s's block at assemblyTarget_[k] from A's
  // value assemblySource_[k], for k in [assemblyStart_[s], assemblyStart_[s + 1]).
  std::vector<std::int64_t> assemblyStart_, assemblyTarget_;
  std::vector<int> assemblySource_;
  // The updates of supernode s: updates_[updateStart_[s] .. updateStart_[s + 1]), increasing descendants.
  std::vector<std::int64_t> updateStart_;
  std::vector<Update> updates_;
  // The pattern analysed (checked by factorize).
  std::vector<int> outer_, inner_;
  SubtreePartition partition_;
  std::vector<Workspace> workspaces_;  // one per group, the last for the top
  Eigen::ComputationInfo info_ = Eigen::InvalidInput;
};

}  // namespace rod
}  // namespace hindsight
