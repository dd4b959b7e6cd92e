"""Agents with spaces of their own: padded storage, masked networks, and an env that never sees a padded action."""

import numpy as np
import pytest
import torch as th
from gymnasium import spaces
from maddpg_test_envs import MixedImageEnv, MixedSpacesEnv, TargetReachEnv

from sb3_maddpg import MADDPG, MATD3, make_multiagent_vec_env
from sb3_maddpg.common.agent_spaces import AgentSpaces, read_agent_spaces


def small_model(venv, algo=MADDPG, policy="MlpPolicy", **kwargs):
    settings = dict(buffer_size=500, learning_starts=20, batch_size=8, seed=0, policy_kwargs=dict(n_quantiles=3))
    settings.update(kwargs)
    return algo(policy, venv, **settings)


def test_masks_by_hand():
    layout = read_agent_spaces(MixedSpacesEnv())
    assert not layout.homogeneous
    assert layout.padded_observation_shape == (4,)
    assert layout.observation_mask().tolist() == [[True, True, True, True], [True, True, False, False]]
    assert layout.action_widths.tolist() == [2, 1]
    assert layout.action_mask().tolist() == [[True, True], [True, False]]
    discrete = read_agent_spaces(MixedSpacesEnv(discrete=True))
    assert discrete.action_mask().tolist() == [[True] * 5, [True, True, True, False, False]]
    images = read_agent_spaces(MixedImageEnv())
    mask = images.observation_mask()
    assert images.padded_observation_shape == (2, 20, 24)
    assert mask[0].sum() == 2 * 16 * 16 and mask[0, :, :16, :16].all() and mask[1].all()
    assert read_agent_spaces(TargetReachEnv()).homogeneous


class _Spaces:
    def __init__(self, observation_spaces, action_spaces):
        self.possible_agents = [f"agent_{i}" for i in range(len(observation_spaces))]
        self._obs, self._act = observation_spaces, action_spaces

    def observation_space(self, agent):
        return self._obs[self.possible_agents.index(agent)]

    def action_space(self, agent):
        return self._act[self.possible_agents.index(agent)]


def test_unsupported_mixes_are_refused_with_the_reason():
    vector, image = spaces.Box(-1, 1, (3,)), spaces.Box(0, 255, (1, 16, 16), np.uint8)
    box, discrete = spaces.Box(-1, 1, (2,)), spaces.Discrete(3)
    with pytest.raises(ValueError, match="number of dimensions and the dtype"):
        read_agent_spaces(_Spaces([vector, image], [box, box]))
    with pytest.raises(ValueError, match="all have Box actions or all Discrete"):
        read_agent_spaces(_Spaces([vector, vector], [box, discrete]))
    with pytest.raises(ValueError, match="same bounds on the entries they share"):
        read_agent_spaces(_Spaces([vector, vector], [box, spaces.Box(0, 1, (1,))]))
    with pytest.raises(ValueError, match="start them at 0"):
        read_agent_spaces(_Spaces([vector, vector], [discrete, spaces.Discrete(2, start=1)]))
    with pytest.raises(TypeError, match="Box observation spaces"):
        read_agent_spaces(_Spaces([spaces.Discrete(2), vector], [box, box]))


def test_vec_env_is_padded_and_the_env_gets_each_agents_own_action():
    venv = make_multiagent_vec_env(MixedSpacesEnv, seed=0)
    assert venv.observation_space.shape == (4,) and venv.action_space.shape == (2,)
    assert venv.agent_spaces == read_agent_spaces(MixedSpacesEnv())
    obs = venv.reset()
    assert obs[1, 2:].tolist() == [0.0, 0.0]  # the slider's padding
    # The env refuses an action outside the agent's space: the slider must get one number
    venv.step(np.array([[0.5, -0.5], [0.25, 0.9]], dtype=np.float32))
    received = venv.parallel_envs[0].unwrapped.received[-1]
    assert np.asarray(received["slider"]).tolist() == [0.25]
    assert np.asarray(received["mover"]).tolist() == [0.5, -0.5]


@pytest.mark.parametrize("algo", [MADDPG, MATD3])
def test_no_padded_entry_is_stored_and_no_weight_on_padding_learns(algo):
    venv = make_multiagent_vec_env(MixedSpacesEnv, seed=0)
    model = small_model(venv, algo=algo)
    critic_first = model.critic.quantile_nets.first_layer.weight.detach().clone()  # (models, in, out)
    actor_first = model.actor.mu.first_layer.weight.detach().clone()
    model.learn(120)
    buffer = model.replay_buffer
    stored = buffer.actions[: buffer.pos, 0]  # (T, N, A) of the one copy
    # random actions (before learning_starts) and noisy ones (after) alike: the slider's second entry is 0
    assert np.all(stored[:, 1, 1] == 0.0) and np.any(stored[:, 1, 0] != 0.0)
    assert np.all(buffer.observations[: buffer.pos, 0, 1, 2:] == 0.0)
    # The joint input is [f_mover (4), f_slider (4), a_mover (2), a_slider (2)]: the slider's padded observation
    # entries (6, 7) and action entry (11) are constant zeros, so no critic's weights on them moved
    padded_inputs = [6, 7, 11]
    after = model.critic.quantile_nets.first_layer.weight.detach()
    assert th.equal(after[:, padded_inputs], critic_first[:, padded_inputs])
    assert not th.equal(after, critic_first)
    # The slider's actor (model 1) reads only its first two observation entries
    actor_after = model.actor.mu.first_layer.weight.detach()
    assert th.equal(actor_after[1, 2:], actor_first[1, 2:]) and not th.equal(actor_after[1, :2], actor_first[1, :2])


def test_padding_values_change_nothing():
    venv = make_multiagent_vec_env(MixedSpacesEnv, seed=0)
    model = small_model(venv)
    model.learn(60)
    obs = th.as_tensor(np.random.default_rng(0).uniform(-1, 1, (5, 2, 4)), dtype=th.float32)
    garbage = obs.clone()
    garbage[:, 1, 2:] = 123.0
    with th.no_grad():
        assert th.equal(model.actor(obs), model.actor(garbage))
        actions = model.actor(obs)
        assert th.all(actions[:, 1, 1] == 0.0)
        noisy = actions.clone()
        noisy[:, 1, 1] = 0.7  # e.g. target policy smoothing on a padded entry
        assert th.equal(model.critic(obs, actions), model.critic(garbage, noisy))


def test_discrete_actions_of_different_sizes():
    venv = make_multiagent_vec_env(MixedSpacesEnv, seed=0, env_kwargs=dict(discrete=True))
    assert venv.action_space == spaces.Discrete(5)
    model = small_model(venv, learning_starts=60)
    model.learn(150)  # the env raises on an action outside an agent's own space
    stored = model.replay_buffer.actions[: model.replay_buffer.pos, 0]  # one-hot (T, N, 5)
    assert np.all(stored[:, 1, 3:] == 0.0) and np.all(stored.sum(axis=-1) == 1.0)
    assert set(np.argmax(stored[:60, 1], axis=-1)) == {0, 1, 2}  # uniform over the slider's own 3 before learning
    obs = np.random.default_rng(1).uniform(-1, 1, (400, 4)).astype(np.float32)
    obs[1::2, 2:] = 0.0
    for deterministic in (True, False):
        actions, _ = model.predict(obs, deterministic=deterministic)
        assert actions[1::2].max() < 3 and actions[0::2].max() < 5


def test_predict_on_agent_dicts_takes_and_gives_each_agents_own_shapes():
    model = small_model(make_multiagent_vec_env(MixedSpacesEnv, seed=0))
    env = MixedSpacesEnv()
    observations, _ = env.reset(seed=3)
    actions, _ = model.predict(observations)
    assert actions["mover"].shape == (2,) and actions["slider"].shape == (1,)
    env.step(actions)  # refuses anything outside the agents' own spaces


def test_save_load_keeps_the_layout(tmp_path):
    venv = make_multiagent_vec_env(MixedSpacesEnv, seed=0)
    model = small_model(venv)
    model.learn(40)
    model.save(tmp_path / "mixed")
    loaded = MADDPG.load(tmp_path / "mixed", env=make_multiagent_vec_env(MixedSpacesEnv, seed=1))
    assert loaded.agent_spaces == model.agent_spaces
    obs = make_multiagent_vec_env(MixedSpacesEnv, seed=5).reset()
    assert np.array_equal(loaded.predict(obs)[0], model.predict(obs)[0])
    assert MADDPG.load(tmp_path / "mixed").policy.agent_spaces == model.agent_spaces
    with pytest.raises(ValueError, match="agents' spaces|spaces of the VecEnv|agents have"):
        MADDPG.load(tmp_path / "mixed", env=make_multiagent_vec_env(TargetReachEnv, seed=0))


def test_images_of_different_sizes():
    venv = make_multiagent_vec_env(MixedImageEnv, seed=0)
    assert venv.observation_space.shape == (2, 20, 24)
    obs = venv.reset()
    assert np.all(obs[0, :, 16:, :] == 0) and np.all(obs[0, :, :16, :16] == 1)
    model = small_model(venv, policy="CnnPolicy", learning_starts=8, batch_size=4, buffer_size=100)
    model.learn(20)
    images = th.as_tensor(np.stack([obs, obs]))
    garbage = images.clone()
    garbage[:, 0, :, 16:, :] = 200
    model.policy.set_training_mode(False)
    with th.no_grad():
        assert th.equal(model.actor(images), model.actor(garbage))


def test_agent_spaces_round_trip_and_errors():
    layout = read_agent_spaces(MixedSpacesEnv())
    assert AgentSpaces(layout.observation_spaces, layout.action_spaces) == layout
    with pytest.raises(ValueError, match="one observation space and one action space per agent"):
        AgentSpaces(layout.observation_spaces, layout.action_spaces[:1])


@pytest.mark.parametrize("continuous", [True, False])
@pytest.mark.parametrize("task", ["simple_speaker_listener_v4", "simple_adversary_v3", "simple_world_comm_v3"])
def test_mpe2_tasks_with_agents_of_their_own_spaces_train(task, continuous):
    module = pytest.importorskip(f"mpe2.{task}")
    venv = make_multiagent_vec_env(module.parallel_env, seed=0, env_kwargs=dict(continuous_actions=continuous, max_cycles=10))
    assert venv.agent_spaces is not None
    model = small_model(venv, learning_starts=15)
    model.learn(40)


def test_team_returns_by_agent_names():
    from sb3_maddpg.common.callbacks import agent_team, team_returns

    assert [agent_team(name) for name in ("adversary_0", "leadadversary_0", "agent_12", "speaker", "eve_0")] == [
        "adversary",
        "leadadversary",
        "agent",
        "speaker",
        "eve",
    ]
    returns = {"adversary_0": 1.5, "adversary_1": -0.5, "agent_0": 2.0}
    assert team_returns(returns) == {"adversary": 1.0, "agent": 2.0}


def test_competing_teams_reach_tensorboard(tmp_path):
    simple_adversary = pytest.importorskip("mpe2.simple_adversary_v3")
    venv = make_multiagent_vec_env(simple_adversary.parallel_env, seed=0, env_kwargs=dict(max_cycles=5))
    model = small_model(venv, learning_starts=5)
    model.set_logger(__import__("stable_baselines3").common.logger.configure(str(tmp_path), ["csv"]))
    model.learn(20, log_interval=1)
    header = (tmp_path / "progress.csv").read_text().splitlines()[0].split(",")
    assert {"rollout/ep_rew_team_adversary", "rollout/ep_rew_team_agent", "rollout/ep_rew_agent_1"} <= set(header)


def test_predict_refuses_another_agents_observation_in_a_dict():
    model = small_model(make_multiagent_vec_env(MixedSpacesEnv, seed=0))
    observations, _ = MixedSpacesEnv().reset(seed=3)
    # the slider (2 entries) given the mover's 4: it fits the padded rows (4,), but is not the slider's observation
    swapped = {"mover": observations["mover"], "slider": observations["mover"]}
    with pytest.raises(ValueError, match=r"observation of 'slider' has the shape \(4,\), but 'slider'.s own .* \(2,\)"):
        model.predict(swapped)
