"""Exploration noise for MADDPG."""

import numpy as np
import numpy.typing as npt
from stable_baselines3.common.noise import ActionNoise, VectorizedActionNoise


class DecayingGaussianNoise(ActionNoise):
    """
    Gaussian action noise whose standard deviation decays geometrically towards a floor.

    At timestep ``k`` the noise has standard deviation
    ``sigma_k = final_sigma + (sigma - final_sigma) * decay**k``,
    so it starts at ``sigma`` and approaches ``final_sigma``. The report's schedule, 1.0 decaying towards 0.1,
    is the default of ``MADDPG``.

    ``k`` is the attribute ``timestep``. During ``learn`` MADDPG sets it to the model's ``num_timesteps`` before
    every VecEnv step (``set_noise_timestep``), so the schedule counts timesteps (joint steps of one environment
    copy), like every other counter: the same ``decay`` gives the same schedule with 1 or 8 copies, and a resumed
    model continues it. Used on its own, each call advances ``timestep`` by one.
    SB3 adds action noise to the action rescaled to [-1, 1] (then clips), so ``sigma`` is measured in that scale.
    ``reset()`` (called at episode ends) does not restart the decay.

    :param mean: mean of the noise, shape (action_dim,)
    :param sigma: initial standard deviation, shape (action_dim,) or a scalar
    :param final_sigma: standard deviation the noise decays towards, shape (action_dim,) or a scalar
    :param decay: factor applied to ``sigma_k - final_sigma`` at each call, in (0, 1]
    :param dtype: dtype of the noise
    """

    def __init__(
        self,
        mean: np.ndarray,
        sigma: np.ndarray | float = 1.0,
        final_sigma: np.ndarray | float = 0.1,
        decay: float = 0.9998,
        dtype: npt.DTypeLike = np.float32,
    ) -> None:
        if not 0.0 < decay <= 1.0:
            raise ValueError(f"decay must lie in (0, 1], got {decay}")
        self._mu = np.asarray(mean, dtype=np.float64)
        self._sigma = np.broadcast_to(np.asarray(sigma, dtype=np.float64), self._mu.shape).copy()
        self._final_sigma = np.broadcast_to(np.asarray(final_sigma, dtype=np.float64), self._mu.shape).copy()
        if np.any(self._sigma < 0) or np.any(self._final_sigma < 0):
            raise ValueError(f"sigma and final_sigma must be >= 0, got {sigma} and {final_sigma}")
        self._decay = decay
        self._dtype = dtype
        self.timestep = 0
        super().__init__()

    @property
    def current_sigma(self) -> np.ndarray:
        """The standard deviation the next call will use, shape (action_dim,)."""
        return self._final_sigma + (self._sigma - self._final_sigma) * self._decay**self.timestep

    def __call__(self) -> np.ndarray:
        noise = np.random.normal(self._mu, self.current_sigma).astype(self._dtype)
        self.timestep += 1
        return noise

    def reset(self) -> None:
        """Episode end: nothing to reset, the decay goes on over the whole training."""

    def __repr__(self) -> str:
        return (
            f"DecayingGaussianNoise(mu={self._mu}, sigma={self._sigma}, final_sigma={self._final_sigma}, "
            f"decay={self._decay}, timestep={self.timestep})"
        )


class RowBatchedActionNoise(VectorizedActionNoise):
    """
    SB3's ``VectorizedActionNoise`` (one noise process per VecEnv row) that, for a ``DecayingGaussianNoise``, draws
    all rows in one NumPy call instead of one call per row: MADDPG's VecEnv has ``n_copies * n_agents`` rows, and
    the per-row Python loop was a large share of the overhead of an environment step. The rows are copies of one
    noise and share its schedule (``set_noise_timestep`` sets them all before every VecEnv step), and the numbers
    drawn are the same, in the same order, as SB3's loop would draw. Any other base noise is called row by row, as
    in SB3.

    :param base_noise: the noise of one row (copied for every row)
    :param n_envs: number of rows
    """

    def __call__(self) -> np.ndarray:
        first = self.noises[0]
        if type(first) is not DecayingGaussianNoise:
            return super().__call__()
        sigma = np.broadcast_to(first.current_sigma, (len(self.noises), *first._mu.shape))
        noise = np.random.normal(first._mu, sigma).astype(first._dtype)
        timestep = first.timestep + 1
        for row_noise in self.noises:
            row_noise.timestep = timestep
        return noise


def set_noise_timestep(action_noise: ActionNoise | None, timestep: int) -> None:
    """
    Set the schedule position of a ``DecayingGaussianNoise`` (or of each copy in a ``VectorizedActionNoise``);
    any other noise is left alone.

    :param action_noise: the algorithm's action noise
    :param timestep: the timestep the next call belongs to
    """
    noises = action_noise.noises if isinstance(action_noise, VectorizedActionNoise) else [action_noise]
    for noise in noises:
        if isinstance(noise, DecayingGaussianNoise):
            noise.timestep = int(timestep)


def current_noise_std(action_noise: ActionNoise | None) -> float | None:
    """
    Mean standard deviation of an action noise right now, for logging (None if it has no known scale).

    :param action_noise: the algorithm's action noise, possibly wrapped in ``VectorizedActionNoise``
    :return: the mean standard deviation over action dimensions, or None
    """
    if isinstance(action_noise, VectorizedActionNoise):
        action_noise = action_noise.noises[0]
    if isinstance(action_noise, DecayingGaussianNoise):
        return float(np.mean(action_noise.current_sigma))
    sigma = getattr(action_noise, "_sigma", None)
    return None if sigma is None else float(np.mean(sigma))
