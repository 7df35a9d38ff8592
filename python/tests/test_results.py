"""hindsight.optimize (with a per-iteration callback) runs what `hindsight optimize` runs: the same
history and designs bit for bit (seconds excepted); read_results reads it with the C++ checks;
plot_comparison draws the Fig.-4 comparison."""
import json
import subprocess

import pytest

import hindsight
from conftest import TINY

CONFIG = {**TINY, "optimization": {"iterations": 3}}
# The columns that are the same bits on every run (the seconds are not), from the library's schema.
EXACT_COLUMNS = [column.name for column in hindsight.history_columns() if column.reproducible]


def test_optimize_with_callback_equals_the_cli(cli, tmp_path):
    seen = []
    history = hindsight.optimize(CONFIG, out=tmp_path / "py", callback=lambda record: seen.append(record))
    assert history.finished and history.checksummed
    assert [r["iteration"] for r in seen] == list(history.history["iteration"]) == [0, 1, 2, 3]
    assert seen[-1]["psi1"] == history.history["psi1"][-1]
    # Every update's first-order residual is recorded; the final evaluation (no update) has none, and
    # a run that used all its iterations did not stop by the convergence rule.
    assert all(k >= 0 for k in history.history["kkt_residual"][:-1])
    assert seen[0]["kkt_residual"] == history.history["kkt_residual"][0]
    assert not any(r["converged"] for r in seen)
    assert history.designs.shape == (4, 2, 8)
    assert history.configuration["optimization"]["iterations"] == 3

    config_file = tmp_path / "config.json"
    config_file.write_text(json.dumps(CONFIG))
    subprocess.run([cli, "optimize", "--config", str(config_file), "--out", str(tmp_path / "cli")], check=True,
                   capture_output=True)
    expected = hindsight.read_results(tmp_path / "cli")
    for column in EXACT_COLUMNS:
        assert history.history[column].tobytes() == expected.history[column].tobytes(), column
    assert history.designs.tobytes() == expected.designs.tobytes()
    assert history.configuration == expected.configuration


def test_history_records_and_plot_share_the_schema(tmp_path):
    """The callback's records, read_results' columns (with the file's types) and the plot script's
    labels all come from the one schema of the C++ library."""
    import os
    import numpy as np
    from hindsight import _plot_history

    schema = hindsight.history_columns()
    names = [column.name for column in schema]
    assert names[:2] == ["iteration", "backtracks"] and len(names) == len(set(names))
    records = []
    result = hindsight.optimize(CONFIG, out=tmp_path / "run", callback=records.append)
    assert list(result.history.keys()) == names
    assert all(list(record.keys()) == names + ["converged"] for record in records)
    for column in schema:
        expected = np.int32 if column.type == "int32" else np.float64
        assert result.history[column.name].dtype == expected, column.name
        assert [record[column.name] for record in records] == list(result.history[column.name]) or \
            column.name in ("max_design_change", "kkt_residual"), column.name  # NaN != NaN in the last row
    # The plot script's JSON (problems/topopt/history_columns.json, copied beside it) is the same table.
    assert list(_plot_history.history_columns().values()) == [dict(column) for column in schema]
    assert _plot_history.axis_label("psi1") == "Integral compliance of the design [J s]"
    assert os.path.basename(_plot_history.__file__) == "_plot_history.py"


def test_callback_can_stop_and_the_run_resumes(tmp_path):
    out = tmp_path / "run"
    stopped = hindsight.optimize(CONFIG, out=out, callback=lambda record: record["iteration"] < 1)
    assert stopped.stopped_by_callback and not stopped.finished
    assert list(stopped.history["iteration"]) == [0, 1]
    resumed = hindsight.optimize(CONFIG, out=out, resume=True)
    whole = hindsight.optimize(CONFIG, out=tmp_path / "whole")
    for column in EXACT_COLUMNS:
        assert resumed.history[column].tobytes() == whole.history[column].tobytes(), column
    # Without resume or force an existing run is refused, in Python's words (not the CLI's flags).
    with pytest.raises(ValueError, match="pass resume=True to continue it or force=True to overwrite it") as error:
        hindsight.optimize(CONFIG, out=out)
    assert "--" not in str(error.value)
    with pytest.raises(ValueError, match="resume=True and force=True exclude each other"):
        hindsight.optimize(CONFIG, out=out, resume=True, force=True)


def test_callback_exception_propagates_and_leaves_a_valid_file(tmp_path):
    def fail(record):
        if record["iteration"] == 1:
            raise KeyError("stop here")

    with pytest.raises(KeyError, match="stop here"):
        hindsight.optimize(CONFIG, out=tmp_path / "run", callback=fail)
    partial = hindsight.read_results(tmp_path / "run")
    assert list(partial.history["iteration"]) == [0, 1]


def test_plot_comparison(tmp_path):
    a = hindsight.optimize(CONFIG, out=tmp_path / "a")
    b = hindsight.optimize(CONFIG, out=tmp_path / "b", optimization={"objective": "psi2"})
    png = tmp_path / "fig4.png"
    figure = hindsight.plot_comparison(tmp_path / "a", b, out=png)
    assert png.stat().st_size > 1000
    assert len(figure.axes) == 3
    assert a.history["psi1"][-1] > 0


def test_verbose_prints_the_cli_progress_lines(tmp_path, capsys):
    hindsight.optimize(CONFIG, out=tmp_path / "run", verbose=True)
    lines = [line for line in capsys.readouterr().out.splitlines() if line.startswith("iter")]
    assert len(lines) == 4 and "psi1" in lines[0] and "V/V0" in lines[0], lines
    hindsight.optimize(CONFIG, out=tmp_path / "quiet")
    assert "iter" not in capsys.readouterr().out


def test_read_results_gives_every_scenarios_history(tmp_path):
    config = {**TINY, "optimization": {"iterations": 2, "aggregate": "max"},
              "scenarios": [{"name": "slow", "crankSpeed": 15.0}, {"name": "fast", "crankSpeed": 40.0}]}
    run = hindsight.optimize(config, out=tmp_path / "run")
    result = hindsight.read_results(tmp_path / "run")
    assert result.scenarios.shape == (3, 2) and result.scenario_psi2.shape == (3, 2)
    assert result.scenario_objective_scale.shape == (2,)
    # psi grows with the crank speed; the history holds the worst scenario's psi1 (relative to its psi(x0)).
    assert (result.scenarios[:, 1] > result.scenarios[:, 0]).all()
    relative = result.scenarios / result.scenario_objective_scale
    for k in range(3):
        assert result.history["psi1"][k] == result.scenarios[k, relative[k].argmax()]
    assert run.history["psi1"].tobytes() == result.history["psi1"].tobytes()
    # The shared plotting code draws them (as `hindsight plot` does).
    figure = hindsight.plot_comparison(result, out=tmp_path / "scenarios.png")
    assert (tmp_path / "scenarios.png").stat().st_size > 0
    assert any("scenario slow" in line.get_label() for line in figure.axes[0].get_lines())
    # A run without scenarios has none of these keys.
    plain = hindsight.optimize(CONFIG, out=tmp_path / "plain")
    assert "scenarios" not in plain and "scenarios" not in hindsight.read_results(tmp_path / "plain")
