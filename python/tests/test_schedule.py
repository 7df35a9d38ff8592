"""hindsight.schedule: the model-free prediction equals a real run's counters (fixed steps)."""
import pytest

import hindsight


@pytest.mark.parametrize("spec", ["full", "binomial:checkpoints=10", "cams:checkpoints=10", "cams:budget=640",
                                  "binomial:checkpoints=10,stages=1", "binomial:checkpoints=1,stages=1",
                                  "cams:checkpoints=10,online=1", "online:checkpoints=10", "online:checkpoints=3,stages=1"])
def test_prediction_equals_a_real_run(spec):
    # The C++ pendulum: 4 parameters, state (theta, omega) = 16 bytes, rk4 with 2000 fixed steps.
    run = hindsight.classic_gradient("pendulum", [1.0, 1.0, 0.1, 0.5], step=1e-3, t1=2.0, storage=spec)
    steps = run.summary["steps"]
    assert steps == 2000
    p = hindsight.schedule(spec, steps, state_bytes=16, stages=4)
    assert p.recomputed_steps == run.summary["recomputed_steps"]
    assert p.rhs_evaluations == run.summary["rhs_evaluations"]
    assert p.states_stored == run.summary["states_stored"]


def test_cams_needs_fewer_rhs_than_binomial_at_equal_bytes():
    binomial = hindsight.schedule("binomial:checkpoints=10", 30000, state_bytes=160)
    cams = hindsight.schedule("cams:checkpoints=10", 30000, state_bytes=160)
    assert cams.peak_ram_bytes <= binomial.peak_ram_bytes
    assert cams.rhs_evaluations < binomial.rhs_evaluations
    # binomial reverses by revolve with all its C + 1 slots as snapshots (x_{N-1} the engine's working
    # state), the optimum without records; cams' records lower it a little at C = 10 (880 400 against
    # 885 748), its online mode (913 280) does not reach it.
    assert binomial.rhs_evaluations == 885_748
    assert cams.rhs_evaluations == 880_400
    online = hindsight.schedule("cams:checkpoints=10,online=1", 30000, state_bytes=160)
    assert cams.rhs_evaluations < online.rhs_evaluations


def test_stage_bytes_enlarge_the_step_records():
    # The rhs data a problem keeps per stage (the rod's 10 modes: 520 bytes) enlarges every step record of
    # full:stages=1 by its stages' data; cams keeps none.
    plain = hindsight.schedule("full:stages=1", 1000, state_bytes=160, stages=4)
    with_data = hindsight.schedule("full:stages=1", 1000, state_bytes=160, stages=4, stage_bytes=520)
    assert with_data.peak_ram_bytes == plain.peak_ram_bytes + 1000 * 4 * 520
    cams = hindsight.schedule("cams:checkpoints=10", 1000, state_bytes=160, stage_bytes=520)
    assert cams.peak_ram_bytes == hindsight.schedule("cams:checkpoints=10", 1000, state_bytes=160).peak_ram_bytes
    with pytest.raises(ValueError, match="stage_bytes = 12 must be a multiple of 8"):
        hindsight.schedule("full:stages=1", 10, state_bytes=16, stage_bytes=12)
    with pytest.raises(TypeError, match="stage_bytes"):
        hindsight.schedule("full:stages=1", 10, state_bytes=16, stage_bytes=8.0)


def test_stage_bytes_give_the_clis_prediction(cli):
    import json
    import subprocess
    out = subprocess.run([cli, "schedule", "--storage", "binomial:checkpoints=10,stages=1", "--steps", "1000",
                          "--state-bytes", "160", "--stage-bytes", "520", "--json"],
                         capture_output=True, text=True, check=True)
    p = hindsight.schedule("binomial:checkpoints=10,stages=1", 1000, state_bytes=160, stage_bytes=520)
    assert json.loads(out.stdout)["peak_ram_bytes"] == p.peak_ram_bytes


def test_actions_and_errors():
    p = hindsight.schedule("binomial:checkpoints=2", 6, state_bytes=16, actions=True)
    assert p.actions.count("restore ") == 6
    with pytest.raises(ValueError, match="steps") as error:
        hindsight.schedule("full", 0, state_bytes=16)
    assert "--" not in str(error.value)  # Python's keywords, not the CLI's flags
    with pytest.raises(ValueError, match="costs"):
        hindsight.schedule("multilevel:ram=1KiB,disk=1MiB", 100, state_bytes=16, costs="1:2")


def test_arguments_are_python_integers():
    # A float would be truncated (2.9 -> 2) and a bool read as 1: both are refused with Python's own types.
    for bad in (2.9, 2.0, True, "100", None, 1e17):
        with pytest.raises(TypeError, match="steps"):
            hindsight.schedule("full", bad, state_bytes=16)
    with pytest.raises(TypeError, match="state_bytes"):
        hindsight.schedule("full", 10, state_bytes=16.0)
    with pytest.raises(TypeError, match="stages"):
        hindsight.schedule("full", 10, state_bytes=16, stages=False)
    with pytest.raises(TypeError, match="costs"):
        hindsight.schedule("full", 10, state_bytes=16, costs=1.0)
    np = pytest.importorskip("numpy")
    assert hindsight.schedule("full", np.int64(10), state_bytes=np.int32(16)).steps == 10
    for steps, bytes_, stages, field in ((0, 16, 4, "steps"), (4 * 10**18 + 1, 16, 4, "steps"), (-5, 16, 4, "steps"),
                                         (10, 12, 4, "state_bytes"), (10, 2**60, 4, "state_bytes"),
                                         (10, 16, 65, "stages"), (10, 16, 0, "stages")):
        with pytest.raises(ValueError, match=field):
            hindsight.schedule("full", steps, state_bytes=bytes_, stages=stages)


@pytest.mark.parametrize("spec", ["full", "full:stages=1,budget=9000000000000000000", "binomial:checkpoints=1",
                                  "binomial:checkpoints=1000,budget=9000000000000000000", "online:checkpoints=10",
                                  "cams:checkpoints=10", "disk:dir=/tmp", "disk:dir=/tmp,chunk=1073741824"])
def test_extreme_arguments_give_sound_counts_or_a_value_error(spec):
    # Property over extreme N, state sizes and stages: counts that are what they claim, or ValueError.
    # Never a negative or wrapped-around count, never a crash of the interpreter (a 4 GiB state was one).
    sound = 0
    for steps in (1, 2, 1000, 2**31, 9 * 10**15, 10**17, 4 * 10**18):
        for state_bytes in (8, 65544, 2**32, 8 * (2**31 - 1)):
            for stages in (1, 4, 64):
                try:
                    p = hindsight.schedule(spec, steps, state_bytes=state_bytes, stages=stages)
                except ValueError as e:
                    assert len(str(e)) > 20
                    continue
                sound += 1
                assert p.steps == steps
                assert p.recomputed_steps >= 0 and p.states_stored >= 0 and p.ram_reads >= 0
                assert p.disk_writes >= 0 and p.disk_reads >= 0 and p.peak_ram_bytes >= 0
                assert p.rhs_evaluations < 2**63 and p.rhs_evaluations >= stages * steps
    assert sound > 0


def test_costs_argument_means_costs_in_the_spec_and_a_stride_trap_is_named():
    # Two 320-byte states of RAM (the 40 x 4 rod's): costs= plans exactly as the spec's costs= does, and the
    # stride, more than twice as dear, carries a warning naming the plan (docs/theory/storage.md).
    given = hindsight.schedule("multilevel:ram=640,disk=64KiB", 6000, state_bytes=320, costs="1:1:2:2")
    spec = hindsight.schedule("multilevel:ram=640,disk=64KiB,costs=1:1:2:2", 6000, state_bytes=320)
    assert given.recomputed_steps == spec.recomputed_steps == 12_308  # 24 752 with the closed-form leaves
    assert "warning" not in given
    stride = hindsight.schedule("multilevel:ram=640,disk=64KiB,schedule=stride", 6000, state_bytes=320,
                                costs="1:1:2:2")
    assert stride.recomputed_steps == 6_748_500
    assert "schedule=optimal" in stride["warning"] and "12308 recomputed steps" in stride["warning"]


def test_three_levels_predict_each_level_as_the_run_does(tmp_path):
    # RAM 3, SSD 10 and HDD 200 states of the pendulum (16 bytes), each level below RAM in its own subfolder.
    spec = f"multilevel:ram=48,levels=ssd:160@1:1;hdd:3200@2:2,costs=1:1,dir={tmp_path}"
    run = hindsight.classic_gradient("pendulum", [1.0, 1.0, 0.1, 0.5], step=1e-3, t1=2.0, storage=spec)
    reference = hindsight.classic_gradient("pendulum", [1.0, 1.0, 0.1, 0.5], step=1e-3, t1=2.0, storage="full")
    assert list(run.gradient) == list(reference.gradient)
    p = hindsight.schedule(spec, 2000, state_bytes=16, stages=4)
    assert p.recomputed_steps == run.summary["recomputed_steps"]
    assert p.states_stored == run.summary["states_stored"]
    assert [level["name"] for level in p.levels] == ["ssd", "hdd"]
    assert p.disk_writes == sum(level["writes"] for level in p.levels)
    assert p.schedule_cost == p.recomputed_steps + sum(
        level["writes"] * level["write_cost"] + level["reads"] * level["read_cost"] for level in p.levels)
    assert list(tmp_path.iterdir()) == []  # the level subfolders are removed after the run


def test_bound_is_below_the_plan_and_named_in_python_words():
    r = hindsight.schedule("multilevel:ram=32,disk=320,costs=1:1:0.5:0.5", 5000, 8, bound=True)
    synchronous = r["schedule_cost"] + r["hidden_io_cost"]
    assert r["lower_bound"] <= synchronous <= 1.01 * r["lower_bound"]
    assert "lower_bound" not in hindsight.schedule("multilevel:ram=32,disk=320,costs=1:1:0.5:0.5", 5000, 8)
    with pytest.raises(ValueError, match="bound=True"):
        hindsight.schedule("binomial:checkpoints=3", 100, 8, bound=True)
    with pytest.raises(TypeError, match="bound"):
        hindsight.schedule("binomial:checkpoints=3", 100, 8, bound=1)
