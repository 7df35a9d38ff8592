// Prints two FNV-1a hashes over 200 000 results each of sin, cos, asin, exp, pow and tanh: those of
// glibc's libm and those of hindsight::dmath (engine/deterministic_math.h). cpu_variants.py runs it
// under emulated CPUs (GLIBC_TUNABLES): the libm hash moving shows that the emulation reaches glibc's
// CPU-specific code paths on this machine, so that the equal hindsight results beside it mean
// something; the dmath hash must never move.
#include <hindsight/engine/deterministic_math.h>
#include <hindsight/engine/hash.h>

#include <cmath>
#include <cstdint>
#include <cstdio>

namespace {

// volatile: keeps the compiler from folding or vectorising the library calls differently per variant.
volatile double sink;

template <typename Function>
void hashOver(Function f, std::uint64_t& hash) {
  for (int i = 0; i < 200000; ++i) {
    const double x = -1.0 + 2.0 * (i + 0.5) / 200000.0;  // (-1, 1): every function's domain
    const double y = f(x);
    sink = y;
    hash = hindsight::fnv1a(&y, sizeof y, hash);
  }
}

}  // namespace

int main() {
  std::uint64_t libm = hindsight::kFnv1aOffsetBasis, dmath = hindsight::kFnv1aOffsetBasis;
  hashOver([](double x) { return std::sin(7.0 * x); }, libm);
  hashOver([](double x) { return std::cos(7.0 * x); }, libm);
  hashOver([](double x) { return std::asin(0.999 * x); }, libm);
  hashOver([](double x) { return std::exp(20.0 * x); }, libm);
  hashOver([](double x) { return std::pow(1.0 + x * x, 2.5 + x); }, libm);
  hashOver([](double x) { return std::tanh(5.0 * x); }, libm);
  hashOver([](double x) { return hindsight::dmath::sin(7.0 * x); }, dmath);
  hashOver([](double x) { return hindsight::dmath::cos(7.0 * x); }, dmath);
  hashOver([](double x) { return hindsight::dmath::asin(0.999 * x); }, dmath);
  hashOver([](double x) { return hindsight::dmath::exp(20.0 * x); }, dmath);
  hashOver([](double x) { return hindsight::dmath::pow(1.0 + x * x, 2.5 + x); }, dmath);
  hashOver([](double x) { return hindsight::dmath::tanh(5.0 * x); }, dmath);
  std::printf("libm %016llx\ndmath %016llx\n", static_cast<unsigned long long>(libm),
              static_cast<unsigned long long>(dmath));
  return 0;
}
