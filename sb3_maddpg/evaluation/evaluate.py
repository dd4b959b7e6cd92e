"""
Run controllers for whole episodes of a multi-agent env and summarise them: the team return (the sum of the agents'
rewards), each agent's return (``return_<agent>``), the length, and the episode metrics of the env's task
(:func:`~sb3_maddpg.evaluation.metrics.task_metrics`: those its ``metadata`` declares, and the event counts its tools
name) where the env reports them.
"""

import contextlib
import csv
import json
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from pettingzoo import ParallelEnv

from sb3_maddpg.common.atomic import atomic_open, atomic_write_text
from sb3_maddpg.common.callbacks import team_returns
from sb3_maddpg.evaluation.baselines import Controller
from sb3_maddpg.evaluation.metrics import TaskMetrics, task_metrics

# The table's column headers of what every env has; a task's metrics are headed as its tools say (TaskMetrics.symbol)
METRIC_SYMBOLS: dict[str, str] = {
    "return": "team return",
    "return_worst_decile": "worst 10 % team return",
    "length": "length",
}


@dataclass
class EpisodeRecord:
    """
    What one recorded episode leaves for the figures.

    :param frames: rendered RGB frames (every ``frame_every`` steps and the last)
    :param state_images: step -> global state image (3, S, S) uint8 at that step (0 is after reset)
    :param render_frames: step -> rendered RGB frame at that step
    :param env: the env it was played on, for the task's own figures (``TaskTools.episode_figures``), drawn from the
        env as it is when the figures are written: after the recorded controller's last episode
    """

    frames: list[np.ndarray] = field(default_factory=list)
    state_images: dict[int, np.ndarray] = field(default_factory=dict)
    render_frames: dict[int, np.ndarray] = field(default_factory=dict)
    env: Any = None


def run_episode(
    env: ParallelEnv,
    controller: Controller,
    seed: int | None = None,
    record: EpisodeRecord | None = None,
    state_steps: Sequence[int] = (),
    frame_every: int = 1,
    metrics: TaskMetrics | None = None,
) -> dict[str, float]:
    """
    Play one episode to its end.

    :param env: a PettingZoo ParallelEnv (with ``render_mode="rgb_array"`` to record frames)
    :param controller: what acts
    :param seed: the episode's seed (start positions with ``start="random"``)
    :param record: if given, filled with frames, state images and the env
    :param state_steps: steps at which to keep the state image and the rendered frame (0 = after reset)
    :param frame_every: keep one rendered frame every this many steps
    :param metrics: the task's episode metrics (default: :func:`~sb3_maddpg.evaluation.metrics.task_metrics` of
        ``env``)
    :return: the task's episode metrics where the env reports them (``metrics.keys``: an episode-end value from the
        first agent's info, an event count summed over the agents'), the team ``return`` (sum over agents and steps),
        each agent's return ``return_<agent>``, each team's ``return_team_<team>`` where the agents' names make
        several teams, and ``length``
    """
    if metrics is None:
        metrics = task_metrics(env)
    observations, infos = env.reset(seed=seed)
    controller.reset(env, seed=seed)
    wanted = set(state_steps)
    agent_returns = dict.fromkeys(env.possible_agents, 0.0)
    step = 0

    def keep(step: int, last: bool = False) -> None:
        if record is None:
            return
        frame = None
        # Only an env made to render draws: one without a render mode may keep PettingZoo's render(), which raises
        if getattr(env, "render_mode", None) is not None and (step % frame_every == 0 or last or step in wanted):
            frame = env.render()
        if frame is not None and (step % frame_every == 0 or last):
            record.frames.append(frame)
        if step in wanted:
            with contextlib.suppress(NotImplementedError, AttributeError):
                record.state_images[step] = env.state()
            if frame is not None:
                record.render_frames[step] = frame

    keep(0)
    while env.agents:
        # The agents still in the episode act (a step's dicts also hold those that left at that step)
        live = {agent: observation for agent, observation in observations.items() if agent in env.agents}
        actions = controller.act(live, env)
        observations, rewards, terminations, truncations, infos = env.step(actions)
        for agent, reward in rewards.items():
            agent_returns[agent] += float(reward)
        step += 1
        keep(step, last=not env.agents)
    if record is not None:
        record.env = env

    last_infos = list(infos.values()) or [{}]
    episode: dict[str, float] = {}
    for key in metrics.keys:
        if key in last_infos[0]:
            summed = key in metrics.summed
            episode[key] = float(sum(info.get(key, 0) for info in last_infos)) if summed else float(last_infos[0][key])
    episode["return"] = float(sum(agent_returns.values()))
    episode.update({f"return_{agent}": value for agent, value in agent_returns.items()})
    teams = team_returns(agent_returns)
    if len(teams) > 1:  # competing teams (MPE2's adversaries and good agents): each team's return
        episode.update({f"return_team_{team}": value for team, value in teams.items()})
    episode["length"] = float(step)
    return episode


def evaluate_controllers(
    make_env: Callable[[], ParallelEnv],
    controllers: Sequence[Controller],
    n_episodes: int,
    seed: int = 0,
    record_controller: str | None = None,
    state_steps: Sequence[int] = (),
    frame_every: int = 1,
    verbose: int = 0,
    on_episode: Callable[[], None] | None = None,
) -> tuple[dict[str, list[dict[str, float]]], EpisodeRecord | None]:
    """
    Run every controller for the same ``n_episodes`` episodes: episode ``e`` uses seed ``seed + e`` for all of them,
    so with ``start="random"`` they start from the same positions (a paired comparison).

    :param make_env: builds the env (one per controller)
    :param controllers: what to evaluate
    :param n_episodes: episodes per controller
    :param seed: seed of the first episode
    :param record_controller: name of the controller whose first episode is recorded for the figures
    :param state_steps: steps of the recorded episode whose state images are kept
    :param frame_every: keep one GIF frame every this many steps of the recorded episode
    :param verbose: 1 to print one line per episode
    :param on_episode: called after each episode (e.g. a progress bar's update)
    :return: controller name -> one metrics dict per episode, and the recorded episode (None if none was asked)
    """
    if n_episodes < 1:
        raise ValueError(f"n_episodes must be >= 1, got {n_episodes}")
    results: dict[str, list[dict[str, float]]] = {}
    record: EpisodeRecord | None = None
    for controller in controllers:
        env = make_env()
        episodes = []
        try:
            task = task_metrics(env)
            for episode in range(n_episodes):
                this_record = None
                if record is None and controller.name == record_controller:
                    this_record = record = EpisodeRecord()
                metrics = run_episode(env, controller, seed + episode, this_record, state_steps, frame_every, task)
                episodes.append(metrics)
                if on_episode is not None:
                    on_episode()
                if verbose:
                    values = "  ".join(
                        f"{_symbol(key, task)}={metrics[key]:.4f}" for key in _table_keys(metrics, task) if key in metrics
                    )
                    print(f"{controller.name} episode {episode + 1}/{n_episodes}: {values}")
        finally:
            env.close()
        results[controller.name] = episodes
    return results, record


def worst_decile(values: Sequence[float]) -> float:
    """
    The mean of the worst 10 % of the values: the lowest max(1, n // 10) of n (what a risk-averse user watches, the
    empirical CVaR at 0.1 of the team return).

    :param values: one value per episode, at least one
    :return: the mean of the lowest tenth
    """
    ordered = np.sort(np.asarray(values, dtype=np.float64))
    if ordered.ndim != 1 or len(ordered) == 0:
        raise ValueError(f"worst_decile needs a non-empty sequence of numbers, got {values!r}")
    return float(ordered[: max(1, len(ordered) // 10)].mean())


def summarize(results: dict[str, list[dict[str, float]]]) -> list[dict[str, Any]]:
    """
    Mean and standard deviation of each metric over the episodes, and the worst decile of the team return.

    :param results: controller name -> per-episode metrics
    :return: one row per controller: ``method``, ``episodes``, ``<metric>_mean`` / ``<metric>_std`` and, after the
        team return's, ``return_worst_decile`` (:func:`worst_decile`)
    """
    rows = []
    for name, episodes in results.items():
        row: dict[str, Any] = {"method": name, "episodes": len(episodes)}
        for key in episodes[0]:
            values = np.array([episode[key] for episode in episodes], dtype=np.float64)
            row[f"{key}_mean"] = float(values.mean())
            row[f"{key}_std"] = float(values.std())
            if key == "return":
                row["return_worst_decile"] = worst_decile(values)
        rows.append(row)
    return rows


def format_table(summary: Sequence[dict[str, Any]], metrics: TaskMetrics | None = None) -> str:
    """
    The summary as a Markdown table of ``mean ± std``: the task's episode-end values where the env has them (on the UAV
    envs c_T, f_T, e_T, eta_T), the team return, its worst decile (the mean of the worst 10 % of the episodes), the
    episode length and the task's event counts per episode where the env reports them (each agent's return is in
    the files).

    :param summary: rows from :func:`summarize`
    :param metrics: the task's metrics (:func:`~sb3_maddpg.evaluation.metrics.task_metrics` of its env); None: every
        metric of the summary other than the returns and the length is shown after the length, headed by its name
    :return: the table
    """
    present = {key[: -len("_mean")]: None for key in summary[0] if key.endswith("_mean")}
    if metrics is None:
        metrics = TaskMetrics(table_counts=tuple(key for key in present if not key.startswith("return") and key != "length"))
    keys = _table_keys(present, metrics)
    header = ["method", "episodes", *(_symbol(key, metrics) for key in keys)]
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    for row in summary:
        cells = [str(row["method"]), str(row["episodes"])]
        for key in keys:
            # the worst decile is one number, not a mean over the episodes
            single = f"{key}_mean" not in row
            cells.append(f"{row[key]:.4f}" if single else f"{row[f'{key}_mean']:.4f} ± {row[f'{key}_std']:.4f}")
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _table_keys(metrics: dict[str, Any], task: TaskMetrics) -> list[str]:
    """
    The keys of the printed table, in order: the task's episode-end values present, the team return, its worst decile
    and each competing team's return, the length and the task's event counts present.
    """
    keys = [key for key in (*task.values, "return", "length", *task.table_counts) if key in metrics]
    if "return" in keys:
        teams = [key for key in metrics if key.startswith("return_team_")]
        keys[keys.index("return") + 1 : keys.index("return") + 1] = ["return_worst_decile", *teams]
    return keys


def _symbol(key: str, task: TaskMetrics) -> str:
    """The table's column header of a key: the library's for the returns and the length, the task's for its metrics."""
    if key in METRIC_SYMBOLS:
        return METRIC_SYMBOLS[key]
    return task.symbol(key) if key in task.keys or key in task.table_counts else key


def write_results(
    out_dir: str | os.PathLike,
    results: dict[str, list[dict[str, float]]],
    summary: Sequence[dict[str, Any]],
    metadata: dict[str, Any] | None = None,
    metrics: TaskMetrics | None = None,
) -> dict[str, Path]:
    """
    Write ``results.csv`` (the summary), ``results.json`` (summary, per-episode values and ``metadata``),
    ``episodes.csv`` (one line per controller and episode) and ``results.md`` (the printed table).

    :param out_dir: output folder (created)
    :param results: controller name -> per-episode metrics
    :param summary: rows from :func:`summarize`
    :param metadata: what produced the results (command, env kwargs, model path, seed)
    :param metrics: the task's metrics, for the table (:func:`format_table`)
    :return: name -> path of each file written
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {name: out / name for name in ("results.csv", "results.json", "episodes.csv", "results.md")}

    with atomic_open(paths["results.csv"], "w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=list(summary[0]))
        writer.writeheader()
        writer.writerows(summary)

    episode_keys = list(next(iter(results.values()))[0])
    with atomic_open(paths["episodes.csv"], "w", newline="") as file:
        writer = csv.writer(file)
        writer.writerow(["method", "episode", *episode_keys])
        for name, episodes in results.items():
            for index, episode in enumerate(episodes):
                writer.writerow([name, index, *(episode[key] for key in episode_keys)])

    payload = {"metadata": metadata or {}, "summary": list(summary), "episodes": results}
    atomic_write_text(paths["results.json"], json.dumps(payload, indent=2, default=_to_json))
    atomic_write_text(paths["results.md"], format_table(summary, metrics) + "\n")
    return paths


def _to_json(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    return str(value)
