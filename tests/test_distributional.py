"""Quantile Huber loss, CVaR and quantile midpoints against hand-computed values."""

import pytest
import torch as th

from sb3_maddpg.common.distributional import (
    cvar,
    cvar_n_lowest,
    mean_anchored_quantile_loss,
    quantile_huber_loss,
    quantile_midpoints,
)


def test_quantile_midpoints():
    assert th.allclose(quantile_midpoints(4), th.tensor([0.125, 0.375, 0.625, 0.875]))
    assert th.allclose(quantile_midpoints(1), th.tensor([0.5]))
    with pytest.raises(ValueError, match="n_quantiles"):
        quantile_midpoints(0)


def test_cvar_hand_computed():
    q = th.tensor([3.0, 1.0, 2.0, 4.0])
    # ceil(0.5 * 4) = 2 lowest: (1 + 2) / 2
    assert cvar(q, 0.5).item() == pytest.approx(1.5)
    # ceil(0.26 * 4) = 2
    assert cvar(q, 0.26).item() == pytest.approx(1.5)
    # ceil(0.25 * 4) = 1: the minimum
    assert cvar(q, 0.25).item() == pytest.approx(1.0)
    assert cvar(q, 0.01).item() == pytest.approx(1.0)
    # ceil(0.75 * 4) = 3
    assert cvar(q, 0.75).item() == pytest.approx(2.0)


def test_cvar_alpha_one_is_mean_and_batched():
    q = th.randn(5, 3, 7)
    assert th.allclose(cvar(q, 1.0), q.mean(dim=-1))
    # batched over leading dims, each row separately
    expected = th.sort(q, dim=-1).values[..., :4].mean(dim=-1)  # ceil(0.5 * 7) = 4
    assert th.allclose(cvar(q, 0.5), expected)


def test_cvar_count_is_not_fooled_by_float_rounding():
    # 0.3 * 10 = 3.0000000000000004 in floating point; CVaR must average 3 values, not 4
    assert cvar_n_lowest(10, 0.3) == 3
    assert cvar(th.arange(10.0), 0.3).item() == pytest.approx(1.0)
    assert cvar_n_lowest(50, 0.5) == 25
    assert cvar_n_lowest(1, 0.1) == 1
    with pytest.raises(ValueError, match="alpha"):
        cvar_n_lowest(10, 0.0)
    with pytest.raises(ValueError, match="alpha"):
        cvar_n_lowest(10, 1.5)


def test_cvar_gradient_reaches_only_the_lowest_quantiles():
    q = th.tensor([3.0, 1.0, 2.0, 4.0], requires_grad=True)
    cvar(q, 0.5).backward()
    assert th.allclose(q.grad, th.tensor([0.0, 0.5, 0.5, 0.0]))


def test_quantile_huber_loss_single_quantile():
    # n = 1, tau = 0.5, z = 0
    z = th.zeros(1, 1)
    # delta = 2 > kappa: huber = 2 - 0.5 = 1.5, weight |0.5 - 0| = 0.5
    assert quantile_huber_loss(z, th.tensor([[2.0]])).item() == pytest.approx(0.75)
    # delta = -0.5: huber = 0.125, weight |0.5 - 1| = 0.5
    assert quantile_huber_loss(z, th.tensor([[-0.5]])).item() == pytest.approx(0.0625)


def test_quantile_huber_loss_two_quantiles_hand_computed():
    current = th.tensor([[0.0, 1.0]])  # taus 0.25, 0.75
    target = th.tensor([[0.5, 3.0]])
    # j=0: delta [0.5, 3]  -> huber [0.125, 2.5], weight 0.25 each -> mean 0.328125
    # j=1: delta [-0.5, 2] -> huber [0.125, 1.5], weights [0.25, 0.75] -> mean 0.578125
    loss = quantile_huber_loss(current, target)
    assert loss.shape == (1,)
    assert loss.item() == pytest.approx(0.90625)


def test_quantile_huber_loss_keeps_leading_dims_and_checks_shapes():
    loss = quantile_huber_loss(th.randn(8, 3, 5), th.randn(8, 3, 7))
    assert loss.shape == (8, 3)
    with pytest.raises(ValueError, match="leading dimensions"):
        quantile_huber_loss(th.randn(8, 3, 5), th.randn(8, 2, 5))


def test_quantile_huber_loss_matches_sb3_contrib():
    utils = pytest.importorskip("sb3_contrib.common.utils")
    current, target = th.randn(16, 4, 10), th.randn(16, 4, 10) * 3
    ours = quantile_huber_loss(current, target).mean()
    theirs = utils.quantile_huber_loss(current, target, sum_over_quantiles=True)
    assert ours.item() == pytest.approx(theirs.item(), rel=1e-5)


def test_quantile_regression_recovers_midpoint_quantiles():
    # Minimising the loss towards samples of U{0..99} puts the 4 quantiles near 12.5, 37.5, 62.5, 87.5 (percentiles)
    th.manual_seed(0)
    samples = th.arange(100.0).view(1, 100)
    z = th.zeros(1, 4, requires_grad=True)
    opt = th.optim.Adam([z], lr=1.0)
    for _ in range(1500):
        opt.zero_grad()
        quantile_huber_loss(z, samples).sum().backward()
        opt.step()
    assert th.allclose(z.detach(), th.tensor([[12.5, 37.5, 62.0, 87.0]]), atol=1.5)


def _plain_quantile_huber_loss(current, target, taus, kappa):
    """The loss written out as in its docstring, differentiated by autograd: the reference of the fused form."""
    delta = target.unsqueeze(-2) - current.unsqueeze(-1)
    huber = th.where(delta.abs() <= kappa, 0.5 * delta**2, kappa * (delta.abs() - 0.5 * kappa))
    weight = (taus.unsqueeze(-1) - (delta.detach() < 0).to(delta.dtype)).abs()
    return (weight * huber / kappa).mean(dim=-1).sum(dim=-1)


@pytest.mark.parametrize("kappa", [1.0, 0.25, 3.0])
@pytest.mark.parametrize(("leading", "n", "m"), [((), 1, 1), ((7,), 5, 3), ((6, 3), 25, 25), ((2, 4, 3), 4, 9)])
def test_fused_quantile_huber_loss_equals_the_formula_and_its_gradient(kappa, leading, n, m):
    generator = th.Generator().manual_seed(n * 100 + m)
    current = (th.randn(*leading, n, generator=generator, dtype=th.float64) * 2).requires_grad_()
    target = th.randn(*leading, m, generator=generator, dtype=th.float64) * 3
    target[..., 0] = current.detach()[..., 0]  # a zero difference: where the weight switches
    taus = th.rand(n, generator=generator, dtype=th.float64)
    weights = th.randn(leading, generator=generator, dtype=th.float64)  # any upstream gradient

    expected = _plain_quantile_huber_loss(current, target, taus, kappa)
    (expected_grad,) = th.autograd.grad((expected * weights).sum(), current)
    fused = quantile_huber_loss(current, target, taus, kappa)
    (fused_grad,) = th.autograd.grad((fused * weights).sum(), current)

    assert fused.shape == expected.shape == leading
    assert th.allclose(fused, expected, rtol=1e-12, atol=1e-12)
    assert th.allclose(fused_grad, expected_grad, rtol=1e-12, atol=1e-12)


def test_fused_quantile_huber_loss_float32_and_reused_workspace():
    current = th.randn(64, 3, 25, requires_grad=True)
    target = th.randn(64, 3, 25) * 3
    taus = quantile_midpoints(25)
    first = quantile_huber_loss(current, target)
    kept = first.detach().clone()
    # A second call of the same shape reuses the scratch tensors: the first result must not change
    quantile_huber_loss(current * 2, target + 1)
    assert th.equal(first.detach(), kept)
    assert th.allclose(first, _plain_quantile_huber_loss(current, target, taus, 1.0), rtol=1e-5, atol=1e-6)
    first.sum().backward()
    expected = current.detach().clone().requires_grad_()
    _plain_quantile_huber_loss(expected, target, taus, 1.0).sum().backward()
    assert th.allclose(current.grad, expected.grad, rtol=1e-5, atol=1e-6)


def test_fused_quantile_huber_loss_large_inputs_are_not_cached(monkeypatch):
    from sb3_maddpg.common import distributional

    monkeypatch.setattr(distributional, "_WORKSPACE_MAX_ELEMENTS", 10)
    monkeypatch.setattr(distributional, "_WORKSPACES", {})
    current, target = th.randn(4, 5), th.randn(4, 6)
    loss = quantile_huber_loss(current, target)
    assert distributional._WORKSPACES == {}
    assert th.allclose(loss, _plain_quantile_huber_loss(current, target, quantile_midpoints(5), 1.0), atol=1e-6)


def test_fused_quantile_huber_loss_passes_no_gradient_to_the_targets():
    current = th.randn(3, 4, requires_grad=True)
    target = th.randn(3, 4, requires_grad=True)
    quantile_huber_loss(current, target).sum().backward()
    assert current.grad is not None and target.grad is None


@pytest.mark.parametrize("chunk_pairs", [1, 7 * 5, 3 * 7 * 5, 1 << 17])
def test_fused_quantile_huber_loss_in_row_chunks_equals_one_piece(monkeypatch, chunk_pairs):
    # 4 x 5 = 20 rows of 5 x 7 pairs: chunks of 1 row (n m > chunk), 1 row, 3 rows (a last chunk of 2) and all rows
    from sb3_maddpg.common import distributional

    generator = th.Generator().manual_seed(0)
    current = th.randn(4, 5, 5, generator=generator, dtype=th.float64).requires_grad_()
    target = th.randn(4, 5, 7, generator=generator, dtype=th.float64) * 2
    taus = quantile_midpoints(5).double()
    expected = _plain_quantile_huber_loss(current, target, taus, 1.0)
    (expected_grad,) = th.autograd.grad(expected.sum(), current)
    monkeypatch.setattr(distributional, "_CHUNK_PAIRS", chunk_pairs)
    chunked = quantile_huber_loss(current, target, taus)
    (chunked_grad,) = th.autograd.grad(chunked.sum(), current)
    assert th.allclose(chunked, expected, rtol=1e-12, atol=1e-12)
    assert th.allclose(chunked_grad, expected_grad, rtol=1e-12, atol=1e-12)


def test_mean_anchored_quantile_loss_hand_computed():
    # n = 2 quantiles at tau 0.25 and 0.75, one target sample. z = (0, 2), t = 1: mean error 0, so only the quantile
    # term: 0.25 * huber(1) + 0.25 * huber(-1) = 0.25 * 0.5 * 2 = 0.25, gradient (-0.25, 0.25) (already mean-free)
    z = th.tensor([[0.0, 2.0]], requires_grad=True)
    loss = mean_anchored_quantile_loss(z, th.tensor([[1.0]]))
    loss.sum().backward()
    assert loss.item() == pytest.approx(0.25)
    assert z.grad[0].tolist() == pytest.approx([-0.25, 0.25])
    # z = (0, 0), t = 2: quantile term 0.25 * 1.5 + 0.75 * 1.5 = 1.5 with gradient (-0.25, -0.75), of which only the
    # mean-free part (0.25, -0.25) passes; mean term n / 2 * huber(2 - 0) = 1.5 with gradient (-0.5, -0.5)
    z = th.tensor([[0.0, 0.0]], requires_grad=True)
    loss = mean_anchored_quantile_loss(z, th.tensor([[2.0]]))
    loss.sum().backward()
    assert loss.item() == pytest.approx(3.0)
    assert z.grad[0].tolist() == pytest.approx([-0.25, -0.75])
    # z = (0, 1), t = 0.9, inside the Huber threshold: plain gradient (-0.25 * 0.9, 0.25 * 0.1) = (-0.225, 0.025), its
    # mean-free part (-0.125, 0.125); mean term 2 / 2 * huber(0.9 - 0.5), d/dz_i = -0.4 / 2: total (-0.325, -0.075)
    z = th.tensor([[0.0, 1.0]], requires_grad=True)
    loss = mean_anchored_quantile_loss(z, th.tensor([[0.9]]))
    loss.sum().backward()
    # quantile term 0.25 * 0.5 * 0.81 + 0.25 * 0.5 * 0.01 = 0.1025; mean term 1 * 0.5 * 0.16 = 0.08
    assert loss.item() == pytest.approx(0.1825)
    assert z.grad[0].tolist() == pytest.approx([-0.325, -0.075])


def test_mean_anchored_quantile_loss_is_the_plain_loss_with_one_quantile():
    z = th.tensor([[0.3], [-1.0]])
    t = th.tensor([[2.0, 0.1], [-0.5, 4.0]])
    assert th.equal(mean_anchored_quantile_loss(z, t), quantile_huber_loss(z, t))


def test_mean_head_quantiles_and_where_the_shape_gradient_goes():
    from gymnasium import spaces

    from sb3_maddpg.maddpg.critics import MultiAgentQuantileCritic

    th.manual_seed(0)
    critic = MultiAgentQuantileCritic(
        spaces.Box(-1, 1, (3,)),
        spaces.Box(-1, 1, (2,)),
        n_agents=2,
        n_quantiles=4,
        net_arch=[8, 8],
        activation_fn=th.nn.ReLU,
        features_extractor_class=__import__("stable_baselines3").common.torch_layers.FlattenExtractor,
        features_extractor_kwargs={},
        normalize_images=False,
        mean_head=True,
    )
    observations, actions = th.randn(5, 2, 3), th.rand(5, 2, 2) * 2 - 1
    features = critic.encode(observations)
    raw = critic.quantile_nets(th.cat([features.flatten(1), actions.flatten(1)], dim=1).unsqueeze(1).expand(5, 2, -1))
    quantiles = critic.all_quantiles_from_features(features, actions)[0]  # (B, N, 4)
    # mu + d_j - mean(d): the mean of the quantiles is output 0, the deviations keep their differences
    assert th.allclose(quantiles.mean(dim=-1), raw[..., 0], atol=1e-6)
    assert th.allclose(quantiles[..., 1] - quantiles[..., 0], raw[..., 2] - raw[..., 1], atol=1e-6)
    layers = [module for module in critic.quantile_nets.net if hasattr(module, "weight")]
    trunk_sizes = {}
    for shape_gradient in (False, True):
        critic.zero_grad()
        spread = critic.all_quantiles_from_features(features, actions, shape_gradient=shape_gradient)[0].var(dim=-1)
        spread.sum().backward()  # depends on the deviations only
        output = layers[-1].weight.grad  # (models, in, out)
        # the mean's row gets nothing (up to rounding: mu cancels in the spread), the deviations' rows do
        assert output[..., 0].abs().max() < 1e-6 * output[..., 1:].abs().max()
        trunk_sizes[shape_gradient] = max(layer.weight.grad.abs().max().item() for layer in layers[:-1])
    # without the shape's gradient the layers below the output get only rounding noise through the mean
    assert trunk_sizes[False] < 1e-6 * trunk_sizes[True]


def test_mean_anchored_quantile_loss_with_a_squared_mean_hand_computed():
    # z = (0, 0), t = 2: the quantile term as above, 1.5, gradient's mean-free part (0.25, -0.25); squared mean term
    # n / 4 * (2 - 0)^2 = 2 with d/dz_i = -(t - z_mean) / 2 = -1: total 3.5, gradient (-0.75, -1.25)
    z = th.tensor([[0.0, 0.0]], requires_grad=True)
    loss = mean_anchored_quantile_loss(z, th.tensor([[2.0]]), squared_mean=True)
    loss.sum().backward()
    assert loss.item() == pytest.approx(3.5)
    assert z.grad[0].tolist() == pytest.approx([-0.75, -1.25])
    # Inside the Huber threshold both mean terms agree: z = (0, 1), t = 0.9 gives 0.1825 as with the Huber mean
    z = th.tensor([[0.0, 1.0]])
    assert mean_anchored_quantile_loss(z, th.tensor([[0.9]]), squared_mean=True).item() == pytest.approx(0.1825)
    # One quantile: (t_mean - z)^2 / 4 over the target samples' mean: z = 1, t = (2, 4): (3 - 1)^2 / 4 = 1
    assert mean_anchored_quantile_loss(th.tensor([[1.0]]), th.tensor([[2.0, 4.0]]), squared_mean=True).item() == 1.0


def test_squared_mean_counts_a_rare_large_loss_that_the_huber_mean_does_not():
    # A scalar critic fitted to targets 0.4 nine times in ten and -100 once in ten (a rare crash). The Huber fit
    # (kappa 1) is where 0.9 * (0.4 - z) = 0.1 * 1: z = 0.4 - 1 / 9 = 0.2889; the mean is 0.36 - 10 = -9.64.
    targets = th.tensor([[0.4]] * 90 + [[-100.0]] * 10)

    def gradient_at(value: float, squared: bool) -> float:
        z = th.full((100, 1), value, requires_grad=True)
        mean_anchored_quantile_loss(z, targets, squared_mean=squared).mean().backward()
        return float(z.grad.sum())

    assert gradient_at(0.4 - 1 / 9, squared=False) == pytest.approx(0.0, abs=1e-6)
    assert gradient_at(-9.64, squared=True) == pytest.approx(0.0, abs=1e-5)
    # At the other's estimate each loss still pulls: the Huber fit up from the mean (90 rows at -0.5 / 100, 10 at
    # +0.5 / 100), the squared fit down from 0.2889 (-0.5 * (-9.64 - 0.2889))
    assert gradient_at(-9.64, squared=False) == pytest.approx(-0.4, abs=1e-6)
    assert gradient_at(0.4 - 1 / 9, squared=True) == pytest.approx(0.5 * (9.64 + 0.4 - 1 / 9), abs=1e-5)
