"""
The evaluation's figures: the returns and each of the task's episode-end values against episode, pairs of them
against each other (on the UAV envs fairness against coverage and against energy efficiency, the report's), from
evaluation results or from a training run's logs; state images, an episode GIF and the task's own figures (on the UAV
envs the coverage heat map). Which metrics a task has and how they are labelled is its own
(:class:`~sb3_maddpg.evaluation.metrics.TaskMetrics`).

Matplotlib is imported with the Agg backend only when a figure is drawn, so no display is needed.
"""

import csv
import glob
import os
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from sb3_maddpg.common.atomic import atomic_path
from sb3_maddpg.evaluation.evaluate import EpisodeRecord
from sb3_maddpg.evaluation.metrics import TaskMetrics, metric_name
from sb3_maddpg.evaluation.task_tools import task_tools

# The axis labels of what every env has; a task's metrics are labelled as its tools say (TaskMetrics.label)
LABELS: dict[str, str] = {
    "r": "team return",
    "return": "team return",
    "length": "episode length",
}

# One series: metric name -> values, one per episode (plus "x", the episode index or timestep, when not 0..n-1).
Series = dict[str, np.ndarray]


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def series_from_results(results: dict[str, list[dict[str, float]]]) -> dict[str, Series]:
    """
    :param results: controller name -> per-episode metrics (from ``evaluate_controllers``)
    :return: controller name -> metric name -> values
    """
    series = {}
    for name, episodes in results.items():
        keys = episodes[0].keys() if episodes else ()
        series[name] = {key: np.array([episode[key] for episode in episodes], dtype=np.float64) for key in keys}
    return series


def pair_file_name(x_key: str, y_key: str) -> str:
    """:return: the file name of the figure of ``y_key`` against ``x_key``: ``<y>_vs_<x>.png``"""
    return f"{y_key}_vs_{x_key}.png"


def pair_title(x_key: str, y_key: str, episodes: str) -> str:
    """:return: the title of the figure of ``y_key`` against ``x_key``, e.g. ``Fairness vs coverage (episode end)``"""
    name = metric_name(y_key)
    return f"{name[:1].upper()}{name[1:]} vs {metric_name(x_key)} ({episodes})"


def plot_metric_pair(
    series: dict[str, Series],
    x_key: str,
    y_key: str,
    path: str | os.PathLike,
    title: str | None = None,
    labels: Mapping[str, str] | None = None,
) -> Path:
    """
    One episode-end metric against another, one point per episode (on the UAV envs fairness against coverage, the
    report's figure 6.5, and against energy efficiency, its figure 6.6).

    :param series: name -> metric -> per-episode values
    :param x_key: the metric on the x axis
    :param y_key: the metric on the y axis
    :param path: output image file
    :param title: figure title (default: :func:`pair_title` of the episodes' end)
    :param labels: axis labels by metric (default: the metric's name, :func:`~sb3_maddpg.evaluation.metrics.metric_name`)
    :return: the path written
    """
    labels = {**LABELS, **(labels or {})}
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(5.5, 4.5))
    for name, values in series.items():
        if x_key in values and y_key in values and len(values[x_key]):
            ax.scatter(values[x_key], values[y_key], s=14, alpha=0.7, label=name)
    ax.set_xlabel(labels.get(x_key, metric_name(x_key)))
    ax.set_ylabel(labels.get(y_key, metric_name(y_key)))
    ax.set_title(title or pair_title(x_key, y_key, "episode end"))
    ax.grid(alpha=0.3)
    if len(series) > 1:
        ax.legend(fontsize="small")
    fig.tight_layout()
    with atomic_path(path) as temporary:
        fig.savefig(temporary, dpi=110)
    plt.close(fig)
    return Path(path)


def plot_task_figures(
    series: dict[str, Series],
    out_dir: str | os.PathLike,
    metrics: TaskMetrics,
    x_label: str = "episode",
    window: int = 1,
    prefix: str = "",
    episodes: str = "episode end",
) -> list[Path]:
    """
    The figures of a task's episode-end values, where every series has them all: each of the task's pairs
    (:func:`plot_metric_pair`, ``<prefix><y>_vs_<x>.png``) and each value against episode (:func:`plot_metrics_vs_episode`,
    ``<prefix>metrics_vs_episode.png``).

    :param series: name -> metric -> per-episode values
    :param out_dir: the folder written into
    :param metrics: the task's metrics
    :param x_label: label of the x axis of the metrics-vs-episode figure
    :param window: moving-average window of the metrics-vs-episode curves
    :param prefix: prefix of the file names
    :param episodes: what the pairs' titles call the episodes (``Fairness vs coverage (episode end)``)
    :return: the paths written, none where the task has no episode-end values or a series lacks one (or has only
        empty values of it, as a monitor file's empty cells)
    """
    if not metrics.values or not all(
        key in values and not np.all(np.isnan(values[key])) for values in series.values() for key in metrics.values
    ):
        return []
    out = Path(out_dir)
    labels = {key: metrics.label(key) for key in metrics.keys}
    paths = [
        plot_metric_pair(series, x, y, out / f"{prefix}{pair_file_name(x, y)}", pair_title(x, y, episodes), labels)
        for x, y in metrics.pairs
    ]
    path = out / f"{prefix}metrics_vs_episode.png"
    paths.append(plot_metrics_vs_episode(series, path, metrics.values, x_label, window, labels=labels))
    return paths


def _moving_average(values: np.ndarray, window: int) -> np.ndarray:
    if window <= 1 or len(values) < window:
        return values
    kernel = np.ones(window) / window
    return np.convolve(values, kernel, mode="valid")


def plot_metrics_vs_episode(
    series: dict[str, Series],
    path: str | os.PathLike,
    metrics: Sequence[str] | None = None,
    x_label: str = "episode",
    window: int = 1,
    title: str | None = None,
    labels: Mapping[str, str] | None = None,
) -> Path:
    """
    Each metric against episode (on the UAV envs the report's figure 6.7 for fairness), one panel per metric.

    :param series: name -> metric -> per-episode values (an optional ``"x"`` entry gives the x values)
    :param path: output image file
    :param metrics: the metrics to draw, one panel each (default: every metric of the series, in order)
    :param x_label: label of the x axis
    :param window: moving-average window drawn over the raw values (1: none)
    :param title: figure title
    :param labels: y-axis labels by metric, over the library's own (``LABELS``; default: the metric's key)
    :return: the path written
    """
    if metrics is None:
        metrics = list({key: None for values in series.values() for key in values if key != "x"})
    labels = {**LABELS, **(labels or {})}
    plt = _pyplot()
    from matplotlib.ticker import MaxNLocator

    n_cols = 2
    n_rows = (len(metrics) + n_cols - 1) // n_cols
    fig, axes = plt.subplots(n_rows, n_cols, figsize=(10, 3.2 * n_rows), squeeze=False)
    for ax, metric in zip(axes.ravel()[: len(metrics)], metrics, strict=True):
        for name, values in series.items():
            if metric not in values or not len(values[metric]):
                continue
            y = values[metric]
            x = values.get("x", np.arange(1, len(y) + 1))
            smooth = _moving_average(y, window)
            if smooth is y:
                ax.plot(x, y, marker="." if len(y) < 60 else None, label=name)
            else:
                (line,) = ax.plot(x, y, alpha=0.25)
                ax.plot(x[window - 1 :], smooth, color=line.get_color(), label=f"{name} (mean of {window})")
        ax.set_xlabel(x_label)
        ax.set_ylabel(labels.get(metric, metric))
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.grid(alpha=0.3)
    for ax in axes.ravel()[len(metrics) :]:
        ax.set_visible(False)
    handles, labels = axes.ravel()[0].get_legend_handles_labels()
    if len(labels) > 1 or window > 1:
        axes.ravel()[0].legend(fontsize="small")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    with atomic_path(path) as temporary:
        fig.savefig(temporary, dpi=110)
    plt.close(fig)
    return Path(path)


def plot_returns_vs_episode(
    series: dict[str, Series], path: str | os.PathLike, x_label: str = "episode", window: int = 1, title: str | None = None
) -> Path:
    """
    The team return, each agent's return (``return_<agent>``) and the episode length against episode, one panel each:
    the figure every env has.

    :param series: name -> metric -> per-episode values (an optional ``"x"`` entry gives the x values)
    :param path: output image file
    :param x_label: label of the x axis
    :param window: moving-average window drawn over the raw values (1: none)
    :param title: figure title
    :return: the path written
    """
    keys = {key for values in series.values() for key in values}
    agents = sorted(key for key in keys if key.startswith("return_"))
    metrics = [key for key in ("return", *agents, "length") if key in keys]
    return plot_metrics_vs_episode(series, path, metrics=metrics, x_label=x_label, window=window, title=title)


def save_episode_figures(record: EpisodeRecord, out_dir: str | os.PathLike, prefix: str = "", fps: int = 10) -> list[Path]:
    """
    The figures of one recorded episode: state images and rendered frames at the chosen steps, the task's own figures
    (``TaskTools.episode_figures``: on the UAV envs the coverage heat map at the end), and a GIF of the episode.

    :param record: the recorded episode
    :param out_dir: output folder (created)
    :param prefix: file name prefix, e.g. the controller's name and an underscore
    :param fps: GIF frames per second
    :return: the paths written
    """
    from PIL import Image

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for step, state in sorted(record.state_images.items()):
        path = out / f"{prefix}state_step{step:04d}.png"
        _save_state_array(state, path)
        written.append(path)
    for step, frame in sorted(record.render_frames.items()):
        path = out / f"{prefix}frame_step{step:04d}.png"
        with atomic_path(path) as temporary:
            Image.fromarray(np.asarray(frame, dtype=np.uint8)).save(temporary)
        written.append(path)
    if record.env is not None:
        for name, write in task_tools(record.env).episode_figures(record.env).items():
            path = out / f"{prefix}{name}"
            with atomic_path(path) as temporary:
                write(temporary)
            written.append(path)
    if record.frames:
        path = out / f"{prefix}episode.gif"
        with atomic_path(path) as temporary:
            images = [Image.fromarray(np.asarray(frame, dtype=np.uint8)) for frame in record.frames]
            images[0].save(temporary, save_all=True, append_images=images[1:], duration=max(1, round(1000 / fps)), loop=0)
        written.append(path)
    return written


def _save_state_array(state: np.ndarray, path: Path, scale: int = 4) -> None:
    """
    Write a stored global state image as ``save_state_image`` draws the live one: channels (PoIs, UAVs, coverage)
    as (red, green, blue), each pixel a ``scale`` x ``scale`` square.
    """
    from PIL import Image

    rgb = np.transpose(np.asarray(state, dtype=np.uint8), (1, 2, 0))
    rgb = np.repeat(np.repeat(rgb, scale, axis=0), scale, axis=1)
    with atomic_path(path) as temporary:
        Image.fromarray(np.ascontiguousarray(rgb)).save(temporary)


# ---------------------------------------------------------------------------------------------------------------------
# Training logs
# ---------------------------------------------------------------------------------------------------------------------
class NotAMonitorFileError(ValueError):
    """A file given or found as a ``monitor.csv`` is not a text CSV file."""


def find_monitor_files(log_path: str | os.PathLike) -> list[Path]:
    """
    :param log_path: a ``monitor.csv`` file, or a folder searched recursively (e.g. an RL Zoo run folder)
    :return: the monitor files found, sorted
    """
    path = Path(log_path)
    if path.is_file():
        return [path]
    return sorted(Path(p) for p in glob.glob(os.path.join(os.fspath(path), "**", "*monitor.csv"), recursive=True))


def load_monitor_series(monitor_file: str | os.PathLike) -> Series:
    """
    Read a ``monitor.csv`` written during training (one line per joint episode).

    :param monitor_file: the file (SB3's format: a ``#{...}`` header line, then CSV with ``r``, ``l``, ``t`` and the
        metric columns)
    :return: column name -> values; empty cells (envs without a metric) are NaN. Lines that are not one number (or
        an empty cell) per column, e.g. two runs' lines interleaved in one file, are skipped with a warning saying how
        many.
    :raises NotAMonitorFileError: if the file is not a text CSV file (a model .zip, a binary file)
    """
    try:
        with open(monitor_file, newline="", encoding="utf-8") as file:
            first = file.readline()
            if not first.startswith("#"):
                file.seek(0)
            reader = csv.reader(file)
            header = next(reader, None)
            rows, skipped = [], 0
            for line in reader:
                try:
                    if len(line) != len(header or []):
                        raise ValueError(f"{len(line)} fields")
                    rows.append([float(cell) if cell != "" else np.nan for cell in line])
                except ValueError:
                    skipped += 1
    except (UnicodeDecodeError, csv.Error) as error:
        raise NotAMonitorFileError(
            f"{os.fspath(monitor_file)} is not a monitor.csv (a text CSV file written during training): {error}"
        ) from error
    if skipped:
        total = skipped + len(rows)
        warnings.warn(f"{monitor_file}: skipped {skipped} malformed line(s) of {total} (not one number per column)")
    if not rows or header is None:
        return {}
    values = np.array(rows, dtype=np.float64)
    return {key: values[:, column] for column, key in enumerate(header)}


# Scalars of the rollout section that are SB3's own episode statistics (and the library's per-agent and per-team
# returns, ``ep_rew_<agent>``), not an env's episode metric
_SB3_ROLLOUT_SCALARS = ("success_rate", "exploration_rate")


def load_tensorboard_series(
    log_path: str | os.PathLike, prefix: str = "rollout", metrics: Sequence[str] | None = None
) -> Series:
    """
    Read the episode metrics logged by ``EpisodeMetricsCallback`` from TensorBoard event files (means over the
    episodes between two dumps, against timesteps), or where there are none (envs without them) SB3's
    ``rollout/ep_rew_mean`` and ``rollout/ep_len_mean`` as ``return`` and ``length``.

    :param log_path: a folder holding event files (searched recursively)
    :param prefix: logger section of the metrics
    :param metrics: the metrics to read (the task's episode-end values); None: every scalar of the section but SB3's
        episode statistics (``ep_*``, ``success_rate``, ``exploration_rate``)
    :return: metric name -> values, and ``"x"``: the timesteps; empty if nothing was found
    """
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    files = sorted(glob.glob(os.path.join(os.fspath(log_path), "**", "events.out.tfevents.*"), recursive=True))
    series: Series = {}
    for event_file in files:
        accumulator = EventAccumulator(event_file, size_guidance={"scalars": 0})
        accumulator.Reload()
        tags = accumulator.Tags().get("scalars", [])
        if metrics is None:
            section = [tag.split("/", 1)[1] for tag in tags if tag.startswith(f"{prefix}/")]
            wanted = [name for name in section if not name.startswith("ep_") and name not in _SB3_ROLLOUT_SCALARS]
        else:
            wanted = list(metrics)
        for metric in wanted:
            tag = f"{prefix}/{metric}"
            if tag in tags:
                events = accumulator.Scalars(tag)
                series[metric] = np.array([event.value for event in events])
                series["x"] = np.array([event.step for event in events], dtype=np.float64)
        if not series:
            for name, tag in (("return", f"{prefix}/ep_rew_mean"), ("length", f"{prefix}/ep_len_mean")):
                if tag in tags:
                    events = accumulator.Scalars(tag)
                    series[name] = np.array([event.value for event in events])
                    series["x"] = np.array([event.step for event in events], dtype=np.float64)
        if series:
            break
    return series


def monitor_returns(series: Series) -> Series:
    """A monitor's columns under the names of the evaluation: r -> return, r_<agent> -> return_<agent>, l -> length."""
    renamed = {"r": "return", "l": "length"}
    return {renamed.get(key, "return_" + key[2:] if key.startswith("r_") else key): values for key, values in series.items()}
