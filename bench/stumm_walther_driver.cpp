// Runs Stumm & Walther's online checkpointing (their revolve code, class Revolve in online mode:
// Online_r2, Online_r3, then Moin; not part of hindsight, the user supplies its source) for N steps
// that it does not know in advance, and prints the forward steps it takes.
//
// The driving protocol is revolve's: call revolve() until `terminate`; while online, the schedule
// advances and takes checkpoints; as soon as the current state reaches x_{N-1} the caller, which now
// knows that the next step is the last, calls turn(N) and the offline reversal follows. getadvances()
// then counts every forward step (the first sweep's N - 1 included), the quantity revolve's numforw()
// gives for the offline optimum T(N, c).
//
// Usage: stumm_walther_driver SNAPS N...   prints one line "SNAPS N advances numforw" per N.
#include "revolve.h"

#include <cstdio>
#include <cstdlib>

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: %s SNAPS N...\n", argv[0]);
    return 2;
  }
  const int snaps = std::atoi(argv[1]);
  for (int k = 2; k < argc; ++k) {
    const int steps = std::atoi(argv[k]);
    Revolve schedule(snaps);
    bool turned = false;
    for (long actions = 0;; ++actions) {
      const ACTION::action action = schedule.revolve();
      if (action == ACTION::terminate) break;
      if (action == ACTION::error || actions > 1000000000L) {
        std::fprintf(stderr, "revolve failed for snaps = %d, N = %d\n", snaps, steps);
        return 1;
      }
      if (!turned && schedule.getcapo() >= steps - 1) {
        schedule.turn(steps);
        turned = true;
      }
    }
    std::printf("RESULT %d %d %d %d\n", snaps, steps, schedule.getadvances(), numforw(steps, snaps));
  }
  return 0;
}
