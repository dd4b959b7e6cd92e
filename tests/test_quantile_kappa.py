"""``quantile_kappa``: the quantile Huber loss's threshold, by hand, in the distributional Bellman fixed point where
kappa 1 shrinks a rare loss's tail, and through MADDPG's checks, updates and save/load."""

import functools
import warnings

import numpy as np
import pytest
import torch as th
from maddpg_test_envs import TargetReachEnv

from sb3_maddpg import MADDPG, MATD3, make_multiagent_vec_env
from sb3_maddpg.common.distributional import cvar, mean_anchored_quantile_loss, quantile_huber_loss
from sb3_maddpg.maddpg import maddpg as maddpg_module


def test_mean_anchored_loss_takes_kappa_for_the_shape_and_mean_kappa_for_the_mean():
    # n = 2 quantiles at tau 0.25 and 0.75, z = (0, 1), one target t = 0.9, kappa 0.5 for the shape:
    # delta = (0.9, -0.1): huber_0.5(0.9) = 0.5 * (0.9 - 0.25) = 0.325, huber_0.5(-0.1) = 0.005, both weighted 0.25 and
    # divided by kappa: 0.1625 + 0.0025 = 0.165; the mean's term keeps kappa 1: 2 / 2 * 0.5 * (0.9 - 0.5)^2 = 0.08.
    # Gradient of the shape term (-0.25 * 0.5 / 0.5, 0.25 * 0.1 / 0.5) = (-0.25, 0.05), mean-free (-0.15, 0.15); the
    # mean's -0.4 / 2 each: (-0.35, -0.05)
    z = th.tensor([[0.0, 1.0]], requires_grad=True)
    loss = mean_anchored_quantile_loss(z, th.tensor([[0.9]]), kappa=0.5)
    loss.sum().backward()
    assert loss.item() == pytest.approx(0.245)
    assert z.grad[0].tolist() == pytest.approx([-0.35, -0.05])
    # The mean's threshold on its own: mean error 0.4 beyond mean_kappa 0.25: 1 * 0.25 * (0.4 - 0.125) / 0.25 = 0.275
    # plus the kappa-1 shape term 0.1025
    loss = mean_anchored_quantile_loss(th.tensor([[0.0, 1.0]]), th.tensor([[0.9]]), mean_kappa=0.25)
    assert loss.item() == pytest.approx(0.1025 + 0.275)


def _fixed_point_tail_depth(kappa: float, alpha: float = 0.25) -> tuple[float, float]:
    """
    A chain of 10 states: 4 safe ones, then 4 where a step costs 1 with probability 1/25 (else 0), then 2 safe ones;
    gamma 0.95. Each
    state's 25 quantiles are fitted, from the last state back, to the targets r + gamma * z_next (the next state's
    fitted quantiles as samples, r drawn in its exact proportions: 24 copies at 0, one at -1), by minimising
    ``quantile_huber_loss`` with threshold kappa. Returns the fitted first state's tail depth (mean minus CVaR_alpha)
    and the exact one (the loss part's distribution, enumerated).
    """
    gamma, n_before, n_risky, n_after, n = 0.95, 4, 4, 2, 25
    following = th.zeros(n)  # the quantiles of the state after the last: none
    for state in reversed(range(n_before + n_risky + n_after)):
        risky = n_before <= state < n_before + n_risky
        rewards = th.tensor([0.0] * 24 + [-1.0]) if risky else th.zeros(25)
        targets = (rewards[:, None] + gamma * following[None, :]).reshape(1, -1)
        z = targets.mean().repeat(1, n).clone().requires_grad_(True)
        optimizer = th.optim.Adam([z], lr=0.02)
        for _ in range(600):
            optimizer.zero_grad()
            quantile_huber_loss(z, targets, kappa=kappa).sum().backward()
            optimizer.step()
        following = z.detach()[0].sort().values
    fitted = float(following.mean() - cvar(following, alpha))
    # The exact distribution: -sum_k gamma^k B_k over the 4 risky steps, B_k ~ Bernoulli(1/25), all 16 outcomes
    outcomes = np.array(np.meshgrid(*[[0, 1]] * n_risky)).reshape(n_risky, -1).T
    returns = -(outcomes * gamma ** np.arange(n_before, n_before + n_risky)).sum(axis=1)
    probabilities = np.prod(np.where(outcomes == 1, 1 / 25, 24 / 25), axis=1)
    order = np.argsort(returns)
    returns, cumulative = returns[order], np.cumsum(probabilities[order])
    # The exact distribution's 25 quantiles at the midpoints (1/50, 3/50, ...): what 25 quantiles can hold at best
    exact_quantiles = th.tensor(returns[np.searchsorted(cumulative, (np.arange(n) + 0.5) / n)], dtype=th.float32)
    exact = float(exact_quantiles.mean() - cvar(exact_quantiles, alpha))
    return fitted, exact


def test_kappa_one_shrinks_a_rare_losss_tail_at_every_bootstrap_and_a_small_kappa_keeps_it():
    # P(some loss) = 1 - 0.96^4 = 15 %: the exact distribution's lowest 4 of 25 midpoint quantiles (tau 0.02 to 0.14)
    # are losses (about -0.95^4 each), the others 0; CVaR_0.25 reads the lowest ceil(0.25 * 25) = 7: depth about
    # 4 * 0.81 / 7 - 4 * 0.81 / 25 = 0.33. With kappa 1 the fit is an expectile's: each of the 10 bootstraps pulls the
    # quantiles towards their mean, the 4 safe ones before the risk included, and little of the tail is left
    shrunk, exact = _fixed_point_tail_depth(kappa=1.0)
    kept, _ = _fixed_point_tail_depth(kappa=0.01)
    assert 0.28 < exact < 0.35
    assert kept == pytest.approx(exact, rel=0.1)
    assert shrunk < 0.25 * exact


def _model(algorithm=MADDPG, **kwargs) -> MADDPG:
    return algorithm("MlpPolicy", make_multiagent_vec_env(TargetReachEnv), learning_starts=0, seed=0, **kwargs)


@pytest.mark.parametrize(
    "kwargs, expected",
    [
        (dict(policy_kwargs=dict(n_quantiles=5)), 0.05),  # plain quantiles: QR-DQN's loss with kappa 0.05
        (dict(policy_kwargs=dict(n_quantiles=5), mean_anchored_quantiles=True), 0.05),  # the shape's kappa
        (dict(policy_kwargs=dict(n_quantiles=1)), 1.0),  # the scalar critic: its Huber mean keeps kappa 1
    ],
)
def test_the_critic_update_uses_quantile_kappa(monkeypatch, kwargs, expected):
    seen = []

    def recording(function, *args, kappa=1.0, **kw):
        seen.append(kappa)
        return function(*args, kappa=kappa, **kw)

    for name in ("quantile_huber_loss", "mean_anchored_quantile_loss"):
        monkeypatch.setattr(maddpg_module, name, functools.partial(recording, getattr(maddpg_module, name)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # kappa with one quantile warns (test below)
        model = _model(quantile_kappa=0.05, **kwargs)
    model.learn(8)
    assert seen and set(seen) == {expected}


def test_quantile_kappa_is_checked_warned_about_kept_and_passed_on_by_matd3(tmp_path):
    for bad in (0.0, -1.0, float("nan"), "0.1", True):
        with pytest.raises(ValueError, match="quantile_kappa"):
            _model(quantile_kappa=bad)
    with pytest.warns(UserWarning, match=r"quantile_kappa=0.1 has no effect with n_quantiles=1"):
        _model(quantile_kappa=0.1, policy_kwargs=dict(n_quantiles=1))
    model = _model(quantile_kappa=0.01, policy_kwargs=dict(n_quantiles=5))
    model.save(tmp_path / "model.zip")
    assert MADDPG.load(tmp_path / "model.zip").quantile_kappa == 0.01
    assert _model(MATD3, quantile_kappa=0.02, policy_kwargs=dict(n_quantiles=5)).quantile_kappa == 0.02
    assert _model(policy_kwargs=dict(n_quantiles=5)).quantile_kappa == 1.0  # QR-DQN's default


def test_own_action_gradients_match_finite_differences():
    from sb3_maddpg.common.diagnostics import own_action_gradients

    model = _model(policy_kwargs=dict(n_quantiles=5))
    critic = model.critic
    observations = th.as_tensor(
        np.random.default_rng(0).normal(size=(3, model.n_agents, *model.observation_space.shape)), dtype=th.float32
    )
    actions = th.rand(3, model.n_agents, model.action_space.shape[0], generator=th.Generator().manual_seed(0)) * 2 - 1
    with th.no_grad():
        features = critic.encode(observations)
    objectives = (lambda q: q.mean(dim=-1), lambda q: cvar(q, 0.4))
    gradients = own_action_gradients(critic, features, actions, objectives)
    eps = 1e-3
    for objective, gradient in zip(objectives, gradients, strict=True):
        for axis in range(actions.shape[-1]):
            step = th.zeros_like(actions)
            step[..., axis] = eps
            with th.no_grad():
                up = objective(critic.quantiles_with_own_actions(features, actions, actions + step))
                down = objective(critic.quantiles_with_own_actions(features, actions, actions - step))
            assert th.allclose(gradient[..., axis], (up - down) / (2 * eps), atol=2e-3)
    assert all(parameter.grad is None for parameter in critic.parameters())  # nothing reaches the weights
