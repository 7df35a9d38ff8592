#include <hindsight/problems/rod/compensated_kernels.h>

#include <cmath>
#include <cstdlib>
#include <stdexcept>
#include <string>

namespace hindsight {
namespace rod {

#if defined(HINDSIGHT_FMA_KERNELS)
// compensated_kernels_fma.cpp
void fmaElementProducts(const double* unit, int rows, const double* x, int columns, double* product,
                        double* high, double* low);
void fmaSparseUpdate(int outerSize, const int* outer, const int* inner, const double* values, const double* x,
                     int columns, double* high, double* low);
#endif

namespace {

#include "compensated_kernels.inc"

// a * b - product exactly for product = fl(a * b), by Veltkamp's split and Dekker's product (Dekker,
// "A floating-point technique for extending the available precision", Numer. Math. 18, 1971): the
// value std::fma(a, b, -product) gives, whenever the split cannot overflow and no partial product
// leaves the normal range (the callers' `dekker`). On the baseline x86-64 target std::fma is a call into
// libm; this is plain arithmetic that stays in registers and vectorises.
struct DekkerError {
  double operator()(double a, double b, double product) const {
    constexpr double kSplitter = 134217729.0;  // 2^27 + 1
    double t = kSplitter * a;
    const double aHigh = t - (t - a), aLow = a - aHigh;
    t = kSplitter * b;
    const double bHigh = t - (t - b), bLow = b - bHigh;
    return ((aHigh * bHigh - product) + aHigh * bLow + aLow * bHigh) + aLow * bLow;
  }
};

struct LibraryFmaError {
  double operator()(double a, double b, double product) const { return std::fma(a, b, -product); }
};

bool cpuHasFma() {
#if defined(HINDSIGHT_FMA_KERNELS)
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
#else
  return false;
#endif
}

void requireAvailable(KernelIsa isa) {
  if (!kernelIsaAvailable(isa))
    throw std::invalid_argument(
        "compensated kernels: the FMA kernels are not available here (this build or this CPU lacks AVX2 "
        "and FMA); use KernelIsa::Baseline");
}

}  // namespace

bool kernelIsaAvailable(KernelIsa isa) {
  static const bool fma = cpuHasFma();
  return isa == KernelIsa::Baseline || fma;
}

KernelIsa kernelIsaFromSetting(const char* setting) {
  const std::string value = setting == nullptr ? "" : setting;
  if (value.empty() || value == "auto")
    return kernelIsaAvailable(KernelIsa::Fma) ? KernelIsa::Fma : KernelIsa::Baseline;
  if (value == "baseline") return KernelIsa::Baseline;
  if (value == "fma") {
    if (!kernelIsaAvailable(KernelIsa::Fma))
      throw std::invalid_argument(
          "HINDSIGHT_KERNELS = fma: this build or this CPU has no AVX2 and FMA kernels; allowed here: auto, "
          "baseline");
    return KernelIsa::Fma;
  }
  throw std::invalid_argument("HINDSIGHT_KERNELS = '" + value +
                              "' is not one of the allowed values auto, baseline, fma");
}

KernelIsa defaultKernelIsa() {
  static const KernelIsa isa = kernelIsaFromSetting(std::getenv("HINDSIGHT_KERNELS"));
  return isa;
}

void compensatedElementProducts(const double* unit, int rows, const double* x, int columns, bool dekker,
                                double* product, double* high, double* low, KernelIsa isa) {
  requireAvailable(isa);
  if (rows != 8 && rows != 24)
    throw std::invalid_argument("compensatedElementProducts: rows = " + std::to_string(rows) +
                                " is outside the allowed range {8, 24}");
#if defined(HINDSIGHT_FMA_KERNELS)
  if (isa == KernelIsa::Fma) return fmaElementProducts(unit, rows, x, columns, product, high, low);
#endif
  if (rows == 8) {
    if (dekker)
      elementProducts<8>(unit, x, columns, product, high, low, DekkerError());
    else
      elementProducts<8>(unit, x, columns, product, high, low, LibraryFmaError());
  } else if (dekker) {
    elementProducts<24>(unit, x, columns, product, high, low, DekkerError());
  } else {
    elementProducts<24>(unit, x, columns, product, high, low, LibraryFmaError());
  }
}

void compensatedSparseUpdate(int outerSize, const int* outer, const int* inner, const double* values,
                             const double* x, int columns, bool dekker, double* high, double* low,
                             KernelIsa isa) {
  requireAvailable(isa);
#if defined(HINDSIGHT_FMA_KERNELS)
  if (isa == KernelIsa::Fma) return fmaSparseUpdate(outerSize, outer, inner, values, x, columns, high, low);
#endif
  if (dekker)
    sparseUpdate(outerSize, outer, inner, values, x, columns, high, low, DekkerError());
  else
    sparseUpdate(outerSize, outer, inner, values, x, columns, high, low, LibraryFmaError());
}

}  // namespace rod
}  // namespace hindsight
