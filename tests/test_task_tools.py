"""
The plug-in point of a task package (``sb3_maddpg.evaluation.task_tools``): a task defined here, outside the library,
gets its own baseline run, its evaluation arguments used and its figure written by ``evaluate``, with no change under
``sb3_maddpg/``; an env without tools is evaluated as any env; tools that lack a member are refused by name.
"""

import csv
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from maddpg_test_envs import TargetReachEnv

from sb3_maddpg.__main__ import main
from sb3_maddpg.evaluation import TaskTools, evaluate_and_report, make_baselines, task_tools
from sb3_maddpg.zoo.registry import MULTIAGENT_ENVS, register_multiagent_env
from tests.cli_testing import fails_with

ENV_ID = "stub_reach_v0"


class TowardGoal:
    """The stub task's baseline: it reads the simulation (each agent's position and goal) and flies straight there."""

    name = "toward_goal"

    def reset(self, env: TargetReachEnv, seed: int | None = None) -> None:
        pass

    def act(self, observations: dict[str, np.ndarray], env: TargetReachEnv) -> dict[str, np.ndarray]:
        moves = np.clip((env.goal - env.pos) / 0.3, -1.0, 1.0).astype(np.float32)
        return {agent: moves[env.possible_agents.index(agent)] for agent in observations}


class StubTools(TaskTools):
    baselines = {"toward_goal": TowardGoal}
    default_baselines = ("toward_goal",)
    evaluation_kwargs = {"max_cycles": 4}

    def episode_figures(self, env: TargetReachEnv) -> dict:
        def write(path: Path) -> None:
            Path(path).write_text(f"{np.round(env.pos, 3).tolist()}\n")

        return {"positions.txt": write}


class StubReachEnv(TargetReachEnv):
    """A task package's env: the target reach task with its tools."""

    task_tools = StubTools()

    def __init__(self, render_mode: str | None = None, **kwargs) -> None:
        # no rendering (PettingZoo's render() raises): evaluate passes render_mode=None and must not call it
        super().__init__(**kwargs)


@pytest.fixture
def stub_env_id() -> Iterator[str]:
    register_multiagent_env(ENV_ID, StubReachEnv)
    yield ENV_ID
    MULTIAGENT_ENVS.pop(ENV_ID)


def test_a_task_of_its_own_gets_its_baseline_its_arguments_and_its_figure(stub_env_id: str, tmp_path: Path) -> None:
    report = evaluate_and_report(tmp_path, n_episodes=3, env_id=stub_env_id, verbose=0)
    assert report["env_kwargs"] == {"max_cycles": 4}
    returns = {row["method"]: row["return_mean"] for row in report["summary"]}
    assert list(returns) == ["random", "toward_goal"]
    assert returns["toward_goal"] > returns["random"]
    assert all(episode["length"] == 4 for episode in report["results"]["toward_goal"])
    # The task's default baseline is the recorded episode; its figure is written with the controller's prefix
    figures = tmp_path / "figures"
    assert (figures / "toward_goal_positions.txt").read_text().startswith("[[")
    assert not list(figures.glob("*state_step*"))  # the stub's state is not an image
    assert not (figures / "fairness_vs_coverage.png").exists()  # nor does it report the UAV metrics

    # Arguments given win over the task's evaluation arguments
    report = evaluate_and_report(tmp_path / "long", 1, env_id=stub_env_id, env_kwargs={"max_cycles": 6}, verbose=0)
    assert report["results"]["toward_goal"][0]["length"] == 6


def test_the_command_line_runs_and_checks_the_tasks_baselines(stub_env_id: str, tmp_path: Path, capsys) -> None:
    argv = ["evaluate", "--baselines-only", "--env", stub_env_id, "--episodes", "1", "--no-gif", "--out", str(tmp_path)]
    assert main([*argv, "--baselines", "toward_goal"]) == 0
    assert "| toward_goal | 1 |" in capsys.readouterr().out
    with open(tmp_path / "results.csv") as file:
        assert [row["method"] for row in csv.DictReader(file)] == ["toward_goal"]
    message = fails_with([*argv, "--baselines", "greedy_static"], capsys)
    assert f"unknown baseline 'greedy_static'; this env accepts: random, toward_goal ({stub_env_id})" in message


def test_an_env_without_tools_and_tools_that_lack_a_member() -> None:
    plain = TargetReachEnv()
    assert not task_tools(plain).baselines and not task_tools(plain).can_draw
    assert [controller.name for controller in make_baselines(None, task_tools(plain))] == ["random"]
    assert [controller.name for controller in make_baselines(None, task_tools(StubReachEnv()))] == ["random", "toward_goal"]

    class Partial:
        baselines = {}

    class PartialEnv(TargetReachEnv):
        task_tools = Partial()

    with pytest.raises(TypeError, match="lacks default_baselines, evaluation_kwargs, state_images, can_draw"):
        task_tools(PartialEnv())
