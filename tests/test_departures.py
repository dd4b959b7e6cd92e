"""Agents that leave before the episode ends: rows kept, the env given no action for them, the losses without them."""

import numpy as np
import pytest
import torch as th
from maddpg_test_envs import TargetReachEnv

from sb3_maddpg import MADDPG, MATD3, make_multiagent_vec_env
from sb3_maddpg.common.departures import KeepDepartedAgents
from sb3_maddpg.common.distributional import quantile_huber_loss


class LeavingAgentEnv(TargetReachEnv):
    """agent_1 terminates at step 2 and leaves; agent_0 goes on to max_cycles. Refuses an action for an absent agent."""

    def __init__(self, max_cycles: int = 5):
        super().__init__(n_agents=2, max_cycles=max_cycles)
        self.received = []

    def step(self, actions):
        unknown = set(actions) - set(self.agents)
        if unknown:
            raise ValueError(f"an action for {unknown}, which are not in the episode")
        self.received.append(sorted(actions))
        leaving = self.t == 1 and "agent_1" in self.agents
        obs, rewards, terms, truncs, infos = super().step(actions)
        if leaving and self.agents:
            terms["agent_1"] = True
            self.agents = ["agent_0"]
        if "agent_1" not in self.agents and not leaving:
            for values in (obs, rewards, terms, truncs, infos):
                values.pop("agent_1", None)
        return obs, rewards, terms, truncs, infos


def test_wrapper_keeps_the_rows_and_marks_who_is_in():
    env = KeepDepartedAgents(LeavingAgentEnv())
    assert env.observation_space("agent_0").shape == (5,)
    obs, _ = env.reset(seed=0)
    assert obs["agent_0"][-1] == 1.0 and obs["agent_1"][-1] == 1.0
    actions = {agent: np.zeros(2, np.float32) for agent in env.possible_agents}
    obs, rewards, terms, truncs, _ = env.step(actions)  # step 1: both in
    assert obs["agent_1"][-1] == 1.0
    obs, rewards, terms, truncs, _ = env.step(actions)  # step 2: agent_1 leaves (its reward still counts)
    assert obs["agent_1"].tolist() == [0.0] * 5 and obs["agent_0"][-1] == 1.0
    assert rewards["agent_1"] != 0.0 and not any(terms.values()) and env.agents == env.possible_agents
    obs, rewards, terms, truncs, _ = env.step(actions)  # step 3: the env gets agent_0's action only
    assert env.unwrapped.received[-1] == ["agent_0"] and rewards["agent_1"] == 0.0
    for _ in range(2):
        obs, rewards, terms, truncs, _ = env.step(actions)
    assert truncs["agent_0"] and terms["agent_1"] and env.agents == []


def test_without_black_death_the_error_names_the_option():
    venv = make_multiagent_vec_env(LeavingAgentEnv, seed=0)
    venv.reset()
    venv.step(np.zeros((2, 2), np.float32))
    with pytest.raises(ValueError, match="agent_1 left before the episode's end.*black_death=True"):
        venv.step(np.zeros((2, 2), np.float32))


@pytest.mark.parametrize("algo", [MADDPG, MATD3])
def test_learning_with_an_agent_that_leaves(algo, tmp_path):
    venv = make_multiagent_vec_env(LeavingAgentEnv, seed=0, black_death=True)
    assert venv.departures and venv.observation_space.shape == (5,)
    model = algo("MlpPolicy", venv, buffer_size=300, learning_starts=20, batch_size=16, seed=0,
                 policy_kwargs=dict(n_quantiles=3))  # fmt: skip
    assert model.departures
    model.learn(150)  # the env refuses any action for agent_1 after it left
    model.save(tmp_path / "leaving")
    assert algo.load(tmp_path / "leaving", env=venv).departures


def test_the_losses_leave_out_an_agent_that_has_left():
    venv = make_multiagent_vec_env(LeavingAgentEnv, seed=0, black_death=True)
    model = MADDPG("MlpPolicy", venv, buffer_size=300, learning_starts=20, batch_size=16, seed=0, gamma=0.9,
                   policy_kwargs=dict(n_quantiles=1))  # fmt: skip
    model.learn(60)
    data = model.replay_buffer.sample(64)
    present = data.observations[..., -1]
    assert 0 < present[:, 1].sum() < 64  # the batch holds rows with agent_1 in and rows after it left
    loss, _, _ = model.critic_loss(data)
    # Agent 1's loss by hand, over its rows only: target r (no bootstrap) where it left, r + gamma Q' where it stays
    with th.no_grad():
        next_actions = model.actor_target(data.next_observations) * data.next_observations[..., -1:]
        next_q = model.critic_target(data.next_observations, next_actions)[:, 1]
        left = present[:, 1] * (1 - data.next_observations[:, 1, -1])
        target = data.rewards[:, 1:2] + (1 - data.dones) * (1 - left[:, None]) * 0.9 * next_q
        q = model.critic(data.observations, data.actions * present[..., None])[:, 1]
        per_row = quantile_huber_loss(q, target)
        expected = (per_row * present[:, 1]).sum() / present[:, 1].sum()
    assert loss[1].item() == pytest.approx(expected.item(), rel=1e-5)
    # Garbage in the rows of an agent that has left changes nothing
    garbage = data._replace(actions=th.where(present[..., None] > 0, data.actions, th.full_like(data.actions, 0.9)))
    assert th.allclose(model.critic_loss(garbage)[0], loss)
    assert th.allclose(model.actor_loss(garbage, model.critic.encode(data.observations)),
                       model.actor_loss(data, model.critic.encode(data.observations)))  # fmt: skip


def test_black_death_needs_vector_observations():
    from maddpg_test_envs import CountingImageEnv

    with pytest.raises(ValueError, match="vector observations"):
        make_multiagent_vec_env(CountingImageEnv, black_death=True)
    with pytest.raises(TypeError, match="black_death must be True or False"):
        make_multiagent_vec_env(TargetReachEnv, black_death="yes")


def test_a_model_trained_with_departures_acts_on_the_plain_env():
    from sb3_maddpg.evaluation.baselines import ModelController
    from sb3_maddpg.evaluation.evaluate import evaluate_controllers

    venv = make_multiagent_vec_env(LeavingAgentEnv, seed=0, black_death=True)
    model = MADDPG("MlpPolicy", venv, buffer_size=100, learning_starts=10, batch_size=8, seed=0,
                   policy_kwargs=dict(n_quantiles=1))  # fmt: skip
    model.learn(20)
    results, _ = evaluate_controllers(LeavingAgentEnv, [ModelController(model)], n_episodes=2)
    assert [episode["length"] for episode in results["maddpg"]] == [5.0, 5.0]


def test_predict_on_the_plain_envs_dict_says_to_append_the_in_episode_entry():
    venv = make_multiagent_vec_env(LeavingAgentEnv, seed=0, black_death=True)
    model = MADDPG("MlpPolicy", venv, buffer_size=100, learning_starts=10, batch_size=8, seed=0,
                   policy_kwargs=dict(n_quantiles=1))  # fmt: skip
    observations, _ = LeavingAgentEnv().reset(seed=0)
    with pytest.raises(ValueError, match=r"'agent_0' has \d+ entries.*black_death=True.*np.append\(observation, 1.0\)"):
        model.predict(observations)
    actions, _ = model.predict({agent: np.append(obs, 1.0).astype(np.float32) for agent, obs in observations.items()})
    assert set(actions) == {"agent_0", "agent_1"}
