"""MATD3: twin quantile critics per agent, their clipped target by hand, delayed actors, saving, resuming.

Its learning test is test_maddpg_learning's, parametrised over both algorithms.
"""

from pathlib import Path

import numpy as np
import pytest
import torch as th
from maddpg_test_envs import CountingImageEnv, TargetReachEnv
from test_resume import tiny_env

from sb3_maddpg import MADDPG, MATD3, make_multiagent_vec_env
from sb3_maddpg.common.buffers import MultiAgentReplayBufferSamples
from sb3_maddpg.common.distributional import quantile_huber_loss
from sb3_maddpg.matd3.policies import MATD3Policy


def make_model(policy: str = "MlpPolicy", n_agents: int = 3, seed: int = 0, **kwargs) -> MATD3:
    env_cls = TargetReachEnv if policy == "MlpPolicy" else CountingImageEnv
    venv = make_multiagent_vec_env(env_cls, n_envs=1, seed=seed, env_kwargs=dict(n_agents=n_agents))
    settings = dict(buffer_size=200, learning_starts=0, batch_size=8, policy_kwargs=dict(n_quantiles=5, net_arch=[16, 16]))
    return MATD3(policy, venv, seed=seed, device="cpu", **{**settings, **kwargs})


def hand_batch(model: MATD3, batch_size: int = 8, seed: int = 0) -> MultiAgentReplayBufferSamples:
    gen = th.Generator().manual_seed(seed)
    n, shape = model.n_agents, model.observation_space.shape
    if model.observation_space.dtype == np.uint8:
        obs = th.randint(0, 256, (2, batch_size, n, *shape), generator=gen, dtype=th.uint8)
    else:
        obs = th.rand((2, batch_size, n, *shape), generator=gen) * 2 - 1
    actions = th.rand((batch_size, n, 2), generator=gen) * 2 - 1
    dones = th.zeros(batch_size, 1)
    dones[::3] = 1.0
    return MultiAgentReplayBufferSamples(obs[0], actions, obs[1], dones, th.randn((batch_size, n), generator=gen))


def test_matd3_has_td3s_defaults_and_twin_critics():
    model = make_model()
    assert (model.policy_delay, model.target_policy_noise, model.target_noise_clip) == (2, 0.2, 0.5)
    assert isinstance(model.policy, MATD3Policy) and model.critic.n_critics == 2 == model.critic_target.n_critics
    # two independent networks per agent on one set of encodings (SB3's ContinuousCritic shares its extractor too)
    assert model.critic.quantile_nets.n_models == 2 * model.n_agents
    batch = hand_batch(model)
    quantiles = model.critic.all_quantiles(batch.observations, batch.actions)
    assert quantiles.shape == (2, 8, 3, 5)
    assert not th.allclose(quantiles[0], quantiles[1])
    # the one-value-per-agent methods use each agent's first network (TD3's q1_forward)
    assert th.equal(model.critic(batch.observations, batch.actions), quantiles[0])
    assert MADDPG("MlpPolicy", model.env, buffer_size=10).critic.n_critics == 1


@pytest.mark.parametrize("policy", ["MlpPolicy", "CnnPolicy"])
def test_twin_critic_loss_fits_both_networks_to_the_smaller_target_at_each_quantile(policy):
    model = make_model(policy, target_policy_noise=0.0)
    batch = hand_batch(model)
    loss, first_quantiles, features = model.critic_loss(batch)
    with th.no_grad():
        # by hand: each target network's quantiles, the element-wise minimum, the Bellman target
        next_actions = model.actor_target(batch.next_observations)
        next_features = model.critic_target.encode(batch.next_observations)
        per_network = []
        for c in range(2):
            inputs = th.cat([next_features.flatten(1), next_actions.flatten(1)], dim=1)  # (B, N*F + N*A)
            z = th.stack(
                [
                    model.critic_target.quantile_nets.model_major_from(inputs.unsqueeze(0), 0, slice(m, m + 1))[0]
                    for m in range(c * 3, c * 3 + 3)
                ],
                dim=1,
            )  # (B, N, n_q) of network c
            per_network.append(z)
        smaller = th.minimum(per_network[0], per_network[1])
        target = batch.rewards[..., None] + model.gamma * (1 - batch.dones[..., None]) * smaller
        current = model.critic.all_quantiles(batch.observations, batch.actions)
    expected = quantile_huber_loss(current[0], target).mean(0) + quantile_huber_loss(current[1], target).mean(0)
    assert th.allclose(loss, expected, atol=1e-6)
    assert th.equal(first_quantiles, current[0])
    # the minimum is taken per quantile level: where the networks cross, the target mixes both
    assert (per_network[0] < per_network[1]).any() and (per_network[0] > per_network[1]).any()


def test_actors_and_targets_wait_for_every_second_critic_update():
    model = make_model()
    model.learn(40)  # learning_starts 0: 40 gradient steps
    actor_before = [p.clone() for p in model.actor.parameters()]
    target_before = [p.clone() for p in model.critic_target.parameters()]
    critic_before = [p.clone() for p in model.critic.parameters()]
    model._n_updates = 2  # the next update is the 3rd: critics only
    model.train(gradient_steps=1, batch_size=8)
    assert all(th.equal(a, b) for a, b in zip(actor_before, model.actor.parameters(), strict=True))
    assert all(th.equal(a, b) for a, b in zip(target_before, model.critic_target.parameters(), strict=True))
    assert not all(th.equal(a, b) for a, b in zip(critic_before, model.critic.parameters(), strict=True))
    model.train(gradient_steps=1, batch_size=8)  # the 4th: critics, actors and targets
    assert not all(th.equal(a, b) for a, b in zip(actor_before, model.actor.parameters(), strict=True))
    assert not all(th.equal(a, b) for a, b in zip(target_before, model.critic_target.parameters(), strict=True))


def test_save_load_keeps_the_twin_critics(tmp_path: Path):
    model = make_model("CnnPolicy")
    model.learn(30)
    model.save(tmp_path / "matd3.zip")
    loaded = MATD3.load(tmp_path / "matd3.zip", env=model.env, device="cpu")
    assert type(loaded) is MATD3 and loaded.critic.n_critics == 2 and loaded.policy_delay == 2
    for key, value in model.policy.state_dict().items():
        assert th.equal(value, loaded.policy.state_dict()[key]), key
    obs = model.env.reset()
    assert np.array_equal(model.predict(obs)[0], loaded.predict(obs)[0])


def test_resume_at_an_episode_boundary_equals_the_uninterrupted_run(tmp_path: Path):
    # test_resume's tiny UAV task (20-step episodes; its resets are among the saved random states)
    def run(seed: int = 0) -> MATD3:
        env = tiny_env(seed=seed)
        return MATD3("CnnPolicy", env, buffer_size=1000, learning_starts=50, batch_size=16, train_freq=4, seed=0,
                     device="cpu", policy_kwargs=dict(n_quantiles=4, net_arch=[16]))  # fmt: skip

    uninterrupted = run()
    uninterrupted.learn(200)
    first = run()
    first.learn(100)
    first.save(tmp_path / "model.zip")
    first.save_replay_buffer(tmp_path / "buffer.pkl")
    resumed = MATD3.load(tmp_path / "model.zip", env=tiny_env(seed=123), device="cpu")
    resumed.load_replay_buffer(tmp_path / "buffer.pkl")
    resumed.learn(100, reset_num_timesteps=False)
    vector = th.nn.utils.parameters_to_vector
    assert resumed._n_updates == uninterrupted._n_updates > 0
    assert th.equal(vector(resumed.policy.parameters()), vector(uninterrupted.policy.parameters()))


def test_evaluate_loads_each_model_with_the_algorithm_that_saved_it(tmp_path: Path):
    from sb3_maddpg.common.model_files import read_maddpg_data
    from sb3_maddpg.evaluation.report import saved_algorithm

    def saved_by(path: Path) -> type:
        return saved_algorithm(read_maddpg_data(path, ("policy_class",))["policy_class"])

    matd3 = make_model()
    matd3.save(tmp_path / "matd3.zip")
    MADDPG("MlpPolicy", matd3.env, buffer_size=10).save(tmp_path / "maddpg.zip")
    assert saved_by(tmp_path / "matd3.zip") is MATD3
    assert saved_by(tmp_path / "maddpg.zip") is MADDPG


def test_a_model_of_the_other_algorithm_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture):
    from cli_testing import fails_with
    from test_cli import TINY_TRAIN

    matd3 = make_model()
    matd3.save(tmp_path / "matd3.zip")
    MADDPG("MlpPolicy", matd3.env, buffer_size=10, device="cpu").save(tmp_path / "maddpg.zip")
    with pytest.raises(ValueError, match=r"matd3.zip is a MATD3 model .*, not a MADDPG model: load it with MATD3.load"):
        MADDPG.load(tmp_path / "matd3.zip", device="cpu")
    with pytest.raises(ValueError, match=r"maddpg.zip is a MADDPG model .*, not a MATD3 model: load it with MADDPG.load"):
        MATD3.load(tmp_path / "maddpg.zip", env=matd3.env, device="cpu")
    err = fails_with(["train", "--algo", "matd3", *TINY_TRAIN, "-i", str(tmp_path / "maddpg.zip")], capsys)
    assert "is a MADDPG model, not a MATD3 one: resume it with --algo maddpg" in err
    # each loads with its own algorithm
    assert MATD3.load(tmp_path / "matd3.zip", device="cpu").critic.n_critics == 2
    assert MADDPG.load(tmp_path / "maddpg.zip", device="cpu").critic.n_critics == 1
