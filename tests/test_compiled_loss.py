"""The quantile Huber loss compiled by torch.compile: the same values and gradients as the formula, a clear fallback."""

import warnings

import pytest
import torch as th
from maddpg_test_envs import TargetReachEnv
from test_distributional import _plain_quantile_huber_loss

from sb3_maddpg import MADDPG, make_multiagent_vec_env
from sb3_maddpg.common import distributional
from sb3_maddpg.common.distributional import mean_anchored_quantile_loss, quantile_huber_loss, quantile_midpoints


def test_compiled_loss_equals_the_formula_and_its_gradient_in_float64():
    generator = th.Generator().manual_seed(3)
    current = (th.randn(8, 3, 5, generator=generator, dtype=th.float64) * 2).requires_grad_()
    target = th.randn(8, 3, 7, generator=generator, dtype=th.float64) * 3
    target[..., 0] = current.detach()[..., 0]  # a zero difference: where the weight switches
    target[..., 1] = current.detach()[..., 1] + 0.25  # exactly at kappa: where the Huber loss turns linear
    taus = th.rand(5, generator=generator, dtype=th.float64)
    weights = th.randn(8, 3, generator=generator, dtype=th.float64)

    expected = _plain_quantile_huber_loss(current, target, taus, 0.25)
    (expected_grad,) = th.autograd.grad((expected * weights).sum(), current)
    compiled = quantile_huber_loss(current, target, taus, kappa=0.25, compiled=True)
    (compiled_grad,) = th.autograd.grad((compiled * weights).sum(), current)

    assert compiled.shape == (8, 3)
    assert th.allclose(compiled, expected, rtol=1e-12, atol=1e-12)
    assert th.allclose(compiled_grad, expected_grad, rtol=1e-12, atol=1e-12)


def test_compiled_loss_in_float32_and_the_mean_anchored_loss():
    current = th.randn(16, 3, 25, requires_grad=True)
    target = th.randn(16, 3, 25) * 3
    compiled = quantile_huber_loss(current, target, compiled=True)
    expected = _plain_quantile_huber_loss(current, target, quantile_midpoints(25), 1.0)
    assert th.allclose(compiled, expected, rtol=1e-5, atol=1e-5)
    (compiled_grad,) = th.autograd.grad(compiled.sum(), current)
    (expected_grad,) = th.autograd.grad(expected.sum(), current)
    assert th.allclose(compiled_grad, expected_grad, rtol=1e-5, atol=1e-6)
    # The mean-anchored loss takes the same kernel for its quantile term
    anchored = mean_anchored_quantile_loss(current, target, compiled=True)
    assert th.allclose(anchored, mean_anchored_quantile_loss(current, target), rtol=1e-5, atol=1e-5)


def test_a_failed_compilation_warns_once_and_computes_the_eager_loss(monkeypatch):
    def broken_compile(function, **kwargs):
        def fails(*args):
            raise RuntimeError("no C++ compiler found\nsecond line")

        return fails

    monkeypatch.setattr(distributional, "_COMPILED", {})
    monkeypatch.setattr(th, "compile", broken_compile)
    current, target = th.randn(4, 3, 5), th.randn(4, 3, 5)
    with pytest.warns(UserWarning, match=r"could not compile its kernel \(RuntimeError: no C\+\+ compiler found\)"):
        loss = quantile_huber_loss(current, target, compiled=True)
    assert th.equal(loss, quantile_huber_loss(current, target))
    # Later calls take the eager loss without trying again
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert th.equal(quantile_huber_loss(current, target, compiled=True), loss)


def make_model(**kwargs) -> MADDPG:
    venv = make_multiagent_vec_env(TargetReachEnv, n_envs=1, seed=0, env_kwargs=dict(n_agents=2))
    return MADDPG(
        "MlpPolicy", venv, buffer_size=200, learning_starts=10, batch_size=16, seed=0,
        policy_kwargs=dict(n_quantiles=5, net_arch=[16]), **kwargs,
    )  # fmt: skip


def critic_loss_and_gradients(model: MADDPG, batch) -> tuple[th.Tensor, list[th.Tensor]]:
    model.critic.zero_grad(set_to_none=True)
    loss, _, _ = model.critic_loss(batch)
    loss.sum().backward()
    return loss.detach(), [p.grad.clone() for p in model.critic.parameters()]


@pytest.mark.parametrize("mean_anchored", [False, True])
def test_maddpg_critic_loss_and_gradients_with_the_compiled_loss(tmp_path, mean_anchored):
    model = make_model(compile_quantile_loss=True, mean_anchored_quantiles=mean_anchored)
    model.learn(30)  # updates with the compiled loss, and a buffer to sample from
    batch = model.replay_buffer.sample(16)
    compiled_loss, compiled_grads = critic_loss_and_gradients(model, batch)
    model.compile_quantile_loss = False
    eager_loss, eager_grads = critic_loss_and_gradients(model, batch)
    assert th.allclose(compiled_loss, eager_loss, rtol=1e-5, atol=1e-6)
    for compiled_grad, eager_grad in zip(compiled_grads, eager_grads, strict=True):
        assert th.allclose(compiled_grad, eager_grad, rtol=1e-4, atol=1e-6)
    model.compile_quantile_loss = True
    model.save(tmp_path / "model.zip")
    assert MADDPG.load(tmp_path / "model.zip").compile_quantile_loss is True


def test_compile_quantile_loss_must_be_a_bool():
    with pytest.raises(TypeError, match="compile_quantile_loss must be True or False, got 'yes'"):
        make_model(compile_quantile_loss="yes")
