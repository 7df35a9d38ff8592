"""hindsight.checkpoint_schedule: checkpoint_schedules' actions from hindsight's plans drive a stepper that is
not hindsight's to the gradient of full storage, recomputing what hindsight.schedule predicts."""
import pytest

import hindsight
from hindsight import Copy, EndForward, EndReverse, Forward, Move, Reverse, StorageType


def run(actions, steps, a=0.3):
    """z_{k+1} = z_k + h (a z_k - z_k^2), J = sum_k h z_{k+1}^2, dJ/da by the discrete adjoint."""
    h = 0.01
    ics, adj_deps = {}, {}
    n, z, lam, dj, advanced, forward_done, objective = 0, 1.0, None, 0.0, 0, False, 0.0
    for action in actions:
        if isinstance(action, Forward):
            assert n == action.n0, action
            if action.write_ics:
                ics[(action.storage, action.n0)] = z
            for k in action:
                if action.write_adj_deps:
                    adj_deps[k] = z
                z = z + h * (a * z - z * z)
                advanced += 1
                if not forward_done:
                    objective += h * z * z
            n = action.n1
        elif isinstance(action, EndForward):
            forward_done, lam = True, 2 * h * z
        elif isinstance(action, Reverse):
            for k in action:
                zk = adj_deps.pop(k)
                dj += lam * h * zk
                lam = lam * (1 + h * (a - 2 * zk)) + (2 * h * zk if k >= 1 else 0.0)
        elif isinstance(action, (Copy, Move)):
            if action.from_storage == StorageType.WORK:  # a checkpoint of the state at hand
                assert n == action.n, action
                ics[(action.to_storage, action.n)] = z
                continue
            assert action.to_storage == StorageType.WORK, action
            z = ics.pop((action.from_storage, action.n)) if isinstance(action, Move) else ics[(action.from_storage, action.n)]
            n = action.n
        else:
            assert isinstance(action, EndReverse)
            return objective, dj, advanced - steps, len(ics) + len(adj_deps)
    raise AssertionError("no EndReverse")


@pytest.mark.parametrize("spec,stages", [("binomial:checkpoints=3", 1), ("cams:checkpoints=3", 1), ("cams:checkpoints=6", 4),
                                         ("full", 1)])
def test_gradient_equals_full_and_recomputation_equals_the_prediction(spec, stages):
    steps = 60
    reference = run(hindsight.checkpoint_schedule("full", steps=steps), steps)
    actions = list(hindsight.checkpoint_schedule(spec, steps=steps, stages=stages))
    objective, gradient, extra, leftover = run(actions, steps)
    assert (objective, gradient) == reference[:2]
    assert leftover == 0  # Move and clear_adj_deps release everything by the end
    p = hindsight.schedule(spec, steps, state_bytes=8, stages=stages)
    # The host re-runs a step for each adjoint step without held data (hindsight's adjoint steps that
    # recompute their stages), except the forward run's last step, which writes its data to WORK itself.
    reruns = p.adjoint_stage_recomputations if spec.startswith("cams") else steps
    last = [a for a in actions[:actions.index(EndForward())] if isinstance(a, Forward)][-1]
    taped_in_forward = last.write_adj_deps and last.storage == StorageType.WORK
    assert extra == p.recomputed_steps + reruns - taped_in_forward


def test_actions_read_as_checkpoint_schedules():
    actions = list(hindsight.checkpoint_schedule("binomial:checkpoints=1", steps=3))
    assert repr(actions[0]) == "Forward(0, 2, True, False, StorageType.RAM)"
    assert actions[2] == EndForward() and actions[-1] == EndReverse()
    assert [list(a) for a in actions if isinstance(a, Reverse)] == [[2], [1], [0]]


def test_bad_arguments_name_themselves():
    with pytest.raises(ValueError, match="online"):
        hindsight.checkpoint_schedule("online:checkpoints=3", steps=10)
    with pytest.raises(ValueError, match="steps"):
        hindsight.checkpoint_schedule("full", steps=0)
    with pytest.raises(TypeError, match="steps"):
        hindsight.checkpoint_schedule("full", steps=2.5)
    with pytest.raises(ValueError, match="stages = 1"):
        hindsight.checkpoint_schedule("binomial:checkpoints=3,stages=1", steps=10, stages=4)
