"""hindsight.checkpoint_schedule: checkpoint_schedules' actions from hindsight's plans drive a stepper that is
not hindsight's to the gradient of full storage, recomputing what hindsight.schedule predicts, and every
stream keeps checkpoint_schedules' contract (stream_contract.py states its rules)."""
import functools
import importlib.util
import os
import pathlib
import random
import types

import pytest

import hindsight
from hindsight import Copy, EndForward, EndReverse, Forward, Move, Reverse, StorageType
from stream_contract import ContractError, check_stream

OWN = types.SimpleNamespace(Forward=Forward, Reverse=Reverse, Copy=Copy, Move=Move, EndForward=EndForward,
                            EndReverse=EndReverse, StorageType=StorageType)


def run(actions, steps, a=0.3, schedule=None):
    """z_{k+1} = z_k + h (a z_k - z_k^2), J = sum_k h z_{k+1}^2, dJ/da by the discrete adjoint. WORK holds
    the state and the adjoint data of the steps reversed next, as the contract has it. schedule: the stream
    (needed for state checkpoints' releases); one opened without N is finalized by the host, which stops
    its forward run at `steps`, inside a Forward. The restart data it keeps is the state itself, so it also runs streams of
    state checkpoints (restart_data == "state"), whose Move(n, RAM, NONE) releases a checkpoint."""
    h = 0.01
    stored = {}  # (storage, n) -> (state or None, {step: state} adjoint data)
    n, z, lam, dj, advanced, forward_done, objective = 0, 1.0, None, 0.0, 0, False, 0.0
    work_deps = {}
    for action in actions:
        if type(action) is Forward:
            assert n == action.n0, action
            start, deps = z, {}
            for k in action:
                if schedule is not None and k == steps and schedule.max_n is None:
                    break  # the host's forward run ends at `steps`, inside this Forward
                if action.write_adj_deps:
                    deps[k] = z
                z = z + h * (a * z - z * z)
                advanced += 1
                n = k + 1
                if not forward_done:
                    objective += h * z * z
            if action.storage == StorageType.WORK:
                work_deps = deps
            else:
                stored[(action.storage, action.n0)] = (start if action.write_ics else None, deps)
            if schedule is not None and n == steps and schedule.max_n is None:
                schedule.finalize(steps)
        elif type(action) is EndForward:
            forward_done, lam = True, 2 * h * z
        elif type(action) is Reverse:
            for k in action:
                zk = work_deps.pop(k)
                dj += lam * h * zk
                lam = lam * (1 + h * (a - 2 * zk)) + (2 * h * zk if k >= 1 else 0.0)
        elif type(action) in (Copy, Move):
            key = (action.from_storage, action.n)
            data = stored.pop(key) if type(action) is Move else stored[key]
            if action.to_storage == StorageType.NONE:
                assert schedule is not None and schedule.restart_data == "state", action  # a release
            elif action.to_storage == StorageType.WORK:
                state, work_deps = data[0], dict(data[1])
                if state is not None:
                    z, n = state, action.n
            else:
                stored[(action.to_storage, action.n)] = data
        else:
            assert type(action) is EndReverse
            return objective, dj, advanced - steps, len(stored) + len(work_deps)
    raise AssertionError("no EndReverse")


@pytest.mark.parametrize("spec,stages", [("binomial:checkpoints=3", 1), ("cams:checkpoints=3", 1), ("cams:checkpoints=6", 4),
                                         ("cams:checkpoints=3,online=1", 1), ("cams:checkpoints=6,online=1", 4),
                                         ("full", 1), ("multilevel:ram=48,disk=64,costs=1:1:0:0", 4),
                                         ("mixed:checkpoints=3", 1), ("mixed:checkpoints=11", 4),
                                         ("online:checkpoints=3", 1), ("online:checkpoints=6", 4)])
def test_gradient_equals_full_and_recomputation_equals_the_prediction(spec, stages):
    steps = 60
    reference = run(hindsight.checkpoint_schedule("full", steps=steps), steps)
    stream = hindsight.checkpoint_schedule(spec, steps=steps, state_bytes=16, stages=stages)
    actions = list(stream)
    objective, gradient, extra, leftover = run(actions, steps, schedule=stream)  # N known: no finalize
    assert (objective, gradient) == reference[:2]
    assert stream.restart_data == ("state" if spec.startswith("online") else "interval")
    assert leftover == 0  # Move and clear_adj_deps release everything by the end
    p = hindsight.schedule(spec, steps, state_bytes=16, stages=stages)
    # The host re-runs a step for each adjoint step without held data (hindsight's adjoint steps that
    # recompute their stages), except the forward run's last step, which writes its data to WORK itself.
    # cams and mixed hold some steps' adjoint data and re-run only the others.
    reruns = p.adjoint_stage_recomputations if spec.startswith(("cams", "mixed")) else steps
    last = [a for a in actions[:actions.index(EndForward())] if type(a) is Forward][-1]
    taped_in_forward = last.write_adj_deps and last.storage == StorageType.WORK
    assert extra == p.recomputed_steps + reruns - taped_in_forward


@pytest.mark.parametrize("spec", ["full", "disk:dir=unused"])
def test_streams_without_n_end_where_the_host_finalizes(spec):
    # A host whose forward run decides N itself (adaptive steps): the stream advances step by step until
    # finalize(n), then reverses; the gradient is full storage's, and the contract holds at every n.
    for steps in (1, 2, 7, 60):
        reference = run(hindsight.checkpoint_schedule("full", steps=steps), steps)
        schedule = hindsight.checkpoint_schedule(spec, steps=None)
        assert schedule.max_n is None and schedule.n == 0
        objective, gradient, extra, leftover = run(schedule, steps, schedule=schedule)
        assert (objective, gradient) == reference[:2] and leftover == 0
        assert schedule.max_n == steps and schedule.is_exhausted
        assert extra == steps  # one re-run per adjoint step, nothing else recomputed
        disk = spec.startswith("disk")
        counts = check_stream(hindsight.checkpoint_schedule(spec, steps=None), steps, OWN, online=True,
                              ram_limit=0 if disk else steps, disk_limit=steps if disk else 0)
        assert counts["recomputed"] == 0
    schedule = hindsight.checkpoint_schedule("full", steps=None)
    assert schedule.restart_data == "interval"
    next(schedule), next(schedule)
    with pytest.raises(RuntimeError, match="forward is at step 2"):
        schedule.finalize(3)
    with pytest.raises(ValueError, match="steps unknown.*binomial needs N") as error:
        hindsight.checkpoint_schedule("binomial:checkpoints=3", steps=None)
    assert "--" not in str(error.value)


def test_cams_without_n_keeps_the_relaxed_contract_and_recomputes_the_prediction_of_one_step_more():
    # cams' online mode as the host goes (restart_data == "state": its placement thins checkpoints with
    # Move(n, RAM, NONE)); finalized at n it is a cams run of n + 1 steps in the online mode, whose
    # working state is the host's x_n: at most M - 1 states while the forward runs, the recomputation and
    # the adjoint re-runs of hindsight.schedule's prediction for n + 1 steps, full storage's gradient.
    rng = random.Random(19)
    cases = [(c, stages, n) for c in (1, 2, 5, 10) for stages in (1, 4) for n in range(1, 121)]
    cases += [(rng.randint(1, 30), rng.randint(1, 4), rng.randint(1, 3000)) for _ in range(12)]
    for c, stages, n in cases:
        spec = f"cams:checkpoints={c},online=1"
        schedule = hindsight.checkpoint_schedule(spec, steps=None, state_bytes=16, stages=stages)
        assert schedule.restart_data == "state" and schedule.max_n is None
        try:
            counts = check_stream(schedule, n, OWN, online=True, ram_limit=c + 1, disk_limit=0)
        except ContractError as error:
            raise AssertionError(f"{spec}, stages {stages}, N = {n}: {error}") from None
        p = hindsight.schedule(spec, n + 1, state_bytes=16, stages=stages)
        assert counts["recomputed"] == p.recomputed_steps, (c, stages, n)
        assert schedule.max_n == n and schedule.is_exhausted
    for c, steps in [(1, 1), (1, 2), (1, 30), (2, 7), (3, 60), (5, 157), (10, 400)]:
        reference = run(hindsight.checkpoint_schedule("full", steps=steps), steps)
        for spec in (f"cams:checkpoints={c},online=1", f"cams:checkpoints={c}"):  # N unknown: online either way
            schedule = hindsight.checkpoint_schedule(spec, steps=None)
            objective, gradient, extra, leftover = run(schedule, steps, schedule=schedule)
            assert (objective, gradient) == reference[:2], (spec, steps)
            assert leftover == 0 and schedule.max_n == steps and schedule.is_exhausted
            p = hindsight.schedule(f"cams:checkpoints={c},online=1", steps + 1, state_bytes=8)
            # The run's adjoint re-runs include its last step n, which the host does not reverse.
            assert extra == p.recomputed_steps + p.adjoint_stage_recomputations - 1, (spec, steps)
    # checkpoint_schedules' classes need N for cams (its state checkpoints are outside their contract).
    from hindsight.checkpoint_schedules import Schedule
    with pytest.raises(ValueError, match="give steps=N") as error:
        Schedule("cams:checkpoints=3", None)
    assert "restart_data == 'state'" in str(error.value)


def _online_without_n(c, steps):
    """online:checkpoints=c without N, checked for N = steps (the checker finalizes where the forward
    crosses it) with at most c + 1 RAM checkpoints; returns the counts."""
    schedule = hindsight.checkpoint_schedule(f"online:checkpoints={c}", steps=None, state_bytes=16)
    assert schedule.restart_data == "state" and schedule.max_n is None
    try:
        counts = check_stream(schedule, steps, OWN, online=True, ram_limit=c + 1, disk_limit=0)
    except ContractError as error:
        raise AssertionError(f"c = {c}, N = {steps}: {error}") from None
    assert schedule.max_n == steps and schedule.is_exhausted
    return counts


def test_online_without_n_keeps_the_relaxed_contract_and_recomputes_the_prediction_of_one_step_more():
    # The stream's forward prefix does not depend on N, so N = 1..200 finalizes at every step of every
    # Forward up there. The host's WORK holds x_N at finalize, as an engine run of N + 1 steps holds its
    # working state: the recomputation is hindsight.schedule's for N + 1 steps.
    rng = random.Random(7)
    cases = [(c, n) for c in (1, 2, 3, 5, 10) for n in range(1, 201)]
    cases += [(rng.randint(1, 30), rng.randint(1, 2000)) for _ in range(12)]
    for c, n in cases:
        counts = _online_without_n(c, n)
        p = hindsight.schedule(f"online:checkpoints={c}", n + 1, state_bytes=16)
        assert counts["recomputed"] == p.recomputed_steps, (c, n)
        assert counts["adjoint_reruns"] == n and counts["peak_ram"] <= c + 1, (c, n, counts)
    # Without the declaration the checker applies checkpoint_schedules' rule 1, which these streams break.
    class Undeclared:
        def __init__(self, schedule):
            self.schedule, self.finalize = schedule, schedule.finalize

        def __iter__(self):
            return iter(self.schedule)

        max_n = property(lambda self: self.schedule.max_n)

    with pytest.raises(ContractError, match="copies to no storage"):
        check_stream(Undeclared(hindsight.checkpoint_schedule("online:checkpoints=2", steps=None)), 100, OWN,
                     online=True)


def test_online_without_n_gives_full_storages_gradient_bit_for_bit():
    for c, steps in [(1, 1), (1, 2), (1, 30), (2, 7), (3, 60), (5, 157), (10, 400), (4, 1000)]:
        reference = run(hindsight.checkpoint_schedule("full", steps=steps), steps)
        schedule = hindsight.checkpoint_schedule(f"online:checkpoints={c}", steps=None)
        objective, gradient, extra, leftover = run(schedule, steps, schedule=schedule)
        assert (objective, gradient) == reference[:2], (c, steps)
        assert leftover == 0 and schedule.max_n == steps and schedule.is_exhausted
        p = hindsight.schedule(f"online:checkpoints={c}", steps + 1, state_bytes=8)
        assert extra == p.recomputed_steps + steps  # and one re-run per adjoint step


def test_online_without_n_refuses_a_wrong_finalize_and_checkpoint_schedules_classes():
    schedule = hindsight.checkpoint_schedule("online:checkpoints=2", steps=None)
    action = next(schedule)
    while type(action) is not Forward or len(action) < 2:
        action = next(schedule)
    with pytest.raises(RuntimeError, match="behind the start"):
        schedule.finalize(action.n0)
    with pytest.raises(RuntimeError, match=f"forward is at step {action.n1}"):
        schedule.finalize(action.n1 + 1)
    with pytest.raises(ValueError, match="finalize: n must be positive"):
        schedule.finalize(0)
    schedule.finalize(action.n0 + 1)
    assert schedule.max_n == schedule.n == action.n0 + 1
    with pytest.raises(RuntimeError, match="finalize was called already"):
        schedule.finalize(action.n0 + 1)
    with pytest.raises(ValueError, match="stages = 1"):
        hindsight.checkpoint_schedule("online:checkpoints=2,stages=1", steps=None)
    with pytest.raises(ValueError, match="online.checkpoints"):
        hindsight.checkpoint_schedule("online:checkpoints=0", steps=None)
    # checkpoint_schedules' own contract (rule 1) has no state checkpoints: its classes are refused.
    from hindsight.checkpoint_schedules import Schedule, classes, uses_checkpoint_schedules
    with pytest.raises(ValueError, match=r"serves steps n0\.\.n1-1 only") as error:
        Schedule("online:checkpoints=3", None)
    assert "steps=None" in str(error.value) and "restart_data == 'state'" in str(error.value)
    # With N known, hindsight.checkpoint_schedule's online keeps states (lazy: nothing walked ahead), and
    # Schedule's is within checkpoint_schedules' contract: the placement walked first, only the checkpoints
    # held at the end written, the same count (rule 1 strict: no state relaxation declared).
    assert hindsight.checkpoint_schedule("online:checkpoints=3", steps=50).restart_data == "state"
    rng = random.Random(23)
    cases = [(c, n) for c in (1, 2, 3, 5, 10) for n in range(1, 121)]
    cases += [(rng.randint(1, 40), rng.randint(1, 5000)) for _ in range(10)]
    for c, n in cases:
        spec = f"online:checkpoints={c}"
        schedule = Schedule(spec, n, state_bytes=16)
        assert schedule.restart_data == "interval"
        counts = check_stream(schedule, n, classes(), ram_limit=c + 1, disk_limit=0)
        assert counts["recomputed"] == hindsight.schedule(spec, n, state_bytes=16).recomputed_steps, (c, n)
    for c, steps in [(1, 30), (3, 60), (10, 400)]:
        reference = run(hindsight.checkpoint_schedule("full", steps=steps), steps)
        if not uses_checkpoint_schedules():  # run() is a host of hindsight's own classes
            assert run(Schedule(f"online:checkpoints={c}", steps), steps)[:2] == reference[:2]
    assert Schedule("full", None).restart_data == "interval"


def _families(rng):
    """Every family with a random budget: (spec, stages, RAM limit, DISK limit) for the checker."""
    c = rng.randint(1, 12)
    ram, disk = rng.randint(2, 8), rng.randint(1, 12)
    return [("full", 1, None, 0), ("disk:dir=unused", 4, 0, None),
            (f"binomial:checkpoints={c}", rng.choice([1, 4]), c + 1, 0),
            (f"cams:checkpoints={c}", rng.choice([1, 4]), None, 0),
            (f"cams:checkpoints={c},online=1", rng.choice([1, 4]), None, 0),
            (f"multilevel:ram={16 * ram},disk={16 * disk},costs=1:1:{rng.choice([0, 0.5, 2])}:0.5", rng.choice([1, 4]),
             ram, disk),
            (f"mixed:checkpoints={c}", 1, c, 0),  # c units: restart states and adjoint data alike
            (f"online:checkpoints={c}", rng.choice([1, 4]), c + 1, 0),  # state checkpoints (rule 8)
            # N unknown (finalized where the forward reaches N): state checkpoints; the count of N + 1 steps
            (f"online:checkpoints={c} steps=None", rng.choice([1, 4]), c + 1, 0),
            (f"cams:checkpoints={c},online=1 steps=None", rng.choice([1, 4]), c + 1, 0)]


def _sweep(ns, seed):
    rng = random.Random(seed)
    checked = 0
    for n in ns:
        for spec, stages, ram, disk in _families(rng):
            unknown = spec.endswith(" steps=None")
            spec = spec.removesuffix(" steps=None")
            try:
                schedule = hindsight.checkpoint_schedule(spec, steps=None if unknown else n, state_bytes=16,
                                                         stages=stages)
            except ValueError as error:
                assert spec.startswith("multilevel"), error  # only too few slots for N steps
                continue
            try:
                counts = check_stream(schedule, n, OWN, ram_limit=ram, disk_limit=disk, online=unknown)
            except ContractError as error:
                raise AssertionError(f"{spec}, N = {n}{' unknown' if unknown else ''}, stages = {stages}: "
                                     f"{error}") from None
            p = hindsight.schedule(spec, n + unknown, state_bytes=16, stages=stages)
            assert counts["recomputed"] == p.recomputed_steps, (spec, n, stages)
            if spec.startswith("multilevel"):
                # At a write cost of 0 the plan may store a state on disk and in RAM at once and read
                # only the RAM copy (free in its cost model); a Forward writes one storage, so the stream
                # keeps the copy that is read and writes one state fewer to disk than the run does
                # (N = 7728, ram=112, disk=96, costs=1:1:0:0.5: 139 against 140).
                if spec.endswith("costs=1:1:0:0.5"):
                    assert counts["disk_writes"] <= p.disk_writes, (spec, n, stages)
                else:
                    assert counts["disk_writes"] == p.disk_writes, (spec, n, stages)
            checked += 1
    return checked


def test_every_family_keeps_the_contract_for_small_n_and_random_budgets():
    assert _sweep(range(1, 41), seed=1) > 150


def test_every_family_keeps_the_contract_up_to_ten_thousand_steps():
    assert _sweep([97, 256, 1000, 3001, 10_000], seed=2) >= 20


@pytest.mark.skipif(not os.environ.get("HINDSIGHT_LONG"), reason="the long sweep (ctest -L long)")
def test_every_family_keeps_the_contract_long_sweep():
    rng = random.Random(3)
    assert _sweep(sorted(rng.sample(range(41, 10_001), 120)), seed=4) > 400


def _bad(*actions):
    return check_stream(list(actions), 2, OWN)


def test_the_checker_rejects_what_checkpoint_schedules_hosts_cannot_run():
    ok = [Forward(0, 1, True, False, StorageType.RAM), Forward(1, 2, False, True, StorageType.WORK), EndForward(),
          Reverse(2, 1, True), Move(0, StorageType.RAM, StorageType.WORK), Forward(0, 1, False, True, StorageType.WORK),
          Reverse(1, 0, True), EndReverse()]
    assert _bad(*ok)["recomputed"] == 0
    with pytest.raises(ContractError, match="holds no checkpoints"):  # a copy out of WORK
        _bad(Forward(0, 1, False, False, StorageType.WORK), Copy(1, StorageType.WORK, StorageType.RAM))
    with pytest.raises(ContractError, match="in WORK"):  # adjoint data read from RAM
        _bad(Forward(0, 1, False, False, StorageType.WORK), Forward(1, 2, False, True, StorageType.RAM), EndForward(),
             Reverse(2, 1, True))
    with pytest.raises(ContractError, match="reach the adjoint"):  # restart data of one step, reused for two
        _bad(Forward(0, 1, True, False, StorageType.RAM), Forward(1, 2, False, False, StorageType.WORK), EndForward(),
             Copy(0, StorageType.RAM, StorageType.WORK))
    with pytest.raises(ContractError, match="left"):
        _bad(*ok[:4], Copy(0, StorageType.RAM, StorageType.WORK), *ok[5:])
    assert not issubclass(Move, Copy)  # a host's isinstance(action, Copy) branch must not take a Move

    @functools.singledispatch
    def kind(action):
        raise TypeError(action)
    kind.register(Copy, lambda action: "copy")
    kind.register(Move, lambda action: "move")
    assert [kind(a) for a in (Copy(0, StorageType.RAM, StorageType.WORK), Move(0, StorageType.RAM, StorageType.WORK))] \
        == ["copy", "move"]


def test_schedule_state_follows_the_host():
    schedule = hindsight.checkpoint_schedule("binomial:checkpoints=2", steps=10)
    assert (schedule.n, schedule.r, schedule.max_n, schedule.is_running, schedule.is_exhausted) == (0, 0, 10, False, False)
    check_stream(schedule, 10, OWN)  # checks n and r after every action
    assert schedule.is_exhausted and schedule.r == 10 and next(schedule, None) is None
    with pytest.raises(RuntimeError, match="N = 10"):
        schedule.finalize(9)
    assert schedule.uses_storage_type(StorageType.RAM) and not schedule.uses_storage_type(StorageType.DISK)


def test_streams_are_made_as_they_are_consumed():
    # 2^40 steps: a stream built before its first action would not fit in any memory.
    schedule = hindsight.checkpoint_schedule("binomial:checkpoints=30", steps=1 << 40)
    first = [next(schedule) for _ in range(3)]
    assert first[0] == Forward(0, first[0].n1, True, False, StorageType.RAM) and first[1].n0 == first[0].n1
    full = hindsight.checkpoint_schedule("full", steps=100_000_000)  # 800 MB of states, within full's budget
    assert next(full) == Forward(0, 1, True, False, StorageType.RAM)
    # cams' exact plan has tables of N (M + 1) entries: beyond them it is refused before any action.
    with pytest.raises(ValueError, match=r"16777217 steps and 4 state units needs more than 12500000 table"):
        hindsight.checkpoint_schedule("cams:checkpoints=3", steps=(1 << 24) + 1)
    # multilevel drives its plan as the host goes: beyond 2^24 steps, its leaves on disk first.
    multilevel = hindsight.checkpoint_schedule("multilevel:ram=160,disk=1MiB,costs=1:1:0.5:0.5",
                                               steps=100_000_000, state_bytes=16)
    assert next(multilevel) == Forward(0, 1526, True, False, StorageType.DISK)


def test_defaults_are_schedules():
    # One set of defaults: the stream recomputes what hindsight.schedule predicts with the same arguments.
    spec, steps = "cams:checkpoints=20", 500
    counts = check_stream(hindsight.checkpoint_schedule(spec, steps), steps, OWN)
    p = hindsight.schedule(spec, steps, state_bytes=8)
    assert counts["recomputed"] == p.recomputed_steps
    assert counts["adjoint_reruns"] == p.adjoint_stage_recomputations


def test_actions_read_as_checkpoint_schedules():
    # C + 1 = 2 snapshots hold x_0 and x_1; x_2's adjoint data is WORK when the forward run ends.
    actions = list(hindsight.checkpoint_schedule("binomial:checkpoints=1", steps=3))
    assert repr(actions[0]) == "Forward(0, 1, True, False, StorageType.RAM)"
    assert repr(actions[2]) == "Forward(2, 3, False, True, StorageType.WORK)"
    assert actions[3] == EndForward() and actions[-1] == EndReverse()
    assert [list(a) for a in actions if type(a) is Reverse] == [[2], [1], [0]]


def test_bad_arguments_name_themselves():
    with pytest.raises(ValueError, match="online.checkpoints"):
        hindsight.checkpoint_schedule("online:checkpoints=0", steps=10)
    with pytest.raises(ValueError, match="steps"):
        hindsight.checkpoint_schedule("full", steps=0)
    with pytest.raises(TypeError, match="steps"):
        hindsight.checkpoint_schedule("full", steps=2.5)
    with pytest.raises(ValueError, match="stages = 1"):
        hindsight.checkpoint_schedule("binomial:checkpoints=3,stages=1", steps=10, stages=4)
    with pytest.raises(ValueError) as error:
        hindsight.schedule("binomial:checkpoints=3", (1 << 24) + 1, state_bytes=8, actions=True)
    assert "actions=True" in str(error.value) and "--" not in str(error.value)


def test_the_adapter_without_checkpoint_schedules_keeps_the_semantics():
    from hindsight import checkpoint_schedules as adapter
    schedule = adapter.Schedule("cams:checkpoints=4", 50)
    names = adapter.classes()
    check_stream(schedule, 50, names)
    if not adapter.uses_checkpoint_schedules():
        assert names.Move is Move and names.StorageType is StorageType


def _their_validity_test():
    """checkpoint_schedules' own test host: the test_validity.py of its test folder, beside the package in
    a source checkout, or where HINDSIGHT_CHECKPOINT_SCHEDULES_TESTS points."""
    cs = pytest.importorskip("checkpoint_schedules")
    root = os.environ.get("HINDSIGHT_CHECKPOINT_SCHEDULES_TESTS") or \
        str(pathlib.Path(cs.__file__).resolve().parent.parent / "tests")
    path = pathlib.Path(root) / "test_validity.py"
    if not path.exists():
        pytest.skip(f"checkpoint_schedules is installed without its tests ({path})")
    spec = importlib.util.spec_from_file_location("checkpoint_schedules_test_validity", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return cs, module.test_validity


@pytest.mark.parametrize("family", ["full", "binomial", "cams", "cams online", "online", "multilevel",
                                    "full without N", "disk without N"])
def test_checkpoint_schedules_own_host_runs_every_family(family):
    cs, test_validity = _their_validity_test()
    from hindsight.checkpoint_schedules import Schedule

    def factory(n, s):
        # Their host passes (N, checkpoint units); it checks storage limits and the schedule's n and r.
        s = max(s, 1)
        if family == "full":
            return Schedule("full", n), {cs.StorageType.RAM: n, cs.StorageType.DISK: 0}, 1
        if family.endswith("without N"):  # their host calls finalize(n) when its forward reaches n
            disk = family.startswith("disk")
            return (Schedule("disk:dir=unused" if disk else "full", None),
                    {cs.StorageType.RAM: 0 if disk else n, cs.StorageType.DISK: n if disk else 0}, 1)
        if family == "binomial":
            return Schedule(f"binomial:checkpoints={s}", n), {cs.StorageType.RAM: s + 1, cs.StorageType.DISK: 0}, 1
        if family == "online":  # with N known: the checkpoints its placement holds at the end
            return Schedule(f"online:checkpoints={s}", n), {cs.StorageType.RAM: s + 1, cs.StorageType.DISK: 0}, 1
        if family.startswith("cams"):
            online = ",online=1" if family.endswith("online") else ""
            return (Schedule(f"cams:checkpoints={s}{online}", n, stages=4),
                    {cs.StorageType.RAM: n, cs.StorageType.DISK: 0}, 1)
        return (Schedule(f"multilevel:ram={16 * (s + 1)},disk={16 * n},costs=1:1:0.5:0.5", n, state_bytes=16),
                {cs.StorageType.RAM: s + 1, cs.StorageType.DISK: n}, 1)

    for n, budgets in [(1, (0,)), (2, (1,)), (3, (1, 2)), (5, (2,)), (10, tuple(range(2, 10))),
                       (100, (1, 5, 30, 99)), (250, (25, 100, 225))]:
        test_validity(factory, n, budgets)


def test_the_checker_accepts_checkpoint_schedules_own_schedules():
    # The checker is not stricter than the contract where it matters: checkpoint_schedules' own schedules
    # pass it (they leave disk checkpoints behind, which hindsight's streams may not).
    cs = pytest.importorskip("checkpoint_schedules")
    checked = 0
    for n in (1, 2, 3, 10, 37, 100):
        for s in (1, 2, 5, 30):
            schedules = [(cs.Revolve(n, s), 1), (cs.MultistageCheckpointSchedule(n, 0, s), 1),
                         (cs.DiskRevolve(n, s), 1), (cs.SingleMemoryStorageSchedule(), n),
                         (cs.SingleDiskStorageSchedule(move_data=True), 1)]
            if 3 <= s < n:  # its own test's split of the units between RAM and disk, where it runs
                schedules.append((cs.HRevolve(n, s // 3, s - s // 3), 1))
            for schedule, work in schedules:
                check_stream(schedule, n, cs, work_limit=work, online=True, allow_leftovers=True)
                checked += 1
    assert checked == 6 * 4 * 5 + 5


def test_mixed_is_checkpoint_schedules_mixed_action_by_action():
    # mixed:checkpoints=C is MixedCheckpointSchedule(N, C) with its units in RAM (storage/mixed_plan.h).
    cs = pytest.importorskip("checkpoint_schedules")

    def key(action):
        name = type(action).__name__
        if name == "Forward":
            return name, action.n0, action.n1, action.write_ics, action.write_adj_deps, action.storage.name
        if name == "Reverse":
            return name, action.n1, action.n0, action.clear_adj_deps
        if name in ("Copy", "Move"):
            return name, action.n, action.from_storage.name, action.to_storage.name
        return (name,)

    for units in (1, 2, 3, 5, 11):
        for n in range(1, 61):
            theirs = [key(a) for a in cs.MixedCheckpointSchedule(n, units, storage=cs.StorageType.RAM)]
            ours = [key(a) for a in hindsight.checkpoint_schedule(f"mixed:checkpoints={units}", n)]
            assert ours == theirs, (units, n)
