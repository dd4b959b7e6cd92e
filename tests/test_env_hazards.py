"""The hazards (wind gusts, crashes, link failures, the storm zone): formulas against values worked out by hand, the
argument checks, the hazardous and storm env ids (PettingZoo API, seeding) and the defaults left unchanged."""

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test, parallel_seed_test

from sb3_maddpg.zoo.registry import make_multiagent_env
from sb3_maddpg_envs import uav_coverage_v1
from sb3_maddpg_envs.uav_coverage.baselines import GreedyStaticController, greedy_placement
from sb3_maddpg_envs.uav_coverage.core import UAVCoverageCore
from sb3_maddpg_envs.uav_coverage.hazards import (
    crash_drain,
    gust_push,
    in_zone,
    push_within_walls,
    storm_strikes,
    surviving_links,
)

HOVER = [0.5, 0.5]  # v1's Cartesian action that hovers


class ScriptedDraws:
    """Stands in for the env's generator: returns the given arrays, in order, and checks their shapes."""

    def __init__(self, *draws: np.ndarray) -> None:
        self.draws = [np.asarray(draw, dtype=np.float64) for draw in draws]

    def random(self, shape):
        draw = self.draws.pop(0)
        assert draw.shape == ((shape,) if isinstance(shape, int) else tuple(shape))
        return draw


class NoDraws:
    def random(self, *args, **kwargs):
        raise AssertionError("a hazard that is off drew a random number")


def core_with(start, draws, **kwargs) -> UAVCoverageCore:
    core = UAVCoverageCore(**{**uav_coverage_v1.V1_DEFAULTS, "obs_size": 16, "start": start, "n_uavs": len(start), **kwargs})
    core.reset(seed=0)
    core._rng = ScriptedDraws(*draws)
    return core


# --- the formulas ---------------------------------------------------------------------------------------------------
def test_gust_distance_is_lomax_and_direction_uniform():
    # (1 - 0.875)^(-1/3) = 8^(1/3) = 2: d = s (2 - 1) = 2 with s = 2; direction 2 pi 0.5 = pi: push (-2, 0)
    # (1 - 0.999)^(-1/3) = 10: d = 0.5 (10 - 1) = 4.5 with s = 0.5 is not drawn for s = 2 here: d = 2 * 9 = 18,
    # direction 2 pi 0.25: push (0, 18); UAV 2 is not hit (0.5 >= p_g), UAV 3 is inactive
    draws = np.array([[0.01, 0.875, 0.5], [0.02, 0.999, 0.25], [0.5, 0.875, 0.0], [0.0, 0.875, 0.0]])
    active = np.array([True, True, True, False])
    hit, push = gust_push(draws, active, gust_prob=0.03, gust_scale=2.0, gust_tail=3.0, map_size=16)
    np.testing.assert_array_equal(hit, [True, True, False, False])
    np.testing.assert_allclose(push, [[-2.0, 0.0], [0.0, 18.0], [0.0, 0.0], [0.0, 0.0]], atol=1e-12)


def test_gust_distance_is_capped_at_twice_the_map():
    # a = 0.5: (1 - 0.99)^-2 = 10 000, d = 9 999 > 2 L = 32
    hit, push = gust_push(
        np.array([[0.0, 0.99, 0.0]]), np.array([True]), gust_prob=1.0, gust_scale=1.0, gust_tail=0.5, map_size=16
    )
    np.testing.assert_allclose(push, [[32.0, 0.0]])


def test_a_gust_out_of_the_area_stops_at_the_wall_and_crashes():
    positions = np.array([[1.0, 5.0], [3.0, 3.0], [5.0, 15.0], [0.5, 0.5]])
    push = np.array([[-1.5, 0.0], [1.0, 0.0], [0.0, 2.0], [-3.0, -3.0]])
    hit = np.array([True, True, True, False])
    crashed = push_within_walls(positions, push, hit, 16)
    np.testing.assert_array_equal(crashed, [True, False, True, False])
    # (1, 5) - 1.5 -> x = -0.5, stopped at 0; (5, 15) + 2 -> y = 17, stopped just below 16; UAV 3 was not hit
    np.testing.assert_allclose(positions, [[0.0, 5.0], [4.0, 3.0], [5.0, 16.0], [0.5, 0.5]])
    assert positions[2, 1] < 16.0


def test_crash_drain_never_more_than_what_is_left():
    np.testing.assert_allclose(crash_drain(np.array([True, True, False]), np.array([100.0, 30.0, 100.0]), 50.0), [50, 30, 0])


def test_link_failures_cut_off_a_uav_with_one_neighbour():
    # a chain 0 - 1 - 2: link 0-1 fails (draw 0.1 < 0.5), link 1-2 holds (0.9); the draws below the diagonal and the
    # one of 0-2 (out of range) change nothing
    links = np.array([[False, True, False], [True, False, True], [False, True, False]])
    draws = np.array([[0.0, 0.1, 0.1], [0.0, 0.0, 0.9], [0.0, 0.0, 0.0]])
    working = surviving_links(links, draws, 0.5)
    np.testing.assert_array_equal(working, [[False, False, False], [False, False, True], [False, True, False]])
    np.testing.assert_array_equal(working, working.T)


# --- one step of the core -------------------------------------------------------------------------------------------
def test_gust_step_crash_energy_penalties_and_rewards():
    # Two hovering UAVs at (1, 8) and (8, 8), each hit by a gust of d = 2 (s = 2, a = 3, u = 0.875): UAV 0 westwards
    # to x = -1, stopped at x = 0 (a crash), UAV 1 eastwards to (10, 8).
    core = core_with(
        [[1.0, 8.0], [8.0, 8.0]],
        [[[0.0, 0.875, 0.5], [0.0, 0.875, 0.0]]],
        gust_prob=1.0,
        gust_scale=2.0,
        gust_tail=3.0,
        crash_energy=50.0,
    )
    _, rewards, _, _ = core.step(np.array([HOVER, HOVER]))
    np.testing.assert_allclose(core.positions, [[0.0, 8.0], [10.0, 8.0]])
    np.testing.assert_allclose(core.last_gust, [[-2.0, 0.0], [2.0, 0.0]], atol=1e-12)
    np.testing.assert_array_equal(core.last_crashed, [True, False])
    # Energy: hovering E_h = 0.5 each, plus E_c = 50 for the crash
    np.testing.assert_allclose(core.last_energy_spent, [50.5, 0.5])
    np.testing.assert_allclose(core.energy, [449.5, 499.5])
    # Penalties: p_w = 1 (v1) for the crash; 10 cells apart > R = 6, both disconnected: p_c = 0.1 each
    np.testing.assert_allclose(core.last_penalties, [1.1, 0.1])
    # Rewards: (N / K) x PoIs covered (18 from x = 0: 7 + 5 + 5 + 1 over x = 0..3; a full disc 29), each worth 1 at
    # t = 1, minus 0.5 e / (eta l_max) = 0.5 e, minus the penalties
    np.testing.assert_allclose(rewards, [2 / 256 * 18 - 25.25 - 1.1, 2 / 256 * 29 - 0.25 - 0.1])
    assert core.wall_hits.tolist() == [0, 0]  # a crash is counted apart from the UAV's own wall hits
    info = core.infos()[0]
    assert (info["gusts"], info["crashes"], info["link_failures"], info["depletions"]) == (1, 1, 0, 0)


def test_a_crash_can_deplete_a_uav():
    core = core_with(
        [[1.0, 8.0], [4.0, 8.0]],
        [[[0.0, 0.875, 0.5], [0.9, 0.0, 0.0]]],
        gust_prob=0.5,
        gust_scale=2.0,
        gust_tail=3.0,
        crash_energy=50.0,
        max_energy=10.0,
    )
    core.step(np.array([HOVER, HOVER]))
    # 0.5 hovering, then min(50, 10 - 0.5) = 9.5: nothing left
    np.testing.assert_allclose(core.last_energy_spent, [10.0, 0.5])
    assert core.active.tolist() == [False, True]
    assert [info["depletions"] for info in core.infos()] == [1, 0]
    assert [info["gusts"] for info in core.infos()] == [1, 0]


def test_link_failure_step_disconnects_the_uav_with_one_neighbour():
    start = [[4.0, 8.0], [8.0, 8.0], [12.0, 8.0]]
    draws = np.array([[0.0, 0.1, 0.1], [0.0, 0.0, 0.9], [0.0, 0.0, 0.0]])
    core = core_with(start, [draws], link_failure_prob=0.5)
    core.step(np.array([HOVER] * 3))
    np.testing.assert_array_equal(core.last_disconnected, [True, False, False])
    np.testing.assert_allclose(core.last_penalties, [0.1, 0.0, 0.0])
    assert [info["link_failures"] for info in core.infos()] == [1, 0, 0]
    assert core.disconnections.tolist() == [1, 0, 0]
    # The links drawn in the observations are those in range: a failure lasts one step
    assert core.links().tolist() == [[0, 1], [1, 2]]


def test_hazards_off_draw_nothing_and_leave_the_infos_as_they_were():
    core = UAVCoverageCore(
        **uav_coverage_v1.V1_DEFAULTS, obs_size=16, crash_energy=50.0, crash_ground_steps=5, grounded_penalty=1.0
    )
    core.reset(seed=0)
    core._rng = NoDraws()
    core.step(np.full((6, 2), 0.7))
    assert not core.hazards
    assert set(core.infos()[0]) == {"coverage", "fairness", "energy", "energy_efficiency", "wall_hits", "disconnections"}


# --- argument checks ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "name, value",
    [
        ("gust_prob", -0.1),
        ("gust_prob", 1.5),
        ("gust_prob", "often"),
        ("gust_prob", float("nan")),
        ("gust_scale", 0.0),
        ("gust_scale", -1.0),
        ("gust_tail", 0.4),
        ("gust_tail", True),
        ("crash_energy", -1.0),
        ("crash_energy", float("inf")),
        ("link_failure_prob", 1.0),
        ("link_failure_prob", -0.01),
        ("link_failure_prob", None),
        ("crash_ground_steps", -1),
        ("crash_ground_steps", 2.5),
        ("grounded_penalty", -0.1),
        ("grounded_penalty", float("nan")),
    ],
)
def test_bad_hazard_values_are_refused_with_their_name(name, value):
    with pytest.raises(ValueError, match=f"{name} must"):
        UAVCoverageCore(obs_size=16, **{name: value})


def test_grounded_penalty_needs_grounding():
    with pytest.raises(ValueError, match="grounded_penalty=0.5 needs crash_ground_steps >= 1"):
        UAVCoverageCore(obs_size=16, grounded_penalty=0.5)


def test_wall_margin_checks():
    pois = np.array([[1.0, 1.0]])
    with pytest.raises(ValueError, match="wall_margin=9 leaves no cell centre"):
        greedy_placement(pois, 2, 16, 3.0, wall_margin=9)
    with pytest.raises(ValueError, match="wall_margin must be a finite number >= 0, got -1.0"):
        GreedyStaticController(wall_margin=-1.0)
    with pytest.raises(ValueError, match="wall_margin must be a finite number >= 0, got inf"):
        GreedyStaticController(wall_margin=float("inf"))
    # margin 3.5 on 16 x 16: only the centres 3.5 ... 12.5 are candidates
    spots = greedy_placement(np.argwhere(np.ones((16, 16))).astype(float), 6, 16, 3.0, 6.0, wall_margin=3.5)
    assert spots.min() >= 3.5 and spots.max() <= 12.5


# --- the hazardous env id -------------------------------------------------------------------------------------------
def test_hazard_env_id_switches_the_hazards_on():
    env = make_multiagent_env("uav_coverage_hazard_cpu_v1")
    core = env.core
    assert (core.gust_prob, core.gust_scale, core.gust_tail, core.crash_energy, core.link_failure_prob) == tuple(
        uav_coverage_v1.HAZARDS[key] for key in ("gust_prob", "gust_scale", "gust_tail", "crash_energy", "link_failure_prob")
    )
    assert env.observation_space("uav_0").shape == (4, 16, 16) and core.action_mode == "cartesian"


#: grounding after crashes, with gusts long enough to crash UAVs within a short test
GROUNDING = {"crash_energy": 0.0, "gust_scale": 4.0, "crash_ground_steps": 5, "grounded_penalty": 0.5}


@pytest.mark.parametrize("kwargs", [{}, GROUNDING], ids=["registered", "grounding"])
def test_hazard_env_parallel_api(kwargs):
    parallel_api_test(make_multiagent_env("uav_coverage_hazard_cpu_v1", n_uavs=3, max_cycles=40, **kwargs), num_cycles=60)


@pytest.mark.parametrize("kwargs", [{"gust_prob": 0.3}, GROUNDING], ids=["registered", "grounding"])
def test_hazard_env_parallel_seed(kwargs):
    parallel_seed_test(lambda: make_multiagent_env("uav_coverage_hazard_cpu_v1", n_uavs=3, **kwargs), num_cycles=30)


def test_hazard_episodes_are_reproducible_from_the_seed():
    def play(seed):
        env = make_multiagent_env("uav_coverage_hazard_cpu_v1", gust_prob=0.3, max_cycles=30)
        env.reset(seed=seed)
        rng = np.random.default_rng(0)
        returns = 0.0
        while env.agents:
            _, rewards, _, _, infos = env.step({agent: rng.random(2) for agent in env.agents})
            returns += sum(rewards.values())
        return returns, [(info["gusts"], info["crashes"], info["link_failures"]) for info in infos.values()]

    assert play(3) == play(3)
    assert play(3) != play(4)


# --- grounding after a crash ----------------------------------------------------------------------------------------
NO_GUSTS = [[0.9, 0.0, 0.0], [0.9, 0.0, 0.0]]  # both draws >= p_g = 0.5: nobody is hit


def test_a_crash_grounds_the_uav_for_k_steps_then_it_flies_again():
    # UAV 0 at (1, 8) is thrown 2 cells west against the wall (as above) at step 1; with k = 2 it sits out steps 2
    # and 3 where it stopped, (0, 8), charged p = 0.3 a step, and flies again at step 4. UAV 1 is never hit.
    core = core_with(
        [[1.0, 8.0], [4.0, 8.0]],
        [[[0.0, 0.875, 0.5], [0.9, 0.0, 0.0]], NO_GUSTS, NO_GUSTS, NO_GUSTS],
        gust_prob=0.5,
        gust_scale=2.0,
        gust_tail=3.0,
        crash_ground_steps=2,
        grounded_penalty=0.3,
    )
    east = [1.0, 0.5]  # a full move east: dx = (2 * 1 - 1) l_max = 3
    _, rewards, _, _ = core.step(np.array([HOVER, HOVER]))
    assert core.last_crashed.tolist() == [True, False]
    np.testing.assert_allclose(core.last_energy_spent, [0.5, 0.5])  # no crash_energy: the crash costs no energy
    assert core.active.tolist() == [False, True] and core.grounded_steps_left.tolist() == [2, 0]
    # From the next observation on the grounded UAV is absent: no own mark (channel 1), not in UAV 1's teammates
    obs = core.observations()
    assert obs[0, 1].max() == 0 and obs[1, 3].max() == 0
    for _ in (2, 3):
        visits_before = core.visits.copy()
        _, rewards, terminated, _ = core.step(np.array([east, HOVER]))
        np.testing.assert_allclose(core.positions[0], [0.0, 8.0])  # its action is ignored
        np.testing.assert_allclose(core.last_energy_spent, [0.0, 0.5])
        assert rewards[0] == pytest.approx(-0.3)
        assert not terminated
        # the PoIs covered are UAV 1's alone: the 29 lattice PoIs within R0 = 3 of (4, 8)
        assert (core.visits - visits_before).sum() == 29
    assert core.active.tolist() == [True, True] and core.grounded_steps_left.tolist() == [0, 0]
    core.step(np.array([east, HOVER]))
    np.testing.assert_allclose(core.positions[0], [3.0, 8.0])
    assert core.last_energy_spent[0] > 0.5
    info = core.infos()[0]
    assert (info["crashes"], info["depletions"]) == (1, 0)


def test_a_grounded_team_is_not_a_terminated_episode():
    # A single UAV crashes and is grounded for 3 steps: the episode goes on (only depletion terminates it), its
    # reward is -p each grounded step and it spends nothing.
    core = core_with(
        [[1.0, 8.0]],
        [[[0.0, 0.875, 0.5]]] + [[[0.9, 0.0, 0.0]]] * 3,
        gust_prob=0.5,
        gust_scale=2.0,
        gust_tail=3.0,
        crash_ground_steps=3,
        grounded_penalty=1.0,
    )
    core.step(np.array([HOVER]))
    for _ in range(3):
        _, rewards, terminated, truncated = core.step(np.array([HOVER]))
        assert rewards.tolist() == [-1.0] and not terminated and not truncated
        assert core.last_energy_spent.tolist() == [0.0]
    assert core.active.tolist() == [True]


# --- the storm zone -------------------------------------------------------------------------------------------------
ZONE = (3.0, 3.0, 13.0, 13.0)


def test_in_zone_includes_the_lower_edges_and_excludes_the_upper_ones():
    positions = np.array([[3.0, 3.0], [12.999, 8.0], [13.0, 8.0], [8.0, 2.999], [0.0, 0.0], [8.0, 8.0]])
    assert in_zone(positions, ZONE).tolist() == [True, True, False, False, False, True]


def test_storm_strikes_only_active_uavs_inside_the_zone_below_p_s():
    # UAV 0 inside, draw 0.004 < 0.005: struck; UAV 1 inside, draw 0.006: not; UAV 2 outside, draw 0: not;
    # UAV 3 inside, draw 0, but inactive: not
    positions = np.array([[5.0, 5.0], [8.0, 8.0], [1.0, 1.0], [10.0, 10.0]])
    struck = storm_strikes(
        np.array([0.004, 0.006, 0.0, 0.0]),
        positions,
        np.array([True, True, True, False]),
        zone=ZONE,
        storm_prob=0.005,
    )
    assert struck.tolist() == [True, False, False, False]


def test_a_strike_grounds_the_uav_where_it_is_for_k_steps():
    # UAV 0 hovers at (8, 8), inside the zone, and is struck at step 1 (draw 0.001 < p_s = 0.01); UAV 1 at (2, 8),
    # outside (and in radio range, 6 cells), draws 0 and is not struck. UAV 0 is not moved, pays no p_w at the strike
    # (no wall), loses E_c = 20 energy with the hover's 0.5, sits out steps 2 and 3 charged p_d = 0.4, and counts one
    # crash.
    core = core_with(
        [[8.0, 8.0], [2.0, 8.0]],
        [[0.001, 0.0], [0.9, 0.9], [0.9, 0.9], [0.9, 0.9]],
        storm_zone=ZONE,
        storm_prob=0.01,
        crash_energy=20.0,
        crash_ground_steps=2,
        grounded_penalty=0.4,
    )
    energy_before = core.energy.copy()
    core.step(np.array([HOVER, HOVER]))
    assert core.last_crashed.tolist() == [True, False]
    np.testing.assert_allclose(core.positions, [[8.0, 8.0], [2.0, 8.0]])
    np.testing.assert_allclose(energy_before - core.energy, [20.5, 0.5])
    np.testing.assert_allclose(core.last_penalties, [0.0, 0.0])
    assert core.active.tolist() == [False, True] and core.grounded_steps_left.tolist() == [2, 0]
    for _ in (2, 3):
        _, rewards, _, _ = core.step(np.array([HOVER, HOVER]))
        assert rewards[0] == pytest.approx(-0.4)
        np.testing.assert_allclose(core.last_energy_spent, [0.0, 0.5])
    assert core.active.tolist() == [True, True]
    core.step(np.array([HOVER, HOVER]))  # flies again: no longer grounded (draws 0.9 >= p_s)
    assert core.last_energy_spent.tolist() == [0.5, 0.5]
    assert [info["crashes"] for info in core.infos()] == [1, 0]
    assert [info["gusts"] for info in core.infos()] == [0, 0]


def test_the_storm_strikes_where_the_uav_is_after_its_move():
    # UAV 0 starts at (2, 8), outside, and moves a full 3 cells east to (5, 8), inside: struck (draw 0)
    core = core_with([[2.0, 8.0]], [[0.0]], storm_zone=ZONE, storm_prob=0.5, crash_ground_steps=1, grounded_penalty=0.1)
    core.step(np.array([[1.0, 0.5]]))
    np.testing.assert_allclose(core.positions, [[5.0, 8.0]])
    assert core.last_crashed.tolist() == [True]


@pytest.mark.parametrize(
    "zone", [(0, 0, 16), (5, 5, 5, 9), (3, 3, 2, 9), (-1, 0, 4, 4), (0, 0, 17, 4), "middle", (0, 0, float("nan"), 4)]
)
def test_bad_storm_zones_are_refused(zone):
    with pytest.raises(ValueError, match="storm_zone must be None or four numbers"):
        UAVCoverageCore(obs_size=16, storm_zone=zone)


def test_storm_prob_needs_a_zone_and_a_cost():
    with pytest.raises(ValueError, match="storm_prob=0.1 needs a storm_zone"):
        UAVCoverageCore(obs_size=16, storm_prob=0.1)
    with pytest.raises(ValueError, match="storm_prob=0.1 needs crash_ground_steps >= 1 or crash_energy > 0"):
        UAVCoverageCore(obs_size=16, storm_zone=ZONE, storm_prob=0.1)
    with pytest.raises(ValueError, match="storm_prob must be a finite number >= 0 and <= 1"):
        UAVCoverageCore(obs_size=16, storm_zone=ZONE, storm_prob=1.5, crash_ground_steps=1)
    # a zone without strikes is accepted and draws nothing (a control run)
    core = UAVCoverageCore(**uav_coverage_v1.V1_DEFAULTS, obs_size=16, storm_zone=ZONE)
    core.reset(seed=0)
    core._rng = NoDraws()
    core.step(np.full((6, 2), 0.5))
    assert not core.hazards


def test_storm_env_id_switches_the_storm_on():
    env = make_multiagent_env("uav_coverage_storm_cpu_v1")
    core = env.core
    assert core.storm_zone == uav_coverage_v1.STORM["storm_zone"] and core.storm_prob == uav_coverage_v1.STORM["storm_prob"]
    assert (core.crash_ground_steps, core.grounded_penalty) == (20, 0.75)
    assert core.gust_prob == 0.0 and core.link_failure_prob == 0.05
    assert env.observation_space("uav_0").shape == (4, 16, 16)


#: strikes frequent enough for a short test
STORM_OFTEN = {"storm_prob": 0.2}


@pytest.mark.parametrize("kwargs", [{}, STORM_OFTEN], ids=["registered", "often"])
def test_storm_env_parallel_api(kwargs):
    parallel_api_test(make_multiagent_env("uav_coverage_storm_cpu_v1", n_uavs=3, max_cycles=40, **kwargs), num_cycles=60)


def test_storm_env_parallel_seed():
    parallel_seed_test(lambda: make_multiagent_env("uav_coverage_storm_cpu_v1", n_uavs=3, **STORM_OFTEN), num_cycles=30)


def test_storm_episodes_are_reproducible_from_the_seed():
    def play(seed):
        env = make_multiagent_env("uav_coverage_storm_cpu_v1", max_cycles=40, **STORM_OFTEN)
        env.reset(seed=seed)
        rng = np.random.default_rng(0)
        returns, crashes = 0.0, 0
        while env.agents:
            _, rewards, _, _, infos = env.step({agent: rng.random(2) for agent in env.agents})
            returns += sum(rewards.values())
            crashes = sum(info["crashes"] for info in infos.values())
        return returns, crashes

    assert play(3) == play(3)
    assert play(3) != play(4)
    assert play(3)[1] > 0  # the strikes happen


def test_avoid_storm_keeps_the_spots_out_of_the_zone():
    grid = np.argwhere(np.ones((16, 16))).astype(float) + 0.5
    spots = greedy_placement(grid, 6, 16, 3.0, 6.0, avoid_zone=ZONE)
    assert not in_zone(spots, ZONE).any()
    assert in_zone(greedy_placement(grid, 6, 16, 3.0, 6.0), ZONE).any()  # the greedy spots without it are inside
    with pytest.raises(ValueError, match="avoid_zone=.* leaves no cell centre"):
        greedy_placement(grid, 6, 16, 3.0, avoid_zone=(0, 0, 16, 16))
    with pytest.raises(ValueError, match="avoid_zone must be None or four numbers"):
        greedy_placement(grid, 6, 16, 3.0, avoid_zone=(0, 0, 17))


def test_show_grounded_marks_a_grounded_uav_with_its_steps_left():
    # UAV 0 at (8.5, 8.5), the centre of a cell (its exact mark fills one pixel at 1 pixel per cell), is struck at
    # step 1 with k = 2: its own channel 1 holds 2, then 1, then its energy value again (round(255 E / E_max)); with
    # show_grounded off it has no mark while grounded. UAV 1 never sees it (no links while grounded).
    draws = [[0.0, 0.9], [0.9, 0.9], [0.9, 0.9]]
    kwargs = dict(storm_zone=ZONE, storm_prob=0.5, crash_ground_steps=2, grounded_penalty=0.1)
    shown = core_with([[8.5, 8.5], [2.5, 8.5]], draws, show_grounded=True, **kwargs)
    hidden = core_with([[8.5, 8.5], [2.5, 8.5]], [list(d) for d in draws], **kwargs)
    marks = []
    for _ in range(3):
        shown.step(np.array([HOVER, HOVER]))
        hidden.step(np.array([HOVER, HOVER]))
        obs, obs_hidden = shown.observations(), hidden.observations()
        marks.append((int(obs[0, 1].sum()), int(obs_hidden[0, 1].sum()), int(obs[1, 3].sum())))
        # the mark sits where the UAV landed: cell (8, 8) is image row 15 - 8 = 7 (y grows upwards), column 8
        assert obs[0, 1, 7, 8] == obs[0, 1].sum()
    energy_value = round(255 * shown.energy[0] / shown.max_energy)
    assert marks == [(2, 0, 0), (1, 0, 0), (energy_value, energy_value, energy_value)]
    # the state shows it too
    shown_state = core_with([[8.5, 8.5], [2.5, 8.5]], [[0.0, 0.9]], show_grounded=True, **kwargs)
    shown_state.step(np.array([HOVER, HOVER]))
    assert shown_state.state()[1, 7, 8] == 2


@pytest.mark.parametrize("value", [1, "yes", None])
def test_show_grounded_must_be_a_bool(value):
    with pytest.raises(TypeError, match="show_grounded must be True or False"):
        UAVCoverageCore(obs_size=16, show_grounded=value)


@pytest.mark.parametrize(
    ("settings", "message"),
    [
        ({"storm_zone": (0, 0, 4, 4)}, "storm_zone has no effect: storm_prob is 0"),
        ({"crash_ground_steps": 5}, "crash_ground_steps has no effect: nothing crashes a UAV without gusts"),
        ({"crash_energy": 2.0}, "crash_energy has no effect: nothing crashes a UAV without gusts"),
        ({"show_grounded": True}, "show_grounded has no effect: crash_ground_steps is 0"),
        ({"storm_penalty": 1.0}, "storm_penalty has no effect: storm_prob is 0"),
        ({"show_storm_zone": True}, "show_storm_zone has no effect: storm_zone is None"),
    ],
    ids=["storm_zone", "crash_ground_steps", "crash_energy", "show_grounded", "storm_penalty", "show_storm_zone"],
)
def test_a_setting_without_effect_is_said(settings, message):
    with pytest.warns(UserWarning, match=message):
        UAVCoverageCore(obs_size=16, **settings)


def test_settings_with_effect_say_nothing():
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        UAVCoverageCore(obs_size=16, gust_prob=0.1, crash_energy=2.0, crash_ground_steps=3, show_grounded=True)
        UAVCoverageCore(obs_size=16, storm_zone=(0, 0, 4, 4), storm_prob=0.1, crash_ground_steps=3)
