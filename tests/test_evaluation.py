"""Baselines, evaluation results files and the report's figures."""

import csv
import json

import numpy as np
import pytest
from PIL import Image

from sb3_maddpg.evaluation import RandomController, evaluate_and_report, evaluate_controllers, plot_training_logs, summarize
from sb3_maddpg.evaluation.evaluate import format_table, worst_decile
from sb3_maddpg.evaluation.metrics import TaskMetrics
from sb3_maddpg.zoo.registry import make_multiagent_env
from sb3_maddpg_envs import uav_coverage_v0
from sb3_maddpg_envs.uav_coverage.baselines import GreedyStaticController, assign_targets, fly_to, greedy_placement

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def assert_png(path) -> None:
    with open(path, "rb") as file:
        assert file.read(8) == PNG_MAGIC, path
    with Image.open(path) as image:
        image.verify()


def test_greedy_placement_covers_distinct_areas_and_stays_connected() -> None:
    lattice = np.stack(np.meshgrid(np.arange(16.0), np.arange(16.0), indexing="xy"), axis=-1).reshape(-1, 2)
    spots = greedy_placement(lattice, n_uavs=6, map_size=16, coverage_range=3.0, comm_range=6.0)
    assert spots.shape == (6, 2)
    assert ((spots >= 0) & (spots < 16)).all()
    # every spot has another spot within comm range (minus the safety margin)
    distances = np.linalg.norm(spots[:, None] - spots[None], axis=-1)
    np.fill_diagonal(distances, np.inf)
    assert (distances.min(axis=1) <= 6.0 - 0.05 + 1e-9).all()
    covered = (np.linalg.norm(lattice[:, None] - spots[None], axis=-1) <= 3.0).any(axis=1)
    # six discs of radius 3 hold at most 6 * 29 lattice points; greedy gets well over half of the 256
    assert covered.sum() > 150


def test_greedy_placement_first_spot_is_the_best_single_spot() -> None:
    pois = np.array([[1.0, 1.0], [1.2, 1.4], [1.5, 0.8], [14.0, 14.0]])
    spot = greedy_placement(pois, n_uavs=1, map_size=16, coverage_range=1.0)[0]
    assert (np.linalg.norm(pois[:3] - spot, axis=1) <= 1.0).all()


def test_assign_targets_and_fly_to() -> None:
    positions = np.array([[0.0, 0.0], [10.0, 10.0]])
    targets = np.array([[9.0, 10.0], [0.0, 2.0]])
    assigned = assign_targets(positions, targets)
    np.testing.assert_allclose(assigned, [[0.0, 2.0], [9.0, 10.0]])
    actions = fly_to(positions, assigned, max_distance=3.0)
    assert actions.dtype == np.float32
    # straight up (theta = pi / 2) at 2/3 of l_max; straight left (theta = pi) at 1/3 of l_max
    np.testing.assert_allclose(actions, [[0.25, 2.0 / 3.0], [0.5, 1.0 / 3.0]], atol=1e-6)
    # at the target: hover
    np.testing.assert_allclose(fly_to(assigned, assigned, 3.0)[:, 1], 0.0)


def test_greedy_static_reaches_its_spots_and_hovers() -> None:
    env = uav_coverage_v0.parallel_env(n_uavs=3, obs_size=16, max_cycles=30, start="random")
    controller = GreedyStaticController()
    observations, _ = env.reset(seed=3)
    controller.reset(env, seed=3)
    for _ in range(30):
        observations, _, _, _, infos = env.step(controller.act(observations, env))
    np.testing.assert_allclose(env.core.positions, controller.targets, atol=1e-3)
    assert all(info["wall_hits"] == 0 for info in infos.values())


def test_greedy_beats_random_on_coverage_with_the_default_configuration() -> None:
    # The default env (6 UAVs, 16 x 16 lattice, 300 steps) with start="random", as evaluate runs it.
    results, _ = evaluate_controllers(
        lambda: uav_coverage_v0.parallel_env(start="random"),
        [RandomController(), GreedyStaticController()],
        n_episodes=2,
        seed=0,
    )
    summary = {row["method"]: row for row in summarize(results)}
    assert summary["greedy_static"]["coverage_mean"] > summary["random"]["coverage_mean"] + 0.1
    assert all(episode["length"] == 300 for episode in results["random"])


def test_random_controller_is_seeded() -> None:
    env = uav_coverage_v0.parallel_env(n_uavs=2, obs_size=16, max_cycles=5, start="random")
    first, _ = evaluate_controllers(lambda: env, [RandomController()], n_episodes=2, seed=7)
    second, _ = evaluate_controllers(lambda: env, [RandomController()], n_episodes=2, seed=7)
    assert first == second


def test_evaluate_and_report_writes_tables_figures_and_gif(tmp_path) -> None:
    out = tmp_path / "evaluation"
    report = evaluate_and_report(
        out, n_episodes=2, env_kwargs=dict(n_uavs=3, obs_size=16, max_cycles=12), state_steps=[0, 6], verbose=0
    )
    assert report["env_kwargs"]["start"] == "random"

    with open(out / "results.csv") as file:
        rows = list(csv.DictReader(file))
    assert [row["method"] for row in rows] == ["random", "greedy_static"]
    for key in ("coverage", "fairness", "energy", "energy_efficiency"):
        assert f"{key}_mean" in rows[0] and f"{key}_std" in rows[0]
    payload = json.loads((out / "results.json").read_text())
    assert len(payload["episodes"]["greedy_static"]) == 2
    assert payload["metadata"]["env_kwargs"]["max_cycles"] == 12
    assert "± " in (out / "results.md").read_text()

    figures = out / "figures"
    for name in (
        "fairness_vs_coverage.png",
        "fairness_vs_energy_efficiency.png",
        "metrics_vs_episode.png",
        "greedy_static_coverage_heatmap.png",
        "greedy_static_state_step0000.png",
        "greedy_static_state_step0006.png",
        "greedy_static_frame_step0006.png",
    ):
        assert_png(figures / name)
    with Image.open(figures / "greedy_static_episode.gif") as gif:
        assert gif.format == "GIF"
        assert gif.n_frames > 5


def test_plot_training_logs_from_a_monitor_file(tmp_path) -> None:
    run = tmp_path / "run"
    run.mkdir()
    lines = [
        '#{"t_start": 0, "env_id": "multi-agent"}',
        "r,l,t,coverage,fairness,energy,energy_efficiency,wall_hits,disconnections",
    ]
    rng = np.random.default_rng(0)
    for episode in range(30):
        c, f = rng.uniform(0.2, 0.8, size=2)
        lines.append(f"{-episode},100,{episode},{c},{f},0.5,{c * f / 0.5},0,1")
    (run / "monitor.csv").write_text("\n".join(lines) + "\n")

    # a bare monitor file says nothing of its env: the env given brings the task's pairs and labels
    paths = plot_training_logs(run, tmp_path / "figures", env_id="uav_coverage_v0")
    assert [path.name for path in paths] == [
        "train_returns_vs_episode.png",
        "train_fairness_vs_coverage.png",
        "train_fairness_vs_energy_efficiency.png",
        "train_metrics_vs_episode.png",
    ]
    for path in paths:
        assert_png(path)
    # without it, each metric of the file against episode
    paths = plot_training_logs(run, tmp_path / "unknown")
    assert [path.name for path in paths] == ["train_returns_vs_episode.png", "train_metrics_vs_episode.png"]


def test_plot_training_logs_without_metrics_is_an_error(tmp_path) -> None:
    with pytest.raises(FileNotFoundError, match="no training log"):
        plot_training_logs(tmp_path, tmp_path / "figures")


def test_worst_decile_is_the_mean_of_the_lowest_tenth() -> None:
    # 20 values: the lowest 2 (-7 and 1) -> -3; 9 values: the lowest one; one value: itself
    values = [5.0, 1.0, 3.0, -7.0, *range(10, 26)]
    assert worst_decile(values) == -3.0
    assert worst_decile([4.0, 2.0, 9.0, 8.0, 7.0, 6.0, 5.0, 3.0, 10.0]) == 2.0
    assert worst_decile([1.5]) == 1.5
    with pytest.raises(ValueError, match="non-empty"):
        worst_decile([])


def test_summary_and_table_show_the_worst_decile_and_the_hazard_events() -> None:
    results = {
        "a": [{"return": float(r), "length": 3.0, "crashes": float(r < 3), "gusts": 2.0} for r in range(1, 21)],
    }
    (row,) = summarize(results)
    assert row["return_worst_decile"] == 1.5 and row["return_mean"] == 10.5
    assert row["crashes_mean"] == 0.1
    # the task's event counts after the length, in the task's order
    table = format_table([row], TaskMetrics(table_counts=("gusts", "crashes", "link_failures")))
    header = table.splitlines()[0]
    assert header == "| method | episodes | team return | worst 10 % team return | length | gusts | crashes |"
    assert "| 10.5000 ± 5.7663 | 1.5000 | 3.0000 ± 0.0000 | 2.0000 ± 0.0000 | 0.1000 ± 0.3000 |" in table
    # without the task's metrics, those of the summary after the length, in its order
    assert format_table([row]).splitlines()[0].endswith("| length | crashes | gusts |")
    # an env without hazards: no hazard column
    plain = format_table(summarize({"b": [{"return": 1.0, "length": 2.0}]}))
    assert "crashes" not in plain and "worst 10 % team return" in plain


def test_evaluation_reports_hazard_events_per_episode() -> None:
    results, _ = evaluate_controllers(
        lambda: make_multiagent_env("uav_coverage_hazard_cpu_v1", n_uavs=3, max_cycles=20),
        [RandomController()],
        n_episodes=2,
        seed=0,
    )
    episode = results["random"][0]
    assert {"gusts", "crashes", "link_failures", "depletions"} <= set(episode)
    assert episode["gusts"] > 0  # p_g = 0.75: about 45 gusts in 3 x 20 steps
