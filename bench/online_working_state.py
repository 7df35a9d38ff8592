#!/usr/bin/env python3
"""`online` in a run of the engine, where the caller's working state holds x_{N-1}
(TrajectoryInfo.workingStateHoldsLast, engine/binomial_checkpointing.h): what an online rule can reach.

The game. online:checkpoints=C holds C + 1 states. With the engine's working state it needs no working copy
of its own: its C + 1 slots hold positions p_0 = 0 < p_1 < ... < p_m (m <= C), each record x_k stored at
once (into a free slot, or replacing p_j, j >= 1) or not, while N is unknown. Once N is known the interval
i (from p_i to p_{i+1}, the last one to N - 1) is reversed by revolve with the C + 1 - i slots not holding
p_0..p_{i-1}: sum_i T(L_i, C + 1 - i) recomputed steps (engine/online_checkpointing.h's game with one slot
more). The offline optimum at the same memory is binomial's count, T(N, S) - (N - 1), S = min(C + 1, N - 1).
The ratio asked for is (2N + online) / (2N + optimum).

  --exhaustive C NMAX   the least ratio any online rule guarantees for every N <= NMAX (every sequence of
                        decisions searched; exact rational bounds, bisection to 1e-3)
  --first C             the least NMAX at which 1.10 is out of reach for every online rule (if below 200)
  --rule NMAX           the worst ratio of the two-horizon rule below for C = 1..12 and N <= NMAX

The two-horizon rule: at record k, among keeping the placement, storing x_k in a free slot and replacing
p_j by it, take the one whose worse ratio, were the run to end at N = k + 1 or N = k + 2, is least
(ties: keep, then store in a free slot, then the least j). Storing moves cost the same at both horizons
(the new last interval has 0 or 1 steps), so a record costs O(1) evaluations of T and a store O(C).

Measured (this script): --first 1 -> 6: with C = 1 (x_0 and one other state) no online rule stays within
1.10 for every N <= 6; --exhaustive 1 400: the least any rule guarantees is 7/6 (1.1667); --exhaustive 2 80:
between 1.0869 and 1.0879. The rule, --rule 100000 (every N <= 10^5, 40 s): C = 1: 7/6 at N = 5 (the least
possible); C = 2: 1.0909 (N = 20); C = 3: 1.0625; C = 4: 1.0556; C = 5: 1.0649; C = 6..12: 1.052 down to
1.033; never above Stumm & Walther's count. At C = 2, N = 32 it recomputes 63 steps (binomial 62; online
without the working state 85), at C = 1, N = 14: 23 (binomial 23; online without it 32). The engine's
`online` plays this rule (engine/online_placement.h, TwoHorizonPlacement; tests/storage/
online_checkpointing_test.cpp compares its counts with this script's).
"""
import argparse
import sys
from fractions import Fraction
from functools import lru_cache
from math import comb


def beta(c, r):
    return comb(c + r, c) if r >= 0 else 0


@lru_cache(maxsize=1 << 20)
def revolve_steps(length, slots):
    """T(L, s): forward steps of revolve over L positions with s slots (engine/binomial_checkpointing.h)."""
    if length <= 1:
        return 0
    if slots == 1:
        return length * (length - 1) // 2
    r = 0
    while beta(slots, r) < length:
        r += 1
    return r * length - beta(slots + 1, r - 1)


def optimum(n, c):
    """binomial's recomputed steps with C + 1 slots and the working state (T(N, S) - (N - 1))."""
    return 0 if n <= 1 else revolve_steps(n, min(c + 1, n - 1)) - (n - 1)


def placement_cost(positions, n, c):
    total = 0
    for i, p in enumerate(positions):
        end = positions[i + 1] if i + 1 < len(positions) else n - 1
        total += revolve_steps(end - p, c + 1 - i)
    return total


def ratio(cost, n, c):
    return Fraction(2 * n + cost, 2 * n + optimum(n, c))


def guarantees(c, nmax, bound):
    """Whether some online rule keeps ratio <= bound for every N <= nmax (exhaustive search)."""
    sys.setrecursionlimit(max(10_000, 4 * nmax))

    @lru_cache(maxsize=None)
    def win(k, positions):  # positions decided after the record of x_k; the run may end here (N = k + 1)
        n = k + 1
        if ratio(placement_cost(positions, n, c), n, c) > bound:
            return False
        if n == nmax:
            return True
        q = k + 1
        moves = [positions]
        if len(positions) < c + 1:
            moves.append(positions + (q,))
        moves += [positions[:j] + positions[j + 1:] + (q,) for j in range(1, len(positions))]
        return any(win(q, m) for m in moves)

    return win(0, (0,))


def least_guarantee(c, nmax):
    lo, hi = Fraction(1), Fraction(2)
    while hi - lo > Fraction(1, 1000):
        mid = (lo + hi) / 2
        if guarantees(c, nmax, mid):
            hi = mid
        else:
            lo = mid
    return lo, hi


class TwoHorizonRule:
    """The rule of the module comment, with the incremental costs of engine/online_placement.h's cost rule."""

    def __init__(self, c):
        self.c = c
        self.p = [0]
        self._rebuild()

    def _rebuild(self):
        c, p = self.c, self.p
        m = len(p) - 1
        self.own = [revolve_steps(p[i + 1] - p[i], c + 1 - i) for i in range(m)]
        self.prefix = sum(self.own)
        grow = [revolve_steps(p[i + 1] - p[i], c + 2 - i) - self.own[i] for i in range(m)]
        suffix = [0] * (m + 1)
        for i in range(m - 1, -1, -1):
            suffix[i] = suffix[i + 1] + grow[i]
        # Replacing p_j, 1 <= j < m, without the last interval's part: min and least j reaching it.
        self.inner = None
        for j in range(1, m):
            value = (self.prefix - self.own[j - 1] - self.own[j] +
                     revolve_steps(p[j + 1] - p[j - 1], c + 2 - j) + suffix[j + 1])
            if self.inner is None or value < self.inner[0]:
                self.inner = (value, j)

    def offer(self, k):
        """The record of x_k; returns the cost were the run to end at N = k + 1."""
        c, p = self.c, self.p
        m = len(p) - 1
        last = k - p[-1]
        keep = [self.prefix + revolve_steps(last + h, c + 1 - m) for h in (0, 1)]
        store = None  # (cost, move): move -1 appends, j replaces p_j
        if m < c:
            store = (self.prefix + revolve_steps(last, c + 1 - m), -1)
        if self.inner is not None:
            value = self.inner[0] + revolve_steps(last, c + 2 - m)
            if store is None or value < store[0]:
                store = (value, self.inner[1])
        if m >= 1:
            value = self.prefix - self.own[m - 1] + revolve_steps(p[m] - p[m - 1] + last, c + 2 - m)
            if store is None or value < store[0]:
                store = (value, m)
        if store is not None:
            keep_score = max(ratio(keep[h], k + 1 + h, c) for h in (0, 1))
            store_score = max(ratio(store[0], k + 1 + h, c) for h in (0, 1))
            if store_score < keep_score:
                if store[1] >= 1:
                    del p[store[1]]
                p.append(k)
                self._rebuild()
                return store[0]
        return keep[0]


def worst_of_rule(c, nmax, check=False):
    """The worst ratio (and its N) of the rule for N <= nmax, and the N at which it recomputes more than
    Stumm & Walther's count T(N, C) - (N - 1) (C snapshots and the current state)."""
    rule = TwoHorizonRule(c)
    worst, above = (Fraction(1), 1), []
    for k in range(1, nmax):
        cost = rule.offer(k)
        if check:
            assert cost == placement_cost(rule.p, k + 1, c), (c, k, rule.p)
        n = k + 1
        r = ratio(cost, n, c)
        if r > worst[0]:
            worst = (r, n)
        if n >= 2 and cost > revolve_steps(n, c) - (n - 1):
            above.append(n)
    return worst, above


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--exhaustive", nargs=2, type=int, metavar=("C", "NMAX"))
    parser.add_argument("--first", type=int, metavar="C")
    parser.add_argument("--rule", type=int, metavar="NMAX")
    parser.add_argument("--check", action="store_true", help="recompute every cost from scratch (slow)")
    args = parser.parse_args()
    if args.exhaustive:
        c, nmax = args.exhaustive
        lo, hi = least_guarantee(c, nmax)
        print(f"C = {c}, N <= {nmax}: every online rule exceeds {float(lo):.4f} somewhere; "
              f"some rule stays within {float(hi):.4f}")
    if args.first is not None:
        for nmax in range(2, 200):
            if not guarantees(args.first, nmax, Fraction(11, 10)):
                print(f"C = {args.first}: no online rule stays within 1.10 for every N <= {nmax}")
                break
        else:
            print(f"C = {args.first}: 1.10 is within reach for every N < 200")
    if args.rule:
        for c in range(1, 13):
            (r, n), above = worst_of_rule(c, args.rule, args.check)
            print(f"C = {c:2d}: worst (2N + online) / (2N + binomial) = {float(r):.4f} at N = {n}; "
                  f"above Stumm & Walther at {len(above)} N{(' (first ' + str(above[0]) + ')') if above else ''}",
                  flush=True)


if __name__ == "__main__":
    main()
