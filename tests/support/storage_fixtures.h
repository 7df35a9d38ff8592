// Shared helpers for storage tests: a scratch directory per test, the two reference runs (pendulum
// with fixed-step rk4 and with adaptive trbdf2), bitwise comparison of gradients against "full".
#pragma once

#include <hindsight/engine/adjoint.h>
#include <hindsight/engine/full_storage.h>
#include <hindsight/problems/classic/classic_problems.h>

#include "support/same_bits.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>

namespace hindsight::testing {

/// A fresh directory under the system temp directory, removed with everything in it.
class ScratchDirectory {
 public:
  ScratchDirectory() {
    std::string pattern = (std::filesystem::temp_directory_path() / "hindsight-test-XXXXXX").string();
    if (::mkdtemp(pattern.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
    path_ = pattern;
  }
  ~ScratchDirectory() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  ScratchDirectory(const ScratchDirectory&) = delete;
  ScratchDirectory& operator=(const ScratchDirectory&) = delete;
  const std::string& path() const { return path_; }
  /// Number of entries in the directory.
  std::size_t entryCount() const {
    std::size_t count = 0;
    for ([[maybe_unused]] const auto& entry : std::filesystem::directory_iterator(path_)) ++count;
    return count;
  }

 private:
  std::string path_;
};

inline Vector pendulumParameters() { return Eigen::Vector4d(1.5, 0.8, 0.3, 1.2); }

/// Pendulum, rk4 with a fixed step: N = 2000 known in advance.
inline IntegratorOptions fixedStepRk4() {
  IntegratorOptions options;
  options.method = "rk4";
  options.t1 = 4.0;
  options.step = 2e-3;
  return options;
}

/// Pendulum, adaptive trbdf2: N unknown in advance.
inline IntegratorOptions adaptiveTrBdf2() {
  IntegratorOptions options;
  options.method = "trbdf2";
  options.t1 = 4.0;
  options.adaptive = true;
  options.step = 1e-3;
  options.relativeTolerance = 1e-8;
  options.absoluteTolerance = 1e-10;
  return options;
}

inline GradientResult fullReference(const Problem& problem, const Vector& p,
                                    const IntegratorOptions& options) {
  FullStorage storage;
  return computeGradient(problem, p, options, storage);
}

/// psi and every bit of dpsi/dp equal.
inline ::testing::AssertionResult bitwiseEqual(const GradientResult& a, const GradientResult& b) {
  if (a.gradient.size() != b.gradient.size()) return ::testing::AssertionFailure() << "gradient sizes differ";
  if (std::memcmp(&a.objective, &b.objective, sizeof(double)) != 0)
    return ::testing::AssertionFailure() << "psi differs: " << a.objective << " vs " << b.objective;
  if (::testing::AssertionResult gradients = sameBits(a.gradient, b.gradient); !gradients)
    return ::testing::AssertionFailure() << "gradients differ: " << gradients.message();
  if (a.times != b.times) return ::testing::AssertionFailure() << "time grids differ";
  return ::testing::AssertionSuccess();
}

/// A recomputer for storages that must not recompute.
struct ForbiddenRecomputer final : StepRecomputer {
  void advance(std::int64_t, VectorRef) override { ADD_FAILURE() << "this storage must not recompute"; }
};

}  // namespace hindsight::testing
