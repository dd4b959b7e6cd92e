"""Every validated parameter rejects a bad value with a ValueError naming it (docs/environment.md, "Parameters")."""

import numpy as np
import pytest

from sb3_maddpg_envs import uav_coverage_v0
from sb3_maddpg_envs.uav_coverage.core import UAVCoverageCore

BAD_VALUES = [
    ("map_size", 0),
    ("map_size", 2.5),
    ("map_size", True),
    ("n_uavs", 0),
    ("n_uavs", "six"),
    ("max_energy", 0.0),
    ("max_energy", -5.0),
    ("max_energy", float("nan")),
    ("max_distance", 0.0),
    ("move_energy", -1.0),
    ("hover_energy", 0.0),
    ("coverage_range", 0.0),
    ("coverage_range", 7.0),  # > comm_range 6
    ("comm_range", -1.0),
    ("comm_range", float("inf")),
    ("wall_penalty", -1.0),
    ("comm_penalty", -0.5),
    ("entropy_coef", -0.1),
    ("eps", 0.0),
    ("eps", 1.0),
    ("max_cycles", 0),
    ("max_cycles", 10.5),
    ("obs_size", 0),
    ("obs_size", 81),  # not a multiple of map_size 16
    ("reward_scale", 0.0),
    ("reward_clip", -1.0),
    ("poi_threshold", 1.5),
    ("start", "anywhere"),
    ("start", [[1.0, 1.0]]),  # 1 row for 6 UAVs
    ("start", [[1.0, 1.0]] * 5 + [[16.0, 1.0]]),  # outside [0, 16)
    ("pois", [[0.0, 0.0], [16.0, 3.0]]),  # outside
    ("pois", "no_such_file.png"),
    ("n_pois", 5),  # only with pois="uniform"
]


@pytest.mark.parametrize("name, value", BAD_VALUES, ids=[f"{n}={v!r}"[:40] for n, v in BAD_VALUES])
def test_bad_value_names_the_parameter(name, value):
    with pytest.raises(ValueError, match=name):
        UAVCoverageCore(**{name: value})


def test_message_shows_value_and_what_is_accepted():
    with pytest.raises(ValueError, match=r"max_energy must be a finite number > 0, got -5\.0"):
        UAVCoverageCore(max_energy=-5.0)
    with pytest.raises(ValueError, match=r"obs_size must be a positive multiple of map_size=16, got 81"):
        UAVCoverageCore(obs_size=81)


def test_uniform_n_pois_validated():
    with pytest.raises(ValueError, match="n_pois"):
        UAVCoverageCore(pois="uniform", n_pois=0)


def test_env_validates_at_construction():
    with pytest.raises(ValueError, match="n_uavs"):
        uav_coverage_v0.parallel_env(n_uavs=0)
    with pytest.raises(ValueError, match="render_mode"):
        uav_coverage_v0.parallel_env(render_mode="human")
    env = uav_coverage_v0.parallel_env(n_uavs=2, obs_size=16)
    with pytest.raises(ValueError, match="max_cycles"):
        env.max_cycles = 0


def test_nan_action_through_the_env_raises():
    env = uav_coverage_v0.parallel_env(n_uavs=2, obs_size=16)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="finite"):
        env.step({"uav_0": np.array([np.nan, 0.5]), "uav_1": np.array([0.1, 0.5])})
    with pytest.raises(ValueError, match="uav_1"):
        env.step({"uav_0": np.array([0.1, 0.5])})


@pytest.mark.parametrize("bad", [np.array([0.5]), "up", np.zeros((2, 2)), [0.1, [0.2, 0.3]]])
def test_malformed_action_names_the_agent(bad):
    env = uav_coverage_v0.parallel_env(n_uavs=2, obs_size=16)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="the action of agent 'uav_1' must be 2 numbers"):
        env.step({"uav_0": np.array([0.1, 0.5]), "uav_1": bad})


def test_action_for_an_unknown_agent_raises():
    env = uav_coverage_v0.parallel_env(n_uavs=2, obs_size=16)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="not live"):
        env.step({"uav_0": np.array([0.1, 0.5]), "uav_1": np.array([0.1, 0.5]), "uav_7": np.array([0.1, 0.5])})


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        (dict(crash_ground_steps=2**63), r"crash_ground_steps must be an integer in \[0, 1000000000\], got 922337203685477"),
        (dict(crash_ground_steps=10**30), r"crash_ground_steps must be an integer in \[0, 1000000000\]"),
        (dict(max_cycles=2**63), r"max_cycles must be an integer in \[1, 1000000000\]"),
        (dict(n_uavs=10**5), r"n_uavs must be an integer in \[1, 1024\], got 100000"),
        (dict(map_size=10**5, obs_size=10**5), r"map_size must be an integer in \[1, 1024\], got 100000"),
        (dict(obs_size=16 * 10**4), r"obs_size must be an integer in \[1, 4096\]"),
        (dict(pois="uniform", n_pois=10**7), r"n_pois must be an integer in \[1, 1048576\]"),
        (dict(n_uavs=1000, map_size=1000, obs_size=1000), r"n_uavs=1000, obs_size=1000: each step would hold 2.79 GiB of obs"),
        (dict(n_uavs=200, pois="uniform", n_pois=10**6), r"n_uavs=200 with 1000000 PoIs .* more than the 1 GiB accepted"),
    ],
)
def test_huge_sizes_and_step_counts_are_refused_at_construction(kwargs, message):
    with pytest.raises(ValueError, match=message):
        UAVCoverageCore(**kwargs)


def test_max_cycles_set_later_is_bounded_too():
    env = uav_coverage_v0.parallel_env(map_size=4, obs_size=4, n_uavs=2)
    with pytest.raises(ValueError, match=r"max_cycles must be an integer in \[1, 1000000000\], got 10000000000"):
        env.unwrapped.max_cycles = 10**10
