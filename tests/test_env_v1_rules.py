"""The rules that ``uav_coverage_v1`` switches on (Cartesian actions, clipped walls, coverage reward), checked against
values worked out by hand, and v1 with v0's rules reproducing v0 exactly."""

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test, parallel_seed_test
from test_env_rules import SCENARIO_A

from sb3_maddpg_envs import uav_coverage_v0, uav_coverage_v1
from sb3_maddpg_envs.uav_coverage.baselines import fly_to
from sb3_maddpg_envs.uav_coverage.core import UAVCoverageCore

V1_RULES = dict(action_mode="cartesian", wall_mode="clip", reward_mode="coverage", fairness_coef=0.5, energy_coef=0.5)


def scenario(**overrides) -> UAVCoverageCore:
    core = UAVCoverageCore(**{**SCENARIO_A, **V1_RULES, **overrides})
    core.reset(seed=0)
    return core


def test_cartesian_actions_move_by_2a_minus_1_times_lmax():
    core = scenario()
    # U0 a = (1, 0.5): d = (1, 0) -> (1.5, 0.5), rho 1; U1 a = (0.5, 0.75): d = (0, 0.5) -> (2.5, 3.0), rho 0.5
    core.step(np.array([[1.0, 0.5], [0.5, 0.75]]))
    np.testing.assert_allclose(core.positions, [[1.5, 0.5], [2.5, 3.0]], atol=1e-12)
    # e = eta l + E_h (1 - rho): 1 * 1 + 0.5 * 0 = 1.0 and 1 * 0.5 + 0.5 * 0.5 = 0.75
    np.testing.assert_allclose(core.last_energy_spent, [1.0, 0.75])
    # a = (0.5, 0.5) hovers (e = E_h); a = (0, 0) asks for (-1, -1), longer than l_max: shortened to length 1
    core.step(np.array([[0.5, 0.5], [0.0, 0.0]]))
    np.testing.assert_allclose(core.positions, [[1.5, 0.5], [2.5 - 0.5**0.5, 3.0 - 0.5**0.5]], atol=1e-12)
    np.testing.assert_allclose(core.last_energy_spent, [0.5, 1.0])


def test_clipped_wall_stops_at_the_boundary_and_charges_the_overshoot():
    core = scenario(start=[[0.5, 0.5], [2.5, 3.5]])
    # U1 asks for (2.5, 4.5): it stops at y just below 4 (flown 0.5, overshoot 0.5); U0 asks for (0.5, -0.5):
    # overshoot 0.5 as well, it stops at y = 0
    core.step(np.array([[0.5, 0.0], [0.5, 1.0]]))
    np.testing.assert_allclose(core.positions, [[0.5, 0.0], [2.5, 4.0]], atol=1e-12)
    assert core.positions[1, 1] < 4.0  # inside [0, L)
    np.testing.assert_array_equal(core.last_wall_hit, [True, True])
    np.testing.assert_array_equal(core.wall_hits, [1, 1])
    # Energy of the distance flown: 1 * 0.5 + 0.5 * (1 - 0.5) = 0.75 each
    np.testing.assert_allclose(core.last_energy_spent, [0.75, 0.75])
    # p_w * overshoot / l_max = 10 * 0.5 / 1 = 5, plus p_c = 1 each (|U0 - U1| = sqrt(4 + 16) > R = 2)
    np.testing.assert_allclose(core.last_penalties, [6.0, 6.0])
    # A move that stays inside is not a wall hit and costs nothing
    core.step(np.array([[0.5, 1.0], [0.5, 0.0]]))
    np.testing.assert_array_equal(core.last_wall_hit, [False, False])


def test_coverage_reward_first_and_second_step():
    core = scenario()
    # Step 1: U0 -> (1.5, 0.5) covers P0 and P1 (distance 1 <= 1.2); U1 -> (2.5, 3.0) covers nothing
    # (P2 at distance 1.80). c_0 = 0, so each covered PoI is worth 1. Credit = (N / K) * sum = (2 / 3) * 2 = 4/3.
    # Energy term 0.5 * e / (eta l_max) = 0.5 and 0.375; both disconnected (2.69 > R = 2): p_c = 1 each.
    _, rewards, _, _ = core.step(np.array([[1.0, 0.5], [0.5, 0.75]]))
    np.testing.assert_allclose(rewards, [4 / 3 - 0.5 - 1.0, 0.0 - 0.375 - 1.0])
    assert core.last_shared_reward == pytest.approx((4 / 3 + 0) / 2)
    # Step 2: U0 hovers (e 0.5), U1 a = (0.5, 0) -> (2.5, 2.0) (e 1.0) and covers P2 (distance 1.118).
    # c_1 = (1, 1, 0): weights 1 - 0.5 c = (0.5, 0.5, 1). U0: (2/3)(0.5 + 0.5) = 2/3; U1: (2/3)(1) = 2/3.
    # |U0 - U1| = sqrt(1 + 2.25) = 1.80 <= 2: connected.
    _, rewards, _, _ = core.step(np.array([[0.5, 0.5], [0.5, 0.0]]))
    np.testing.assert_allclose(rewards, [2 / 3 - 0.25, 2 / 3 - 0.5])


def two_uav_core(pois: list, start: list, **overrides) -> UAVCoverageCore:
    """Two UAVs on a 4 x 4 map with l_max = 1, eta = 1, E_h = 0.5, R0 = 1, R = 2 and v1's rules, after reset."""
    geometry = dict(map_size=4, n_uavs=2, obs_size=4, max_distance=1.0, coverage_range=1.0, comm_range=2.0)
    energy = dict(move_energy=1.0, hover_energy=0.5)
    core = UAVCoverageCore(**geometry, **energy, pois=pois, start=start, **{**V1_RULES, **overrides})
    core.reset(seed=0)
    return core


def test_coverage_credit_is_split_between_the_uavs_covering_a_poi():
    # One PoI under two hovering UAVs: each gets (N / K) * 1 / 2 = (2 / 1) / 2 = 1, minus 0.5 * E_h = 0.25
    core = two_uav_core(pois=[[1.0, 1.0]], start=[[1.0, 1.0], [1.5, 1.0]])
    _, rewards, _, _ = core.step(np.full((2, 2), 0.5))
    np.testing.assert_allclose(rewards, [0.75, 0.75])
    # With fairness_coef = 1 the PoI covered at every step so far is worth nothing at the next step
    core = UAVCoverageCore(**{**core_kwargs_of(core), "fairness_coef": 1.0})
    core.reset(seed=0)
    core.step(np.full((2, 2), 0.5))
    _, rewards, _, _ = core.step(np.full((2, 2), 0.5))
    np.testing.assert_allclose(rewards, [-0.25, -0.25])


def core_kwargs_of(core: UAVCoverageCore) -> dict:
    return dict(
        map_size=core.map_size,
        n_uavs=core.n_uavs,
        pois=core.pois,
        start=core._start_array,
        max_distance=core.max_distance,
        move_energy=core.move_energy,
        hover_energy=core.hover_energy,
        coverage_range=core.coverage_range,
        comm_range=core.comm_range,
        obs_size=core.obs_size,
        action_mode=core.action_mode,
        wall_mode=core.wall_mode,
        reward_mode=core.reward_mode,
        fairness_coef=core.fairness_coef,
        energy_coef=core.energy_coef,
    )


def test_depleted_uav_gets_no_coverage_reward():
    core = scenario(max_energy=1.0)
    core.step(np.array([[1.0, 0.5], [0.5, 0.75]]))  # U0 spends 1.0 = all its energy
    _, rewards, _, _ = core.step(np.array([[0.5, 0.5], [0.5, 0.5]]))
    assert rewards[0] == 0.0 and not core.active[0]


@pytest.mark.parametrize(
    "name, value",
    [
        ("action_mode", "spherical"),
        ("wall_mode", "bounce"),
        ("reward_mode", "dense"),
        ("fairness_coef", 1.5),
        ("fairness_coef", -0.1),
        ("energy_coef", -1.0),
        ("energy_coef", float("nan")),
        ("action_mode", 1),
    ],
)
def test_v1_parameters_are_validated(name, value):
    with pytest.raises(ValueError, match=name):
        UAVCoverageCore(**{name: value})


def test_v1_defaults_and_api():
    env = uav_coverage_v1.parallel_env(obs_size=16, max_cycles=20)
    assert env.metadata["name"] == "uav_coverage_v1"
    for key, value in uav_coverage_v1.V1_DEFAULTS.items():
        assert getattr(env.core, key if key != "start" else "start_mode") == value
    parallel_api_test(env, num_cycles=25)
    parallel_seed_test(lambda: uav_coverage_v1.parallel_env(obs_size=16, max_cycles=20))


def test_v1_with_v0_rules_reproduces_v0_exactly():
    v0_rules = dict(
        action_mode="polar",
        wall_mode="refuse",
        reward_mode="report",
        wall_penalty=10.0,
        comm_penalty=1.0,
        start="fixed",
        position_mark="cell",
        teammate_channel=False,
    )
    envs = [
        uav_coverage_v0.parallel_env(obs_size=16, max_cycles=30),
        uav_coverage_v1.parallel_env(obs_size=16, max_cycles=30, **v0_rules),
    ]
    rng = np.random.default_rng(3)
    for env in envs:
        env.reset(seed=7)
    while envs[0].agents:
        actions = {agent: rng.random(2).astype(np.float32) * 1.2 - 0.1 for agent in envs[0].agents}
        out0, out1 = (env.step(actions) for env in envs)
        for agent in out0[0]:
            np.testing.assert_array_equal(out0[0][agent], out1[0][agent])
            assert out0[1][agent] == out1[1][agent]
            assert out0[4][agent] == out1[4][agent]


def test_fly_to_in_cartesian_encoding_reaches_the_target():
    core = UAVCoverageCore(map_size=8, n_uavs=2, obs_size=8, start=[[1.0, 1.0], [6.0, 6.0]], action_mode="cartesian")
    core.reset(seed=0)
    targets = np.array([[5.0, 4.0], [6.0, 6.0]])
    for _ in range(3):
        core.step(fly_to(core.positions, targets, core.max_distance, action_mode="cartesian"))
    np.testing.assert_allclose(core.positions, targets, atol=1e-6)
    np.testing.assert_allclose(core.last_energy_spent, [core.hover_energy, core.hover_energy], atol=1e-6)


def test_teammate_channel_shows_the_active_teammates_within_radio_range():
    # L = S = 16 (one pixel per cell), R = 6. Map point (x, y) is pixel (15 - floor(y), floor(x)).
    start = [[1.0, 1.0], [2.0, 1.5], [10.0, 10.0], [1.5, 6.5], [14.2, 14.0], [14.0, 13.5]]
    kwargs = dict(map_size=16, obs_size=16, n_uavs=6, start=start, comm_range=6.0)
    core = UAVCoverageCore(**kwargs, teammate_channel=True)
    plain = UAVCoverageCore(**kwargs)
    obs, obs_plain = core.reset(seed=0), plain.reset(seed=0)
    assert obs.shape == (6, 4, 16, 16) and obs_plain.shape == (6, 3, 16, 16)
    np.testing.assert_array_equal(obs[:, :3], obs_plain)  # the first three channels are unchanged
    # Links (distance <= 6): 0-1 (1.1), 0-3 (5.5), 1-3 (5.0), 2-4 (5.8), 2-5 (5.4), 4-5 (0.5); 0-2 is 12.7, 3-2 is 9.1
    expected = {
        0: {(14, 2), (9, 1)},
        1: {(14, 1), (9, 1)},
        2: {(1, 14), (2, 14)},
        3: {(14, 1), (14, 2)},
        4: {(5, 10), (2, 14)},
        5: {(5, 10), (1, 14)},
    }
    for agent, pixels in expected.items():
        assert {tuple(p) for p in np.argwhere(obs[agent, 3])} == pixels
        assert (obs[agent, 3][obs[agent, 3] > 0] == 255).all()  # full batteries: round(255 E / E_max) = 255
    # A depleted teammate drops out of the channel (and of the links).
    core.energy[1] = 0.0
    core.active[1] = False
    assert {tuple(p) for p in np.argwhere(core.observations()[0, 3])} == {(9, 1)}


def test_teammate_channel_env_api_and_validation():
    env = uav_coverage_v1.parallel_env(obs_size=32, max_cycles=20, teammate_channel=True)
    assert env.observation_space("uav_0").shape == (4, 32, 32)
    assert env.state_space.shape == (3, 32, 32)
    parallel_api_test(env, num_cycles=25)
    with pytest.raises(TypeError, match="teammate_channel"):
        UAVCoverageCore(teammate_channel="yes")


def test_cnn_policy_trains_and_predicts_on_the_teammate_channel():
    from sb3_maddpg import MADDPG, make_multiagent_vec_env

    def make_env():
        return uav_coverage_v1.parallel_env(map_size=16, obs_size=16, n_uavs=2, max_cycles=10, teammate_channel=True)

    venv = make_multiagent_vec_env(make_env, n_envs=1, seed=0)
    assert venv.observation_space.shape == (4, 16, 16)
    policy_kwargs = dict(n_quantiles=3, net_arch=[8], features_extractor_kwargs=dict(padding=1, coord_channels=True))
    model = MADDPG("CnnPolicy", venv, buffer_size=100, learning_starts=20, batch_size=8, policy_kwargs=policy_kwargs, seed=0)
    model.learn(40)
    actions, _ = model.predict(venv.reset(), deterministic=True)
    assert actions.shape == (2, 2) and np.isfinite(actions).all()


def test_exact_position_mark_is_an_antialiased_cell_sized_square():
    # L = S = 16 (one pixel per cell), full batteries (value 255). U0 at (2.25, 3.5): the square spans x in
    # [1.75, 2.75] (columns 1 and 2 covered 0.25 and 0.75) and y in [3, 4] (row 15 - 3 = 12 only).
    # U1 at (0.25, 15.9): x in [-0.25, 0.75] is cut by the wall (column 0 covered 0.75), y in [15.4, 16.4] (row 0
    # covered 0.6).
    kwargs = dict(map_size=16, obs_size=16, n_uavs=2, start=[[2.25, 3.5], [0.25, 15.9]])
    core = UAVCoverageCore(**kwargs, position_mark="exact")
    obs = core.reset(seed=0)
    mark = obs[0, 1]
    assert {tuple(p) for p in np.argwhere(mark)} == {(12, 1), (12, 2)}
    assert mark[12, 1] == 64 and mark[12, 2] == 191  # round(255 * 0.25) and round(255 * 0.75)
    assert {tuple(p) for p in np.argwhere(obs[1, 1])} == {(0, 0)}
    assert obs[1, 1][0, 0] == 115  # round(255 * 0.75 * 0.6) = round(114.75)
    # Channels 0 and 2 are those of the cell mark; the state shows both squares (each agent's own mark)
    plain = UAVCoverageCore(**kwargs).reset(seed=0)
    np.testing.assert_array_equal(obs[:, [0, 2]], plain[:, [0, 2]])
    np.testing.assert_array_equal(core.state()[1], np.maximum(obs[0, 1], obs[1, 1]))
    # The cell mark (the report's, v0's and v1's default) fills the cell's block
    assert {tuple(p) for p in np.argwhere(plain[0, 1])} == {(12, 2)}


def test_exact_position_mark_centre_of_mass_is_the_position():
    # At 5 pixels per cell the square covers up to 6 x 6 pixels; away from the walls its weights sum to s^2 = 25
    # and their centre of mass (column, row) is (x s - 1/2, S - 1/2 - y s), to the uint8 rounding.
    rng = np.random.default_rng(3)
    start = rng.uniform(0.5, 15.5, size=(6, 2))
    core = UAVCoverageCore(map_size=16, obs_size=80, n_uavs=6, start=start, position_mark="exact")
    obs = core.reset(seed=0).astype(np.float64)
    for agent in range(6):
        mark = obs[agent, 1]
        mass = mark.sum()
        assert mass == pytest.approx(255 * 25, rel=0.01)
        column = (mark.sum(axis=0) @ np.arange(80)) / mass
        row = (mark.sum(axis=1) @ np.arange(80)) / mass
        assert column == pytest.approx(start[agent, 0] * 5 - 0.5, abs=0.02)
        assert row == pytest.approx(80 - 0.5 - start[agent, 1] * 5, abs=0.02)
    # A depleted UAV has no mark
    core.energy[2] = 0.0
    core.active[2] = False
    assert not core.observations()[2, 1].any()


def test_exact_position_mark_env_api_and_validation():
    env = uav_coverage_v1.parallel_env(obs_size=32, max_cycles=20, position_mark="exact")
    parallel_api_test(env, num_cycles=25)
    assert uav_coverage_v0.parallel_env().core.position_mark == "cell"
    for bad in ("subpixel", 1):
        with pytest.raises(ValueError, match="position_mark"):
            UAVCoverageCore(position_mark=bad)


def test_where_in_its_cell_a_uav_hovers_changes_what_it_covers():
    # Why the exact mark matters (docs/environment.md): on the 16 x 16 lattice with R0 = 3, a disc on a cell's
    # centre covers 32 PoIs, one on a cell's corner (a lattice point) 29, though both UAVs are in cell (7, 7).
    counts = []
    for point in ([7.5, 7.5], [7.0, 7.0]):
        core = UAVCoverageCore(map_size=16, obs_size=16, n_uavs=1, start=[point])
        core.reset(seed=0)
        core.step(np.array([[0.0, 0.0]]))  # polar, rho = 0: hover
        counts.append(round(core.coverage * 256))
    assert counts == [32, 29]
