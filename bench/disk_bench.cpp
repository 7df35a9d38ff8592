// Disk, lossy and multilevel storage against full storage on a large-state problem: the 1-D heat
// equation with decay, z_i' = p0 (n+1)^2 (z_{i-1} - 2 z_i + z_{i+1}) - p1 z_i, z = 0 at both ends,
// n = 10000 unknowns, rk4 with 2000 fixed steps (160 MB of states), psi = int (1/2) dx |z|^2 dt.
// Every iteration makes a fresh storage and computes psi and dpsi/dp; full storage is the baseline
// in the same run. Counters: compression ratio, MB on disk, peak MB in memory, effective write and
// read throughput (uncompressed MB over the forward and backward sweep's wall time, I/O overlapped
// with computation), seconds of the I/O thread, relative gradient error against full storage;
// multilevel also: its schedule's seconds (recomputation and the disk I/O waited for) and the sweeps' wall
// seconds, with overlap=0 and 1 (docs/theory/storage.md, "Overlapped disk I/O").
//
//   ./build/bench/disk_bench --benchmark_repetitions=3 --benchmark_report_aggregates_only=true
#include <hindsight/engine/adjoint.h>
#include <hindsight/storage/storage_factory.h>

#include <benchmark/benchmark.h>

#include <cmath>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

namespace hindsight {
namespace {

constexpr int kUnknowns = 10000;
constexpr double kStep = 1e-3;
constexpr double kHorizon = 2.0;  // 2000 steps

class HeatEquation final : public Problem {
 public:
  explicit HeatEquation(int n) : n_(n), scale_(static_cast<double>(n + 1) * (n + 1)) {}
  std::string name() const override { return "heat-equation"; }
  int stateSize() const override { return n_; }
  int parameterSize() const override { return 2; }
  bool hasDenseJacobian() const override { return false; }
  void initialState(ConstVectorRef, VectorRef z0) const override {
    const double pi = std::acos(-1.0);
    for (int i = 0; i < n_; ++i) {
      const double x = (i + 1.0) / (n_ + 1.0);
      z0(i) = std::sin(pi * x) + 0.3 * std::sin(7 * pi * x) + 0.1 * std::sin(40 * pi * x);
    }
  }
  void rhs(double, ConstVectorRef z, ConstVectorRef p, VectorRef f, ProblemWorkspace*) const override {
    laplacian(z, f);
    f = p(0) * scale_ * f - p(1) * z;
  }
  void rhsStateVjp(double, ConstVectorRef, ConstVectorRef p, ConstVectorRef w, VectorRef out,
                   ProblemWorkspace*) const override {
    laplacian(w, out);  // the operator is symmetric
    out = p(0) * scale_ * out - p(1) * w;
  }
  void addRhsParameterVjp(double, ConstVectorRef z, ConstVectorRef, ConstVectorRef w, VectorRef out,
                          ProblemWorkspace*) const override {
    double dot = 0.0;
    for (int i = 0; i < n_; ++i) {
      const double left = i > 0 ? z(i - 1) : 0.0, right = i + 1 < n_ ? z(i + 1) : 0.0;
      dot += w(i) * (left - 2.0 * z(i) + right);
    }
    out(0) += scale_ * dot;
    out(1) -= w.dot(z);
  }
  double integrand(double, ConstVectorRef z, ConstVectorRef, ProblemWorkspace*) const override {
    return 0.5 * z.squaredNorm() / (n_ + 1.0);
  }
  void addIntegrandStateGradient(double, ConstVectorRef z, ConstVectorRef, double scale, VectorRef out,
                                 ProblemWorkspace*) const override {
    out += (scale / (n_ + 1.0)) * z;
  }
  void addIntegrandParameterGradient(double, ConstVectorRef, ConstVectorRef, double, VectorRef,
                                     ProblemWorkspace*) const override {}

 private:
  void laplacian(ConstVectorRef z, VectorRef out) const {
    for (int i = 0; i < n_; ++i) {
      const double left = i > 0 ? z(i - 1) : 0.0, right = i + 1 < n_ ? z(i + 1) : 0.0;
      out(i) = left - 2.0 * z(i) + right;
    }
  }
  int n_;
  double scale_;
};

struct Setup {
  HeatEquation problem{kUnknowns};
  Vector parameters = Eigen::Vector2d(1e-6, 0.5);  // diffusion number p0 h (n+1)^2 = 0.1: rk4-stable
  IntegratorOptions options;
  Vector referenceGradient;
  Setup() {
    options.method = "rk4";
    options.t1 = kHorizon;
    options.step = kStep;
    auto full = createStorage("full:budget=1GiB");
    referenceGradient = computeGradient(problem, parameters, options, *full).gradient;
  }
};

Setup& setup() {
  static Setup instance;
  return instance;
}

std::string scratchDirectory() {
  const auto dir = std::filesystem::temp_directory_path() / "hindsight-bench";
  std::filesystem::create_directories(dir);
  return dir.string();
}

void runStorage(benchmark::State& state, const std::string& spec) {
  Setup& s = setup();
  GradientResult result;
  StorageCounters counters;
  for (auto _ : state) {
    auto storage = createStorage(spec);
    result = computeGradient(s.problem, s.parameters, s.options, *storage);
    counters = storage->counters();
    benchmark::DoNotOptimize(result.gradient.data());
  }
  const double megabytes = static_cast<double>(result.summary.steps) * kUnknowns * 8 / 1e6;
  state.counters["ratio"] = counters.compressionRatio();
  state.counters["disk_MB"] = static_cast<double>(counters.bytesOnDisk) / 1e6;
  state.counters["peak_MB"] = static_cast<double>(counters.peakBytesInMemory) / 1e6;
  state.counters["write_MBps"] = megabytes / result.summary.forwardSeconds;
  state.counters["read_MBps"] = megabytes / result.summary.backwardSeconds;
  state.counters["io_s"] = counters.ioSeconds;
  state.counters["recomputed"] = static_cast<double>(counters.recomputedSteps);
  // multilevel: the schedule's seconds (recomputation + the disk I/O the main thread waited for).
  state.counters["schedule_s"] = counters.scheduleSeconds;
  state.counters["sweeps_s"] = result.summary.forwardSeconds + result.summary.backwardSeconds;
  state.counters["grad_err"] = (result.gradient - s.referenceGradient).norm() / s.referenceGradient.norm();
}

}  // namespace

/// The spec without its "dir=..." entry, for benchmark names.
std::string withoutDirectory(std::string spec) {
  const auto at = spec.find("dir=");
  if (at == std::string::npos) return spec;
  const auto end = spec.find(',', at);
  if (end == std::string::npos) {
    spec.erase(at - 1);
  } else {
    spec.erase(at, end - at + 1);
  }
  return spec;
}

}  // namespace hindsight

int main(int argc, char** argv) {
  const std::string dir = hindsight::scratchDirectory();
  const std::vector<std::string> specs = {
      "full:budget=1GiB",
      "disk:dir=" + dir + ",level=1",
      "disk:dir=" + dir,
      "multilevel:ram=32MiB,disk=64MiB,dir=" + dir,
      // The disk level's I/O waited for (overlap=0) and overlapped, same plans and bits
      // (docs/theory/storage.md, "Overlapped disk I/O"): writes that reach the device (sync=1; 13 RAM
      // slots of 80 KB, 136 disk writes and reads), and the page cache with 2 RAM slots (665 each).
      "multilevel:ram=1MiB,disk=64MiB,costs=1:1:4:1,sync=1,overlap=0,dir=" + dir,
      "multilevel:ram=1MiB,disk=64MiB,costs=1:1:4:1,sync=1,dir=" + dir,
      "multilevel:ram=200KiB,disk=64MiB,costs=1:1:1:1,overlap=0,dir=" + dir,
      "multilevel:ram=200KiB,disk=64MiB,costs=1:1:1:1,dir=" + dir,
      "lossy:codec=zfp,tolerance=1e-4",
      "lossy:codec=zfp,tolerance=1e-6",
      "lossy:codec=zfp,tolerance=1e-8",
      "lossy:codec=zfp,tolerance=1e-10",
      "lossy:codec=round,tolerance=1e-4",
      "lossy:codec=round,tolerance=1e-6",
      "lossy:codec=round,tolerance=1e-8",
      "lossy:codec=round,tolerance=1e-10",
  };
  for (const std::string& spec : specs) {
    const std::string label = hindsight::withoutDirectory(spec);
    benchmark::RegisterBenchmark(("heat10000_rk4_2000/" + label).c_str(), hindsight::runStorage, spec)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime()
        ->Iterations(1);
  }
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  std::filesystem::remove_all(dir);
  return 0;
}
