"""
The plug-in point of a task package (``sb3_maddpg.evaluation.task_tools``): a task defined here, outside the library,
gets its own baseline run, its evaluation arguments used and its figure written by ``evaluate``, with no change under
``sb3_maddpg/``; a task that declares its metrics gets its own columns, symbols, labels and figures, and its picture
under its own TensorBoard tag; an env without tools is evaluated as any env; tools that lack a member are refused by
name.
"""

import csv
import functools
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from maddpg_test_envs import TargetReachEnv

from sb3_maddpg.__main__ import main
from sb3_maddpg.common.eval_tensorboard import MAP_SIZE_PX, image_tag
from sb3_maddpg.evaluation import (
    TaskTools,
    evaluate_and_report,
    make_baselines,
    plot_training_logs,
    task_metrics,
    task_tools,
)
from sb3_maddpg.evaluation.task_tools import NO_TASK_TOOLS
from sb3_maddpg.zoo.registry import MULTIAGENT_ENVS, register_multiagent_env
from tests.cli_testing import fails_with

ENV_ID = "stub_reach_v0"
METERED_ID = "metered_reach_v0"


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


class MeteredTools(StubTools):
    """The tools of a task with metrics of its own: how its table and its figures show them, and its picture."""

    can_draw = True
    map_name = "reach_map"
    metric_symbols = {"mean_distance": "d_mean"}
    metric_labels = {"mean_distance": "mean distance $d$", "worst_distance": "worst distance (cells)"}
    metric_pairs = (("mean_distance", "worst_distance"),)
    # the arrivals the env declares, and the misses it reports without declaring them
    event_counts = ("misses", "arrivals")

    def draw_map(self, env: TargetReachEnv, size_px: tuple[int, int]) -> np.ndarray:
        image = np.zeros((size_px[1], size_px[0], 3), dtype=np.uint8)
        image[..., 1] = 200
        return image


class MeteredReachEnv(StubReachEnv):
    """The stub task with episode metrics: two episode-end values, a declared count and an undeclared one."""

    metadata = {
        **TargetReachEnv.metadata,
        "episode_metrics": ("mean_distance", "worst_distance", "arrivals"),
        "per_agent_episode_metrics": ("arrivals",),
    }
    task_tools = MeteredTools()

    def step(self, actions: dict) -> tuple:
        observations, rewards, terminations, truncations, infos = super().step(actions)
        distances = np.linalg.norm(self.pos - self.goal, axis=1)
        for i, info in enumerate(infos.values()):
            near = int(distances[i] < 0.5)
            info.update(
                mean_distance=float(distances.mean()), worst_distance=float(distances.max()), arrivals=near, misses=1 - near
            )
        return observations, rewards, terminations, truncations, infos


@pytest.fixture
def metered_env_id() -> Iterator[str]:
    register_multiagent_env(METERED_ID, MeteredReachEnv)
    yield METERED_ID
    MULTIAGENT_ENVS.pop(METERED_ID)


def test_a_task_with_metrics_of_its_own_gets_its_columns_and_labels(
    metered_env_id: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from matplotlib.axes import Axes

    labels: list[str] = []

    def recording(original):
        def record(ax, label, *args, **kwargs):
            labels.append(label)
            return original(ax, label, *args, **kwargs)

        return record

    for name in ("set_xlabel", "set_ylabel"):
        monkeypatch.setattr(Axes, name, recording(getattr(Axes, name)))

    metrics = task_metrics(MeteredReachEnv())
    assert metrics.values == ("mean_distance", "worst_distance")
    assert metrics.keys == ("mean_distance", "worst_distance", "arrivals", "misses")
    assert metrics.summed == ("arrivals", "misses") and metrics.table_counts == ("misses", "arrivals")

    report = evaluate_and_report(tmp_path, n_episodes=3, env_id=metered_env_id, verbose=0)
    header = report["table"].splitlines()[0]
    assert header == (
        "| method | episodes | d_mean | worst distance | team return | worst 10 % team return | length | misses | arrivals |"
    )
    assert (tmp_path / "results.md").read_text().splitlines()[0] == header
    episode = report["results"]["toward_goal"][0]
    # episode-end values from the first agent's info, counts summed over the two agents
    assert list(episode)[:4] == ["mean_distance", "worst_distance", "arrivals", "misses"]
    assert episode["arrivals"] + episode["misses"] == 2.0
    with open(tmp_path / "results.csv") as file:
        assert {"mean_distance_mean", "worst_distance_std", "misses_mean"} <= set(next(csv.DictReader(file)))
    figures = tmp_path / "figures"
    assert (figures / "worst_distance_vs_mean_distance.png").is_file()
    assert (figures / "metrics_vs_episode.png").is_file()
    assert not (figures / "fairness_vs_coverage.png").exists()
    # the task's labels on the pair's axes and the panels
    assert {"mean distance $d$", "worst distance (cells)", "evaluation episode"} <= set(labels)

    # the same figures from a training run's monitor file, for the env named
    run = tmp_path / "run"
    run.mkdir()
    rows = [f"{-i},4,{i},{0.5 + i / 10},{1.0 + i / 10},1,1" for i in range(6)]
    text = "\n".join(['#{"t_start": 0, "env_id": "multi-agent"}', "r,l,t,mean_distance,worst_distance,arrivals,misses", *rows])
    (run / "monitor.csv").write_text(text + "\n")
    paths = plot_training_logs(run, tmp_path / "training", env_id=metered_env_id)
    assert [path.name for path in paths] == [
        "train_returns_vs_episode.png",
        "train_worst_distance_vs_mean_distance.png",
        "train_metrics_vs_episode.png",
    ]


def test_the_tasks_picture_under_its_own_tag(tmp_path: Path) -> None:
    from stable_baselines3.common.callbacks import EvalCallback
    from stable_baselines3.common.logger import configure
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    from sb3_maddpg import MADDPG, make_multiagent_vec_env
    from sb3_maddpg.common.eval_tensorboard import EvalTensorBoardCallback
    from sb3_maddpg.zoo.monitor import JointEpisodeMonitor

    assert image_tag(MeteredReachEnv().task_tools) == "eval/reach_map"
    assert image_tag(NO_TASK_TOOLS) == "eval/state_image"

    env = make_multiagent_vec_env(MeteredReachEnv, n_envs=1, seed=0, env_kwargs={"max_cycles": 4})
    eval_env = JointEpisodeMonitor(make_multiagent_vec_env(MeteredReachEnv, seed=1, env_kwargs={"max_cycles": 4}))
    model = MADDPG("MlpPolicy", JointEpisodeMonitor(env), buffer_size=50, learning_starts=100, batch_size=4, seed=0)
    model.set_logger(configure(str(tmp_path), ["tensorboard"]))
    pictures = EvalTensorBoardCallback(functools.partial(MeteredReachEnv, max_cycles=4))
    model.learn(8, callback=EvalCallback(eval_env, callback_after_eval=pictures, n_eval_episodes=1, eval_freq=4, warn=False))
    (events,) = tmp_path.glob("**/events.out.tfevents.*")
    accumulator = EventAccumulator(str(events), size_guidance={"images": 0})
    accumulator.Reload()
    assert accumulator.Tags()["images"] == ["eval/reach_map"]
    assert {(image.width, image.height) for image in accumulator.Images("eval/reach_map")} == {MAP_SIZE_PX}
    # the episode metrics the env declares, each evaluation's mean
    assert {"eval/mean_distance", "eval/arrivals"} <= set(accumulator.Tags()["scalars"])
