"""A storage strategy's plan as a stream of checkpointing actions for any time-stepper, in the vocabulary
and under the contract of the checkpoint_schedules package (Forward, Reverse, Copy, Move, EndForward,
EndReverse; StorageType RAM, DISK, WORK): docs/guides/checkpoint_schedule.md. The actions are made by the
C++ library (storage/checkpoint_stream.h) as the host asks for them, from the plan the strategy itself
executes.

    for action in hindsight.checkpoint_schedule("binomial:checkpoints=10", steps=1000):
        ...   # dispatch on type(action): Forward(n0, n1, write_ics, write_adj_deps, storage), ...

hindsight.checkpoint_schedules.Schedule makes the same stream of checkpoint_schedules' own classes when
that package is installed.
"""
import enum

from . import _hindsight


class StorageType(enum.Enum):
    """Where data lives: RAM and DISK hold checkpoints, WORK is the state being advanced (and the adjoint
    data of the step reversed next), NONE means released."""
    RAM = 0
    DISK = 1
    WORK = -1
    NONE = None

    def __repr__(self):
        return f"StorageType.{self.name}"


class CheckpointAction:
    """Base of the actions; `args` are the constructor's arguments, repr as in checkpoint_schedules."""

    def __init__(self, *args):
        self.args = args

    def __repr__(self):
        return f"{type(self).__name__}({', '.join(repr(a) for a in self.args)})"

    def __eq__(self, other):
        return type(self) is type(other) and self.args == other.args

    def __hash__(self):
        return hash((type(self).__name__, self.args))


class Forward(CheckpointAction):
    """Advance the WORK state from the start of step n0 to the start of step n1. write_ics: first store
    that state (restart data) in `storage`; write_adj_deps: store what the adjoint of steps n0..n1-1 needs
    from the forward in `storage` (WORK: for the Reverse that follows)."""

    def __init__(self, n0, n1, write_ics, write_adj_deps, storage):
        super().__init__(n0, n1, write_ics, write_adj_deps, storage)

    n0 = property(lambda self: self.args[0])
    n1 = property(lambda self: self.args[1])
    write_ics = property(lambda self: self.args[2])
    write_adj_deps = property(lambda self: self.args[3])
    storage = property(lambda self: self.args[4])

    def __iter__(self):
        return iter(range(self.n0, self.n1))

    def __len__(self):
        return self.n1 - self.n0


class Reverse(CheckpointAction):
    """The adjoint from the start of step n1 down to the start of step n0 (steps n1-1 .. n0) from their
    adjoint data; clear_adj_deps: release that data afterwards."""

    def __init__(self, n1, n0, clear_adj_deps):
        super().__init__(n1, n0, clear_adj_deps)

    n1 = property(lambda self: self.args[0])
    n0 = property(lambda self: self.args[1])
    clear_adj_deps = property(lambda self: self.args[2])

    def __iter__(self):
        return iter(range(self.n1 - 1, self.n0 - 1, -1))

    def __len__(self):
        return self.n1 - self.n0


class Copy(CheckpointAction):
    """The state at the start of step n from from_storage to to_storage (to WORK: it is advanced next);
    it stays in from_storage."""

    def __init__(self, n, from_storage, to_storage):
        super().__init__(n, from_storage, to_storage)

    n = property(lambda self: self.args[0])
    from_storage = property(lambda self: self.args[1])
    to_storage = property(lambda self: self.args[2])


class Move(CheckpointAction):
    """As Copy, and the data is released in from_storage. Not a kind of Copy (as in checkpoint_schedules),
    so that isinstance and functools.singledispatch tell them apart."""

    def __init__(self, n, from_storage, to_storage):
        super().__init__(n, from_storage, to_storage)

    n = property(lambda self: self.args[0])
    from_storage = property(lambda self: self.args[1])
    to_storage = property(lambda self: self.args[2])


class EndForward(CheckpointAction):
    """The forward run has reached the start of step N."""

    def __init__(self):
        super().__init__()


class EndReverse(CheckpointAction):
    """The adjoint has reversed step 0: the schedule is done."""

    def __init__(self):
        super().__init__()


_KINDS = (Forward, Reverse, Copy, Move, EndForward, EndReverse)  # the C++ CheckpointAction::Kind order


class CheckpointSchedule:
    """The action stream of a storage strategy for a host's time-stepper: an iterator of actions, generated
    as they are asked for, with checkpoint_schedules' schedule state (n, r, max_n, is_exhausted,
    is_running, finalize, uses_storage_type). `classes` is the namespace whose action classes and
    StorageType it yields (hindsight's own, or checkpoint_schedules')."""

    def __init__(self, spec, steps, state_bytes, stages, costs, classes, intervals=False):
        from . import _in_python_words
        self.spec = spec
        self._classes = classes
        try:
            self._stream = _hindsight._open_checkpoint_stream(spec, steps, state_bytes, stages, costs or "",
                                                              intervals)
        except ValueError as error:
            raise _in_python_words(error) from None
        self._storage = {name: getattr(classes.StorageType, name) for name in ("RAM", "DISK", "WORK", "NONE")}
        self._kinds = tuple(getattr(classes, kind.__name__) for kind in _KINDS)
        self._running = False

    def __iter__(self):
        return self

    def __next__(self):
        raw = self._stream.next()
        if raw is None:
            raise StopIteration
        self._running = True
        kind, n0, n1, write_ics, write_adj_deps, storage, clear, source, target = raw
        cls = self._kinds[kind]
        where = self._storage
        if kind == 0:
            return cls(n0, n1, write_ics, write_adj_deps, where[storage])
        if kind == 1:
            return cls(n1, n0, clear)
        if kind in (2, 3):
            return cls(n0, where[source], where[target])
        return cls()

    @property
    def n(self):
        """The step the forward is at."""
        return self._stream.n

    @property
    def r(self):
        """The number of adjoint steps taken."""
        return self._stream.r

    @property
    def max_n(self):
        """N, the steps of the forward run; None while it is unknown (steps=None, before finalize)."""
        n = self._stream.max_n
        return None if n < 0 else n

    @property
    def restart_data(self):
        """What a checkpoint's restart data is: "interval" (checkpoint_schedules' rule: the data written by
        Forward(n0, n1, write_ics=True, ...) serves steps n0..n1-1 only) or "state" (online, with N
        or without: it is the state at n0 itself, which the host may advance any distance, and
        Move(n, storage, StorageType.NONE) releases a checkpoint). A host whose step is not a function
        of the state alone must refuse "state" (docs/guides/checkpoint_schedule.md, "An unknown N")."""
        return self._stream.restart_data

    @property
    def is_exhausted(self):
        """EndReverse has been yielded: one adjoint run per schedule."""
        return self._stream.is_exhausted

    @property
    def is_running(self):
        """At least one action has been yielded."""
        return self._running

    def finalize(self, n):
        """The forward run ends at step n (checkpoint_schedules' finalize): for a stream opened with
        steps=None, n becomes N, once, and the host stops at n inside the last Forward yielded
        (n0 < n <= n1); otherwise n must be N and the forward there. RuntimeError otherwise (a second call
        without N, n behind that Forward's start or beyond its end), as there."""
        if n < 1:
            raise ValueError(f"finalize: n must be positive, not {n}")
        self._stream.finalize(n)

    def uses_storage_type(self, storage_type):
        """Whether the stream may keep checkpoints in `storage_type` (RAM or DISK)."""
        name = self.spec.split(":", 1)[0].strip()
        if storage_type == self._storage["DISK"]:
            return name in ("disk", "multilevel")
        if storage_type == self._storage["RAM"]:
            return name != "disk"
        return False

    def __repr__(self):
        return f"CheckpointSchedule({self.spec!r}, max_n={self.max_n}, n={self.n}, r={self.r})"


def checkpoint_schedule(spec, steps, state_bytes=8, stages=4, costs=None):
    """The actions that reverse `steps` fixed steps with storage strategy `spec` (full, disk, binomial,
    multilevel, cams; the same plan a run of the strategy executes; or mixed, checkpoint_schedules' Mixed
    plan, whose units hold a state or one step's adjoint data), as a CheckpointSchedule: an iterator
    of Forward, Reverse, Copy, Move, EndForward and EndReverse under checkpoint_schedules' contract.
    steps=None (full, disk, online and cams): N is unknown; the host calls finalize(n) when its forward
    run stops at step n inside a Forward, as with checkpoint_schedules' schedules of unknown length. full
    and disk advance step by step; online keeps at most C + 1 states as checkpoints, cams (in its online
    mode, online=1 or not, as a run of unknown length) at most M - 1 while the forward runs
    (restart_data == "state": a checkpoint restarts any distance, and Move(n, RAM, NONE) releases one);
    both recompute what hindsight.schedule(spec, n + 1) predicts (docs/guides/checkpoint_schedule.md, "An
    unknown N").
    Arguments and defaults are hindsight.schedule's: `state_bytes` sizes the budgets (a strategy given
    in bytes: cams:budget=, multilevel:ram=); `stages` (4) is the right-hand sides per step, whose values
    cams may keep in step records; `costs` = "uf:ub:wd:rd" for multilevel without costs= in its spec.
    ValueError names a bad argument. binomial, full and disk streams are made as they are consumed (any
    N), multilevel and cams once their plan is made (cams: its optimal plan over N, N (M + 1) <= 1.25e7 table
    entries, seconds at N = 10^4); mixed translates its plan first (steps up to 2^24)."""
    return _open(spec, steps, state_bytes, stages, costs, _OWN)


def _open(spec, steps, state_bytes, stages, costs, classes, intervals=False):
    """intervals: the host's restart data serves only the steps of the Forward that wrote it
    (checkpoint_schedules' contract): online with N known then walks its placement first and writes only
    the checkpoints it holds at the end (restart_data == "interval")."""
    from . import _schedule_integer
    if not isinstance(spec, str):
        raise TypeError(f"spec must be a storage spec string such as 'binomial:checkpoints=50', not "
                        f"{type(spec).__name__} {spec!r}")
    steps = -1 if steps is None else _schedule_integer("steps", steps, 1, 4_000_000_000_000_000_000)
    state_bytes = _schedule_integer("state_bytes", state_bytes, 8, 8 * 2147483647)
    stages = _schedule_integer("stages", stages, 1, 64)
    if costs is not None and not isinstance(costs, str):
        raise TypeError(f"costs must be a string 'uf:ub:wd:rd' or None, not {type(costs).__name__}")
    return CheckpointSchedule(spec, steps, state_bytes, stages, costs, classes, intervals)


class _Classes:
    """hindsight's own action classes, as a namespace like the checkpoint_schedules module."""
    Forward, Reverse, Copy, Move, EndForward, EndReverse = Forward, Reverse, Copy, Move, EndForward, EndReverse
    StorageType = StorageType


_OWN = _Classes
