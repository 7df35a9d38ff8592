// The AVX2 and FMA build of the kernels (compensated_kernels.h): compiled with -mavx2 -mfma
// -ffp-contract=off (CMakeLists.txt) and called only on a CPU that has both (compensated_kernels.cpp).
#if defined(HINDSIGHT_FMA_KERNELS)

namespace hindsight {
namespace rod {
namespace {

#include "compensated_kernels.inc"

struct FusedError {
  double operator()(double a, double b, double product) const { return __builtin_fma(a, b, -product); }
};

}  // namespace

void fmaElementProducts(const double* unit, int rows, const double* x, int columns, double* product,
                        double* high, double* low) {
  if (rows == 8)
    elementProducts<8>(unit, x, columns, product, high, low, FusedError());
  else
    elementProducts<24>(unit, x, columns, product, high, low, FusedError());
}

void fmaSparseUpdate(int outerSize, const int* outer, const int* inner, const double* values, const double* x,
                     int columns, double* high, double* low) {
  sparseUpdate(outerSize, outer, inner, values, x, columns, high, low, FusedError());
}

}  // namespace rod
}  // namespace hindsight

#endif
