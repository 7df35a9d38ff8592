"""hindsight's action streams for hosts written for the checkpoint_schedules package (Firedrake,
pyadjoint, tlm_adjoint): `Schedule(spec, steps)` yields checkpoint_schedules' own action classes and
StorageType when that package is installed, so a host that dispatches on them (isinstance,
functools.singledispatch) runs unchanged; without it, hindsight's classes with the same semantics.
docs/guides/switching_from_checkpoint_schedules.md compares the two side by side.

    from hindsight.checkpoint_schedules import Schedule
    for action in Schedule("binomial:checkpoints=10", 1000):
        action_handler(action)          # the host's checkpoint_schedules dispatch
"""
from .checkpoint_schedule import _OWN, _open


def classes():
    """The namespace the streams are made of: the checkpoint_schedules module when it can be imported,
    else hindsight.checkpoint_schedule (Forward, Reverse, Copy, Move, EndForward, EndReverse,
    StorageType in both)."""
    try:
        import checkpoint_schedules
    except ImportError:
        return _OWN
    return checkpoint_schedules


def uses_checkpoint_schedules():
    """Whether Schedule yields checkpoint_schedules' classes (the package is importable)."""
    return classes() is not _OWN


def Schedule(spec, steps, state_bytes=8, stages=4, costs=None):
    """hindsight.checkpoint_schedule's stream (same arguments and defaults) made of classes()' actions:
    an iterator with n, r, max_n, is_exhausted, is_running, finalize and uses_storage_type, as
    checkpoint_schedules' CheckpointSchedule has them, within its contract: online with N known walks its
    placement first (O(N): 0.45-1.1 s of CPU at N = 10^6, C = 100) and writes only the checkpoints it holds at the end.
    ValueError for online and cams with steps=None, whose checkpoints are states (restart_data ==
    "state"), which checkpoint_schedules' contract does not allow."""
    schedule = _open(spec, steps, state_bytes, stages, costs, classes(), intervals=True)
    if schedule.restart_data == "state":
        raise ValueError(
            f"steps={steps!r}: {spec!r} has no stream of checkpoint_schedules' classes. Its placement "
            "drops checkpoints during the forward run (Move(n, RAM, NONE), which no checkpoint_schedules "
            "schedule emits), after which the checkpoint before a dropped one must restart steps beyond "
            "the Forward that wrote it, while checkpoint_schedules' restart data written by Forward(n0, n1, "
            "write_ics=True, ...) serves steps n0..n1-1 only. With N known it streams in checkpoint_schedules' "
            "classes: give steps=N; or use hindsight.checkpoint_schedule(spec, steps), whose checkpoints are states "
            "(restart_data == 'state'), with a host that can advance a state any distance")
    return schedule


__all__ = ["Schedule", "classes", "uses_checkpoint_schedules"]
