// Why `cams` keeps step records rather than the stage values of the last recomputed step.
//
// binomial/online with stages=1 keep two step records of scratch (engine/recomputed_stages.h): the stages
// of the last step a restore recomputed serve the next adjoint step. A plan built around that trick would
// place checkpoints so that positions are reached by advancing: an adjoint step e then recomputes its
// stages only when x_{e+1} was loaded rather than advanced into. This program computes that plan's
// optimum exactly (an O(N^2 M) dynamic program over state checkpoints, with a flag for "the interval's last
// step has its stages") and compares it with the cams optimum (engine/cams_checkpointing.h) at the same
// bytes, where the scratch takes 2 (w - 1) of the M = C + 1 state units (w = 4 for rk4), and with the
// scratch for free. Usage: cams_scratch_model N C [C ...]   (N up to a few thousand: exhaustive search)
#include <hindsight/engine/cams_checkpointing.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <vector>

namespace {

using I = std::int64_t;

/// Step evaluations (forward, recomputed, adjoint stage recomputations) of the best plan with M state units
/// (x_0 included) and the scratch records on top.
I scratchOptimum(I N, I M) {
  if (M < 1) return -1;
  // F: replay interval, H: interval the forward sweep ran through; index [f][m][l], f = the stages of the
  // interval's last step are held.
  std::vector<I> F(2 * static_cast<std::size_t>((M + 1) * (N + 1))), H(F.size());
  const auto at = [&](std::vector<I>& t, int f, I m, I l) -> I& {
    return t[(static_cast<std::size_t>(f) * static_cast<std::size_t>(M + 1) + static_cast<std::size_t>(m)) *
                 static_cast<std::size_t>(N + 1) +
             static_cast<std::size_t>(l)];
  };
  // No checkpoint: deliver l - 1 (advance l - 1, its stages held or recomputed), then every e < l - 1 by
  // advancing e steps, its stages left behind by the delivery of e + 1.
  const auto replay = [](I l, int f) { return (l - 1) + (f ? 0 : 1) + (l - 2) * (l - 1) / 2; };
  for (I m = 0; m <= M; ++m) {
    for (int f = 0; f < 2; ++f) at(F, f, m, 1) = at(H, f, m, 1) = f ? 0 : 1;
    for (I l = 2; l <= N; ++l) {
      for (int f = 0; f < 2; ++f) {
        I b = replay(l, f), h = replay(l, f);
        if (m >= 1) {
          for (I k = 1; k < l; ++k) {
            // The left part's last step has its stages only if x_k was advanced into just before (a right
            // part of one step in a replay interval); the forward sweep stored x_k without advancing.
            b = std::min(b, k + at(F, f, m - 1, l - k) + at(F, l - k == 1 ? 1 : 0, m, k));
            h = std::min(h, at(H, f, m - 1, l - k) + at(F, 0, m, k));
          }
        }
        at(F, f, m, l) = b;
        at(H, f, m, l) = h;
      }
    }
  }
  return N + at(H, 1, M - 1, N);  // x_0 held; the forward sweep's last step leaves its stages
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: %s N C [C ...]\n", argv[0]);
    return 2;
  }
  const I N = std::atoll(argv[1]);
  const I w = 4;  // rk4: the state and three stage states
  std::printf(
      "| N | C | cams (records) | scratch, same bytes | scratch, bytes for free |\n|---|---|---|---|---|\n");
  for (int i = 2; i < argc; ++i) {
    const I C = std::atoll(argv[i]);
    const I cams = hindsight::cams::Plan(N, C + 1, w).optimalStepEvaluations();
    const I same = scratchOptimum(N, C + 1 - 2 * (w - 1));
    const I free = scratchOptimum(N, C + 1);
    std::printf("| %lld | %lld | %lld | %s%lld | %lld |\n", static_cast<long long>(N),
                static_cast<long long>(C), static_cast<long long>(cams), same < 0 ? "no room " : "",
                static_cast<long long>(same), static_cast<long long>(free));
  }
  return 0;
}
