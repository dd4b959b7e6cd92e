"""The PettingZoo interface: API and seed tests, agents, spaces, infos, registry."""

import numpy as np
import pettingzoo
import pytest
from pettingzoo.test import api_test, parallel_api_test, parallel_seed_test

from sb3_maddpg_envs import uav_coverage_v0
from sb3_maddpg_envs.uav_coverage.core import UAVCoverageCore

INFO_KEYS = {"coverage", "fairness", "energy", "energy_efficiency", "wall_hits", "disconnections"}


def test_parallel_api():
    parallel_api_test(uav_coverage_v0.parallel_env(n_uavs=3, obs_size=16), num_cycles=120)


def test_parallel_api_with_termination():
    # Tiny batteries: every UAV is depleted after a few steps, so episodes end by termination.
    parallel_api_test(uav_coverage_v0.parallel_env(n_uavs=2, obs_size=16, max_energy=2.0), num_cycles=50)


@pytest.mark.parametrize("kwargs", [{}, {"start": "random", "pois": "uniform", "n_pois": 20}])
def test_parallel_seed(kwargs):
    parallel_seed_test(lambda: uav_coverage_v0.parallel_env(n_uavs=3, obs_size=16, **kwargs), num_cycles=30)


def test_aec_api():
    api_test(uav_coverage_v0.env(n_uavs=2, obs_size=16, max_cycles=30), num_cycles=40)


def test_default_spaces_and_metadata():
    env = uav_coverage_v0.parallel_env()
    assert env.possible_agents == [f"uav_{i}" for i in range(6)]
    obs_space = env.observation_space("uav_0")
    assert obs_space.shape == (3, 80, 80) and obs_space.dtype == np.uint8
    assert obs_space.low.min() == 0 and obs_space.high.max() == 255
    act_space = env.action_space("uav_0")
    assert act_space.shape == (2,) and act_space.dtype == np.float32
    assert act_space.low.tolist() == [0.0, 0.0] and act_space.high.tolist() == [1.0, 1.0]
    assert env.observation_space("uav_1") is env.observation_space("uav_1")
    assert env.state_space.shape == (3, 80, 80)
    assert env.metadata["name"] == "uav_coverage_v0" and env.metadata["is_parallelizable"]
    assert isinstance(env.core, UAVCoverageCore)
    assert env.core.n_uavs == 6 and env.core.map_size == 16 and env.core.pois.shape == (256, 2)


def test_episode_infos_agents_and_observations_not_mutated():
    env = uav_coverage_v0.parallel_env(n_uavs=3, obs_size=16, max_cycles=4)
    obs, infos = env.reset(seed=0)
    assert set(obs) == set(infos) == set(env.possible_agents)
    assert all(set(info) == INFO_KEYS for info in infos.values())
    held = {agent: o.copy() for agent, o in obs.items()}
    held_obs = obs
    for t in range(1, 5):
        assert env.agents == env.possible_agents
        obs, rewards, terms, truncs, infos = env.step({a: np.array([0.3, 0.9]) for a in env.agents})
        assert all(set(info) == INFO_KEYS for info in infos.values()) and len(infos) == 3
        assert all(isinstance(r, float) for r in rewards.values())
        assert all(0.0 <= info["coverage"] <= 1.0 for info in infos.values())
        assert env.core.t == t
        # Observations already handed out are never written to again.
        for agent in held:
            np.testing.assert_array_equal(held_obs[agent], held[agent])
        held = {agent: o.copy() for agent, o in obs.items()}
        held_obs = obs
    assert all(truncs.values()) and not any(terms.values())
    assert env.agents == []
    state = env.state()
    assert state.shape == (3, 16, 16) and state.dtype == np.uint8


def test_registered_in_pettingzoo():
    env = pettingzoo.make("parallel", "sb3_maddpg/uav_coverage_v0", n_uavs=2, obs_size=16)
    assert isinstance(env, pettingzoo.ParallelEnv) and env.core.n_uavs == 2
    aec = pettingzoo.make("aec", "sb3_maddpg/uav_coverage-v0", n_uavs=2, obs_size=16)
    assert isinstance(aec, pettingzoo.AECEnv)
