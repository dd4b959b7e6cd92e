"""`evaluate` and `plot` on an env without the UAV metrics (MPE2's simple_spread_v3)."""

import csv
from pathlib import Path

import pytest

from sb3_maddpg.__main__ import main

pytest.importorskip("mpe2")
ARGS = ["--env-kwargs", "continuous_actions:True", "max_cycles:15", "-params", "learning_starts:30", "batch_size:8"]


def test_evaluate_and_plot_a_brought_env(tmp_path: Path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(["train", "--env", "simple_spread_v3", "-n", "60", "-f", "logs", "--seed", "0", *ARGS]) == 0
    run = tmp_path / "logs" / "maddpg" / "simple_spread_v3_1"
    assert main(["evaluate", "--model", str(run / "simple_spread_v3.zip"), "--episodes", "2", "--out", "eval"]) == 0
    table = capsys.readouterr().out
    assert "| method | episodes | team return | worst 10 % team return | length |" in table and "| random | 2 |" in table
    with open(tmp_path / "eval" / "episodes.csv") as file:
        rows = list(csv.DictReader(file))
    assert {"return", "return_agent_0", "return_agent_2", "length"} <= set(rows[0])
    for row in rows:
        agents = sum(float(row[f"return_agent_{i}"]) for i in range(3))
        assert abs(agents - float(row["return"])) < 1e-6
    assert (tmp_path / "eval" / "figures" / "returns_vs_episode.png").is_file()
    assert (tmp_path / "eval" / "figures" / "maddpg_episode.gif").is_file()
    assert main(["plot", "--log", str(run), "--out", "figures"]) == 0
    assert (tmp_path / "figures" / "train_returns_vs_episode.png").is_file()
    assert not (tmp_path / "figures" / "train_fairness_vs_coverage.png").exists()


def test_evaluate_imports_gym_packages(tmp_path: Path, monkeypatch, capsys) -> None:
    package = tmp_path / "my_envs.py"
    package.write_text(
        "from sb3_maddpg.zoo import register_multiagent_env\n"
        "register_multiagent_env('my_spread_v0', 'mpe2.simple_spread_v3:parallel_env', {'continuous_actions': True})\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.chdir(tmp_path)
    argv = ["evaluate", "--baselines-only", "--env", "my_spread_v0", "--episodes", "1", "--out", "eval", "--no-gif"]
    assert main([*argv, "--gym-packages", "my_envs", "--env-kwargs", "max_cycles:5"]) == 0
    assert "| random | 1 |" in capsys.readouterr().out
