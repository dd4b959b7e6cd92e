"""The published setting of Liu et al. (TMC 2020) as an env id, and the paper's step greedy worked out by hand."""

import math
from pathlib import Path

import numpy as np
import pytest

from sb3_maddpg.__main__ import main
from sb3_maddpg.evaluation.baselines import make_baselines
from sb3_maddpg.zoo.registry import make_multiagent_env
from sb3_maddpg_envs import uav_coverage_v0, uav_coverage_v1
from sb3_maddpg_envs.uav_coverage.baselines import GreedyStepController, greedy_step_scores, step_actions
from sb3_maddpg_envs.uav_coverage.task_tools import TASK_TOOLS
from tests.cli_testing import fails_with

EPS = 1e-4


def test_tmc_env_id_has_the_papers_setting() -> None:
    env = make_multiagent_env("uav_coverage_tmc_v1")
    core = env.core
    assert (core.map_size, core.n_uavs, core.n_pois_total) == (10, 6, 100)
    assert (core.coverage_range, core.comm_range, core.max_distance) == (3.0, 5.0, 1.0)
    assert (core.max_cycles, core.hover_energy, core.move_energy) == (500, 0.5, 1.0)
    # v1's rules
    assert (core.action_mode, core.wall_mode, core.reward_mode, core.start_mode) == ("cartesian", "clip", "coverage", "random")
    # 2 pixels per cell, 4 channels (v1's teammate channel): large enough for ReportCNN (>= 15 x 15)
    assert env.observation_space("uav_0").shape == (4, 20, 20)
    assert env.metadata["name"] == "uav_coverage_v1"
    env.close()


def test_tmc_energy_is_half_hovering_and_one_for_a_full_move() -> None:
    start = np.array([[5.0, 5.0], [5.0, 6.0]])
    env = make_multiagent_env("uav_coverage_tmc_v1", n_uavs=2, start=start)
    env.reset(seed=0)
    # uav_0 hovers, uav_1 flies one cell east (Cartesian: (dx, dy) = (2 a - 1) l_max)
    _, _, _, _, infos = env.step({"uav_0": np.array([0.5, 0.5], np.float32), "uav_1": np.array([1.0, 0.5], np.float32)})
    np.testing.assert_allclose(env.core.last_energy_spent, [0.5, 1.0])
    np.testing.assert_allclose(env.core.positions[1], [6.0, 6.0])
    # e_T = energy / (N t * full-move energy) = 1.5 / (2 * 1 * 1.0)
    assert infos["uav_0"]["energy"] == pytest.approx(0.75)
    env.close()


def test_tmc_env_id_takes_the_sweeps_n_uavs() -> None:
    env = make_multiagent_env("uav_coverage_tmc_v1", n_uavs=3)
    assert env.core.n_uavs == 3 and env.core.map_size == 10
    env.close()


# ---------------------------------------------------------------------------------------------------------------------
# The step greedy on tiny cases. Candidate 0 hovers, candidate j + 1 flies l_max = 1 at heading 2 pi j / 30 (12 deg).
# ---------------------------------------------------------------------------------------------------------------------
def on_heading(origin: tuple[float, float], heading: int, distance: float = 2.0) -> list[float]:
    """The point ``distance`` from ``origin`` along heading ``heading`` of 30."""
    theta = 2.0 * math.pi * heading / 30
    return [origin[0] + distance * math.cos(theta), origin[1] + distance * math.sin(theta)]


def tiny_env(pois: list[list[float]], coverage_range: float, start: list[list[float]] | None = None, **kwargs):
    """A v0 env (polar actions, refused walls) on a 10 x 10 map with the paper's energy, reset; one UAV at (5, 5)."""
    start = start or [[5.0, 5.0]]
    env = uav_coverage_v0.parallel_env(
        map_size=10,
        n_uavs=len(start),
        pois=np.array(pois),
        coverage_range=coverage_range,
        max_distance=1.0,
        move_energy=1.0,
        hover_energy=0.5,
        obs_size=10,
        start=np.array(start),
        **kwargs,
    )
    env.reset(seed=0)
    return env


def test_greedy_step_flies_the_one_heading_that_reaches_the_poi() -> None:
    # A PoI 2 cells away on heading 3 (36 deg), R0 1.02: only that heading ends within R0 (distance 1); headings 2 and
    # 4 end sqrt(5 - 4 cos 12 deg) = 1.043 away. Covering it at t = 1: c' = 1, gain 1, fairness 1, energy 1.0.
    env = tiny_env([on_heading((5.0, 5.0), 3)], coverage_range=1.02)
    scores, candidates, rho = greedy_step_scores(env.core)
    assert scores.shape == (1, 31) and candidates.shape == (1, 31, 2)
    np.testing.assert_array_equal(rho, [0.0] + [1.0] * 30)
    expected = np.zeros(31)
    expected[4] = 1.0 / (1.0 + EPS)
    np.testing.assert_allclose(scores[0], expected, atol=1e-12)

    controller = GreedyStepController()
    controller.reset(env)
    action = controller.act({"uav_0": None}, env)["uav_0"]
    np.testing.assert_allclose(action, [3 / 30, 1.0], atol=1e-7)  # polar: (theta / 2 pi, rho)
    _, _, _, _, infos = env.step({"uav_0": action})
    assert infos["uav_0"]["coverage"] == 1.0


def test_greedy_step_hovers_when_every_move_covers_the_same() -> None:
    # R0 3 covers the PoI from every candidate: equal gains, and hovering costs 0.5 against 1.0 (score 2 against 1).
    env = tiny_env([[5.0, 5.5]], coverage_range=3.0)
    scores, _, _ = greedy_step_scores(env.core)
    assert scores[0, 0] == pytest.approx(1.0 / (0.5 + EPS))
    np.testing.assert_allclose(scores[0, 1:], 1.0 / (1.0 + EPS))
    controller = GreedyStepController()
    np.testing.assert_array_equal(controller.act({"uav_0": None}, env)["uav_0"], [0.0, 0.0])


def test_greedy_step_weighs_the_gain_by_fairness() -> None:
    # PoI A on heading 3, PoI B on heading 18 (216 deg); after t = 2 steps A was covered once, B never: c = (1/2, 0).
    # Covering A: c' = (2/3, 0), gain 1/6, fairness 1/2 -> 1/12. Covering B: c' = (1/3, 1/3), gain 1/6, fairness 1
    # -> 1/6. Hovering (nothing covered): c' = (1/3, 0), gain -1/6, fairness 1/2, energy 0.5 -> -1/6; a move covering
    # nothing: -1/12 / 1.0.
    env = tiny_env([on_heading((5.0, 5.0), 3), on_heading((5.0, 5.0), 18)], coverage_range=1.02)
    core = env.core
    core.t = 2
    core.visits[:] = [1, 0]
    core.coverage_scores[:] = [0.5, 0.0]
    scores, _, _ = greedy_step_scores(core)
    assert scores[0, 4] == pytest.approx((1 / 2) * (1 / 6) / (1 + EPS))
    assert scores[0, 19] == pytest.approx(1 * (1 / 6) / (1 + EPS))
    assert scores[0, 0] == pytest.approx((1 / 2) * (-1 / 6) / (0.5 + EPS))
    assert scores[0, 1] == pytest.approx((1 / 2) * (-1 / 6) / (1 + EPS))
    assert int(np.argmax(scores[0])) == 19
    np.testing.assert_allclose(GreedyStepController().act({"uav_0": None}, env)["uav_0"], [18 / 30, 1.0], atol=1e-7)


def test_greedy_step_charges_the_penalties_of_the_env() -> None:
    # Nothing is ever covered (the only PoI is far away), so a candidate's score is minus its penalties.
    # Two UAVs 1.5 apart, R 2: uav_0 flying west ends 2.5 from uav_1 (disconnected, p_c 0.3); uav_1 flying east too.
    env = tiny_env([[9.5, 9.5]], 0.5, start=[[5.0, 5.0], [6.5, 5.0]], comm_range=2.0, comm_penalty=0.3)
    scores, _, _ = greedy_step_scores(env.core)
    assert scores[0, 0] == 0.0 and scores[0, 1] == 0.0  # hover, east
    assert scores[0, 16] == pytest.approx(-0.3)  # heading 15 of 30: west
    assert scores[1, 1] == pytest.approx(-0.3) and scores[1, 16] == 0.0
    # refused walls (v0): a UAV at x = 0.5 flying west would leave the area, charged p_w = 10 and the comm penalty
    env = tiny_env([[9.5, 9.5]], 0.5, start=[[0.5, 5.0]])
    scores, candidates, _ = greedy_step_scores(env.core)
    assert scores[0, 16] == pytest.approx(-10.0)
    np.testing.assert_allclose(candidates[0, 16], [0.5, 5.0])  # refused: it stays
    # the moves that would leave the area (the headings within 60 deg of west) score -10, the others 0: the tie goes
    # to the first, hovering
    assert np.all((scores[0] == 0.0) | np.isclose(scores[0], -10.0)) and scores[0, 0] == 0.0
    np.testing.assert_array_equal(GreedyStepController().act({"uav_0": None}, env)["uav_0"], [0.0, 0.0])


def test_greedy_step_actions_in_the_cartesian_encoding() -> None:
    env = uav_coverage_v1.parallel_env(
        map_size=10,
        n_uavs=1,
        pois=np.array([on_heading((5.0, 5.0), 3)]),
        coverage_range=1.02,
        max_distance=1.0,
        obs_size=10,
        start=np.array([[5.0, 5.0]]),
    )
    env.reset(seed=0)
    action = GreedyStepController().act({"uav_0": None}, env)["uav_0"]
    theta = 2 * math.pi * 3 / 30
    np.testing.assert_allclose(action, [0.5 + 0.5 * math.cos(theta), 0.5 + 0.5 * math.sin(theta)], atol=1e-7)
    _, _, _, _, infos = env.step({"uav_0": action})
    assert infos["uav_0"]["coverage"] == 1.0
    np.testing.assert_allclose(step_actions(np.array([0]), 30, "cartesian"), [[0.5, 0.5]])


def test_make_baselines_and_bad_values() -> None:
    assert [c.name for c in make_baselines(None, TASK_TOOLS)] == ["random", "greedy_static"]
    assert [c.name for c in make_baselines(None)] == ["random"]
    assert [c.name for c in make_baselines(["greedy_step", "random", "greedy_step"], TASK_TOOLS)] == [
        "greedy_step",
        "random",
    ]
    with pytest.raises(ValueError, match="unknown baseline 'greedy'; this env accepts: random, greedy_static, greedy_step"):
        make_baselines(["greedy"], TASK_TOOLS)
    with pytest.raises(ValueError, match="unknown baseline 'greedy_step'; this env accepts: random$"):
        make_baselines(["greedy_step"])
    with pytest.raises(TypeError, match="sequence of names"):
        make_baselines("random", TASK_TOOLS)
    with pytest.raises(ValueError, match="n_headings must be an integer >= 1, got 0"):
        GreedyStepController(n_headings=0)
    with pytest.raises(ValueError, match="n_headings must be an integer >= 1, got 2.5"):
        GreedyStepController(n_headings=2.5)


def test_evaluate_command_runs_the_chosen_baselines(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "eval"
    argv = ["evaluate", "--baselines-only", "--env", "uav_coverage_tmc_v1", "--baselines", "greedy_step", "random"]
    argv += ["--env-kwargs", "n_uavs:2", "max_cycles:6", "--episodes", "1", "--no-gif", "--out", str(out)]
    assert main(argv) == 0
    table = capsys.readouterr().out
    assert table.index("| greedy_step | 1 |") < table.index("| random | 1 |")
    assert "greedy_static" not in table
    unknown = "--baselines: unknown baseline 'greedy'; this env accepts: random, greedy_static, greedy_step"
    assert unknown in fails_with([*argv[:5], "greedy"], capsys)
    non_uav = ["evaluate", "--baselines-only", "--env", "simple_spread_v3", "--baselines", "greedy_step"]
    assert "unknown baseline 'greedy_step'; this env accepts: random (simple_spread_v3)" in fails_with(non_uav, capsys)
