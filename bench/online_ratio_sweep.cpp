// `online`'s worst ratio to the offline optimum over every run length N <= NMAX, in one forward sweep.
//
// `online:checkpoints=C` in a run of the engine (the caller's working state holds x_{N-1}) places its
// checkpoints record by record without knowing N (internal::TwoHorizonPlacement, engine/online_placement.h)
// and reverses interval i by revolve with C + 1 - i slots. The placement after the record x_{N-1} is the
// one a run of N steps ends with (a run of N steps offers x_1 .. x_{N-1}), so one sweep of records
// 1 .. NMAX - 1 gives the cost of every N <= NMAX: the intervals before the last one change only when a
// record is stored, the last one (p_m to N - 1) grows by one step per record. The ratio is the one
// docs/theory/storage.md states, (2N + online's recomputed steps) / (2N + binomial's at the same memory,
// T(N, S) - (N - 1), S = min(C + 1, N - 1)); bench/online_working_state.py is the exact Python reference
// for N <= 10^5 (its --rule), which this tool extends to N = 10^7 and beyond in C++.
//
// Every `--check` records the sweep's cost is compared with OnlineCheckpointing::predictedForwardSteps
// (the engine's own prediction, which simulates the placement from scratch): the tool stops with exit 1
// on a difference, so the figures it prints are the engine's.
//
//   online_ratio_sweep --steps 10000000 --checkpoints 2-16,20,24,32,48,64 [--check 1000003]
//
// Prints one line per C: the worst ratio, the N where it occurs (the least such N), the ratio at NMAX
// and the largest ratio over N in the last decade (NMAX/10, NMAX], which shows the trend.
#include <hindsight/engine/binomial_checkpointing.h>
#include <hindsight/engine/online_checkpointing.h>
#include <hindsight/engine/online_placement.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

using hindsight::UnsignedInt128;
using hindsight::internal::intervalForwardSteps;
using hindsight::internal::PlacementCost;
using hindsight::internal::TwoHorizonPlacement;

struct Worst {
  long double ratio = 0.0L;
  std::int64_t steps = 0;
  long double lastDecade = 0.0L;
  long double atEnd = 0.0L;
  std::int64_t checks = 0;
};

// "2-16,20,32" -> {2, 3, ..., 16, 20, 32}.
std::vector<std::int64_t> parseList(const std::string& text) {
  std::vector<std::int64_t> values;
  std::stringstream stream(text);
  std::string item;
  while (std::getline(stream, item, ',')) {
    const std::size_t dash = item.find('-');
    const std::int64_t first = std::stoll(item.substr(0, dash));
    const std::int64_t last = dash == std::string::npos ? first : std::stoll(item.substr(dash + 1));
    if (first < 1 || last < first || last > hindsight::BinomialCheckpointing::kMaxCheckpoints)
      throw std::invalid_argument("--checkpoints: each C must be in [1, " +
                                  std::to_string(hindsight::BinomialCheckpointing::kMaxCheckpoints) +
                                  "], ranges increasing: '" + item + "'");
    for (std::int64_t c = first; c <= last; ++c) values.push_back(c);
  }
  if (values.empty()) throw std::invalid_argument("--checkpoints: no value");
  return values;
}

Worst sweep(std::int64_t c, std::int64_t maxSteps, std::int64_t checkEvery) {
  TwoHorizonPlacement placement;
  placement.reset(c);
  Worst worst;
  // The intervals before the last one, sum_{i < m} T(L_i, c + 1 - i), recomputed after each store.
  PlacementCost prefix = 0;
  const auto refreshPrefix = [&] {
    const std::vector<std::int64_t>& p = placement.positions();
    prefix = 0;
    for (std::size_t i = 0; i + 1 < p.size(); ++i)
      prefix += intervalForwardSteps(p[i + 1] - p[i], c + 1 - static_cast<std::int64_t>(i));
  };
  for (std::int64_t steps = 2; steps <= maxSteps; ++steps) {
    // The record x_{N-1}; then the placement is a run of N steps'.
    if (placement.offer(steps - 1) != TwoHorizonPlacement::kSkipped) refreshPrefix();
    const std::vector<std::int64_t>& p = placement.positions();
    const auto m = static_cast<std::int64_t>(p.size()) - 1;
    const PlacementCost recomputed = prefix + intervalForwardSteps(steps - 1 - p.back(), c + 1 - m);
    if (checkEvery > 0 && (steps % checkEvery == 0 || steps == maxSteps)) {
      const UnsignedInt128 engine = hindsight::OnlineCheckpointing::predictedForwardSteps(steps, c, true) -
                                    static_cast<UnsignedInt128>(steps - 1);
      if (engine != static_cast<UnsignedInt128>(recomputed)) {
        std::fprintf(stderr,
                     "C = %lld, N = %lld: the sweep gives %s recomputed steps, the engine's prediction %s\n",
                     static_cast<long long>(c), static_cast<long long>(steps),
                     hindsight::revolve::toString(static_cast<UnsignedInt128>(recomputed)).c_str(),
                     hindsight::revolve::toString(engine).c_str());
        std::exit(1);
      }
      ++worst.checks;
    }
    const UnsignedInt128 optimum = hindsight::internal::binomialAtSameMemory(steps, c);
    const long double twice = 2.0L * static_cast<long double>(steps);
    const long double ratio =
        (twice + static_cast<long double>(recomputed)) / (twice + static_cast<long double>(optimum));
    if (ratio > worst.ratio) {
      worst.ratio = ratio;
      worst.steps = steps;
    }
    if (steps > maxSteps / 10 && ratio > worst.lastDecade) worst.lastDecade = ratio;
    if (steps == maxSteps) worst.atEnd = ratio;
  }
  return worst;
}

}  // namespace

int main(int argc, char** argv) {
  std::int64_t maxSteps = 100000, checkEvery = 0;
  std::string list = "2-12";
  try {
    for (int i = 1; i < argc; ++i) {
      const std::string flag = argv[i];
      if (i + 1 >= argc) throw std::invalid_argument(flag + " needs a value");
      const std::string value = argv[++i];
      if (flag == "--steps") {
        maxSteps = std::stoll(value);
        if (maxSteps < 2 || maxSteps > (std::int64_t{1} << 40))
          throw std::invalid_argument("--steps must be in [2, 2^40]: " + value);
      } else if (flag == "--checkpoints") {
        list = value;
      } else if (flag == "--check") {
        checkEvery = std::stoll(value);
        if (checkEvery < 0) throw std::invalid_argument("--check must be >= 0 (0: no check): " + value);
      } else {
        throw std::invalid_argument("unknown flag " + flag + " (--steps, --checkpoints, --check)");
      }
    }
    const std::vector<std::int64_t> checkpoints = parseList(list);
    std::printf("online (two-horizon rule, working state), every N in [2, %lld]\n",
                static_cast<long long>(maxSteps));
    std::printf("%6s %12s %14s %22s %14s %7s\n", "C", "worst ratio", "at N", "worst in last decade",
                "ratio at NMAX", "checks");
    for (const std::int64_t c : checkpoints) {
      const Worst worst = sweep(c, maxSteps, checkEvery);
      std::printf("%6lld %12.6Lf %14lld %22.6Lf %14.6Lf %7lld\n", static_cast<long long>(c), worst.ratio,
                  static_cast<long long>(worst.steps), worst.lastDecade, worst.atEnd,
                  static_cast<long long>(worst.checks));
      std::fflush(stdout);
    }
  } catch (const std::exception& error) {
    std::fprintf(stderr, "online_ratio_sweep: %s\n", error.what());
    return 2;
  }
  return 0;
}
