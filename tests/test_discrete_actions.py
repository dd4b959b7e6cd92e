"""Discrete actions: integers for the env, one-hot vectors for the critics and the buffer, the straight-through
Gumbel-softmax actor update, the temperature, saving and the command line. The learning test is in
test_maddpg_learning.py."""

from pathlib import Path

import numpy as np
import pytest
import torch as th
from gymnasium import spaces
from maddpg_test_envs import DiscreteTargetReachEnv, TargetReachEnv

from sb3_maddpg import MADDPG, MATD3, evaluate_policy, make_multiagent_vec_env
from sb3_maddpg.common.actions import gumbel_max_sample, one_hot, straight_through_gumbel_softmax
from sb3_maddpg.common.agent_spaces import read_agent_spaces
from sb3_maddpg.common.buffers import MultiAgentReplayBuffer, MultiAgentReplayBufferSamples
from sb3_maddpg.common.distributional import quantile_huber_loss
from sb3_maddpg.common.noise import DecayingGaussianNoise


def make_model(algorithm=MADDPG, n_agents: int = 3, n_envs: int = 2, share_features_extractor: bool = False, **kwargs):
    venv = make_multiagent_vec_env(DiscreteTargetReachEnv, n_envs=n_envs, seed=0, env_kwargs=dict(n_agents=n_agents))
    kwargs = dict(dict(buffer_size=200, learning_starts=20, batch_size=8, seed=0), **kwargs)
    policy_kwargs = dict(n_quantiles=5, net_arch=[16, 16], share_features_extractor=share_features_extractor)
    return algorithm("MlpPolicy", venv, policy_kwargs=policy_kwargs, **kwargs)


def logits_of(model, observations: np.ndarray) -> th.Tensor:
    """The actors' logits for VecEnv rows, (rows, n)."""
    obs = th.as_tensor(np.asarray(observations)).view(-1, model.n_agents, *model.observation_space.shape)
    with th.no_grad():
        return model.actor.preactivations(obs).reshape(len(observations), -1)


# --- The VecEnv ----------------------------------------------------------------------------------------------------


def test_vec_env_takes_a_shared_discrete_space_and_the_env_gets_integers():
    venv = make_multiagent_vec_env(DiscreteTargetReachEnv, n_envs=2, seed=0, env_kwargs=dict(n_agents=3))
    assert venv.action_space == spaces.Discrete(5)
    venv.reset()
    # The env raises unless each agent gets an integer in [0, 5)
    venv.step(np.array([0, 1, 2, 3, 4, 0]))


def test_mpe2_discrete_simple_spread_is_accepted():
    simple_spread_v3 = pytest.importorskip("mpe2.simple_spread_v3")
    agent_spaces = read_agent_spaces(simple_spread_v3.parallel_env(continuous_actions=False))
    assert agent_spaces.homogeneous and agent_spaces.action_spaces == (spaces.Discrete(5),) * 3
    venv = make_multiagent_vec_env(simple_spread_v3.parallel_env, seed=0, env_kwargs=dict(continuous_actions=False))
    model = MADDPG("MlpPolicy", venv, buffer_size=100, learning_starts=10, batch_size=4, seed=0)
    model.learn(20)
    assert model.replay_buffer.actions.shape[-1] == 5


class _MultiDiscreteEnv(TargetReachEnv):
    def action_space(self, agent):
        return spaces.MultiDiscrete([5, 3])


def test_multidiscrete_is_refused_with_a_clear_error():
    with pytest.raises(TypeError, match="MultiDiscrete.*not supported yet"):
        make_multiagent_vec_env(_MultiDiscreteEnv)


# --- Acting ---------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("algorithm", [MADDPG, MATD3])
def test_predict_returns_integers_and_deterministically_the_argmax(algorithm):
    model = make_model(algorithm)
    obs = model.env.reset()
    actions, _ = model.predict(obs, deterministic=True)
    assert actions.shape == (6,) and actions.dtype.kind == "i"
    assert ((actions >= 0) & (actions < 5)).all()
    np.testing.assert_array_equal(actions, logits_of(model, obs).argmax(dim=-1).numpy())
    np.testing.assert_array_equal(model.predict(obs, deterministic=True)[0], actions)
    # Exploring samples the logits: integers of the space, not always the argmax
    samples = np.stack([model.predict(obs, deterministic=False)[0] for _ in range(50)])
    assert samples.dtype.kind == "i" and ((samples >= 0) & (samples < 5)).all()
    assert (samples != actions).any()
    # A PettingZoo dict in, a dict of integers out
    env = DiscreteTargetReachEnv(n_agents=3)
    observations, _ = env.reset(seed=0)
    agent_actions, _ = model.predict(observations, deterministic=True)
    assert set(agent_actions) == set(env.possible_agents)
    env.step(agent_actions)


def test_gumbel_max_sample_draws_from_the_softmax():
    th.manual_seed(0)
    probabilities = th.tensor([0.6, 0.25, 0.1, 0.05])
    draws = gumbel_max_sample(probabilities.log().expand(40_000, 4))
    frequencies = th.bincount(draws, minlength=4).float() / len(draws)
    assert th.allclose(frequencies, probabilities, atol=0.01)


def test_rollouts_before_learning_starts_are_uniform_integers():
    model = make_model(learning_starts=2000, buffer_size=2000)
    model.learn(1000)
    stored = model.replay_buffer.actions[: model.replay_buffer.pos].reshape(-1, 5)
    frequencies = stored.mean(axis=0)
    assert np.allclose(frequencies, 0.2, atol=0.03), frequencies


# --- The buffer -----------------------------------------------------------------------------------------------------


def test_the_buffer_holds_one_hot_actions():
    model = make_model()
    model.learn(60)
    stored = model.replay_buffer.actions[: model.replay_buffer.pos]
    assert stored.shape[-1] == 5 and stored.dtype == np.float32
    assert set(np.unique(stored)) == {0.0, 1.0}
    np.testing.assert_array_equal(stored.sum(axis=-1), 1.0)
    assert model.replay_buffer.sample(4).actions.shape == (4, 3, 5)


def test_buffer_add_converts_integers_and_refuses_actions_outside_the_space():
    space = spaces.Discrete(4, start=1)
    buffer = MultiAgentReplayBuffer(10, spaces.Box(-1, 1, (2,)), space, device="cpu", n_envs=2, n_agents=2)
    obs, infos = np.zeros((2, 2), np.float32), [{}, {}]
    buffer.add(obs, obs, np.array([1, 4]), np.zeros(2), np.zeros(2), infos)
    np.testing.assert_array_equal(buffer.actions[0, 0], [[1, 0, 0, 0], [0, 0, 0, 1]])
    np.testing.assert_array_equal(one_hot(np.array([2]), space), [[0, 1, 0, 0]])
    with pytest.raises(ValueError, match="integers in \\[1, 5\\)"):
        buffer.add(obs, obs, np.array([0, 2]), np.zeros(2), np.zeros(2), infos)


# --- The update -----------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("temperature", [0.5, 1.0, 2.0])
def test_straight_through_gumbel_softmax_is_one_hot_forward_with_the_soft_gradient(temperature):
    logits = th.randn(64, 3, 5, generator=th.Generator().manual_seed(1), requires_grad=True)
    weights = th.randn(64, 3, 5, generator=th.Generator().manual_seed(2))
    th.manual_seed(3)
    sample = straight_through_gumbel_softmax(logits, temperature)
    # The same Gumbel noise by hand (torch.nn.functional.gumbel_softmax draws -log Exponential(1))
    th.manual_seed(3)
    gumbels = -th.empty_like(logits).exponential_().log()
    soft = th.softmax((logits.detach() + gumbels) / temperature, dim=-1)
    # Forward: the hard one-hot sample of argmax(logits + g)
    assert set(sample.detach().unique().tolist()) == {0.0, 1.0}
    assert th.equal(sample.detach().argmax(-1), (logits.detach() + gumbels).argmax(-1))
    assert th.equal(sample.detach().sum(-1), th.ones(64, 3))
    # Backward: the gradient of the relaxed sample, non-zero
    (sample * weights).sum().backward()
    expected = soft * (weights - (soft * weights).sum(-1, keepdim=True)) / temperature
    assert th.allclose(logits.grad, expected, atol=1e-6)
    assert logits.grad.abs().sum() > 0


@pytest.mark.parametrize(("algorithm", "shared"), [(MADDPG, False), (MATD3, False), (MADDPG, True)])
def test_critic_target_by_hand_uses_the_target_actors_one_hot_argmax(algorithm, shared):
    model = make_model(algorithm, n_agents=2, share_features_extractor=shared)
    model.policy.set_training_mode(True)
    gen = th.Generator().manual_seed(0)
    observations = th.rand((2, 4, 2, 4), generator=gen) * 2 - 1
    actions = th.nn.functional.one_hot(th.randint(0, 5, (4, 2), generator=gen), 5).float()
    batch = MultiAgentReplayBufferSamples(
        observations[0], actions, observations[1], th.tensor([[0.0], [1.0], [0.0], [0.0]]), th.randn((4, 2), generator=gen)
    )
    with th.no_grad():
        next_logits = model.actor_target.preactivations(batch.next_observations)
        next_actions = th.nn.functional.one_hot(next_logits.argmax(-1), 5).float()  # MATD3: no smoothing on one-hot
        next_quantiles = model.critic_target.all_quantiles(batch.next_observations, next_actions).min(dim=0).values
        target = batch.rewards[..., None] + model.gamma * (1 - batch.dones[..., None]) * next_quantiles
        current = model.critic.all_quantiles(batch.observations, batch.actions)
    expected = sum(quantile_huber_loss(quantiles, target).mean(dim=0) for quantiles in current)
    loss, _, _ = model.critic_loss(batch)
    assert th.allclose(loss, expected, atol=1e-6)
    # The actor loss sends a gradient to every actor's logits through the straight-through sample
    features = model.critic.encode(batch.observations).detach()
    model.actor_loss(batch, features).sum().backward()
    assert all(p.grad is not None and p.grad.abs().sum() > 0 for p in model.actor.parameters())


# --- Arguments ------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("algorithm", [MADDPG, MATD3])
@pytest.mark.parametrize(
    ("value", "error"),
    [(0.0, ValueError), (-1.0, ValueError), (float("nan"), ValueError), ("1", ValueError), (True, ValueError)],
)
def test_gumbel_temperature_is_checked(algorithm, value, error):
    with pytest.raises(
        error, match=r"gumbel_temperature \(the Gumbel-softmax temperature, default 1.0\) must be a finite number > 0"
    ):
        make_model(algorithm, gumbel_temperature=value)


def test_action_noise_is_refused_with_discrete_actions():
    with pytest.raises(ValueError, match="action_noise applies to continuous"):
        make_model(action_noise=DecayingGaussianNoise(np.zeros(1)))
    assert make_model().action_noise is None


# --- Saving ---------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("algorithm", [MADDPG, MATD3])
def test_save_load_and_resume_keep_the_discrete_model(algorithm, tmp_path: Path):
    model = make_model(algorithm, gumbel_temperature=0.5)
    model.learn(60)
    obs = model.env.reset()
    actions, _ = model.predict(obs, deterministic=True)
    model.save(tmp_path / "model")
    model.save_replay_buffer(tmp_path / "buffer")

    loaded = algorithm.load(tmp_path / "model", device="cpu")
    assert loaded.gumbel_temperature == 0.5 and loaded.action_space == spaces.Discrete(5)
    assert loaded.action_noise is None and loaded.actor.discrete
    np.testing.assert_array_equal(loaded.predict(obs, deterministic=True)[0], actions)

    resumed = algorithm.load(tmp_path / "model", env=model.env, device="cpu")
    resumed.load_replay_buffer(tmp_path / "buffer")
    resumed.learn(20, reset_num_timesteps=False)
    assert resumed.num_timesteps == 80
    stored = resumed.replay_buffer.actions[: resumed.replay_buffer.pos]
    np.testing.assert_array_equal(stored.sum(axis=-1), 1.0)
    mean, _ = evaluate_policy(resumed, resumed.env, n_eval_episodes=2)
    assert np.isfinite(mean)


# --- The command line -----------------------------------------------------------------------------------------------


def test_cli_trains_and_evaluates_discrete_simple_spread(tmp_path: Path, monkeypatch, capsys):
    pytest.importorskip("mpe2")
    from sb3_maddpg.__main__ import main

    monkeypatch.chdir(tmp_path)
    params = ["-params", "learning_starts:30", "batch_size:8", "buffer_size:1000"]
    argv = ["train", "--algo", "matd3", "--env", "simple_spread_discrete_v3", "-n", "60", "-f", "logs", "--seed", "0"]
    assert main([*argv, "--env-kwargs", "max_cycles:15", *params]) == 0
    model = tmp_path / "logs" / "matd3" / "simple_spread_discrete_v3_1" / "simple_spread_discrete_v3.zip"
    argv = ["evaluate", "--model", str(model), "--episodes", "2", "--out", "eval", "--no-gif"]
    assert main(argv) == 0
    assert "| random | 2 |" in capsys.readouterr().out
