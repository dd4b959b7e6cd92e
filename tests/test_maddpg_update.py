"""One MADDPG update on hand-built batches: targets, per-agent actor gradients, centralised critics, BatchNorm."""

import copy

import numpy as np
import pytest
import torch as th
from maddpg_test_envs import CountingImageEnv, TargetReachEnv

from sb3_maddpg import MADDPG, make_multiagent_vec_env
from sb3_maddpg.common.buffers import MultiAgentReplayBufferSamples
from sb3_maddpg.common.distributional import cvar, quantile_huber_loss
from sb3_maddpg.common.torch_layers import ReportCNN


def make_model(policy: str = "MlpPolicy", n_agents: int = 3, n_quantiles: int = 5, **kwargs) -> MADDPG:
    env_cls = TargetReachEnv if policy == "MlpPolicy" else CountingImageEnv
    venv = make_multiagent_vec_env(env_cls, n_envs=1, seed=0, env_kwargs=dict(n_agents=n_agents))
    return MADDPG(
        policy,
        venv,
        buffer_size=100,
        learning_starts=0,
        batch_size=8,
        seed=0,
        policy_kwargs=dict(n_quantiles=n_quantiles, net_arch=[16, 16]),
        **kwargs,
    )


def hand_batch(model: MADDPG, batch_size: int = 8, seed: int = 0, done_every: int = 2) -> MultiAgentReplayBufferSamples:
    gen = th.Generator().manual_seed(seed)
    n, shape = model.n_agents, model.observation_space.shape
    if model.observation_space.dtype == np.uint8:
        obs = th.randint(0, 256, (2, batch_size, n, *shape), generator=gen, dtype=th.uint8)
    else:
        obs = th.rand((2, batch_size, n, *shape), generator=gen) * 2 - 1
    actions = th.rand((batch_size, n, 2), generator=gen) * 2 - 1
    rewards = th.randn((batch_size, n), generator=gen)
    dones = th.zeros(batch_size, 1)
    dones[::done_every] = 1.0
    return MultiAgentReplayBufferSamples(obs[0], actions, obs[1], dones, rewards)


def expected_critic_loss(model: MADDPG, batch: MultiAgentReplayBufferSamples, current: th.Tensor) -> th.Tensor:
    with th.no_grad():
        next_actions = model.actor_target(batch.next_observations)
        next_q = model.critic_target(batch.next_observations, next_actions)
        target = batch.rewards[..., None] + model.gamma * (1 - batch.dones[..., None]) * next_q
    return quantile_huber_loss(current, target).mean(dim=0)


def perturb_(module: th.nn.Module, seed: int = 1) -> None:
    gen = th.Generator().manual_seed(seed)
    with th.no_grad():
        for p in module.parameters():
            p.add_(th.randn(p.shape, generator=gen) * 0.5)


@pytest.mark.parametrize("policy", ["MlpPolicy", "CnnPolicy"])
def test_critic_target_uses_reward_gamma_termination_and_target_actors(policy):
    model = make_model(policy)
    model.policy.set_training_mode(True)
    batch = hand_batch(model)
    loss, current, _ = model.critic_loss(batch)
    assert loss.shape == (3,) and current.shape == (8, 3, 5)
    assert th.allclose(loss, expected_critic_loss(model, batch, current), atol=1e-6)

    # Terminated transitions do not bootstrap: with every sample terminal the target is the reward alone
    terminal = batch._replace(dones=th.ones(8, 1))
    loss_t, current_t, _ = model.critic_loss(terminal)
    assert th.allclose(loss_t, quantile_huber_loss(current_t, terminal.rewards[..., None]).mean(0), atol=1e-6)
    # gamma = 0 also removes the bootstrap
    model.gamma = 0.0
    loss_g, current_g, _ = model.critic_loss(batch)
    assert th.allclose(loss_g, quantile_huber_loss(current_g, batch.rewards[..., None]).mean(0), atol=1e-6)
    model.gamma = 0.95

    # The target uses the target actors: changing the online actors leaves the critic loss unchanged
    saved = copy.deepcopy(model.policy.state_dict())
    perturb_(model.actor)
    assert th.allclose(model.critic_loss(batch)[0], loss, atol=1e-6)
    model.policy.load_state_dict(saved)
    perturb_(model.actor_target)
    assert not th.allclose(model.critic_loss(batch)[0], loss)
    model.policy.load_state_dict(saved)

    # Critic i's target uses reward i only
    rewards = batch.rewards.clone()
    rewards[:, 1] += 5.0
    loss_r = model.critic_loss(batch._replace(rewards=rewards))[0]
    assert th.allclose(loss_r[[0, 2]], loss[[0, 2]], atol=1e-6) and not th.isclose(loss_r[1], loss[1])


@pytest.mark.parametrize("policy", ["MlpPolicy", "CnnPolicy"])
def test_actor_loss_of_agent_i_moves_only_actor_i(policy):
    model = make_model(policy, cvar_alpha=0.4)
    model.policy.set_training_mode(True)
    batch = hand_batch(model)
    features = model.critic.encode(batch.observations).detach()
    actor_loss = model.actor_loss(batch, features)
    n = model.n_agents
    params = list(model.actor.parameters())
    for i in range(n):
        grads = th.autograd.grad(actor_loss[i], params, retain_graph=True, allow_unused=True)
        moved = th.zeros(n)
        for g in grads:
            if g is not None:
                # stacked parameters: the first dimension is agent-major (N, ...) or (N * k, ...)
                moved += g.reshape(n, -1).abs().sum(dim=1)
        assert moved[i] > 0
        assert th.all(moved[np.arange(n) != i] == 0), f"agent {i}'s actor loss reached other actors: {moved}"

    # Hand-computed loss of agent 0: CVaR of critic 0 with a_0 = mu_0(o_0), others from the batch
    with th.no_grad():
        mixed = batch.actions.clone()
        mixed[:, 0] = model.actor(batch.observations)[:, 0]
        z0 = model.critic.quantiles_from_features(features, mixed)[:, 0]
        assert actor_loss[0].item() == pytest.approx(-cvar(z0, 0.4).mean().item(), abs=1e-6)


@pytest.mark.parametrize("n_agents", [1, 2, 3])
def test_own_action_critic_path_equals_the_mixed_joint_actions(n_agents):
    # The actor update's critic pass (the shared first layer plus each agent's own-action change) against the
    # explicit form: one joint action per critic, built with th.where and fed through the whole MLP
    model = make_model("MlpPolicy", n_agents=n_agents)
    batch = hand_batch(model)
    features = model.critic.encode(batch.observations).detach()
    own = th.tanh(th.randn(batch.actions.shape, generator=th.Generator().manual_seed(3))).requires_grad_(True)
    fast = model.critic.quantiles_with_own_actions(features, batch.actions, own)
    eye = th.eye(n_agents, dtype=th.bool).view(1, n_agents, n_agents, 1)
    mixed = th.where(eye, own.unsqueeze(1), batch.actions.unsqueeze(1))  # (B, N_critics, N, A)
    slow = model.critic.quantiles_from_features(features, mixed)
    th.testing.assert_close(fast, slow, rtol=1e-5, atol=1e-6)
    weights = th.randn(fast.shape, generator=th.Generator().manual_seed(4))
    (grad_fast,) = th.autograd.grad((fast * weights).sum(), own)
    (grad_slow,) = th.autograd.grad((slow * weights).sum(), own)
    th.testing.assert_close(grad_fast, grad_slow, rtol=1e-5, atol=1e-6)
    # the shared-input path for one joint action equals the per-critic path with that action repeated
    repeated = batch.actions.unsqueeze(1).expand(-1, n_agents, -1, -1)
    th.testing.assert_close(
        model.critic.quantiles_from_features(features, batch.actions),
        model.critic.quantiles_from_features(features, repeated),
        rtol=1e-5,
        atol=1e-6,
    )


def test_each_critic_sees_every_agents_observation_and_action():
    model = make_model("MlpPolicy", n_agents=3)
    model.policy.set_training_mode(False)
    batch = hand_batch(model)
    with th.no_grad():
        base = model.critic(batch.observations, batch.actions)
        for j in range(3):
            obs = batch.observations.clone()
            obs[:, j] += 0.3
            actions = batch.actions.clone()
            actions[:, j] *= -1
            for changed in (model.critic(obs, batch.actions), model.critic(batch.observations, actions)):
                # every critic i (dimension 1) reacts to agent j's observation and action
                assert th.all((changed - base).abs().sum(dim=(0, 2)) > 0)


def test_single_quantile_with_alpha_one_is_classic_maddpg():
    model = make_model("MlpPolicy", n_quantiles=1, cvar_alpha=1.0)
    batch = hand_batch(model)
    loss, current, features = model.critic_loss(batch)
    with th.no_grad():
        # classic TD target y_i = r_i + gamma (1 - d) Q_i'(o', mu'(o'))
        y = (
            batch.rewards
            + model.gamma
            * (1 - batch.dones)
            * model.critic_target(batch.next_observations, model.actor_target(batch.next_observations))[..., 0]
        )
    delta = y - current[..., 0]
    # one quantile at tau = 0.5: half the Huber loss of the TD error (gradient 0.5 * delta inside |delta| <= 1)
    huber = th.where(delta.abs() <= 1, 0.5 * delta**2, delta.abs() - 0.5)
    assert th.allclose(loss, (0.5 * huber).mean(dim=0), atol=1e-6)
    # the actor maximises Q itself
    with th.no_grad():
        mixed = batch.actions.clone()
        mixed[:, 1] = model.actor(batch.observations)[:, 1]
        q1 = model.critic.quantiles_from_features(features, mixed)[:, 1, 0]
        assert model.actor_loss(batch, features.detach())[1].item() == pytest.approx(-q1.mean().item(), abs=1e-6)


def _count_cnn_passes(n_agents: int) -> tuple[int, list[tuple[int, ...]]]:
    model = make_model("CnnPolicy", n_agents=n_agents)
    model.learn(20)
    shapes = []
    hooks = [
        m.register_forward_hook(lambda mod, inp, out: shapes.append(tuple(inp[0].shape)))
        for m in model.policy.modules()
        if isinstance(m, ReportCNN)
    ]
    model.train(gradient_steps=1, batch_size=8)
    for h in hooks:
        h.remove()
    return len(shapes), shapes


def test_cnn_passes_per_update_do_not_grow_with_agents():
    # actor on o, actor_target on o', critic on o, critic_target on o': 4 (batched) passes, whatever N
    count2, shapes2 = _count_cnn_passes(2)
    count4, shapes4 = _count_cnn_passes(4)
    assert count2 == count4 == 4
    assert all(s[:2] == (8, 4) for s in shapes4)


def test_batchnorm_eval_when_acting_train_in_updates_and_copied_to_targets():
    model = make_model("CnnPolicy", n_agents=2)
    model.learn(30)
    # acting: eval mode, so a copy's actions do not depend on the other rows of the batch
    obs = np.random.default_rng(0).integers(0, 256, (6, 3, 16, 16), dtype=np.uint8)
    alone, _ = model.predict(obs[:2], deterministic=True)
    together, _ = model.predict(obs, deterministic=True)
    np.testing.assert_allclose(alone, together[:2], atol=1e-6)
    assert not model.actor.training and not model.critic.training

    modes = []
    hook = model.critic.features.register_forward_hook(lambda mod, inp, out: modes.append(mod.training))
    model.train(gradient_steps=2, batch_size=8)
    hook.remove()
    assert modes and all(modes)
    assert not model.actor_target.training and not model.critic_target.training
    online, target = model._online_batch_norm_stats, model._target_batch_norm_stats
    assert len(online) == len(target) == 4  # running_mean and running_var of the critics' and the actors' encoders
    for a, b in zip(online, target, strict=True):
        assert th.equal(a, b)
    assert not th.all(online[0] == 0) and not th.all(online[2] == 0)


def test_train_step_changes_all_networks_and_logs_per_agent():
    model = make_model("MlpPolicy", n_agents=2)
    model.learn(30)
    before = {k: v.clone() for k, v in model.policy.state_dict().items()}
    model.train(gradient_steps=3, batch_size=8)
    after = model.policy.state_dict()
    for prefix in ("actor.", "actor_target.", "critic.", "critic_target."):
        assert any(not th.equal(before[k], after[k]) for k in after if k.startswith(prefix)), prefix
    logged = model.logger.name_to_value
    for name in ("agent_0", "agent_1"):
        for key in ("critic_loss", "actor_loss", "q_mean", "cvar", "q_spread"):
            assert np.isfinite(logged[f"train/{key}_{name}"])
    assert 0.1 <= logged["train/noise_std"] <= 1.0


def test_step_statistics_by_hand():
    # the logged CVaR and spread of each agent's critic on the batch, against the quantiles computed here
    model = make_model("MlpPolicy", n_agents=2, cvar_alpha=0.5)
    batch = hand_batch(model)
    with th.no_grad():
        quantiles = model.critic(batch.observations, batch.actions)  # (B, N, n_q) before the step
    stats = model._gradient_step(batch, update_actor=False, update_targets=False)
    assert quantiles.shape[-1] == 5
    for i in range(2):
        rows = quantiles[:, i].sort(dim=-1).values
        worst = rows[:, :3].mean(dim=-1)  # CVaR_0.5 of 5 quantiles: the ceil(0.5 * 5) = 3 lowest
        assert stats.cvar[i].item() == pytest.approx(worst.mean().item(), rel=1e-5)
        spread = ((rows - rows.mean(dim=-1, keepdim=True)) ** 2).mean(dim=-1).sqrt()
        assert stats.q_spread[i].item() == pytest.approx(spread.mean().item(), rel=1e-5)
        assert stats.q_mean[i].item() == pytest.approx(rows.mean().item(), rel=1e-5, abs=1e-7)


def test_actor_reg_adds_mean_squared_preactivation_of_each_actor():
    model = make_model("MlpPolicy", n_agents=2, cvar_alpha=1.0, actor_reg=0.5)
    batch = hand_batch(model)
    features = model.critic.encode(batch.observations).detach()
    with th.no_grad():
        loss = model.actor_loss(batch, features)
        model.actor_reg = 0.0
        unregularised = model.actor_loss(batch, features)
        pre = model.actor.preactivations(batch.observations)  # (B, N, A)
    # agent i pays 0.5 * mean over batch and action dimensions of its pre-tanh outputs squared
    for i in range(2):
        assert loss[i].item() == pytest.approx(unregularised[i].item() + 0.5 * pre[:, i].pow(2).mean().item(), abs=1e-6)
    assert th.allclose(th.tanh(pre), model.actor(batch.observations))


def test_batch_norm_eps_reaches_every_encoder():
    venv = make_multiagent_vec_env(CountingImageEnv, n_envs=1, seed=0, env_kwargs=dict(n_agents=2))
    model = MADDPG(
        "CnnPolicy",
        venv,
        buffer_size=10,
        policy_kwargs=dict(n_quantiles=2, net_arch=[8], features_extractor_kwargs=dict(batch_norm_eps=1e-3)),
    )
    norms = [m for m in model.policy.modules() if isinstance(m, th.nn.BatchNorm2d)]
    assert len(norms) == 4  # actor, target actor, critic, target critic
    assert all(m.eps == 1e-3 for m in norms)


@pytest.mark.parametrize("eps", [0.0, -1e-3, "1e-3"])
def test_batch_norm_eps_must_be_positive(eps):
    from gymnasium import spaces

    with pytest.raises(ValueError, match="batch_norm_eps must be a number > 0"):
        ReportCNN(spaces.Box(0, 255, (3, 16, 16), np.uint8), batch_norm_eps=eps)


@pytest.mark.parametrize("channels", [(8, 16), (8, 0, 32), (8.0, 16, 32), "8,16,32", (True, 16, 32)])
def test_report_cnn_channels_must_be_three_positive_integers(channels):
    from gymnasium import spaces

    with pytest.raises(ValueError, match="channels must be three integers >= 1"):
        ReportCNN(spaces.Box(0, 255, (3, 16, 16), np.uint8), channels=channels)


def test_report_cnn_channels_set_the_widths_and_the_features():
    from gymnasium import spaces

    encoder = ReportCNN(spaces.Box(0, 255, (4, 16, 16), np.uint8), n_agents=3, padding=1, channels=[8, 16, 32])
    convolutions = [m for m in encoder.cnn if isinstance(m, th.nn.Conv2d)]
    # grouped: 3 agents' copies side by side
    assert [(c.in_channels, c.out_channels) for c in convolutions] == [(12, 24), (24, 48), (48, 96)]
    # 16 -> 8 -> 4 -> 2 pixels with padding 1: 32 channels x 2 x 2 per agent
    assert encoder.features_dim == 32 * 2 * 2
    assert encoder(th.rand(5, 3, 4, 16, 16)).shape == (5, 3, 128)


@pytest.mark.parametrize("policy", ["MlpPolicy", "CnnPolicy"])
def test_sampled_actions_equal_sb3s_predict_path(policy):
    # MADDPG takes the actors' [-1, 1] outputs as they are; SB3's _sample_action maps them to the action space's
    # bounds through predict and back. Both must give the same env and buffer actions, with the same noise.
    from stable_baselines3.common.noise import NormalActionNoise
    from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm

    model = make_model(policy, n_agents=2)
    model.learn(4)  # sets _last_obs; the CountingImageEnv actions lie in [0, 1], not [-1, 1]
    noises = [NormalActionNoise(np.zeros(2), np.full(2, 0.3)) for _ in range(2)]
    np.random.seed(5)
    ours = model._sample_action(0, noises[0], model.env.num_envs)
    np.random.seed(5)
    theirs = OffPolicyAlgorithm._sample_action(model, 0, noises[1], model.env.num_envs)
    for mine, reference in zip(ours, theirs, strict=True):
        assert mine.shape == reference.shape
        np.testing.assert_allclose(mine, reference, rtol=0, atol=1e-6)
    if policy == "CnnPolicy":  # env actions in the env's bounds [0, 1], buffer actions in [-1, 1]
        assert not np.allclose(ours[0], ours[1])
