"""The best-of-checkpoints protocol: a run's checkpoints in order, the choice on validation episodes, the test rows."""

import csv
import json
import os
from pathlib import Path

import pytest
from cli_testing import fails_with

from sb3_maddpg.__main__ import main
from sb3_maddpg.evaluation.checkpoints import run_checkpoints

pytest.importorskip("mpe2")
ENV_ID = "simple_spread_v3"


@pytest.fixture(scope="module")
def run_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 60-timestep run of simple_spread_v3 (5-step episodes) with a checkpoint every 5 timesteps."""
    folder = tmp_path_factory.mktemp("run")
    cwd = os.getcwd()
    os.chdir(folder)
    try:
        args = [
            "train",
            "--algo",
            "maddpg",
            "--env",
            ENV_ID,
            "-n",
            "60",
            "--seed",
            "0",
            "--eval-freq",
            "-1",
            "--save-freq",
            "5",
        ]
        small = ["-params", "learning_starts:10", "batch_size:8", "buffer_size:100", "--env-kwargs", "max_cycles:5"]
        assert main([*args, *small]) == 0
    finally:
        os.chdir(cwd)
    return folder / "logs" / "maddpg" / f"{ENV_ID}_1"


def test_checkpoints_come_in_training_order_then_the_final_model(run_folder: Path):
    models = run_checkpoints(run_folder / f"{ENV_ID}.zip")
    # 5, 10, ..., 60: in the order of their timesteps, not of their names (rl_model_10 sorts before rl_model_5)
    assert [path.name for path in models] == [f"rl_model_{5 * k}_steps.zip" for k in range(1, 13)] + [f"{ENV_ID}.zip"]


def test_the_choice_is_the_best_validation_score_and_its_test_row_is_evaluates(run_folder: Path, tmp_path: Path, capsys):
    out = tmp_path / "select"
    argv = ["select-checkpoint", "--model", str(run_folder / f"{ENV_ID}.zip"), "--validation-episodes", "2"]
    assert main([*argv, "--episodes", "3", "--seed", "100", "--env-kwargs", "max_cycles:5", "--out", str(out)]) == 0
    with (out / "checkpoint_scores.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 13 and sum(int(row["chosen"]) for row in rows) == 1
    chosen = next(row for row in rows if row["chosen"] == "1")
    scores = [float(row["validation_return_mean"]) for row in rows]
    assert float(chosen["validation_return_mean"]) == max(scores)
    assert scores.index(max(scores)) == rows.index(chosen)  # the first of equal scores
    table = (out / "results.md").read_text()
    assert "| final model |" in table and f"best of 13 checkpoints ({Path(chosen['model']).name})" in table
    with (out / "results.csv").open() as handle:
        table_rows = list(csv.DictReader(handle))
    # the table's rows as evaluate's results.csv has them (what experiments/tmc_table.py reads)
    assert [row["method"] for row in table_rows] == ["final model", f"best of 13 checkpoints ({Path(chosen['model']).name})"]
    assert all(f"{float(row['return_mean']):.4f}" in table for row in table_rows)
    printed = capsys.readouterr().out

    # evaluate's own row of the chosen model on the same test episodes (seeds 100, 101, 102) is the best-of row
    assert main(["evaluate", "--model", chosen["model"], "--episodes", "3", "--seed", "100", "--env-kwargs", "max_cycles:5",
                 "--baselines", "random", "--no-gif", "--verbose", "0", "--out", str(tmp_path / "eval")]) == 0  # fmt: skip
    evaluated = json.loads((tmp_path / "eval" / "results.json").read_text())
    own_row = next(row for row in evaluated["summary"] if row["method"] == "maddpg")
    best_line = next(line for line in printed.splitlines() if line.startswith("| best of"))
    assert f"| {own_row['return_mean']:.4f} ± {own_row['return_std']:.4f} |" in best_line


def test_bad_input_is_one_line(run_folder: Path, tmp_path: Path, capsys):
    model = str(run_folder / f"{ENV_ID}.zip")
    out = ["--out", str(tmp_path / "o")]
    assert "model file" in fails_with(["select-checkpoint", "--model", str(tmp_path / "none.zip"), *out], capsys)
    assert "test_episodes must be an integer >= 1" in fails_with(
        ["select-checkpoint", "--model", model, "--episodes", "0", *out], capsys
    )
    message = fails_with(
        ["select-checkpoint", "--model", model, "--metric", "coverage", "--validation-episodes", "1", *out], capsys
    )
    assert "metric 'coverage' is not reported by simple_spread_v3" in message
