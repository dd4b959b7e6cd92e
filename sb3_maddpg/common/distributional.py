"""Pure functions for the quantile critic: quantile midpoints, the quantile Huber loss and CVaR.

Shapes are written as ``(..., n)``: any number of leading dimensions (batch, agents) followed by the quantile dimension.
"""

import math

import torch as th


def quantile_midpoints(n_quantiles: int, device: th.device | str = "cpu") -> th.Tensor:
    """
    The quantile fractions the critic's outputs stand for: tau_j = (j + 0.5) / n, j = 0 .. n - 1 (QR-DQN's midpoints).

    :param n_quantiles: number of quantiles n (>= 1)
    :param device: device of the returned tensor
    :return: tensor of shape (n,)
    """
    if n_quantiles < 1:
        raise ValueError(f"n_quantiles must be an integer >= 1, got {n_quantiles}")
    return (th.arange(n_quantiles, device=device, dtype=th.float32) + 0.5) / n_quantiles


def quantile_huber_loss(
    current_quantiles: th.Tensor,
    target_quantiles: th.Tensor,
    taus: th.Tensor | None = None,
    kappa: float = 1.0,
) -> th.Tensor:
    """
    Quantile Huber loss of QR-DQN, left unreduced over the leading dimensions.

    For current quantiles z_j (at fractions tau_j) and target samples t_k, with delta_jk = t_k - z_j:
    ``loss = sum_j mean_k |tau_j - 1{delta_jk < 0}| * huber_kappa(delta_jk) / kappa``.
    With ``kappa=1`` and the midpoints as ``taus`` this is exactly ``sb3_contrib.common.utils.quantile_huber_loss``
    before its final mean; that function is not used because it always reduces to one scalar, while MADDPG needs one
    loss per agent (for per-agent logging and without one call per agent), and because sb3-contrib is not a
    dependency of this package.

    :param current_quantiles: the critic's quantiles, shape (..., n)
    :param target_quantiles: samples of the target distribution (treated as constants), shape (..., m)
    :param taus: quantile fractions of ``current_quantiles``, shape (n,); midpoints when None
    :param kappa: Huber threshold (> 0)
    :return: loss per leading index, shape (...)
    """
    if current_quantiles.shape[:-1] != target_quantiles.shape[:-1]:
        raise ValueError(
            "current_quantiles and target_quantiles must share their leading dimensions, "
            f"got {tuple(current_quantiles.shape)} and {tuple(target_quantiles.shape)}"
        )
    if kappa <= 0:
        raise ValueError(f"kappa must be > 0, got {kappa}")
    n_quantiles = current_quantiles.shape[-1]
    if taus is None:
        taus = quantile_midpoints(n_quantiles, device=current_quantiles.device)
    # delta: (..., n, m), delta[..., j, k] = t_k - z_j
    delta = target_quantiles.detach().unsqueeze(-2) - current_quantiles.unsqueeze(-1)
    abs_delta = delta.abs()
    huber = th.where(abs_delta <= kappa, 0.5 * delta**2, kappa * (abs_delta - 0.5 * kappa))
    # |tau_j - 1{delta < 0}|: (..., n, m); taus broadcast along the target dimension
    weight = (taus.unsqueeze(-1) - (delta.detach() < 0).float()).abs()
    # mean over target samples k, sum over current quantiles j: (...)
    return (weight * huber / kappa).mean(dim=-1).sum(dim=-1)


def cvar_n_lowest(n_quantiles: int, alpha: float) -> int:
    """
    How many of the lowest quantiles CVaR_alpha averages: ceil(alpha * n), at least 1.

    The product is rounded to 9 decimals first so that, e.g., alpha = 0.3 with n = 10 gives 3 and not
    ceil(3.0000000000000004) = 4.

    :param n_quantiles: number of quantiles n
    :param alpha: CVaR level in (0, 1]
    :return: the number of quantiles k, 1 <= k <= n
    """
    if not 0.0 < alpha <= 1.0:
        raise ValueError(f"alpha must lie in (0, 1], got {alpha}")
    return max(1, min(n_quantiles, math.ceil(round(alpha * n_quantiles, 9))))


def cvar(quantiles: th.Tensor, alpha: float) -> th.Tensor:
    """
    CVaR_alpha of a distribution given by equally weighted quantiles: the mean of its lowest ceil(alpha * n) values.

    alpha = 1 gives the mean (risk-neutral); smaller alpha looks only at the lower tail (risk-averse).
    Gradients flow to the selected quantiles.

    :param quantiles: quantile values, shape (..., n), in any order
    :param alpha: CVaR level in (0, 1]
    :return: CVaR per leading index, shape (...)
    """
    k = cvar_n_lowest(quantiles.shape[-1], alpha)
    if k == quantiles.shape[-1]:
        return quantiles.mean(dim=-1)
    lowest, _ = th.topk(quantiles, k, dim=-1, largest=False, sorted=False)
    return lowest.mean(dim=-1)
