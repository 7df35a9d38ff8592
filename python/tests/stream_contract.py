"""hindsight's own statement of the contract a checkpoint_schedules host relies on, as an executable
checker: a host that tracks, for every piece of data, which steps it belongs to (not the data itself).
The rules were read from checkpoint_schedules' action semantics (the docstrings of its schedule.py) and
the validity test its schedules pass (the test_validity.py of its test folder); this is not its code.
A stream that passes here passes there, and a few rules are stricter (marked), where that test would crash or count
an empty checkpoint instead of failing.

State: `at` the step the WORK state is at (None: no restartable state in WORK), `r` the adjoint steps
taken, `work_ics`/`work_deps` the steps whose restart data / adjoint data are in WORK, and per storage
(RAM, DISK) the checkpoints, each keyed by its step and holding the step sets of its restart data and of
its adjoint data.

 1. Forward(n0, n1, ics, deps, storage) starts at `at`, advances at least one step and never past the
    adjoint (n1 <= N - r). It first discards what WORK holds. Its restart data covers steps n0..n1-1
    (so a checkpoint can restart only the steps its Forward ran), its adjoint data the same range. With
    storage RAM/DISK the two sets become one checkpoint keyed n0 (none may exist there already); with
    WORK they stay in WORK. (Stricter: a Forward to RAM/DISK must write something.)
 2. Reverse(n1, n0, clear) starts where the adjoint is (n1 = N - r), takes at least one step, and needs
    the adjoint data of steps n0..n1-1 in WORK (never read from RAM/DISK directly); clear discards the
    WORK adjoint data. (Stricter: only after EndForward.)
 3. Copy/Move(n, from, to) need an empty WORK (no restart or adjoint data), a non-empty checkpoint at n
    in `from` (RAM or DISK: WORK is not a checkpoint storage) and n < N - r. To RAM/DISK it becomes a
    checkpoint there (none at n yet); to WORK its data becomes WORK's, and `at` becomes n only when its
    restart data covers n, in which case it must cover every step up to the adjoint (n..N-r-1). Move
    removes the checkpoint from `from`. (Stricter: `to` is never NONE, which that test cannot execute.)
 4. EndForward once, when `at` = N; EndReverse when r = N, and nothing after it.
 5. Limits, after every action: checkpoints per storage <= the given limit; WORK holds at most
    `work_limit` units, one for any restart data plus one per step of adjoint data.
 6. When the schedule object exposes n, r (checkpoint_schedules' CheckpointSchedule), after every action
    n = `at` (unless `at` is None) and r = `r` (0 again after EndReverse when the schedule is not
    exhausted, i.e. allows another adjoint run).
 7. (Stricter, unless allow_leftovers) no checkpoint is left when EndReverse comes.
 online=True: while the schedule's max_n is None, a Forward may run past N (the host stops at N and
 calls finalize(N)), as for checkpoint_schedules' schedules of unknown length.
 8. State checkpoints, only for a schedule that declares them (restart_data == "state", hindsight's online
    stream without N): rule 1's restart range becomes every step from n0 on (the restart data is the state
    x_{n0}, which the host advances any distance), and Move(n, RAM/DISK, NONE) releases the checkpoint at
    n (it must exist; WORK and the adjoint are untouched). Every other rule stays.

Run on checkpoint_schedules' own schedules (Revolve, HRevolve, MultistageCheckpointSchedule,
MixedCheckpointSchedule, DiskRevolve, SingleMemoryStorageSchedule with a WORK limit of N,
SingleDiskStorageSchedule) this checker accepts them, with allow_leftovers for the revolve family, which
leaves its disk checkpoints behind.
"""


class ContractError(AssertionError):
    pass


def check_stream(schedule, steps, classes, ram_limit=None, disk_limit=None, work_limit=1, online=False,
                 allow_leftovers=False):
    """Executes `schedule` (an iterable of actions made of `classes`, a namespace with Forward, Reverse,
    Copy, Move, EndForward, EndReverse, StorageType) for N = `steps` and returns counts; raises
    ContractError naming the action and the rule. online: the stream does not know N until the forward
    run reaches it; the checker calls schedule.finalize(N) then, as a host would."""
    Forward, Reverse, Copy, Move = classes.Forward, classes.Reverse, classes.Copy, classes.Move
    EndForward, EndReverse, StorageType = classes.EndForward, classes.EndReverse, classes.StorageType
    RAM, DISK, WORK, NONE = StorageType.RAM, StorageType.DISK, StorageType.WORK, StorageType.NONE
    at, r = 0, 0
    work_ics, work_deps = set(), set()
    checkpoints = {RAM: {}, DISK: {}}
    limits = {RAM: ram_limit, DISK: disk_limit}
    forward_done = reverse_done = False
    counts = {"actions": 0, "advanced": 0, "recomputed": 0, "adjoint_reruns": 0, "peak_ram": 0, "peak_disk": 0, "disk_writes": 0}
    state = hasattr(schedule, "n") and hasattr(schedule, "r")
    states = getattr(schedule, "restart_data", "interval") == "state"  # rule 8
    if state and (schedule.n != 0 or schedule.r != 0):
        raise ContractError(f"a fresh schedule is at n = {schedule.n}, r = {schedule.r}")
    for action in schedule:
        counts["actions"] += 1

        def fail(rule):
            raise ContractError(f"action {counts['actions']} {action!r}: {rule}")

        if reverse_done:
            fail("after EndReverse")
        # type() rather than isinstance: a Move must not be taken for a Copy, and the reverse.
        kind = type(action)
        if kind is Forward:
            n0, n1 = action.n0, action.n1
            if at is None or n0 != at:
                fail(f"does not start at the WORK state (step {at})")
            if n1 <= n0:
                fail("advances no step")
            if online and getattr(schedule, "max_n", None) is None:
                n1 = min(n1, steps)  # N unknown to the stream: the host stops the forward at N
            elif n1 > steps - r:
                fail(f"advances past the adjoint (step {steps - r})")
            work_ics.clear()
            work_deps.clear()
            ics = set(range(n0, steps if states else n1)) if action.write_ics else set()
            deps = set(range(n0, n1)) if action.write_adj_deps else set()
            if action.storage in (RAM, DISK):
                if not ics and not deps:
                    fail("writes nothing to a checkpoint storage")
                if n0 in checkpoints[action.storage]:
                    fail(f"a checkpoint at {n0} exists in {action.storage!r}")
                checkpoints[action.storage][n0] = (ics, deps)
                counts["disk_writes"] += action.storage == DISK
            elif action.storage == WORK:
                work_ics |= ics
                work_deps |= deps
            elif action.storage != NONE:
                fail("unknown storage")
            at = n1
            counts["advanced"] += n1 - n0
            # A one-step Forward that writes adjoint data to WORK re-runs its step for the Reverse that
            # follows (hindsight's adjoint step recomputing its stages); any other after EndForward
            # recomputes (hindsight.schedule's recomputed_steps).
            rerun = action.write_adj_deps and action.storage == WORK and n1 - n0 == 1
            if forward_done and not rerun:
                counts["recomputed"] += n1 - n0
            elif rerun and (forward_done or n1 == steps):
                counts["adjoint_reruns"] += 1
            if online and not forward_done and n1 == steps and getattr(schedule, "max_n", steps) is None:
                schedule.finalize(steps)
        elif kind is Reverse:
            if not forward_done:
                fail("before EndForward")
            if action.n1 != steps - r:
                fail(f"the adjoint is at step {steps - r}")
            if action.n0 >= action.n1:
                fail("takes no step")
            missing = set(range(action.n0, action.n1)) - work_deps
            if missing:
                fail(f"no adjoint data of steps {sorted(missing)[:5]} in WORK")
            r += action.n1 - action.n0
            if action.clear_adj_deps:
                work_deps.clear()
        elif (kind is Move and states and action.from_storage in (RAM, DISK)
              and action.to_storage == NONE):  # rule 8: the release of a state checkpoint
            if checkpoints[action.from_storage].pop(action.n, None) is None:
                fail(f"no checkpoint at {action.n} in {action.from_storage!r}")
        elif kind is Copy or kind is Move:
            n, source, target = action.n, action.from_storage, action.to_storage
            if source not in (RAM, DISK):
                fail("copies from a storage that holds no checkpoints")
            if target == NONE or target not in (RAM, DISK, WORK):
                fail("copies to no storage")
            if work_ics or work_deps:
                fail("WORK still holds data")
            if n not in checkpoints[source]:
                fail(f"no checkpoint at {n} in {source!r}")
            ics, deps = checkpoints[source].pop(n) if kind is Move else checkpoints[source][n]
            if not ics and not deps:
                fail("the checkpoint is empty")
            if n >= steps - r:
                fail(f"the checkpoint is not before the adjoint (step {steps - r})")
            if target in (RAM, DISK):
                if n in checkpoints[target]:
                    fail(f"a checkpoint at {n} exists in {target!r}")
                checkpoints[target][n] = (set(ics), set(deps))
                counts["disk_writes"] += target == DISK
            else:
                at = n if n in ics else None
                if at is not None and not ics.issuperset(range(n, steps - r)):
                    fail(f"its restart data does not reach the adjoint (step {steps - r})")
                work_ics |= ics
                work_deps |= deps
        elif kind is EndForward:
            if forward_done or at != steps:
                fail(f"the forward run is at step {at}, not N = {steps}")
            forward_done = True
        elif kind is EndReverse:
            if r != steps:
                fail(f"{r} of {steps} steps reversed")
            reverse_done = True
            if state and not getattr(schedule, "is_exhausted", True):
                r = 0  # a schedule that allows another adjoint run starts it afresh
        else:
            fail("not an action of these classes")
        for storage, limit in limits.items():
            if limit is not None and len(checkpoints[storage]) > limit:
                fail(f"{len(checkpoints[storage])} checkpoints in {storage!r}, more than {limit}")
        if min(1, len(work_ics)) + len(work_deps) > work_limit:
            fail(f"WORK holds more than {work_limit} units")
        counts["peak_ram"] = max(counts["peak_ram"], len(checkpoints[RAM]))
        counts["peak_disk"] = max(counts["peak_disk"], len(checkpoints[DISK]))
        if state:
            if at is not None and schedule.n != at:
                fail(f"schedule.n = {schedule.n}, the host is at step {at}")
            if schedule.r != r:
                fail(f"schedule.r = {schedule.r}, the host has reversed {r} steps")
        if reverse_done:
            break
    if not reverse_done:
        raise ContractError("the stream ends without EndReverse")
    if not allow_leftovers and any(checkpoints.values()):
        raise ContractError(f"checkpoints left at the end: {checkpoints}")
    return counts
