// Eigen's dense matrix products, pinned to one blocking on every CPU.
//
// Eigen's general matrix-matrix product (and every dense product large enough to take that path:
// Spectra's Lanczos, the modal reduction's projections, the Ritz vectors) splits its inner sums into
// panels whose depth follows the cache sizes Eigen reads from the CPU at run time (cpuid, Eigen's
// queryCacheSizes). A panel boundary is a place where a partial sum is rounded and added to the
// result, so the same product of the same matrices gives other bits on a CPU with another L1 or L2:
// measured on the default piston rod, ψ1(x0) ends in ...624 with a 32 KiB L1 and in ...607 with
// 48 KiB, and the optimisation that follows ends elsewhere (docs/guides/reproducibility.md).
//
// hindsight therefore sets the sizes Eigen plans with to fixed values in every program and shared
// object that links the engine: a static initializer in dense_blocking.cpp runs pinDenseBlocking()
// when the object is loaded, and the engine's link interface forces that object into every link
// (the CMake target's --undefined anchor, CMakeLists.txt), so a program that never names it still
// gets it. Eigen keeps its cache sizes in a static of its own headers, i.e. one copy per shared
// object with hidden symbols (the Python module): each such object links the engine and so pins
// its own copy.
//
// The pinned L1 and L2 are what the CPU of the machine the results were first recorded on reports (AMD
// EPYC: 32 KiB, 512 KiB), the L3 that machine's kernel reports (32 MiB; Eigen reads 256 MiB there, which
// gives the same ψ1(x0), as does a 2 MiB L2 with a 105 MiB L3). Any fixed values would do; these keep
// the recorded bits (tests/reproducibility/record.json). What it costs: docs/guides/reproducibility.md.
#pragma once

#include <cstddef>
#include <optional>
#include <string>

namespace hindsight {

/// Cache sizes in bytes, as Eigen's product blocking reads them.
struct CacheSizes {
  std::ptrdiff_t l1 = 0;
  std::ptrdiff_t l2 = 0;
  std::ptrdiff_t l3 = 0;
  bool operator==(const CacheSizes& other) const {
    return l1 == other.l1 && l2 == other.l2 && l3 == other.l3;
  }
};

/// The sizes every hindsight process hands Eigen, whatever its CPU reports.
inline constexpr CacheSizes kPinnedCacheSizes{32 * 1024, 512 * 1024, 32 * 1024 * 1024};

/// Sets Eigen's cache sizes in this shared object to kPinnedCacheSizes. Idempotent and cheap; runs by
/// itself when the object is loaded, and may be called again (e.g. after user code changed them).
void pinDenseBlocking();

/// The cache sizes Eigen's products in this shared object plan with now.
CacheSizes denseBlockingCacheSizes();

/// What this CPU reports to Eigen (its own cpuid query), i.e. what Eigen would have used unpinned.
CacheSizes cpuReportedCacheSizes();

/// HINDSIGHT_EMULATE_CPU_CACHES="L1,L2,L3" (bytes, each in [1024, 2^40]), a testing aid: the sizes are
/// handed to Eigen as if the CPU had reported them, before the pin, so that a test can run the same
/// binary as on a CPU with other caches (tests/reproducibility/cpu_variants.py). Returns the parsed
/// sizes, nothing when the variable is unset or empty; throws std::invalid_argument naming the variable
/// and the allowed form otherwise.
std::optional<CacheSizes> emulatedCacheSizesFromSetting(const char* value);

/// "32 KiB L1, 512 KiB L2, 32768 KiB L3": for reports.
std::string describeCacheSizes(const CacheSizes& sizes);

}  // namespace hindsight
