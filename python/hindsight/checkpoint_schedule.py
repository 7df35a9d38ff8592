"""A storage strategy's plan as a stream of checkpointing actions for any time-stepper, in the vocabulary
of the checkpoint_schedules package (Forward, Reverse, Copy, Move, EndForward, EndReverse; StorageType
RAM, DISK, WORK): docs/guides/checkpoint_schedule.md. The actions are made by the C++ library
(storage/checkpoint_actions.h) from the plan the strategy itself executes.

    for action in hindsight.checkpoint_schedule("binomial:checkpoints=10", steps=1000):
        ...   # dispatch on type(action): Forward(n0, n1, write_ics, write_adj_deps, storage), ...
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


class Move(Copy):
    """As Copy, and the state is released in from_storage."""


class EndForward(CheckpointAction):
    """The forward run has reached the start of step N."""

    def __init__(self):
        super().__init__()


class EndReverse(CheckpointAction):
    """The adjoint has reversed step 0: the schedule is done."""

    def __init__(self):
        super().__init__()


_KINDS = (Forward, Reverse, Copy, Move, EndForward, EndReverse)  # the C++ CheckpointAction::Kind order


def checkpoint_schedule(spec, steps, state_bytes=8, stages=1, costs=None):
    """The actions that reverse `steps` fixed steps with storage strategy `spec` (full, disk, binomial,
    multilevel, cams; the same plan a run of the strategy executes), as a generator of Forward, Reverse,
    Copy, Move, EndForward and EndReverse. `state_bytes` sizes the budgets (a strategy given in bytes:
    cams:budget=, multilevel:ram=); `stages` > 1 lets cams keep step records of that many state units;
    `costs` = "uf:ub:wd:rd" for multilevel without costs= in its spec. ValueError names a bad argument;
    the whole stream is computed (and validated) before the first action is yielded."""
    from . import _in_python_words, _schedule_integer
    steps = _schedule_integer("steps", steps, 1, 1 << 24)
    state_bytes = _schedule_integer("state_bytes", state_bytes, 8, 8 * 2147483647)
    stages = _schedule_integer("stages", stages, 1, 64)
    if costs is not None and not isinstance(costs, str):
        raise TypeError(f"costs must be a string 'uf:ub:wd:rd' or None, not {type(costs).__name__}")
    try:
        raw = _hindsight._checkpoint_schedule(spec, steps, state_bytes, stages, costs or "")
    except ValueError as error:
        raise _in_python_words(error) from None
    return _actions(raw)


def _actions(raw):
    for kind, n0, n1, write_ics, write_adj_deps, storage, clear, source, target in raw:
        cls = _KINDS[kind]
        if cls is Forward:
            yield Forward(n0, n1, write_ics, write_adj_deps, StorageType[storage])
        elif cls is Reverse:
            yield Reverse(n1, n0, clear)
        elif cls in (Copy, Move):
            yield cls(n0, StorageType[source], StorageType[target])
        else:
            yield cls()
