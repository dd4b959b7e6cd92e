"""The storm task redesigned (``uav_coverage_storm_cpu_v2``): the strike's penalty, the grounding and the zone drawn on
channel 0 against values worked out by hand, the strike rate, the new parameters' checks, the hand-worked numbers of
docs/environment.md ("Hazards"), and the PettingZoo API and seed tests on the env id."""

import warnings

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test, parallel_seed_test

from sb3_maddpg.zoo.registry import make_multiagent_env
from sb3_maddpg_envs import uav_coverage_v1
from sb3_maddpg_envs.uav_coverage.core import UAVCoverageCore
from sb3_maddpg_envs.uav_coverage.observations import ZONE_EMPTY_VALUE, ZONE_POI_VALUE, zone_pixels

ENV_ID = "uav_coverage_storm_cpu_v2"
STORM_V2 = uav_coverage_v1.STORM_V2
HOVER = [0.5, 0.5]  # v1's Cartesian action that hovers
NO_FAILURE = np.full((2, 2), 0.9)  # link draws >= p_f: no link fails


class ScriptedDraws:
    """Stands in for the env's generator: returns the given arrays, in order, and checks their shapes."""

    def __init__(self, *draws) -> None:
        self.draws = [np.asarray(draw, dtype=np.float64) for draw in draws]

    def random(self, shape):
        draw = self.draws.pop(0)
        assert draw.shape == ((shape,) if isinstance(shape, int) else tuple(shape))
        return draw


def v2_core(start, draws, **kwargs) -> UAVCoverageCore:
    """A core with the task's parameters (1 pixel per cell), the UAVs at ``start`` and the random draws scripted."""
    core = UAVCoverageCore(
        **{**uav_coverage_v1.V1_DEFAULTS, **STORM_V2, "obs_size": 16, "start": start, "n_uavs": len(start), **kwargs}
    )
    core.reset(seed=0)
    core._rng = ScriptedDraws(*draws)
    return core


# --- the strike -----------------------------------------------------------------------------------------------------
def test_a_strike_costs_p_k_in_its_own_step_and_grounds_for_three_steps():
    # UAV 0 hovers at (7.5, 5.5), inside the zone (5, 3)-(10, 8); UAV 1 at (2.5, 5.5), outside, 5 cells away (linked).
    # Per step the core draws the storm's (2,) and then the links' (2, 2). Step 1: UAV 0 draws 0.0699 < p_s = 0.07 and
    # is struck, UAV 1 draws 0 but is outside. The strike costs p_k = 0.9 in step 1 itself, on top of what the same
    # step gives without the penalty; UAV 0 then sits out steps 2-4 with reward 0 (no grounded penalty) and flies at
    # step 5 (its draw 0.07 is not below p_s: not struck).
    storm = [[0.0699, 0.0], [0.5, 0.5], [0.5, 0.5], [0.5, 0.5], [0.07, 0.5]]
    draws = [d for pair in zip(storm, [NO_FAILURE] * 5, strict=True) for d in pair]
    penalised = v2_core([[7.5, 5.5], [2.5, 5.5]], draws)
    free = v2_core([[7.5, 5.5], [2.5, 5.5]], [np.array(d) for d in draws], storm_penalty=0.0)
    _, rewards, _, _ = penalised.step(np.array([HOVER, HOVER]))
    _, free_rewards, _, _ = free.step(np.array([HOVER, HOVER]))
    np.testing.assert_allclose(rewards - free_rewards, [-0.9, 0.0], atol=1e-12)
    np.testing.assert_allclose(penalised.last_penalties, [0.9, 0.0])
    assert penalised.last_crashed.tolist() == [True, False]
    assert penalised.grounded_steps_left.tolist() == [3, 0] and penalised.active.tolist() == [False, True]
    np.testing.assert_allclose(penalised.positions, [[7.5, 5.5], [2.5, 5.5]])  # a strike does not move the UAV
    for _ in range(3):
        _, rewards, _, _ = penalised.step(np.array([HOVER, HOVER]))
        assert rewards[0] == 0.0 and penalised.last_energy_spent[0] == 0.0
    assert penalised.active.tolist() == [True, True]
    penalised.step(np.array([HOVER, HOVER]))
    assert penalised.last_crashed.tolist() == [False, False] and penalised.last_penalties.tolist() == [0.0, 0.0]
    assert [info["crashes"] for info in penalised.infos()] == [1, 0]


def test_a_uav_inside_is_struck_at_p_s_of_its_flying_steps():
    # One UAV hovering inside for 6 000 steps of the env's own generator (a battery that lasts them): each strike
    # takes 1 flying step and 3 grounded ones, so about 6 000 / (1 / 0.07 + 3) = 347 strikes among about 4 960 flying
    # steps (binomial standard deviation 18); the share of flying steps struck is p_s.
    core = UAVCoverageCore(
        **{
            **uav_coverage_v1.V1_DEFAULTS,
            **STORM_V2,
            "obs_size": 16,
            "n_uavs": 1,
            "start": [[7.5, 5.5]],
            "max_cycles": 6000,
            "max_energy": 1e4,
        }
    )
    core.reset(seed=1)
    flying = 0
    for _ in range(6000):
        flying += int(core.grounded_steps_left[0] == 0)
        core.step(np.array([HOVER]))
    strikes = core.hazard_counts["crashes"][0]
    assert abs(strikes - 0.07 * flying) < 4 * np.sqrt(flying * 0.07 * 0.93)
    assert abs(strikes - 6000 / (1 / 0.07 + 3)) < 4 * 18


# --- the zone on channel 0 -------------------------------------------------------------------------------------------
def test_zone_pixels_by_hand():
    # 4 x 4 map, 8 x 8 image (2 pixels per cell): pixel centres at 0.25, 0.75, ..., 3.75 along each axis. The zone
    # (1, 1)-(3, 2.5) holds the centres x in {1.25, ..., 2.75} (columns 2-5) and y in {1.25, 1.75, 2.25} (rows 5, 4, 3:
    # row r has y = (8 - r - 1/2) / 2).
    expected = np.zeros((8, 8), dtype=bool)
    expected[3:6, 2:6] = True
    np.testing.assert_array_equal(zone_pixels((1.0, 1.0, 3.0, 2.5), 4, 8), expected)


def test_the_zone_is_drawn_on_channel_0_of_the_observations_and_the_state():
    # PoIs at (0, 0) (cell (0, 0): rows 6-7, columns 0-1) and (1.5, 1.5) (cell (1, 1): rows 4-5, columns 2-3, inside
    # the zone): channel 0 holds 255 on the PoI cell outside the zone, 128 on the PoI cell inside it, 64 on the
    # zone's other pixels and 0 elsewhere.
    kwargs = dict(map_size=4, obs_size=8, n_uavs=1, pois=[[0.0, 0.0], [1.5, 1.5]], start=[[3.5, 3.5]])
    storm = dict(storm_zone=(1.0, 1.0, 3.0, 2.5), storm_prob=0.5, crash_ground_steps=1)
    expected = np.zeros((8, 8), dtype=np.uint8)
    expected[6:8, 0:2] = 255
    expected[3:6, 2:6] = ZONE_EMPTY_VALUE
    expected[4:6, 2:4] = ZONE_POI_VALUE
    assert (ZONE_POI_VALUE, ZONE_EMPTY_VALUE) == (128, 64)
    core = UAVCoverageCore(**kwargs, **storm, show_storm_zone=True)
    obs = core.reset(seed=0)
    np.testing.assert_array_equal(obs[0, 0], expected)
    np.testing.assert_array_equal(core.state()[0], expected)
    obs, *_ = core.step(np.array([[0.0, 0.0]]))
    np.testing.assert_array_equal(obs[0, 0], expected)  # terrain: the same at every step
    # off (the default): the PoIs alone, as in every other task
    plain = UAVCoverageCore(**kwargs, **storm).reset(seed=0)[0, 0]
    np.testing.assert_array_equal(plain, np.where(expected == ZONE_POI_VALUE, 255, np.where(expected == 255, 255, 0)))


def test_the_task_shows_its_zone_and_keeps_the_observation_space_of_the_calm_task():
    env = make_multiagent_env(ENV_ID)
    calm = make_multiagent_env("uav_coverage_cpu_v1")
    assert env.observation_space("uav_0") == calm.observation_space("uav_0") and env.state_space == calm.state_space
    obs, _ = env.reset(seed=0)
    channel = obs["uav_0"][0]
    # grid PoIs: every cell holds one, so channel 0 is 255 but on the zone's 5 x 5 cells (rows 15 - 7 ... 15 - 3)
    assert (channel[8:13, 5:10] == ZONE_POI_VALUE).all() and (channel == 255).sum() == 256 - 25
    old, _ = make_multiagent_env("uav_coverage_storm_cpu_v1").reset(seed=0)
    assert (old["uav_0"][0] == 255).all()  # the old storm task draws no zone


# --- the parameters --------------------------------------------------------------------------------------------------
def test_the_env_id_has_the_documented_parameters():
    core = make_multiagent_env(ENV_ID).core
    assert core.storm_zone == (5.0, 3.0, 10.0, 8.0) and core.storm_prob == 0.07 and core.storm_penalty == 0.9
    assert (core.crash_ground_steps, core.grounded_penalty, core.crash_energy) == (3, 0.0, 0.0)
    assert core.show_storm_zone and core.gust_prob == 0.0 and core.link_failure_prob == 0.05
    assert core.obs_size == 16 and core.max_cycles == 300


def test_the_hand_worked_numbers():
    # docs/environment.md: from a state inside, a strike within gamma 0.9's horizon (10 steps) has probability
    # 1 - 0.93^10 = 0.516, between 0.4 and 0.6 and more than twice alpha 0.25; within 4 steps 1 - 0.93^4 = 0.252, so
    # the worst quarter of the returns from inside are those struck within about 4 steps (discount >= 0.9^3 = 0.729).
    p_s = STORM_V2["storm_prob"]
    assert 1 - (1 - p_s) ** 10 == pytest.approx(0.516, abs=5e-4)
    assert 1 - (1 - p_s) ** 4 == pytest.approx(0.252, abs=5e-4)
    # the expected discounted count of strikes from a flying state inside: V = p_s + 0.9 (1 - p_s) V + 0.9^4 p_s V
    # (after a strike 3 steps out, then flying again), V = p_s / (1 - 0.9 (1 - p_s) - 0.9^4 p_s) = 0.598
    assert p_s / (1 - 0.9 * (1 - p_s) - 0.9**4 * p_s) == pytest.approx(0.598, abs=5e-4)
    # strikes of a UAV hovering inside for 297 steps (about 3 to get there): 297 / (1 / 0.07 + 3) = 17.2
    assert 297 / (1 / p_s + 3) == pytest.approx(17.2, abs=0.05)


def test_bad_values_of_the_new_parameters_are_refused():
    with pytest.raises(ValueError, match="storm_penalty must be a finite number >= 0, got -1"):
        UAVCoverageCore(obs_size=16, storm_penalty=-1)
    with pytest.raises(ValueError, match="storm_penalty must be a finite number >= 0, got nan"):
        UAVCoverageCore(obs_size=16, storm_penalty=float("nan"))
    with pytest.raises(TypeError, match="show_storm_zone must be True or False, got 1"):
        UAVCoverageCore(obs_size=16, show_storm_zone=1)


def test_the_task_says_nothing():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        make_multiagent_env(ENV_ID)


# --- the PettingZoo interface ----------------------------------------------------------------------------------------
def test_parallel_api():
    parallel_api_test(make_multiagent_env(ENV_ID, n_uavs=3, max_cycles=40), num_cycles=60)


def test_parallel_seed():
    parallel_seed_test(lambda: make_multiagent_env(ENV_ID, n_uavs=3), num_cycles=30)


def test_episodes_are_reproducible_from_the_seed_and_strikes_happen():
    def play(seed):
        env = make_multiagent_env(ENV_ID, max_cycles=60)
        env.reset(seed=seed)
        rng = np.random.default_rng(0)
        returns, strikes = 0.0, 0
        while env.agents:
            # jitter around hovering: a UAV that starts in the zone stays there a while and is struck
            _, rewards, _, _, infos = env.step({agent: 0.5 + 0.1 * rng.standard_normal(2) for agent in env.agents})
            returns += sum(rewards.values())
            strikes = sum(info["crashes"] for info in infos.values())
        return returns, strikes

    assert play(3) == play(3)
    assert play(3) != play(4)
    assert play(3)[1] > 0  # the strikes happen
