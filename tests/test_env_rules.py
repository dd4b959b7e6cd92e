"""The rules of a step, the metrics and the episode's end (docs/environment.md, "One step" and "Metrics") checked against
values worked out by hand in tiny scenarios of the numpy core."""

import numpy as np
import pytest

from sb3_maddpg_envs.uav_coverage.core import UAVCoverageCore

# Scenario A: L = 4, two UAVs, three PoIs, every length 1 so the arithmetic stays short.
#   PoIs: P0 (0.5, 0.5), P1 (2.5, 0.5), P2 (3.5, 1.5); starts U0 (0.5, 0.5), U1 (2.5, 2.5)
#   E_max 10, l_max 1, eta 1, E_h 0.5, R0 1.2, R 2, p_w 10, p_c 1, lambda 0.1, eps 1e-4, S 8 (2 px per cell)
SCENARIO_A = dict(
    map_size=4,
    n_uavs=2,
    pois=[[0.5, 0.5], [2.5, 0.5], [3.5, 1.5]],
    start=[[0.5, 0.5], [2.5, 2.5]],
    max_energy=10.0,
    max_distance=1.0,
    move_energy=1.0,
    hover_energy=0.5,
    coverage_range=1.2,
    comm_range=2.0,
    wall_penalty=10.0,
    comm_penalty=1.0,
    entropy_coef=0.1,
    eps=1e-4,
    obs_size=8,
    max_cycles=5,
)
# Step 1: U0 a = (0, 1): theta 0, l 1 -> (1.5, 0.5); U1 a = (0.25, 0.5): theta pi/2, l 0.5 -> (2.5, 3.0).
STEP_1 = np.array([[0.0, 1.0], [0.25, 0.5]])
# Step 2: U0 a = (0.5, 1): theta pi, l 1 -> (0.5, 0.5); U1 a = (0.25, 1): theta pi/2 -> (2.5, 4.0), outside: refused.
STEP_2 = np.array([[0.5, 1.0], [0.25, 1.0]])


def scenario_a(**overrides) -> UAVCoverageCore:
    core = UAVCoverageCore(**{**SCENARIO_A, **overrides})
    core.reset(seed=0)
    return core


def test_move_energy_and_coverage_first_step():
    core = scenario_a()
    obs, rewards, terminated, truncated = core.step(STEP_1)
    np.testing.assert_allclose(core.positions, [[1.5, 0.5], [2.5, 3.0]], atol=1e-12)
    # e_0 = eta * 1 + E_h * (1 - 1) = 1.0 ; e_1 = 1 * 0.5 + 0.5 * (1 - 0.5) = 0.75
    np.testing.assert_allclose(core.last_energy_spent, [1.0, 0.75])
    np.testing.assert_allclose(core.energy, [9.0, 9.25])
    # |P0 - U0| = 1.0 <= 1.2, |P1 - U0| = 1.0, P2: |P2 - U0| = sqrt(5) = 2.24, |P2 - U1| = sqrt(1 + 2.25) = 1.80
    np.testing.assert_array_equal(core.visits, [1, 1, 0])
    np.testing.assert_allclose(core.coverage_scores, [1.0, 1.0, 0.0])  # w(k) / t with t = 1
    assert core.t == 1
    assert core.coverage == pytest.approx(2 / 3)  # (1 + 1 + 0) / 3
    assert core.fairness == pytest.approx(2 / 3)  # (1 + 1)^2 / (3 * (1 + 1)) = 4 / 6
    assert core.energy_ratio == pytest.approx(0.875)  # 1.75 / (N 2 * t 1 * eta 1 * l_max 1)
    assert core.energy_efficiency == pytest.approx(0.5078784646834013)  # (2/3 * 2/3) / (0.875 + 1e-4)
    # |U0 - U1| = sqrt(1 + 6.25) = 2.69 > R = 2: both disconnected, p_c each.
    np.testing.assert_array_equal(core.last_disconnected, [True, True])
    # Cells (1, 0) and (2, 3) differ: H = -2 * (1/2 ln 1/2) = ln 2 = 0.693147
    assert core.last_entropy == pytest.approx(0.6931471805599453)
    # s = f * sum(dc) / (sum e + eps) + lambda H = (2/3) * 2 / 1.7501 + 0.1 * 0.693147 = 0.761861 + 0.069315
    assert core.last_shared_reward == pytest.approx(0.8311759450335006)
    np.testing.assert_allclose(rewards, [-0.16882405496649944, -0.16882405496649944])  # s - p_c
    assert not terminated and not truncated
    assert obs.shape == (2, 3, 8, 8) and obs.dtype == np.uint8


def test_refused_move_at_wall_and_second_step():
    core = scenario_a()
    core.step(STEP_1)
    _, rewards, _, _ = core.step(STEP_2)
    # U0 flew back to (0.5, 0.5); U1 would reach y = 3.0 + 1 = 4.0, not < L = 4: it stays and is charged p_w.
    np.testing.assert_allclose(core.positions, [[0.5, 0.5], [2.5, 3.0]], atol=1e-12)
    np.testing.assert_array_equal(core.last_wall_hit, [False, True])
    # The refused move costs as much as the move: eta * 1 + E_h * 0 = 1.0 for each UAV.
    np.testing.assert_allclose(core.last_energy_spent, [1.0, 1.0])
    np.testing.assert_allclose(core.energy, [8.0, 8.25])
    # Only P0 covered (|P1 - U0| = 2 > 1.2): w = (2, 1, 0), t = 2 -> c = (1, 0.5, 0)
    np.testing.assert_allclose(core.coverage_scores, [1.0, 0.5, 0.0])
    assert core.coverage == pytest.approx(0.5)  # 1.5 / 3
    assert core.fairness == pytest.approx(0.6)  # 1.5^2 / (3 * (1 + 0.25)) = 2.25 / 3.75
    assert core.energy_ratio == pytest.approx(0.9375)  # (1.75 + 2) / (2 * 2 * 1 * 1)
    assert core.energy_efficiency == pytest.approx(0.3199658703071672)  # 0.6 * 0.5 / (0.9375 + 1e-4)
    # s = 0.6 * (1.5 - 2) / (2 + 1e-4) + 0.1 ln 2 = -0.149993 + 0.069315
    assert core.last_shared_reward == pytest.approx(-0.08067778231898672)
    # U0: s - p_c ; U1: s - p_c - p_w
    np.testing.assert_allclose(rewards, [-1.0806777823189868, -11.080677782318986])
    np.testing.assert_array_equal(core.wall_hits, [0, 1])
    np.testing.assert_array_equal(core.disconnections, [2, 2])
    infos = core.infos()
    assert infos[1]["wall_hits"] == 1 and infos[0]["wall_hits"] == 0
    assert infos[0]["disconnections"] == 2
    assert infos[0]["coverage"] == pytest.approx(0.5) and infos[1]["fairness"] == pytest.approx(0.6)


def test_observation_pixels_of_each_channel():
    core = scenario_a()
    core.step(STEP_1)
    obs, _, _, _ = core.step(STEP_2)
    # Pixel of (x, y) with S = 8, L = 4: (row, col) = (7 - floor(2 y), floor(2 x)); a cell is a 2 x 2 block.
    # Channel 0: P0 (0.5, 0.5) -> (6, 1), block rows 6-7 cols 0-1; P1 (2.5, 0.5) -> rows 6-7 cols 4-5;
    # P2 (3.5, 1.5) -> (4, 7), rows 4-5 cols 6-7.
    expected_pois = np.zeros((8, 8), dtype=np.uint8)
    expected_pois[6:8, 0:2] = expected_pois[6:8, 4:6] = expected_pois[4:6, 6:8] = 255
    for i in range(2):
        np.testing.assert_array_equal(obs[i, 0], expected_pois)
    # Channel 2: round(255 * (1, 0.5, 0)) = (255, 128, 0) on the PoI blocks.
    expected_cov = np.zeros((8, 8), dtype=np.uint8)
    expected_cov[6:8, 0:2] = 255
    expected_cov[6:8, 4:6] = 128
    np.testing.assert_array_equal(obs[0, 2], expected_cov)
    np.testing.assert_array_equal(obs[1, 2], expected_cov)
    # Channel 1: U0 at (0.5, 0.5), E = 8 -> round(255 * 0.8) = 204 on rows 6-7 cols 0-1;
    # U1 at (2.5, 3.0) -> pixel (7 - 6, 5) = (1, 5), block rows 0-1 cols 4-5, E = 8.25 -> round(210.375) = 210.
    expected_u0 = np.zeros((8, 8), dtype=np.uint8)
    expected_u0[6:8, 0:2] = 204
    expected_u1 = np.zeros((8, 8), dtype=np.uint8)
    expected_u1[0:2, 4:6] = 210
    np.testing.assert_array_equal(obs[0, 1], expected_u0)
    np.testing.assert_array_equal(obs[1, 1], expected_u1)
    # state(): channel 1 shows both UAVs, the other channels are the same.
    state = core.state()
    np.testing.assert_array_equal(state[1], expected_u0 + expected_u1)
    np.testing.assert_array_equal(state[0], expected_pois)
    np.testing.assert_array_equal(state[2], expected_cov)


def test_reset_observation_and_clamping():
    core = UAVCoverageCore(**{**SCENARIO_A, "start": [[0.5, 0.5], [3.99, 3.99]]})
    obs = core.reset(seed=0)
    # Nothing covered yet: channel 2 is zero; full energy -> 255 on each UAV's own block.
    assert obs[:, 2].max() == 0
    assert obs[1, 1, 0, 7] == 255 and obs[1, 1, 1, 6] == 255 and obs[1, 1].sum() == 4 * 255
    # A point on the far edge (x = y = L) is clamped into the last cell: block row 0, block column L - 1.
    rows, cols = core.cells_of(np.array([[4.0, 4.0], [-0.1, 0.0]]))
    assert rows.tolist() == [0, 3] and cols.tolist() == [3, 0]


def test_self_channel_is_at_least_one_while_active():
    # E = 0.15 of E_max 100 after one move would give round(255 * 0.0015) = 0; the channel shows 1 instead.
    core = UAVCoverageCore(
        map_size=2, n_uavs=1, pois="grid", start=[[0.5, 0.5]], max_energy=1.0, hover_energy=0.999, obs_size=2
    )
    core.reset(seed=0)
    obs, _, terminated, _ = core.step(np.array([[0.0, 0.0]]))  # hover: E = 1 - 0.999 = 0.001 > eps * E_max = 1e-4
    assert not terminated
    assert obs[0, 1, 1, 0] == 1  # round(255 * 0.001) = 0 -> at least 1


def test_out_of_range_actions_are_clipped_and_nan_raises():
    core = scenario_a()
    # (-3, 7) clips to (0, 1): the same move as STEP_1's U0.
    core.step(np.array([[-3.0, 7.0], [0.25, 0.5]]))
    np.testing.assert_allclose(core.positions[0], [1.5, 0.5], atol=1e-12)
    for bad in (np.nan, np.inf, -np.inf):
        with pytest.raises(ValueError, match="finite"):
            core.step(np.array([[bad, 0.5], [0.0, 0.0]]))
    with pytest.raises(ValueError, match="shape"):
        core.step(np.zeros((3, 2)))


def test_reward_scale_and_clip():
    core = scenario_a(reward_scale=2.0, reward_clip=1.5)
    _, rewards, _, _ = core.step(STEP_1)
    np.testing.assert_allclose(rewards, [-0.3376481099329989] * 2)  # 2 * (0.831176 - 1), inside +-1.5
    _, rewards, _, _ = core.step(STEP_2)
    np.testing.assert_allclose(rewards, [-1.5, -1.5])  # 2 * -1.08 = -2.16 and 2 * -11.08 both clipped to -1.5


def test_truncation_at_max_cycles():
    core = scenario_a(max_cycles=2)
    assert core.step(STEP_1)[2:] == (False, False)
    assert core.step(STEP_2)[2:] == (False, True)
    with pytest.raises(RuntimeError, match="reset"):
        core.step(STEP_1)


# Scenario B: depletion and the min() rule. L = 4, E_max 2, eta 1, E_h 0.5, l_max 1, one PoI at (2.5, 0.5), R0 0.4.
SCENARIO_B = dict(
    map_size=4,
    n_uavs=2,
    pois=[[2.5, 0.5]],
    start=[[0.5, 0.5], [1.5, 0.5]],
    max_energy=2.0,
    max_distance=1.0,
    move_energy=1.0,
    hover_energy=0.5,
    coverage_range=0.4,
    comm_range=2.0,
    obs_size=4,
    max_cycles=3,
)


def test_min_energy_depletion_and_termination():
    core = UAVCoverageCore(**SCENARIO_B)
    core.reset(seed=0)
    # Step 1: U0 a = (0, 1): e = 1 -> E 1, to (1.5, 0.5); U1 hovers: e = E_h = 0.5 -> E 1.5.
    _, _, terminated, _ = core.step(np.array([[0.0, 1.0], [0.0, 0.0]]))
    np.testing.assert_allclose(core.energy, [1.0, 1.5])
    assert core.coverage_scores[0] == 0.0  # |P - U0| = 1 > 0.4
    # Step 2: U0 again: e = 1 -> E 0 (depleted during this step, still moves, covers and is rewarded);
    # U1 a = (0, 0.5): e = 0.5 + 0.5 * 0.5 = 0.75 -> E 0.75, to (2.0, 0.5).
    _, rewards, terminated, _ = core.step(np.array([[0.0, 1.0], [0.0, 0.5]]))
    np.testing.assert_allclose(core.energy, [0.0, 0.75])
    np.testing.assert_allclose(core.positions, [[2.5, 0.5], [2.0, 0.5]])
    assert core.coverage_scores[0] == pytest.approx(0.5)  # U0 sits on P: w = 1, t = 2
    # K = 1 so f = 1; both in cell (2, 0): H = 0; |U0 - U1| = 0.5 <= 2: connected.
    # s = 1 * (0.5 - 0) / (1 + 0.75 + 1e-4) = 0.285698
    np.testing.assert_allclose(rewards, [0.2856979601165648] * 2)
    np.testing.assert_array_equal(core.active, [False, True])
    assert not terminated
    # Step 3: U0 is depleted: it does not move, spend, cover or connect, and gets 0.
    # U1 a = (0, 1) would cost 1 but has 0.75: e = min(1, 0.75) = 0.75 -> E 0; it still flies to (3.0, 0.5).
    obs, rewards, terminated, truncated = core.step(np.array([[0.0, 1.0], [0.0, 1.0]]))
    np.testing.assert_allclose(core.last_energy_spent, [0.0, 0.75])
    np.testing.assert_allclose(core.energy, [0.0, 0.0])
    np.testing.assert_allclose(core.positions, [[2.5, 0.5], [3.0, 0.5]])
    # The landed U0 sits on P but does not cover it; |P - U1| = 0.5 > 0.4: w stays 1, c = 1/3.
    assert core.coverage_scores[0] == pytest.approx(1 / 3)
    # U1 is the only active UAV: disconnected (N = 2), H = 0 (one UAV);
    # s = 1 * (1/3 - 1/2) / (0.75 + 1e-4) = -0.222193 ; r1 = s - p_c = -1.222193 ; r0 = 0.
    np.testing.assert_allclose(rewards, [0.0, -1.2221925965426832])
    np.testing.assert_array_equal(core.disconnections, [0, 1])
    # Every UAV depleted at t = T = 3: termination wins over truncation.
    assert terminated and not truncated
    # The landed UAVs vanish from channel 1.
    assert obs[:, 1].max() == 0
    # All 4 units of energy spent over 3 steps: 4 / (2 * 3 * 1 * 1)
    assert core.energy_ratio == pytest.approx(0.6666666666666666)


def test_fairness_zero_when_nothing_covered_and_single_uav_never_disconnected():
    core = UAVCoverageCore(
        map_size=4, n_uavs=1, pois=[[3.5, 3.5]], start=[[0.5, 0.5]], coverage_range=1.0, comm_range=1.0, obs_size=4
    )
    core.reset(seed=0)
    _, rewards, _, _ = core.step(np.array([[0.0, 0.0]]))  # hover far from the PoI
    assert core.coverage == 0.0 and core.fairness == 0.0 and core.energy_efficiency == 0.0
    assert not core.last_disconnected[0] and core.disconnections[0] == 0
    # s = 0 * 0 / (0.5 + eps) + 0.1 * 0 (one UAV: H = 0) = 0, no penalty.
    assert rewards[0] == 0.0
    # hover: e = E_h = 0.5 ; energy = 0.5 / (1 * 1 * (1/3) * 3) = 0.5
    assert core.energy_ratio == pytest.approx(0.5)


def test_entropy_of_cell_histogram():
    # Three hovering UAVs, two in cell (0, 0), one in (3, 3): H = -(2/3 ln 2/3 + 1/3 ln 1/3) = 0.636514
    core = UAVCoverageCore(
        map_size=4, n_uavs=3, pois="grid", start=[[0.2, 0.2], [0.8, 0.9], [3.5, 3.5]], obs_size=4, entropy_coef=1.0
    )
    core.reset(seed=0)
    core.step(np.zeros((3, 2)))
    assert core.last_entropy == pytest.approx(0.6365141682948128)


def test_coverage_range_is_inclusive_and_counted_after_moving():
    # PoI at (2, 0.5); the UAV starts 2 away and flies 1 towards it: distance 1 = R0 after the move -> covered.
    core = UAVCoverageCore(
        map_size=4,
        n_uavs=1,
        pois=[[2.0, 0.5]],
        start=[[0.0, 0.5]],
        max_distance=1.0,
        coverage_range=1.0,
        comm_range=1.0,
        obs_size=4,
    )
    core.reset(seed=0)
    core.step(np.array([[0.0, 1.0]]))
    assert core.visits[0] == 1


def test_several_pois_in_one_cell_show_the_maximum():
    # Two PoIs in cell (0, 0): one under the UAV, one sqrt(0.8^2 + 0.8^2) = 1.13 away (outside R0 = 1):
    # c = (1, 0) in that cell -> channel 2 shows the maximum, 255.
    core = UAVCoverageCore(
        map_size=4,
        n_uavs=1,
        pois=[[0.1, 0.1], [0.9, 0.9], [3.5, 3.5]],
        start=[[0.1, 0.1]],
        coverage_range=1.0,
        comm_range=1.0,
        obs_size=4,
    )
    core.reset(seed=0)
    obs, _, _, _ = core.step(np.array([[0.0, 0.0]]))
    np.testing.assert_allclose(core.coverage_scores, [1.0, 0.0, 0.0])
    assert obs[0, 2, 3, 0] == 255 and obs[0, 2, 0, 3] == 0
