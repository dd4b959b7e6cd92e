"""
The best-of-checkpoints protocol beside the final-model one: score every checkpoint of a run on validation episodes,
pick the best, and report it on separate test episodes, next to the final model on the same test episodes.

Liu et al. (TMC 2020), the published line of the UAV task, trained 4 000 episodes and reported the best of 40
checkpoints, each tested on 100 episodes: their choice was made on the episodes they report. Here the choice is made
on validation episodes (other seeds) and the chosen model is reported on test episodes it was not chosen on, so its row
is not inflated by the choice; give the same seeds to both to reproduce the paper's way.
"""

import csv
import os
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from sb3_maddpg.evaluation.evaluate import evaluate_controllers, format_table, summarize
from sb3_maddpg.evaluation.progress import episode_progress
from sb3_maddpg.evaluation.report import _load_controller, evaluation_env

# RL Zoo's CheckpointCallback names: <prefix>_<timesteps>_steps.zip
_CHECKPOINT_STEPS = re.compile(r"_(\d+)_steps\.zip$")


def run_checkpoints(model_path: str | os.PathLike) -> list[Path]:
    """
    A run's checkpoints in training order, then its final model: the ``*_<timesteps>_steps.zip`` files beside
    ``model_path`` (RL Zoo's ``--save-freq``) and ``model_path`` itself.

    :param model_path: the run's final model (``logs/<algo>/<env>_<k>/<env>.zip``)
    :return: the paths, the final model last
    """
    final = Path(model_path)
    if not final.is_file():
        raise ValueError(f"model file {final} not found")
    found = [
        (int(match.group(1)), path) for path in final.parent.glob("*.zip") if (match := _CHECKPOINT_STEPS.search(path.name))
    ]
    return [path for _, path in sorted(found)] + [final]


def select_checkpoint(
    model_paths: Sequence[str | os.PathLike],
    metric: str | None = None,
    validation_episodes: int = 10,
    validation_seed: int = 20_000,
    test_episodes: int = 20,
    test_seed: int = 10_000,
    env_id: str | None = None,
    env_kwargs: dict[str, Any] | None = None,
    device: str = "auto",
    progress: bool = False,
) -> dict[str, Any]:
    """
    Score each model on the validation episodes by the mean of ``metric``, then run the best one and the last one
    (the final model) on the test episodes.

    :param model_paths: the models to choose from, in training order, the final model last (``run_checkpoints``)
    :param metric: the per-episode metric to maximise (``evaluate``'s keys: ``return``, the task's metrics, on the UAV
        envs ``energy_efficiency`` (η_T), ``coverage``, ...); None: the task's ``selection_metric`` where the episodes
        report it (``TaskTools``; on the UAV envs ``energy_efficiency``), else the team return
    :param validation_episodes: episodes each model is scored on
    :param validation_seed: seed of the first validation episode (episode e: seed + e)
    :param test_episodes: episodes the chosen and the final model are reported on
    :param test_seed: seed of the first test episode (``evaluate``'s ``--seed`` for a table's rows)
    :param env_id: the env; by default the run's
    :param env_kwargs: env arguments over the run's (the UAV envs start at random places unless given here)
    :param device: device of the models
    :param progress: draw a progress bar of all the episodes (validation and test), with the time left, on stderr
    :return: ``scores`` (path, validation mean, per model), ``chosen`` and ``final`` (paths), ``metric``, and
        ``summary`` / ``table`` of the test episodes with the rows ``final model`` and ``best of K checkpoints``
    """
    from sb3_maddpg.zoo.registry import make_multiagent_env

    if not model_paths:
        raise ValueError("select_checkpoint needs at least one model")
    for name, count in (("validation_episodes", validation_episodes), ("test_episodes", test_episodes)):
        if isinstance(count, bool) or not isinstance(count, int) or count < 1:
            raise ValueError(f"{name} must be an integer >= 1, got {count!r}")
    # As evaluate: the run's env, and on the UAV envs a new start at random places every episode
    target = evaluation_env(model_paths[-1], env_id, env_kwargs)
    env_id, kwargs = target.env_id, target.kwargs

    total = len(model_paths) * validation_episodes + 2 * test_episodes
    with episode_progress(total, "select-checkpoint", progress) as advance:

        def run(path: str | os.PathLike, n_episodes: int, seed: int) -> list[dict[str, float]]:
            controller = _load_controller(path, env_id, kwargs, device)
            results, _ = evaluate_controllers(
                lambda: make_multiagent_env(env_id, **kwargs), [controller], n_episodes, seed, on_episode=advance
            )
            return results[controller.name]

        scores: list[tuple[Path, float]] = []
        for path in model_paths:
            episodes = run(path, validation_episodes, validation_seed)
            if metric is None:
                preferred = target.metrics.selection_metric
                metric = preferred if preferred is not None and preferred in episodes[0] else "return"
            if metric not in episodes[0]:
                raise ValueError(f"metric {metric!r} is not reported by {env_id}; it reports {sorted(episodes[0])}")
            scores.append((Path(path), sum(episode[metric] for episode in episodes) / len(episodes)))
        # The first of equal scores: the earliest checkpoint that reached it
        chosen = max(scores, key=lambda item: item[1])[0]
        final = Path(model_paths[-1])
        summary = summarize(
            {
                "final model": run(final, test_episodes, test_seed),
                f"best of {len(scores)} checkpoints ({chosen.name})": run(chosen, test_episodes, test_seed),
            }
        )
    return {
        "scores": scores,
        "chosen": chosen,
        "final": final,
        "metric": metric,
        "summary": summary,
        "table": format_table(summary, target.metrics),
        "env_id": env_id,
        "env_kwargs": kwargs,
    }


def write_selection(out_dir: str | os.PathLike, selection: dict[str, Any]) -> list[Path]:
    """
    Write ``checkpoint_scores.csv`` (each model's validation score), ``results.md`` (the test table) and
    ``results.csv`` (its rows, with the columns of ``evaluate``'s ``results.csv``) into ``out_dir``.

    :param out_dir: output folder (made if missing)
    :param selection: what ``select_checkpoint`` returned
    :return: the files written
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    scores_file = out / "checkpoint_scores.csv"
    with scores_file.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["model", f"validation_{selection['metric']}_mean", "chosen"])
        for path, score in selection["scores"]:
            writer.writerow([os.fspath(path), f"{score:.6f}", int(path == selection["chosen"])])
    table_file = out / "results.md"
    table_file.write_text(
        f"{selection['env_id']} {selection['env_kwargs']}: the final model and the best of {len(selection['scores'])} "
        f"models by validation {selection['metric']}, on the same test episodes\n\n{selection['table']}\n"
    )
    rows_file = out / "results.csv"
    with rows_file.open("w", newline="") as handle:
        rows = csv.DictWriter(handle, fieldnames=list(selection["summary"][0]))
        rows.writeheader()
        rows.writerows(selection["summary"])
    return [scores_file, table_file, rows_file]
