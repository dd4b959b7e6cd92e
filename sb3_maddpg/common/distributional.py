"""Pure functions for the quantile critic: quantile midpoints, the quantile Huber loss and CVaR.

Shapes are written as ``(..., n)``: any number of leading dimensions (batch, agents) followed by the quantile dimension.
"""

import functools
import math
import warnings
from collections.abc import Callable
from typing import Any

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


# Scratch tensors of the fused loss, reused between calls: three fresh (..., n, m) tensors per call cost more in
# allocation and first-touch page faults than the arithmetic on them (they are too large for the allocator's free
# lists). One set per (shape, dtype, device); the loss never returns or saves them.
_WORKSPACES: dict[tuple[tuple[int, ...], th.dtype, th.device], tuple[th.Tensor, ...]] = {}


_WORKSPACE_MAX_ELEMENTS = 1 << 22  # 16 MB per float32 tensor; larger ones are allocated per call (and freed)
_CHUNK_PAIRS = 1 << 17  # (row, j, k) pairs per chunk on CPU: three float32 scratch tensors of 512 KB


def _workspace(shape: tuple[int, ...], dtype: th.dtype, device: th.device) -> tuple[th.Tensor, ...]:
    if math.prod(shape) > _WORKSPACE_MAX_ELEMENTS:
        return tuple(th.empty(shape, dtype=dtype, device=device) for _ in range(3))
    key = (shape, dtype, device)
    buffers = _WORKSPACES.get(key)
    if buffers is None:
        if len(_WORKSPACES) >= 8:  # a few shapes are in use at a time (training and evaluation batches)
            _WORKSPACES.clear()
        buffers = tuple(th.empty(shape, dtype=dtype, device=device) for _ in range(3))
        _WORKSPACES[key] = buffers
    return buffers


class _FusedQuantileHuberLoss(th.autograd.Function):
    """
    The quantile Huber loss and its gradient in one pass over the (..., n, m) pairwise differences.

    Autograd through the plain formula keeps about a dozen (..., n, m) temporaries for the backward pass and walks
    over them twice; here the forward pass computes the loss and, from the same differences, the gradient with
    respect to the current quantiles (the only input that needs one), and keeps only that (..., n) gradient.

    With delta = t_k - z_j, c = clamp(delta, -kappa, kappa) and e = delta - c / 2: huber_kappa(delta) = c e, and its
    derivative in delta is c. The weight |tau_j - 1{delta < 0}| is tau_j where delta > 0 and 1 - tau_j where
    delta < 0 (where delta = 0 the terms are 0), that is 1/2 - (1/2 - tau_j) sign(delta); and sign(delta) c = |c|.
    So the weight leaves the sums over k:
    sum_k w c e = (sum_k c e - (1 - 2 tau_j) sum_k |c| e) / 2 and sum_k w c = (sum_k c - (1 - 2 tau_j) sum_k |c|) / 2:
    only sums of elementwise products remain, with no (..., n, m) weight tensor and no boolean mask.
    """

    @staticmethod
    def forward(  # type: ignore[override]
        ctx, current: th.Tensor, target: th.Tensor, taus: th.Tensor, kappa: float, compiled: bool = False
    ) -> th.Tensor:
        # The sums over k are products with a vector of ones (faster than sum(dim=-1) over a short last dimension),
        # kept in the inputs' precision under autocast
        with th.autocast(device_type=current.device.type, enabled=False):
            return _FusedQuantileHuberLoss._forward(ctx, current, target, taus, kappa, compiled)

    @staticmethod
    def _forward(ctx: Any, current: th.Tensor, target: th.Tensor, taus: th.Tensor, kappa: float, compiled: bool) -> th.Tensor:
        n, m = current.shape[-1], target.shape[-1]
        dtype = th.result_type(current, target)
        rows_current = current.reshape(-1, n).to(dtype)
        rows_target = target.reshape(-1, m).to(dtype)
        tails = 1.0 - 2.0 * taus.to(dtype)  # (n,)
        compiled_rows = _compiled_loss_and_gradient() if compiled and current.device.type == "cpu" else None
        result = None if compiled_rows is None else compiled_rows(rows_current, rows_target, tails, kappa)
        if result is not None:
            loss, grad = result
            ctx.save_for_backward(grad.reshape(current.shape))
            return loss.reshape(current.shape[:-1])
        n_rows = rows_current.shape[0]
        loss = th.empty(n_rows, dtype=dtype, device=current.device)
        grad = th.empty(n_rows, n, dtype=dtype, device=current.device)
        ones = th.ones(m, dtype=dtype, device=current.device)
        # Row chunks whose (rows, n, m) scratch tensors stay in a core's cache: the passes over them are memory-bound,
        # and one pass over the whole batch evicts what the next pass reads (benchmarks/quantile_loss_chunks.py on a
        # 2 MB-L2 core: 256 x 3 rows of 25 x 25 pairs, loss and gradient 1.46 ms in one piece, 1.15 ms in 4 chunks).
        step = max(1, _CHUNK_PAIRS // (n * m)) if current.device.type == "cpu" else n_rows
        for start in range(0, n_rows, step):
            stop = min(start + step, n_rows)
            _FusedQuantileHuberLoss._rows(
                rows_current[start:stop], rows_target[start:stop], tails, ones, kappa, loss[start:stop], grad[start:stop]
            )
        ctx.save_for_backward(grad.reshape(current.shape))
        return loss.reshape(current.shape[:-1])

    @staticmethod
    def _rows(
        current: th.Tensor,
        target: th.Tensor,
        tails: th.Tensor,
        ones: th.Tensor,
        kappa: float,
        loss_out: th.Tensor,
        grad_out: th.Tensor,
    ) -> None:
        """Loss (rows,) and gradient (rows, n) of a block of rows, written into ``loss_out`` and ``grad_out``."""
        scale = 0.5 / (kappa * target.shape[-1])
        shape = (*current.shape, target.shape[-1])
        delta, clamped, magnitude = _workspace(shape, loss_out.dtype, current.device)
        th.sub(target.unsqueeze(-2), current.unsqueeze(-1), out=delta)  # (rows, n, m)
        th.clamp(delta, -kappa, kappa, out=clamped)
        th.abs(clamped, out=magnitude)
        # d loss_j / d z_j = -sum_k w_jk c_jk / (kappa m)
        th.matmul(clamped, ones, out=grad_out)
        grad_out.sub_(tails * (magnitude @ ones)).mul_(-scale)  # (rows, n)
        # In place from here on: e = delta - c / 2, then c e and |c| e
        excess = delta.add_(clamped, alpha=-0.5)
        huber = clamped.mul_(excess) @ ones
        signed_huber = magnitude.mul_(excess) @ ones
        th.sum(huber.sub_(tails * signed_huber), dim=-1, out=loss_out).mul_(scale)  # (rows,)

    @staticmethod
    def backward(ctx, grad_output: th.Tensor) -> tuple[th.Tensor | None, None, None, None, None]:  # type: ignore[override]
        (grad,) = ctx.saved_tensors
        return grad * grad_output.unsqueeze(-1), None, None, None, None


def _loss_and_gradient(current: th.Tensor, target: th.Tensor, tails: th.Tensor, kappa: float) -> tuple[th.Tensor, th.Tensor]:
    """
    ``_FusedQuantileHuberLoss._rows`` written as plain tensor expressions, (rows, n) and (rows, m) -> the loss (rows,) and
    its gradient (rows, n), for ``torch.compile``, which fuses the passes over the (rows, n, m) differences into one
    loop that keeps them in registers (``quantile_huber_loss(compiled=True)``).
    """
    delta = target.unsqueeze(-2) - current.unsqueeze(-1)
    clamped = delta.clamp(-kappa, kappa)
    magnitude = clamped.abs()
    scale = 0.5 / (kappa * target.shape[-1])
    grad = (clamped.sum(dim=-1) - tails * magnitude.sum(dim=-1)) * -scale
    excess = delta - 0.5 * clamped
    loss = ((clamped * excess).sum(dim=-1) - tails * (magnitude * excess).sum(dim=-1)).sum(dim=-1) * scale
    return loss, grad


# The compiled loss, made at its first use; None once compiling it has failed (then the eager loss runs)
_COMPILED: dict[str, Any] = {}


def _compiled_loss_and_gradient() -> Callable[..., tuple[th.Tensor, th.Tensor]] | None:
    """
    The compiled ``_loss_and_gradient`` (a first call per shape compiles it, about 15 s on one core), or None where
    compiling has failed once in this process (no C++ compiler, for example: TorchInductor builds a CPU kernel with one).
    """
    if "function" not in _COMPILED:
        compiled = th.compile(_loss_and_gradient, fullgraph=True, dynamic=False)

        def checked(*args: Any) -> tuple[th.Tensor, th.Tensor] | None:
            try:
                return compiled(*args)
            except Exception as error:  # any failure of the compiler stack: the eager loss computes the same
                warnings.warn(
                    f"quantile_huber_loss(compiled=True) could not compile its kernel ({type(error).__name__}: "
                    f"{str(error).splitlines()[0] if str(error) else ''}); the eager loss is used instead",
                    stacklevel=2,
                )
                _COMPILED["function"] = None
                return None

        _COMPILED["function"] = checked
    return _COMPILED["function"]


@functools.lru_cache(maxsize=16)
def _cached_midpoints(n_quantiles: int, device: th.device) -> th.Tensor:
    # the midpoints of every update, made once per size and device (never modified in place)
    return quantile_midpoints(n_quantiles, device=device)


def quantile_huber_loss(
    current_quantiles: th.Tensor,
    target_quantiles: th.Tensor,
    taus: th.Tensor | None = None,
    kappa: float = 1.0,
    compiled: bool = False,
) -> th.Tensor:
    """
    Quantile Huber loss of QR-DQN, left unreduced over the leading dimensions.

    For current quantiles z_j (at fractions tau_j) and target samples t_k, with delta_jk = t_k - z_j:
    ``loss = sum_j mean_k |tau_j - 1{delta_jk < 0}| * huber_kappa(delta_jk) / kappa``.
    With ``kappa=1`` and the midpoints as ``taus`` this is exactly ``sb3_contrib.common.utils.quantile_huber_loss``
    before its final mean; that function is not used because it always reduces to one scalar, while MADDPG needs one
    loss per agent (for per-agent logging and without one call per agent), and because sb3-contrib is not a
    dependency of this package.

    The loss and its gradient are computed together in one fused pass (``_FusedQuantileHuberLoss``): the gradient
    reaches ``current_quantiles`` only (the targets are constants), and second derivatives are not available.

    :param current_quantiles: the critic's quantiles, shape (..., n)
    :param target_quantiles: samples of the target distribution (treated as constants), shape (..., m)
    :param taus: quantile fractions of ``current_quantiles``, shape (n,); midpoints when None
    :param kappa: Huber threshold (> 0)
    :param compiled: on CPU, compute the loss and its gradient with a kernel that ``torch.compile`` makes from the same
        formula (one pass over the pairs instead of a dozen: at (256, 3, 25, 25) 0.43 ms against 1.26 ms for the loss
        and its gradient on one core; the first call per shape compiles, about 15 s). Equal to the eager loss up to
        float rounding; where compiling fails, a warning, and the eager loss. Other devices always take the eager loss
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
        taus = _cached_midpoints(n_quantiles, current_quantiles.device)
    return _FusedQuantileHuberLoss.apply(
        current_quantiles, target_quantiles.detach(), taus.detach(), float(kappa), bool(compiled)
    )


def mean_anchored_quantile_loss(
    current_quantiles: th.Tensor,
    target_quantiles: th.Tensor,
    kappa: float = 1.0,
    squared_mean: bool = False,
    compiled: bool = False,
    mean_kappa: float = 1.0,
) -> th.Tensor:
    """
    The quantile Huber loss on the quantiles' deviations from their mean, plus the scalar critic's TD loss on the mean.

    With n current quantiles z_j, their mean z̄ and m target samples t_k with mean t̄:
    ``loss = qr(z, t) + n * huber_mean_kappa(t̄ - z̄) / (2 mean_kappa)``, where ``qr`` is ``quantile_huber_loss``
    (threshold kappa) but its gradient reaches z only through z_j - z̄ (the part that keeps the mean fixed:
    d/dz_i = g_i - mean_j g_j). So the mean moves
    only with the TD error of the mean, as a scalar critic's value does (the second term is a one-quantile critic's loss
    at tau 1/2, times n), and the quantile regression shapes the spread around it.

    Why: the mean of quantile regression's midpoints is not the mean of the distribution, and it moves with the signs
    of the pairwise errors rather than their sizes (robust to rare large outcomes, which a risk-neutral actor must
    count). With this loss, an actor maximising the mean (CVaR at alpha 1) follows the same value as with a scalar
    critic, while CVaR_alpha < 1 still reads the lower quantiles. With one quantile (and the Huber mean) it is
    ``quantile_huber_loss``.

    With ``squared_mean=True`` the mean's loss is the squared error ``n * (t̄ - z̄)^2 / 4`` (the same as the Huber term
    with kappa 1 while ``|t̄ - z̄| <= 1``), TD3's and the MADDPG paper's critic loss: the mean is then the mean of the targets,
    rare large outcomes counted in full. The Huber term is an M-estimator between the median and the mean: for targets
    0.4 nine times in ten and -100 once in ten it settles at 0.289 instead of the mean -9.64, so a critic fitted with
    it hardly sees a rare crash. With one quantile (the scalar critic) the shape term vanishes and only the mean's
    loss remains.

    :param current_quantiles: the critic's quantiles, shape (..., n)
    :param target_quantiles: samples of the target distribution (treated as constants), shape (..., m)
    :param kappa: Huber threshold (> 0) of the quantile term (the shape)
    :param squared_mean: fit the mean with the squared error instead of the Huber loss
    :param compiled: compute the quantile Huber term with the compiled kernel (``quantile_huber_loss``)
    :param mean_kappa: Huber threshold (> 0) of the mean's loss (without ``squared_mean``)
    :return: loss per leading index, shape (...)
    """
    n_quantiles = current_quantiles.shape[-1]
    if n_quantiles == 1 and not squared_mean:
        return quantile_huber_loss(current_quantiles, target_quantiles, kappa=mean_kappa, compiled=compiled)
    means = current_quantiles.mean(dim=-1, keepdim=True)
    mean_error = target_quantiles.detach().mean(dim=-1) - means.squeeze(-1)
    if squared_mean:
        mean_loss = 0.5 * mean_error.square()
    else:
        mean_loss = (
            th.nn.functional.huber_loss(mean_error, th.zeros_like(mean_error), reduction="none", delta=mean_kappa) / mean_kappa
        )
    if n_quantiles == 1:
        return 0.5 * mean_loss
    # the same values; the gradient without its component along the mean
    deviations_only = current_quantiles - means + means.detach()
    shape_loss = quantile_huber_loss(deviations_only, target_quantiles, kappa=kappa, compiled=compiled)
    return shape_loss + 0.5 * n_quantiles * mean_loss


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
