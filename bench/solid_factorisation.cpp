// The solid member's linear algebra at production size (bench/RESULTS.md, "The solid member"): assembly
// of K and M, the sparse factorisation of K on the pinned-roller support (joint axes A and B, u_z held on
// the symmetry plane), Eigen's SimplicialLDLT (AMD ordering) against CHOLMOD's supernodal LL^T (its
// default ordering choice: AMD, then METIS when AMD's fill is large), and Spectra's shift-and-invert
// Lanczos for the lowest modes with the faster factorisation. A measurement, not a timing benchmark
// fixture: each phase runs once (the factorisations take seconds) and prints CPU and wall seconds, the
// factor's nonzeros and the process's peak resident memory.
//
// CHOLMOD's simplicial LDL^T (cholmod-simplicial: CHOLMOD's ordering choice; cholmod-simplicial-metis:
// METIS forced) calls no BLAS, so unlike the supernodal factorisation its bits do not depend on the BLAS
// the system selects: the bit-safe way to METIS's smaller fill (bench/RESULTS.md, "The solid's gradient").
// simplicial-metis is the production's factorisation of the solid: Eigen's SimplicialLDLT in METIS's
// ordering (rod::SubtreeParallelLdlt with FillOrdering::Metis, problems/rod/subtree_ldlt.h) until
// supernodal replaced it: hindsight's own supernodal LDL^T in METIS's ordering (rod::SupernodalLdlt,
// problems/rod/supernodal_ldlt.h, dense blocks through Eigen's products: the same bits on every machine),
// timed as analysis + factorisation, a second numeric factorisation (what each design of an optimisation
// pays) and one solve.
//
// Usage: solid_factorisation NX NY NZ SYMMETRIC(0|1) SOLVERS MODES, SOLVERS a comma-separated list of
// simplicial, simplicial-metis, supernodal, cholmod, cholmod-simplicial, cholmod-simplicial-metis
#include <hindsight/problems/rod/solid_model.h>
#include <hindsight/problems/rod/subtree_ldlt.h>
#include <hindsight/problems/rod/supernodal_ldlt.h>

#include <Spectra/MatOp/SparseSymMatProd.h>
#include <Spectra/SymGEigsShiftSolver.h>
#include <Eigen/SparseCholesky>
#ifdef HINDSIGHT_WITH_CHOLMOD
#include <Eigen/CholmodSupport>
#endif

#include <sys/resource.h>

#include <chrono>
#include <cstdio>
#include <ctime>
#include <iostream>
#include <string>
#include <vector>

namespace {

using hindsight::Vector;
using hindsight::rod::SparseMatrix;

struct Clock {
  std::clock_t cpu = std::clock();
  std::chrono::steady_clock::time_point wall = std::chrono::steady_clock::now();
  void report(const char* phase) const {
    const double cpuSeconds = double(std::clock() - cpu) / CLOCKS_PER_SEC;
    const double wallSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall).count();
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    std::printf("%-34s cpu %8.2f s  wall %8.2f s  peak RSS %7.0f MB\n", phase, cpuSeconds, wallSeconds,
                usage.ru_maxrss / 1024.0);
    std::fflush(stdout);
  }
};

template <typename Factor>
class ShiftInvert {
 public:
  using Scalar = double;
  ShiftInvert(const SparseMatrix& stiffness, const SparseMatrix& mass, Factor& factor)
      : stiffness_(stiffness), mass_(mass), factor_(factor) {}
  Eigen::Index rows() const { return stiffness_.rows(); }
  Eigen::Index cols() const { return stiffness_.cols(); }
  void set_shift(double sigma) {
    factor_.compute(SparseMatrix(stiffness_ - sigma * mass_));
    if (factor_.info() != Eigen::Success) throw std::runtime_error("factorisation of K - sigma M failed");
  }
  void perform_op(const double* in, double* out) const {
    Eigen::Map<Vector>(out, rows()) = factor_.solve(Eigen::Map<const Vector>(in, rows()));
    ++solves;
  }
  mutable int solves = 0;

 private:
  const SparseMatrix& stiffness_;
  const SparseMatrix& mass_;
  Factor& factor_;
};

template <typename Factor>
void eigenSolve(const SparseMatrix& stiffness, const SparseMatrix& mass, int modes, Factor& factor,
                const char* name) {
  const Clock clock;
  ShiftInvert<Factor> op(stiffness, mass, factor);
  Spectra::SparseSymMatProd<double> massProduct(mass);
  Spectra::SymGEigsShiftSolver<ShiftInvert<Factor>, Spectra::SparseSymMatProd<double>,
                               Spectra::GEigsMode::ShiftInvert>
      solver(op, massProduct, modes, 2 * modes + 1, -1.0);
  solver.init();
  const Eigen::Index converged = solver.compute(Spectra::SortRule::LargestMagn, 1000, 1e-10);
  const std::string label = std::string("eigen-solve (") + name + ")";
  clock.report(label.c_str());
  Vector values = solver.eigenvalues();
  std::printf("  %ld of %d modes converged, %d solves; lowest frequencies [Hz]:", long(converged), modes,
              op.solves);
  for (Eigen::Index i = values.size() - 1; i >= 0; --i)
    std::printf(" %.3f", std::sqrt(std::max(values(i), 0.0)) / (2.0 * 3.14159265358979323846));
  std::printf("\n");
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 7) {
    std::cerr << "usage: solid_factorisation NX NY NZ SYMMETRIC(0|1) "
                 "SOLVERS(simplicial,simplicial-metis,supernodal,cholmod,cholmod-simplicial,cholmod-"
                 "simplicial-metis) MODES\n";
    return 2;
  }
  hindsight::rod::RodConfig config;
  config.elementsAlongLength = std::stoi(argv[1]);
  config.elementsThroughHeight = std::stoi(argv[2]);
  hindsight::rod::SolidMeshOptions options;
  options.elementsThroughThickness = std::stoi(argv[3]);
  options.midPlaneSymmetry = std::string(argv[4]) == "1";
  const std::string solvers = "," + std::string(argv[5]) + ",";
  auto asked = [&](const std::string& name) { return solvers.find("," + name + ",") != std::string::npos; };
  const int modes = std::stoi(argv[6]);
  const int designs = hindsight::rod::SolidModel::designCountOf(config, options);

  Clock clock;
  const hindsight::rod::SolidModel model(config, options, Vector::Constant(designs, config.initialDesign));
  clock.report("assemble K, M");
  std::vector<int> fixed = model.symmetryConstrainedDofs();
  for (int node : model.jointANodes()) {
    fixed.push_back(3 * node);
    fixed.push_back(3 * node + 1);
  }
  for (int node : model.jointBNodes()) fixed.push_back(3 * node + 1);
  // The pin's axis runs through the thickness: holding u_x, u_y along it also holds the tilts about x and
  // y; the translation along z is still free, so the pin holds u_z too (its axial restraint).
  for (int node : model.jointANodes()) fixed.push_back(3 * node + 2);
  clock = Clock();
  const SparseMatrix stiffness = hindsight::rod::removeDofs(model.stiffness(), fixed);
  const SparseMatrix mass = hindsight::rod::removeDofs(model.mass(), fixed);
  clock.report("remove supported DOFs");
  std::printf("elements %d (designs %d), free DOFs %ld, nonzeros of K %ld\n", model.elementCount(), designs,
              long(stiffness.rows()), long(stiffness.nonZeros()));

  // Eigen's simplicial factorisation in one ordering: its time, its fill and the eigen-solve with it.
  const auto simplicial = [&](auto& factor, const char* phase, const char* solver) {
    clock = Clock();
    factor.compute(stiffness);
    clock.report(phase);
    std::printf("  info %d, L nonzeros %ld\n", int(factor.info()),
                long(factor.matrixL().nestedExpression().nonZeros()));
    if (modes > 0) eigenSolve(stiffness, mass, modes, factor, solver);
  };
  if (asked("simplicial")) {
    Eigen::SimplicialLDLT<SparseMatrix> factor;
    simplicial(factor, "SimplicialLDLT (AMD) of K", "SimplicialLDLT");
  }
  if (asked("simplicial-metis")) {
    hindsight::rod::SubtreeParallelLdlt factor({}, hindsight::rod::FillOrdering::Metis);
    simplicial(factor, "SimplicialLDLT (METIS) of K", "SimplicialLDLT, METIS");
  }
  if (asked("supernodal")) {
    hindsight::rod::SupernodalLdlt factor;
    clock = Clock();
    factor.compute(stiffness);
    clock.report("supernodal LDL^T (METIS) of K");
    std::printf("  info %d, supernodes %d, L entries stored %lld, share in parallel subtrees %.2f\n",
                int(factor.info()), factor.supernodeCount(), static_cast<long long>(factor.storedNonZeros()),
                factor.parallelShare());
    clock = Clock();
    factor.factorize(stiffness);
    clock.report("  numeric factorisation again");
    clock = Clock();
    const Eigen::MatrixXd x = factor.solve(Vector::Ones(stiffness.rows()));
    clock.report("  one solve");
    // The sweeps' cost against the block's width: a one-column sweep streams the whole factor for one
    // right-hand side, so what a block eigensolver would save is the per-column cost at its width.
    for (const Eigen::Index width : {1, 2, 4, 8, 11, 16, 24}) {
      Eigen::MatrixXd block = Eigen::MatrixXd::Ones(width, stiffness.rows());  // by rows: x[i * width + c]
      const int repeats = width <= 4 ? 4 : 2;
      Clock sweeps;
      for (int r = 0; r < repeats; ++r) {
        factor.forwardSweep(block.data(), width);
        factor.backwardSweep(block.data(), width, false);
      }
      const double seconds = double(std::clock() - sweeps.cpu) / CLOCKS_PER_SEC / repeats;
      std::printf("  L^-1 and L^-T on %2ld columns: cpu %6.3f s, %6.4f s a column\n", long(width), seconds,
                  seconds / double(width));
    }
    if (modes > 0) eigenSolve(stiffness, mass, modes, factor, "supernodal");
  }
#ifdef HINDSIGHT_WITH_CHOLMOD
  for (const bool metis : {false, true}) {
    if (!asked(metis ? "cholmod-simplicial-metis" : "cholmod-simplicial")) continue;
    Eigen::CholmodSimplicialLDLT<SparseMatrix> factor;
    if (metis) {
      factor.cholmod().nmethods = 1;
      factor.cholmod().method[0].ordering = CHOLMOD_METIS;
    }
    clock = Clock();
    factor.compute(stiffness);
    clock.report(metis ? "CHOLMOD simplicial LDL^T, METIS" : "CHOLMOD simplicial LDL^T");
    const cholmod_common& common = factor.cholmod();
    std::printf("  info %d, ordering %d (0 natural, 1 given, 2 AMD, 3 METIS, 4 NESDIS), L nonzeros %.0f\n",
                int(factor.info()), int(common.method[common.selected].ordering), common.lnz);
    if (modes > 0) eigenSolve(stiffness, mass, modes, factor, "CHOLMOD simplicial");
  }
  if (asked("cholmod")) {
    Eigen::CholmodSupernodalLLT<SparseMatrix> factor;
    clock = Clock();
    factor.compute(stiffness);
    clock.report("CHOLMOD supernodal LL^T of K");
    const cholmod_common& common = factor.cholmod();
    std::printf("  info %d, ordering %d (0 natural, 1 given, 2 AMD, 3 METIS, 4 NESDIS), L nonzeros %.0f\n",
                int(factor.info()), int(common.method[common.selected].ordering), common.lnz);
    if (modes > 0) eigenSolve(stiffness, mass, modes, factor, "CHOLMOD supernodal");
  }
#else
  if (solvers.find(",cholmod") != std::string::npos)
    std::printf("built without CHOLMOD (libsuitesparse-dev)\n");
#endif
  return 0;
}
