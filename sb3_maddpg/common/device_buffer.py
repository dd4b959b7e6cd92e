"""
A joint replay buffer whose storage lives on a torch device (a GPU for GPU training), sampled without a host round
trip.

Written by hand because SB3's replay buffers are numpy-only: they sample with numpy and copy every batch from the
host to the training device. Here the arrays that sampling reads are torch tensors on ``storage_device``; a batch is
drawn with ``torch.randint`` on that device and gathered there, so a gradient step does not wait for the host, and
only ``add`` (once per environment step) copies data from the host, in one transfer. The host-side index (what
``add`` keeps, the free list) and the copies between layouts and storages are ``MultiAgentReplayBuffer``'s; this
module only allocates, writes and samples the device storage.
"""

import functools
import warnings
from typing import Any

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.utils import get_device
from stable_baselines3.common.vec_env import VecNormalize

from sb3_maddpg.common.buffers import STORED, MultiAgentReplayBuffer, MultiAgentReplayBufferSamples

ACCEPTED_DEVICES = "'cuda', 'cuda:N', 'cpu', 'auto' (CUDA when available, else the CPU) or a torch.device"


@functools.cache
def torch_dtype(dtype: np.dtype | type) -> th.dtype:
    """The torch dtype of a numpy dtype (``np.uint8`` -> ``torch.uint8``)."""
    return th.from_numpy(np.zeros(0, dtype=dtype)).dtype


def _device_problem(device: th.device) -> str | None:
    """Why tensors cannot be put on ``device`` here, or None when they can."""
    if device.type == "cuda":
        if not th.cuda.is_available():
            return "CUDA is not available on this machine"
        if device.index is not None and device.index >= th.cuda.device_count():
            return f"this machine has {th.cuda.device_count()} CUDA device(s)"
        return None
    if device.type == "cpu":
        return None
    try:  # other backends (mps, xpu, ...): try one tiny allocation
        th.empty(1, device=device)
    except (RuntimeError, AssertionError) as error:
        return f"torch cannot allocate on it here ({error})"
    return None


def resolve_storage_device(storage_device: th.device | str) -> th.device:
    """
    Check a ``storage_device`` argument and make it concrete (``"cuda"`` -> ``cuda:<current device>``), so that it
    compares equal to the device of the tensors stored on it.

    :param storage_device: see ``DeviceReplayBuffer``
    :return: the device
    :raises ValueError: if torch does not accept it, or it is not usable on this machine
    """
    if isinstance(storage_device, str) and storage_device == "auto":
        return resolve_storage_device(get_device("auto"))
    if isinstance(storage_device, str):
        try:
            device = th.device(storage_device)
        except RuntimeError as error:
            raise ValueError(f"storage_device must be {ACCEPTED_DEVICES}, got {storage_device!r}") from error
    elif isinstance(storage_device, th.device):
        device = storage_device
    else:
        raise ValueError(f"storage_device must be {ACCEPTED_DEVICES}, got {storage_device!r}")
    problem = _device_problem(device)
    if problem is not None:
        raise ValueError(
            f"storage_device={str(device)!r} cannot be used: {problem}; use storage_device='cpu', "
            "or the default MultiAgentReplayBuffer (numpy storage)"
        )
    if device.type == "cuda" and device.index is None:
        device = th.device("cuda", th.cuda.current_device())
    return device


def _as_index(indices: np.ndarray | th.Tensor, device: th.device) -> th.Tensor:
    """Indices as an int64 tensor on ``device`` (a host copy only when they come from the host)."""
    if isinstance(indices, th.Tensor):
        return indices.to(device=device, dtype=th.int64)
    return th.as_tensor(np.asarray(indices, dtype=np.int64)).to(device)


def _select_rows(condition: th.Tensor, a: th.Tensor, b: th.Tensor) -> th.Tensor:
    """
    ``torch.where(condition, a, b)`` over whole rows (``condition`` of shape (B,), ``a`` and ``b`` contiguous, of
    the same shape and dtype), on a view of the rows' bytes as the widest integer type that divides them: it moves
    the same bits, and is much faster than ``torch.where`` on uint8 elements (10x on CPU).
    """
    n_bytes = a[0].numel() * a.element_size() if len(a) > 0 else 0
    if n_bytes == 0:
        return th.where(condition.view(-1, *([1] * (a.dim() - 1))), a, b)
    wide = next(dtype for dtype, size in ((th.int64, 8), (th.int32, 4), (th.int16, 2), (th.uint8, 1)) if n_bytes % size == 0)

    def rows(x: th.Tensor) -> th.Tensor:
        return x.reshape(len(x), -1).view(th.uint8).view(wide)

    selected = th.where(condition.view(-1, 1), rows(a), rows(b))
    return selected.view(th.uint8).view(a.dtype).view(a.shape)


class DeviceReplayBuffer(MultiAgentReplayBuffer):
    """
    ``MultiAgentReplayBuffer`` (same layout, same host-side index, same derivation of next observations, same
    samples for the same indices) whose storage is torch tensors on ``storage_device``.

    On ``storage_device``: ``observations`` (observation dtype, uint8 images stay ``torch.uint8``), ``actions``,
    ``rewards``, ``dones``, ``timeouts``, ``next_obs_index``, ``extra_next_observations`` and
    ``pending_next_observations`` (the last two are views of one tensor, pending rows first, then the kept next
    observations, so that a sample reads a derived next observation with a single gather). In host memory: the index
    (``pos``, ``full``, ``_next_obs_index_host``, the free list, a copy of the pending next observations), which is
    all that ``add`` reads.

    ``add`` copies each environment step to the device in one host->device transfer. ``sample`` does no host round
    trip: the indices are drawn with ``torch.randint`` on ``storage_device`` from **torch's global generator of that
    device** (the CUDA generator for a GPU; ``torch.manual_seed`` / SB3's ``set_random_seed`` seed it, and MADDPG's
    saved random states include it when the model is on the GPU), and the next observations are chosen with
    ``torch.where``, so nothing waits for the device. The batches therefore differ from those of
    ``MultiAgentReplayBuffer``, which draws with numpy's global generator; ``_get_samples`` with given indices
    returns exactly what the parent returns.

    Not supported: VecNormalize (``env`` in ``sample``), which normalises on the host with numpy.

    :param buffer_size: maximum number of joint transitions
    :param observation_space: one agent's observation space (a Box)
    :param action_space: one agent's action space
    :param device: PyTorch device of the sampled tensors (typically ``storage_device``)
    :param n_envs: number of VecEnv rows, ``n_copies * n_agents``
    :param optimize_memory_usage: accepted for SB3 compatibility; the buffer always derives next observations
    :param handle_timeout_termination: return truncations as non-terminal (bootstrap through time limits)
    :param n_agents: number of agents N
    :param storage_device: where the stored transitions live: ``'cuda'``, ``'cuda:N'``, ``'cpu'``, ``'auto'`` (CUDA
        when available, else the CPU) or a ``torch.device``
    """

    observations: th.Tensor  # type: ignore[assignment]
    actions: th.Tensor  # type: ignore[assignment]
    rewards: th.Tensor  # type: ignore[assignment]
    dones: th.Tensor  # type: ignore[assignment]
    timeouts: th.Tensor  # type: ignore[assignment]
    next_obs_index: th.Tensor  # type: ignore[assignment]
    _aux: th.Tensor  # type: ignore[assignment]

    def __init__(
        self,
        buffer_size: int,
        observation_space: spaces.Space,
        action_space: spaces.Space,
        device: th.device | str = "auto",
        n_envs: int = 1,
        optimize_memory_usage: bool = False,
        handle_timeout_termination: bool = True,
        n_agents: int = 1,
        storage_device: th.device | str = "cuda",
    ) -> None:
        self.storage_device = resolve_storage_device(storage_device)
        super().__init__(
            buffer_size,
            observation_space,
            action_space,
            device,
            n_envs,
            optimize_memory_usage,
            handle_timeout_termination,
            n_agents,
        )

    def _zeros(self, shape: tuple[int, ...], dtype: np.dtype | type) -> th.Tensor:  # type: ignore[override]
        return th.zeros(shape, dtype=torch_dtype(dtype), device=self.storage_device)

    def _upload(self, *arrays: np.ndarray) -> list[th.Tensor]:  # type: ignore[override]
        """
        The arrays on ``storage_device``, copied in one host->device transfer: they are packed into one byte array
        (each at an 8-byte aligned offset, so that the device bytes can be viewed as its dtype).
        """
        offsets, total = [], 0
        for array in arrays:
            total = -(-total // 8) * 8
            offsets.append(total)
            total += array.nbytes
        packed = np.empty(total, dtype=np.uint8)
        for array, offset in zip(arrays, offsets, strict=True):
            packed[offset : offset + array.nbytes] = np.ascontiguousarray(array).reshape(-1).view(np.uint8)
        # non_blocking: `packed` is pageable memory, which CUDA copies to a staging buffer before returning, so the
        # host does not wait for the device's queued work (a blocking copy would synchronise the stream)
        device_bytes = th.from_numpy(packed).to(self.storage_device, non_blocking=True)
        return [
            device_bytes[offset : offset + array.nbytes].view(torch_dtype(array.dtype)).view(array.shape)
            for array, offset in zip(arrays, offsets, strict=True)
        ]

    def _index(self, indices: np.ndarray | th.Tensor) -> th.Tensor:  # type: ignore[override]
        return _as_index(indices, self.storage_device)

    def _storage_kwargs(self) -> dict[str, Any]:
        return {"storage_device": self.storage_device}

    def sample(self, batch_size: int, env: VecNormalize | None = None) -> MultiAgentReplayBufferSamples:  # type: ignore[override]
        """
        Sample whole joint transitions uniformly over (stored step, copy), on the device, without a host round trip.
        The indices come from torch's global generator of ``storage_device`` (see the class docstring).

        :param batch_size: number of joint transitions B
        :param env: must be None (VecNormalize is not supported)
        :return: the batch on ``device``, shapes in ``MultiAgentReplayBufferSamples``
        """
        self._check_no_vec_normalize(env)
        upper_bound = self.buffer_size if self.full else self.pos  # a host int: no sync to know it
        if upper_bound == 0:
            raise ValueError("Cannot sample from an empty replay buffer")
        # One draw over (slot, copy) pairs, slot-major: uniform over both, like two independent draws
        flat = th.randint(0, upper_bound * self.n_copies, (batch_size,), device=self.storage_device)
        return self._gather(flat // self.n_copies, flat % self.n_copies)

    def _get_samples(  # type: ignore[override]
        self,
        batch_inds: np.ndarray | th.Tensor,
        env: VecNormalize | None = None,
        copy_inds: np.ndarray | th.Tensor | None = None,
    ) -> MultiAgentReplayBufferSamples:
        """
        The joint transitions at given indices: the same tensors as ``MultiAgentReplayBuffer._get_samples``.

        :param batch_inds: slots, shape (B,), numpy or torch
        :param env: must be None (VecNormalize is not supported)
        :param copy_inds: copies, shape (B,); drawn uniformly (torch's generator of ``storage_device``) when None
        """
        self._check_no_vec_normalize(env)
        slots = self._index(batch_inds)
        if copy_inds is None:
            copies = th.randint(0, self.n_copies, (len(slots),), device=self.storage_device)
        else:
            copies = self._index(copy_inds)
        return self._gather(slots, copies)

    @staticmethod
    def _check_no_vec_normalize(env: VecNormalize | None) -> None:
        if env is not None:
            raise ValueError(
                "DeviceReplayBuffer does not support VecNormalize (it normalises on the host with numpy); "
                "use the default MultiAgentReplayBuffer with a VecNormalize env"
            )

    def _gather(self, slots: th.Tensor, copies: th.Tensor) -> MultiAgentReplayBufferSamples:
        """The batch at int64 indices on ``storage_device``, moved to ``device``."""
        flat_observations = self.observations.view(-1, *self.observations.shape[2:])
        observations = flat_observations.index_select(0, slots * self.n_copies + copies)
        next_observations = self._next_observations(slots, copies, flat_observations)
        dones = self.dones[slots, copies]
        if self.handle_timeout_termination:
            dones = dones * (1 - self.timeouts[slots, copies])
        data = (
            observations,
            self.actions[slots, copies],
            next_observations,
            dones.reshape(-1, 1),
            self.rewards[slots, copies],
        )
        # A device-to-host copy must block (the host reads the result); host-to-device or device-to-device need not
        non_blocking = self.device.type != "cpu"
        return MultiAgentReplayBufferSamples(*(x.to(self.device, non_blocking=non_blocking) for x in data))

    def _next_observations(self, slots: th.Tensor, copies: th.Tensor, flat_observations: th.Tensor) -> th.Tensor:
        """
        The next observations, derived as in the parent's class docstring, with gathers and ``torch.where`` only
        (no boolean-mask indexing or ``.any()``, which would wait for the device).
        """
        following = flat_observations.index_select(0, ((slots + 1) % self.buffer_size) * self.n_copies + copies)
        extra = self.next_obs_index[slots, copies]
        kept = extra >= 0
        newest = slots == (self.pos - 1) % self.buffer_size
        # A kept next observation takes precedence; the newest step's is the pending row of its copy
        aux = self._aux.index_select(0, th.where(kept, extra + self.n_copies, copies))
        return _select_rows(kept | newest, aux, following)

    def next_observations_of(  # type: ignore[override]
        self, batch_inds: np.ndarray | th.Tensor, copy_inds: np.ndarray | th.Tensor
    ) -> th.Tensor:
        """
        The next joint observations of stored steps, derived as described in the parent's class docstring.

        :param batch_inds: slots, shape (B,), numpy or torch
        :param copy_inds: copies, shape (B,), numpy or torch
        :return: (B, n_agents, *obs_shape), a tensor on ``storage_device`` (not numpy, unlike the parent)
        """
        flat_observations = self.observations.view(-1, *self.observations.shape[2:])
        return self._next_observations(self._index(batch_inds), self._index(copy_inds), flat_observations)

    def __getstate__(self) -> dict[str, Any]:
        # The tensors go in the pickle as numpy arrays: readable without CUDA, and pickled without torch's storage copy
        state = self.__dict__.copy()
        for name in STORED:
            state[name] = state[name].detach().cpu().numpy()
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        storage_device, device = state["storage_device"], state["device"]
        if _device_problem(storage_device) is not None:
            warnings.warn(
                f"The replay buffer was stored on {storage_device}, which cannot be used here "
                f"({_device_problem(storage_device)}): loading it on the CPU"
            )
            storage_device = state["storage_device"] = th.device("cpu")
        if _device_problem(device) is not None:
            state["device"] = storage_device
        for name in STORED:
            array = state[name]
            if not array.flags.writeable:
                array = array.copy()
            state[name] = th.from_numpy(array).to(storage_device)
        self.__dict__.update(state)
