// The two double-double kernels of the modal refinement (modal_reduction.h: compensatedResidual and
// elementwiseStiffnessForm), on raw arrays, built twice: for the x86-64 baseline (SSE2; each product's
// rounding error by Dekker's split) and, in a second translation unit, for AVX2 with FMA (the error by one
// fused multiply-add, four columns per instruction). Both compute every entry with the same operations
// in the same order, and a product's error a * b - fl(a * b) is exact either way, so the two give the
// same bits: the machine picks the faster one and results stay those of any other x86-64 CPU. A
// compiler may not reorder strict IEEE arithmetic, so the wider vectors change nothing but the speed;
// the FMA unit is used only where the source says fma (-ffp-contract=off, CMakeLists.txt).
#pragma once

namespace hindsight {
namespace rod {

/// The instruction sets the kernels are built for.
enum class KernelIsa { Baseline, Fma };

/// True when this build has the kernels for `isa` and this CPU can run them (Baseline: always; Fma:
/// an x86-64 build with GCC or Clang on a CPU with AVX2 and FMA).
bool kernelIsaAvailable(KernelIsa isa);

/// The kernels a setting of the environment variable HINDSIGHT_KERNELS asks for: unset, empty or "auto":
/// Fma where available, else Baseline; "baseline": Baseline (to check on one machine that both give the
/// same bits); "fma": Fma. Throws std::invalid_argument naming the variable for any other value, and for
/// "fma" where kernelIsaAvailable(KernelIsa::Fma) is false.
KernelIsa kernelIsaFromSetting(const char* setting);

/// kernelIsaFromSetting(getenv("HINDSIGHT_KERNELS")), read once per process (the first call that
/// succeeds).
KernelIsa defaultKernelIsa();

/// product[a + r c] = sum_{b = 0..r-1} unit[a + r b] x[b * columns + c] (unit: an r x r element matrix,
/// column-major, r = rows: 8 for the plate's quadrilateral, 24 for the solid's hexahedron; x: r rows of
/// `columns`, row-major), each sum accumulated in double-double over b in
/// increasing order (two-sum of the rounded products, their exact errors added to the low part) and
/// rounded once. `dekker` (Baseline only): every entry of unit and x is zero or of magnitude in
/// [2^-480, 2^480], where Dekker's split is exact; otherwise the baseline takes each error from std::fma.
/// high, low: scratch of `columns` doubles. Throws std::invalid_argument for an ISA kernelIsaAvailable()
/// denies or rows outside {8, 24}.
void compensatedElementProducts(const double* unit, int rows, const double* x, int columns, bool dekker,
                                double* product, double* high, double* low, KernelIsa isa);

/// (high, low) <- (high, low) - A X in double-double, for A in compressed column storage (outerSize
/// columns: outer[k] .. outer[k + 1] - 1 index inner and values) and X row-major (outerSize rows of
/// `columns`); high and low are row-major with A's rows. For every entry the terms come in increasing
/// column k of A, and a zero x(k, c) adds nothing (as a skipped term). `dekker` as above, for the values
/// of A and the entries of X.
void compensatedSparseUpdate(int outerSize, const int* outer, const int* inner, const double* values,
                             const double* x, int columns, bool dekker, double* high, double* low,
                             KernelIsa isa);

}  // namespace rod
}  // namespace hindsight
