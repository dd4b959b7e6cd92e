"""make_multiagent_vec_env: row layout, seeding, truncation flags, terminal observations, episode statistics."""

import numpy as np
import pytest
from gymnasium import spaces
from maddpg_test_envs import CountingImageEnv, TargetReachEnv

from sb3_maddpg import make_multiagent_vec_env


def test_rows_are_agent_major_inside_copies():
    venv = make_multiagent_vec_env(CountingImageEnv, n_envs=3, env_kwargs=dict(n_agents=2, episode_length=5))
    assert (venv.num_envs, venv.n_agents, venv.n_copies) == (6, 2, 3)
    assert venv.possible_agents == ["agent_0", "agent_1"]
    obs = venv.reset()
    assert obs.shape == (6, 3, 16, 16) and obs.dtype == np.uint8
    # CountingImageEnv fills agent i's image with 10 * t + i
    np.testing.assert_array_equal(obs[:, 0, 0, 0], [0, 1, 0, 1, 0, 1])
    assert venv.get_attr("episode_length") == [5] * 6


def test_seeds_reach_every_copy_distinct_and_reproducible():
    def first_obs(seed):
        venv = make_multiagent_vec_env(TargetReachEnv, n_envs=3, seed=seed, env_kwargs=dict(n_agents=2))
        return venv.reset()

    a, b, c = first_obs(0), first_obs(0), first_obs(1)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    copies = a.reshape(3, 2, 4)
    assert not np.array_equal(copies[0], copies[1]) and not np.array_equal(copies[1], copies[2])
    # SB3's convention: seed(s) then reset()
    venv = make_multiagent_vec_env(TargetReachEnv, n_envs=3, env_kwargs=dict(n_agents=2))
    assert venv.seed(0) == [0, 0, 1, 1, 2, 2]
    np.testing.assert_array_equal(venv.reset(), a)
    # without a seed the copies still differ
    unseeded = make_multiagent_vec_env(TargetReachEnv, n_envs=3, env_kwargs=dict(n_agents=2)).reset().reshape(3, 2, 4)
    assert not np.array_equal(unseeded[0], unseeded[1])


@pytest.mark.parametrize("truncate", [False, True])
def test_episode_end_infos(truncate):
    venv = make_multiagent_vec_env(
        CountingImageEnv, n_envs=2, env_kwargs=dict(n_agents=3, episode_length=4, truncate=truncate)
    )
    venv.reset()
    for t in range(1, 5):
        obs, rewards, dones, infos = venv.step(np.full((6, 2), 0.5, np.float32))
        if t < 4:
            assert not dones.any()
            assert all("episode" not in info and "TimeLimit.truncated" not in info for info in infos)
    assert dones.all()
    for row, info in enumerate(infos):
        agent = row % 3
        # terminal observation of step 4; the returned obs is already the reset one (step 0)
        assert info["terminal_observation"][0, 0, 0] == 40 + agent
        assert obs[row, 0, 0, 0] == agent
        assert info["TimeLimit.truncated"] == truncate
        # the final step's own infos are kept; the automatic reset's infos go to reset_infos
        assert info["t"] == 4 and venv.reset_infos[row]["t"] == 0
        # SB3 episode statistics once per joint episode, in the row of agent 0
        if agent == 0:
            # team return: sum over agents and steps of (t + 0.1 * i)
            assert info["episode"]["r"] == pytest.approx(3 * (1 + 2 + 3 + 4) + 4 * (0.1 + 0.2))
            assert info["episode"]["l"] == 4
        else:
            assert "episode" not in info


class MixedRankEnv(TargetReachEnv):
    def observation_space(self, agent):
        return spaces.Box(-1.0, 1.0, (4,) if agent == "agent_0" else (1, 2, 2), np.float32)


class MultiDiscreteActionEnv(TargetReachEnv):
    def action_space(self, agent):
        return spaces.MultiDiscrete([4, 2])


def test_unsupported_envs_get_clear_errors():
    # agents may have spaces of their own (tests/test_heterogeneous_spaces.py), but not a vector beside an image
    with pytest.raises(ValueError, match="share the number of dimensions"):
        make_multiagent_vec_env(MixedRankEnv)
    with pytest.raises(TypeError, match="MultiDiscrete"):
        make_multiagent_vec_env(MultiDiscreteActionEnv)
    with pytest.raises(TypeError, match="ParallelEnv"):
        make_multiagent_vec_env(lambda: object())
    with pytest.raises(ValueError, match="n_envs"):
        make_multiagent_vec_env(TargetReachEnv, n_envs=0)


class DepartingAgentEnv(TargetReachEnv):
    """agent_1 leaves after the first step, before the episode ends."""

    def step(self, actions):
        obs, rewards, terms, truncs, infos = super().step(actions)
        if self.t == 1 and self.agents:
            self.agents = [agent for agent in self.agents if agent != "agent_1"]
            for values in (obs, rewards, terms, truncs, infos):
                values.pop("agent_1")
        return obs, rewards, terms, truncs, infos


def test_departing_agents_get_a_clear_error():
    venv = make_multiagent_vec_env(DepartingAgentEnv, seed=0)
    venv.reset()
    with pytest.raises(ValueError, match="agent_1 left before the episode's end: agents that are not in the episode"):
        venv.step(np.zeros((2, 2), np.float32))
