"""Competing teams from the command line: train on an MPE2 task with two teams, evaluate one team against another."""

import json
import os
from pathlib import Path

import pytest

from sb3_maddpg.__main__ import main

pytest.importorskip("mpe2")
ENV = "simple_adversary_discrete_v3"


@pytest.fixture(scope="module")
def adversary_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A tiny run of MPE2's simple_adversary (an adversary against two good agents, observations of two sizes)."""
    root = tmp_path_factory.mktemp("teams")
    cwd = os.getcwd()
    os.chdir(root)
    try:
        args = ["train", "--algo", "maddpg", "--env", ENV, "-n", "120", "--seed", "0", "--eval-freq", "-1"]
        status = main([*args, "--env-kwargs", "max_cycles:10", "-params", "learning_starts:40", "batch_size:16"])
    finally:
        os.chdir(cwd)
    assert status == 0
    return root / "logs" / "maddpg" / f"{ENV}_1" / f"{ENV}.zip"


def test_team_against_random_and_against_a_model(adversary_run: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "vs_random"
    assert main(["evaluate", "--model", str(adversary_run), "--team", "adversary", "--episodes", "2", "--out", str(out)]) == 0
    payload = json.loads((out / "results.json").read_text())
    methods = [row["method"] for row in payload["summary"]]
    assert methods == ["maddpg (adversary) vs random", "random (adversary) vs random", "random"]
    row = payload["summary"][0]
    # each team's return, beside the sum over all agents
    assert row["return_mean"] == pytest.approx(row["return_team_adversary_mean"] + row["return_team_agent_mean"])
    assert "return_team_adversary" in capsys.readouterr().out
    out = tmp_path / "vs_model"
    args = ["evaluate", "--model", str(adversary_run), "--team", "agent", "--opponent", str(adversary_run)]
    assert main([*args, "--episodes", "1", "--out", str(out)]) == 0
    methods = [row["method"] for row in json.loads((out / "results.json").read_text())["summary"]]
    assert methods[0] == f"maddpg (agent) vs {adversary_run.stem}"


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--team", "nobody"], "no agent of the team 'nobody' in this env; its teams: adversary, agent"),
        (["--team", "agent", "--opponent", "missing.zip"], "neither 'random' nor a saved model"),
        (["--opponent", "missing.zip"], "give --team as well"),
    ],
)
def test_team_errors(adversary_run: Path, tmp_path: Path, capsys, extra, message) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["evaluate", "--model", str(adversary_run), *extra, "--out", str(tmp_path / "e")])
    assert exit_info.value.code == 2 and message in capsys.readouterr().err


def test_team_needs_a_model(tmp_path: Path, capsys) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["evaluate", "--baselines-only", "--env", ENV, "--team", "agent", "--out", str(tmp_path / "e")])
    assert exit_info.value.code == 2 and "--team needs --model" in capsys.readouterr().err


def test_team_controller_refuses_a_team_the_env_lacks() -> None:
    from mpe2 import simple_adversary_v3

    from sb3_maddpg.evaluation.baselines import RandomController, TeamController

    controller = TeamController("nobody", RandomController(), RandomController())
    with pytest.raises(ValueError, match="no agent of the team 'nobody' in this env; its teams: adversary, agent"):
        controller.reset(simple_adversary_v3.parallel_env(), seed=0)


def test_an_opponent_that_does_not_fit_is_refused_naming_the_opponent(adversary_run: Path, tmp_path: Path, capsys) -> None:
    from maddpg_test_envs import TargetReachEnv

    from sb3_maddpg import MADDPG, make_multiagent_vec_env

    other = tmp_path / "target_reach.zip"
    MADDPG("MlpPolicy", make_multiagent_vec_env(TargetReachEnv), buffer_size=10, device="cpu").save(other)
    args = ["evaluate", "--model", str(adversary_run), "--team", "agent", "--opponent", str(other)]
    with pytest.raises(SystemExit) as exit_info:
        main([*args, "--episodes", "1", "--out", str(tmp_path / "e")])
    err = capsys.readouterr().err
    assert exit_info.value.code == 2 and "error: --opponent: the model was trained with 2 agents" in err
