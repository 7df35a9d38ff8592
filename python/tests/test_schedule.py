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
    online = hindsight.schedule("cams:checkpoints=10,online=1", 30000, state_bytes=160)
    assert cams.rhs_evaluations < online.rhs_evaluations < binomial.rhs_evaluations


def test_actions_and_errors():
    p = hindsight.schedule("binomial:checkpoints=2", 6, state_bytes=16, actions=True)
    assert p.actions.count("restore ") == 6
    with pytest.raises(ValueError, match="steps") as error:
        hindsight.schedule("full", 0, state_bytes=16)
    assert "--" not in str(error.value)  # Python's keywords, not the CLI's flags
    with pytest.raises(ValueError, match="costs"):
        hindsight.schedule("multilevel:ram=1KiB,disk=1MiB", 100, state_bytes=16, costs="1:2")
