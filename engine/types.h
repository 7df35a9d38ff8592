// Common vocabulary of hindsight: vector aliases and the exceptions that carry numerical failures.
//
// Failure kinds (docs/design.md P 4): bad user input throws std::invalid_argument naming the
// argument, its value and the allowed range; a numerical outcome (Newton divergence, step-size
// underflow, I/O failure) throws hindsight::NumericalError or hindsight::StorageError, which carry
// the simulation time or the file involved; internal bugs are asserts.
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <stdexcept>
#include <string>

namespace hindsight {

using Vector = Eigen::VectorXd;
using Matrix = Eigen::MatrixXd;
using VectorRef = Eigen::Ref<Eigen::VectorXd>;
using ConstVectorRef = const Eigen::Ref<const Eigen::VectorXd>&;
using MatrixRef = Eigen::Ref<Eigen::MatrixXd>;
using ConstMatrixRef = const Eigen::Ref<const Eigen::MatrixXd>&;

/// A numerical failure during a simulation (Newton divergence, step-size underflow, non-finite
/// state). `time()` is the simulation time at which it happened.
class NumericalError : public std::runtime_error {
 public:
  NumericalError(const std::string& what, double time)
      : std::runtime_error(what + " (at t = " + std::to_string(time) + ")"), time_(time) {}
  double time() const { return time_; }

 private:
  double time_;
};

/// A failure of trajectory storage: unwritable directory, full disk, corrupted or truncated file,
/// exhausted byte budget. `path()` names the file when one is involved.
class StorageError : public std::runtime_error {
 public:
  explicit StorageError(const std::string& what, std::string path = {})
      : std::runtime_error(path.empty() ? what : what + " [file: " + path + "]"), path_(std::move(path)) {}
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

/// The library version, "MAJOR.MINOR.PATCH".
const char* version();

}  // namespace hindsight
