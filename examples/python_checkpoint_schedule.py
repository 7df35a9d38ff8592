#!/usr/bin/python3
# %% [markdown]
# # Checkpointing your own time-stepper with hindsight's schedules
#
# A host code with a stepper of its own -- here a 1-D reaction-diffusion equation
#     u_t = kappa u_xx - u^3   on (0, 1), u = 0 at both ends,
# explicit Euler in NumPy, nothing of hindsight's engine -- computes the gradient of
#     J(kappa) = sum_{k=1..N} dt * (h/2) |u_k|^2
# by its own discrete adjoint, reversing the run by the actions of hindsight.checkpoint_schedule
# (docs/guides/checkpoint_schedule.md): Forward, Reverse, Copy, Move, EndForward, EndReverse, with storage
# RAM, DISK (files in a scratch directory) or WORK; "online" is also run as a host that decides N itself
# (steps=None, finalize inside a Forward, state checkpoints). Every strategy must give the gradient of "full"
# bit for bit (recomputed steps repeat the same arithmetic), and "full" must agree with central finite
# differences.
#
#     PYTHONPATH=build/python python3 examples/python_checkpoint_schedule.py [--steps 400]

# %%
import argparse
import os
import tempfile

import numpy as np

import hindsight
from hindsight import Copy, EndForward, EndReverse, Forward, Move, Reverse, StorageType

parser = argparse.ArgumentParser(description="gradients of a NumPy stepper driven by hindsight's schedules")
parser.add_argument("--steps", type=int, default=400, help="time steps N")
parser.add_argument("--cells", type=int, default=64, help="interior grid points")
args, _ = parser.parse_known_args()  # parse_known_args: also runs in a notebook kernel


# %% The host's own model: a stepper, the objective's increment and the adjoint of one step.
class ReactionDiffusion:
    def __init__(self, cells, steps, t1=0.05):
        self.n = cells
        self.h = 1.0 / (cells + 1)
        self.dt = t1 / steps
        x = np.linspace(self.h, 1.0 - self.h, cells)
        self.u0 = np.sin(np.pi * x) + 0.5 * np.sin(3 * np.pi * x)

    def laplacian(self, u):
        padded = np.concatenate(([0.0], u, [0.0]))
        return (padded[:-2] - 2.0 * u + padded[2:]) / self.h**2

    def step(self, u, kappa):
        return u + self.dt * (kappa * self.laplacian(u) - u**3)

    def objective_increment(self, u):  # dt * (h/2) |u|^2, for every u_k with k >= 1
        return self.dt * 0.5 * self.h * float(u @ u)

    def adjoint_step(self, u, lam, kappa):
        """Given u_k and lam = dJ/du_{k+1}: (dJ/du_k through this step, dJ/dkappa of this step). The
        Laplacian is symmetric, so its transpose is itself."""
        dkappa = self.dt * float(lam @ self.laplacian(u))
        lam_k = lam + self.dt * (kappa * self.laplacian(lam) - 3.0 * u**2 * lam)
        return lam_k, dkappa


# %% The host loop: one function per action, as checkpoint_schedules' users write it.
class Host:
    """Runs a schedule's actions under checkpoint_schedules' contract: a checkpoint (RAM, or DISK in .npz
    files) holds what one Forward wrote -- the state it started from (restart data) and/or the states its
    steps' adjoints need -- and WORK holds the state being advanced and the adjoint data of the steps
    reversed next. Counts the steps it advances. schedule: a stream opened with steps=None; the host ends
    its forward run at step `stop`, inside a Forward, and calls schedule.finalize(stop). Its restart data is
    the state itself, so it also runs streams of state checkpoints (restart_data == "state"), whose
    Move(n, RAM, NONE) releases a checkpoint."""

    def __init__(self, model, kappa, directory, schedule=None, stop=None):
        self.model, self.kappa, self.directory = model, kappa, directory
        self.schedule, self.stop = schedule, stop
        self.stored = {StorageType.RAM: {}, StorageType.DISK: {}}
        self.work_deps = {}  # step -> u_k, for the Reverse that follows
        self.n, self.u = 0, model.u0.copy()  # WORK: the state at the start of step n
        self.objective, self.gradient, self.lam = 0.0, 0.0, None
        self.forward_done, self.advanced = False, 0

    def put(self, storage, n, ics, deps):
        if storage == StorageType.DISK:
            path = os.path.join(self.directory, f"checkpoint_{n}.npz")
            arrays = {f"deps_{k}": u for k, u in deps.items()}
            if ics is not None:
                arrays["ics"] = ics
            np.savez(path, **arrays)
            self.stored[storage][n] = path
        else:
            self.stored[storage][n] = (ics, deps)

    def get(self, storage, n, release):
        data = self.stored[storage].pop(n) if release else self.stored[storage][n]
        if storage != StorageType.DISK:
            return data[0], dict(data[1])
        with np.load(data) as f:
            ics = f["ics"] if "ics" in f.files else None
            deps = {int(name[5:]): f[name] for name in f.files if name.startswith("deps_")}
        if release:
            os.remove(data)
        return ics, deps

    def forward(self, a):
        assert self.n == a.n0, f"{a}: WORK holds the start of step {self.n}"
        start, deps = self.u.copy(), {}
        deciding = self.schedule is not None and self.schedule.max_n is None
        end = min(a.n1, self.stop) if deciding else a.n1  # the host's own forward run ends at `stop`
        for k in range(a.n0, end):
            if a.write_adj_deps:
                deps[k] = self.u.copy()  # this adjoint needs u_k only
            self.u = self.model.step(self.u, self.kappa)
            self.advanced += 1
            if not self.forward_done:
                self.objective += self.model.objective_increment(self.u)
        if a.storage in (StorageType.RAM, StorageType.DISK):
            self.put(a.storage, a.n0, start if a.write_ics else None, deps)
            self.work_deps = {}
        else:
            self.work_deps = deps
        self.n = end
        if deciding and end == self.stop:
            self.schedule.finalize(end)

    def end_forward(self, a):
        self.forward_done = True
        self.lam = self.model.dt * self.model.h * self.u  # dJ/du_N

    def reverse(self, a):
        for k in range(a.n1 - 1, a.n0 - 1, -1):
            u_k = self.work_deps[k]
            self.lam, dkappa = self.model.adjoint_step(u_k, self.lam, self.kappa)
            self.gradient += dkappa
            if k >= 1:
                self.lam = self.lam + self.model.dt * self.model.h * u_k  # J's term in u_k
        if a.clear_adj_deps:
            self.work_deps = {}

    def copy(self, a, release=False):
        ics, deps = self.get(a.from_storage, a.n, release)
        if a.to_storage == StorageType.NONE:  # a release (state checkpoints only)
            assert self.schedule is not None and self.schedule.restart_data == "state", a
        elif a.to_storage == StorageType.WORK:
            self.work_deps = deps
            if ics is not None:
                self.n, self.u = a.n, ics
        else:
            self.put(a.to_storage, a.n, ics, deps)

    def run(self, actions):
        handlers = {Forward: self.forward, Reverse: self.reverse, Copy: self.copy,
                    Move: lambda a: self.copy(a, release=True), EndForward: self.end_forward}
        for action in actions:
            if type(action) is EndReverse:
                return self
            handlers[type(action)](action)
        raise RuntimeError("the schedule ended without EndReverse")


def gradient(spec, model, kappa, stages=1, unknown_n=False):
    with tempfile.TemporaryDirectory() as directory:
        actions = hindsight.checkpoint_schedule(spec, steps=None if unknown_n else args.steps,
                                                state_bytes=8 * model.n, stages=stages, costs="1:1:0.5:0.5")
        host = Host(model, kappa, directory, actions if unknown_n else None, args.steps).run(actions)
        leftover = sum(len(v) for v in host.stored.values()) + len(host.work_deps)
        return host.objective, host.gradient, host.advanced - args.steps, leftover


# %% Every strategy against full storage, and full against finite differences.
model = ReactionDiffusion(args.cells, args.steps)
kappa = 0.8
state = 8 * model.n
strategies = [("full", 1), ("binomial:checkpoints=8", 1), ("cams:checkpoints=8", 1),
              ("cams:checkpoints=8", 4),  # step records of 4 state units: some adjoint steps need no re-run
              (f"multilevel:ram={4 * state},disk={16 * state},costs=1:1:0.5:0.5", 1),
              ("disk:dir=" + tempfile.gettempdir(), 1),
              ("online:checkpoints=8", None),  # steps=None: the host decides N, the checkpoints are states
              ("cams:checkpoints=8,online=1", None)]
J_full, g_full, _, _ = gradient("full", model, kappa)
print(f"{'strategy':<50} {'J':>14} {'dJ/dkappa':>22} {'extra steps':>12}")
bitwise = True
for spec, stages in strategies:
    J, g, extra, leftover = gradient(spec, model, kappa, stages or 1, unknown_n=stages is None)
    same = J == J_full and g == g_full
    bitwise &= same
    label = spec if stages == 1 else f"{spec} (steps=None)" if stages is None else f"{spec} (records of {stages} units)"
    print(f"{label:<50} {J:14.10f} {g:22.17g} {extra:12d}  {'same bits' if same else 'DIFFERENT'}"
          f"{'' if leftover == 0 else f', {leftover} items left in storage'}")

eps = 1e-6
objective = lambda k: sum(model.objective_increment(u) for u in _trajectory(k))  # noqa: E731


def _trajectory(k):
    u = model.u0.copy()
    for _ in range(args.steps):
        u = model.step(u, k)
        yield u


fd = (objective(kappa + eps) - objective(kappa - eps)) / (2 * eps)
fd_ok = abs(fd - g_full) <= 1e-6 * abs(g_full)
print(f"central difference {fd:.10g}, adjoint {g_full:.10g}, relative difference {abs(fd - g_full) / abs(g_full):.1e}")
print(f"every strategy's gradient bitwise equal to full: {'yes' if bitwise else 'no'}, "
      f"finite differences agree: {'yes' if fd_ok else 'no'}")
