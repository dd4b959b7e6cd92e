"""
A joint replay buffer whose storage lives on a torch device (a GPU for GPU training), sampled without a host round
trip.

Written by hand because SB3's replay buffers are numpy-only: they sample with numpy and copy every batch from the
host to the training device. Here the arrays that sampling reads are torch tensors on ``storage_device``; a batch is
drawn with ``torch.randint`` on that device and gathered there, so a gradient step does not wait for the host, and
only ``add`` (once per environment step) copies data from the host, in one transfer.
"""

import functools
import warnings
from typing import Any

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.buffers import BaseBuffer
from stable_baselines3.common.utils import get_device
from stable_baselines3.common.vec_env import VecNormalize

from sb3_maddpg.common.buffers import MultiAgentReplayBuffer, MultiAgentReplayBufferSamples

try:
    import psutil
except ImportError:  # pragma: no cover
    psutil = None

ACCEPTED_DEVICES = "'cuda', 'cuda:N', 'cpu', 'auto' (CUDA when available, else the CPU) or a torch.device"

# The tensors that sampling reads, pickled as numpy arrays (see __getstate__)
_TENSORS = ("observations", "actions", "rewards", "dones", "timeouts", "next_obs_index", "_aux")


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
    ``MultiAgentReplayBuffer`` (same layout, same derivation of next observations, same samples for the same
    indices) whose storage is torch tensors on ``storage_device``.

    On ``storage_device``: ``observations`` (observation dtype, uint8 images stay ``torch.uint8``), ``actions``,
    ``rewards``, ``dones``, ``timeouts``, ``next_obs_index``, ``extra_next_observations`` and
    ``pending_next_observations``. The last two are views of one tensor (pending rows first, then the kept next
    observations), so that a sample reads a derived next observation with a single gather. On the host: the free list
    of kept next observations, a copy of ``next_obs_index`` and of the pending next observations (what ``add`` reads
    to decide what to keep), ``pos`` and ``full``.

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
    next_obs_index: th.Tensor

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
        # Not MultiAgentReplayBuffer.__init__: it would allocate the numpy arrays (and warn about host memory)
        self._set_layout(
            buffer_size,
            observation_space,
            action_space,
            device,
            n_envs,
            optimize_memory_usage,
            handle_timeout_termination,
            n_agents,
        )
        self.storage_device = resolve_storage_device(storage_device)
        self._obs_np_dtype = np.dtype(observation_space.dtype)
        self._action_np_dtype = np.dtype(self._maybe_cast_dtype(action_space.dtype))
        self._check_memory()

        slots, copies, agents = self.buffer_size, self.n_copies, self.n_agents
        obs_dtype, on = torch_dtype(self._obs_np_dtype), self.storage_device
        self.observations = th.zeros((slots, copies, agents, *self.obs_shape), dtype=obs_dtype, device=on)
        self.actions = th.zeros((slots, copies, agents, self.action_dim), dtype=torch_dtype(self._action_np_dtype), device=on)
        self.rewards = th.zeros((slots, copies, agents), dtype=th.float32, device=on)
        self.dones = th.zeros((slots, copies), dtype=th.float32, device=on)
        self.timeouts = th.zeros((slots, copies), dtype=th.float32, device=on)
        self.next_obs_index = th.full((slots, copies), -1, dtype=th.int64, device=on)
        # Rows [0, n_copies): pending next observations; rows n_copies + k: extra_next_observations[k]
        self._aux = th.zeros((copies, agents, *self.obs_shape), dtype=obs_dtype, device=on)
        # Host bookkeeping for add(): it must not read the device
        self._next_obs_index_host = np.full((slots, copies), -1, dtype=np.int64)
        self._pending_host = np.zeros((copies, agents, *self.obs_shape), dtype=self._obs_np_dtype)
        self._free_extra: list[int] = []
        self._has_pending = False

    @property
    def pending_next_observations(self) -> th.Tensor:  # type: ignore[override]
        """Next observation of the newest step, (n_copies, n_agents, *obs_shape), on ``storage_device``."""
        return self._aux[: self.n_copies]

    @property
    def extra_next_observations(self) -> th.Tensor:  # type: ignore[override]
        """The kept next observations (growable, with a free list), on ``storage_device``."""
        return self._aux[self.n_copies :]

    def _check_memory(self) -> None:
        """Warn, like the parent, when the preallocated storage does not fit in the storage device's free memory."""
        total = self.nbytes_per_slot() * self.buffer_size
        if self.storage_device.type == "cuda":
            available = th.cuda.mem_get_info(self.storage_device)[0]
            where = f"free memory on {self.storage_device}"
        elif self.storage_device.type == "cpu" and psutil is not None:
            available = psutil.virtual_memory().available
            where = "available memory"
        else:
            return
        if total > available:
            warnings.warn(f"The replay buffer storage needs {total / 1e9:.2f}GB but there is {available / 1e9:.2f}GB {where}")

    def nbytes_per_slot(self) -> int:
        """Bytes of the preallocated storage per slot (one slot holds ``n_copies`` joint transitions), as the parent."""
        copies, agents = self.n_copies, self.n_agents
        return copies * (
            agents * int(np.prod(self.obs_shape)) * self._obs_np_dtype.itemsize
            + agents * self.action_dim * self._action_np_dtype.itemsize
            + agents * 4  # rewards
            + 4  # dones
            + 4  # timeouts
            + 8  # next_obs_index
        )

    def _upload(self, *arrays: np.ndarray) -> list[th.Tensor]:
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

    def add(
        self,
        obs: np.ndarray,
        next_obs: np.ndarray,
        action: np.ndarray,
        reward: np.ndarray,
        done: np.ndarray,
        infos: list[dict[str, Any]],
    ) -> None:
        """
        Store one VecEnv step: every copy's joint transition (as ``MultiAgentReplayBuffer.add``; the check whether the
        environment was reset in between compares the observations after their cast to the storage dtype).

        :param obs: (n_copies * n_agents, *obs_shape) in SB3's row layout
        :param next_obs: (n_copies * n_agents, *obs_shape); rows that ended an episode hold the terminal observation
        :param action: (n_copies * n_agents, action_dim)
        :param reward: (n_copies * n_agents,)
        :param done: (n_copies * n_agents,) episode ended (terminated or truncated)
        :param infos: one dict per row; ``TimeLimit.truncated`` marks truncations
        """
        copies, agents = self.n_copies, self.n_agents
        obs = np.asarray(obs).reshape(copies, agents, *self.obs_shape).astype(self._obs_np_dtype, copy=False)
        next_obs = np.asarray(next_obs).reshape(copies, agents, *self.obs_shape).astype(self._obs_np_dtype, copy=False)
        action = np.asarray(action).reshape(copies, agents, self.action_dim).astype(self._action_np_dtype, copy=False)
        reward = np.asarray(reward).reshape(copies, agents).astype(np.float32, copy=False)
        copy_done = np.asarray(done).reshape(copies, agents).any(axis=1)
        truncated = np.array([info.get("TimeLimit.truncated", False) for info in infos], dtype=bool)
        copy_timeout = truncated.reshape(copies, agents).any(axis=1)

        # Host bookkeeping first, in the parent's order (so the kept rows are the parent's); device writes after
        had_pending, prev = self._has_pending, (self.pos - 1) % self.buffer_size
        lost = np.zeros(0, dtype=np.int64)
        if had_pending:
            # The previous step's successor is the observation arriving now, unless the env was reset in between
            differs = (obs != self._pending_host).reshape(copies, -1).any(axis=1)
            lost = np.flatnonzero(differs & (self._next_obs_index_host[prev] < 0))
        lost_rows = self._claim_rows(prev, lost)
        self._release_slot(self.pos)
        ended = np.flatnonzero(copy_done)
        ended_rows = self._claim_rows(self.pos, ended)

        (obs_d, next_d, action_d, reward_d, done_d, timeout_d, lost_d, lost_rows_d, ended_d, ended_rows_d, prev_d, pos_d) = (
            self._upload(
                obs,
                next_obs,
                action,
                reward,
                copy_done.astype(np.float32),
                copy_timeout.astype(np.float32),
                lost,
                lost_rows + copies,
                ended,
                ended_rows + copies,
                self._next_obs_index_host[prev],
                self._next_obs_index_host[self.pos],
            )
        )
        if len(lost) > 0:
            # Keep the old pending next observations (rows [0, n_copies)) before they are overwritten below
            self._aux.index_copy_(0, lost_rows_d, self._aux[lost_d])
        self.observations[self.pos] = obs_d
        self.actions[self.pos] = action_d
        self.rewards[self.pos] = reward_d
        self.dones[self.pos] = done_d
        if self.handle_timeout_termination:
            self.timeouts[self.pos] = timeout_d
        if len(ended) > 0:
            # The next row of `observations` will be the first observation of the next episode
            self._aux.index_copy_(0, ended_rows_d, next_d[ended_d])
        self._aux[:copies] = next_d
        if had_pending:
            self.next_obs_index[prev] = prev_d
        self.next_obs_index[self.pos] = pos_d
        self._pending_host[...] = next_obs
        self._has_pending = True

        self.pos += 1
        if self.pos == self.buffer_size:
            self.full = True
            self.pos = 0

    def _claim_rows(self, slot: int, copies: np.ndarray) -> np.ndarray:
        """
        Take rows of ``extra_next_observations`` for ``(slot, copies[i])`` in the host bookkeeping (growing the
        device storage as the parent grows its array); the caller writes the rows on the device.

        :return: the rows, shape (k,)
        """
        while len(self._free_extra) < len(copies):
            old = len(self._aux) - self.n_copies
            new = max(2 * old, 2 * self.n_copies, 8)
            grown = th.zeros((self.n_copies + new, *self._aux.shape[1:]), dtype=self._aux.dtype, device=self._aux.device)
            grown[: len(self._aux)] = self._aux
            self._aux = grown
            self._free_extra.extend(range(new - 1, old - 1, -1))
        index = np.array([self._free_extra.pop() for _ in range(len(copies))], dtype=np.int64)
        self._next_obs_index_host[slot, copies] = index
        return index

    def _release_slot(self, slot: int) -> None:
        """Free the explicit next observations of a slot that is about to be overwritten (host bookkeeping only)."""
        index = self._next_obs_index_host[slot]
        self._free_extra.extend(index[index >= 0].tolist())
        self._next_obs_index_host[slot] = -1

    def reset(self) -> None:
        BaseBuffer.reset(self)
        self.next_obs_index.fill_(-1)
        self._next_obs_index_host[...] = -1
        self._aux = self._aux[: self.n_copies].clone()  # frees the kept next observations
        self._free_extra = []
        self._has_pending = False

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
        slots = _as_index(batch_inds, self.storage_device)
        if copy_inds is None:
            copies = th.randint(0, self.n_copies, (len(slots),), device=self.storage_device)
        else:
            copies = _as_index(copy_inds, self.storage_device)
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
        slots = _as_index(batch_inds, self.storage_device)
        copies = _as_index(copy_inds, self.storage_device)
        flat_observations = self.observations.view(-1, *self.observations.shape[2:])
        return self._next_observations(slots, copies, flat_observations)

    def to_numpy_buffer(self) -> MultiAgentReplayBuffer:
        """
        A ``MultiAgentReplayBuffer`` with the same contents and state, in host memory (a full copy).

        :return: the numpy buffer (this one is unchanged)
        """
        buffer = MultiAgentReplayBuffer(
            self.buffer_size * self.n_copies,
            self.observation_space,
            self.action_space,
            device=self.device,
            n_envs=self.n_envs,
            optimize_memory_usage=self.optimize_memory_usage,
            handle_timeout_termination=self.handle_timeout_termination,
            n_agents=self.n_agents,
        )
        # Replace the parent's (untouched, so unallocated) zero arrays with copies of the tensors
        for name in ("observations", "actions", "rewards", "dones", "timeouts", "next_obs_index"):
            setattr(buffer, name, getattr(self, name).to("cpu", copy=True).numpy())
        buffer.pending_next_observations = self.pending_next_observations.to("cpu", copy=True).numpy()
        buffer.extra_next_observations = self.extra_next_observations.to("cpu", copy=True).numpy()
        buffer._free_extra = list(self._free_extra)
        buffer._has_pending = self._has_pending
        buffer.pos, buffer.full = self.pos, self.full
        return buffer

    @classmethod
    def from_buffer(
        cls, buffer: MultiAgentReplayBuffer, storage_device: th.device | str = "cuda", device: th.device | str | None = None
    ) -> "DeviceReplayBuffer":
        """
        A ``DeviceReplayBuffer`` with the contents and state of another joint buffer (for example one loaded from a
        file saved with the numpy buffer).

        :param buffer: a ``MultiAgentReplayBuffer`` (or ``DeviceReplayBuffer``)
        :param storage_device: where the new buffer's storage lives
        :param device: device of the sampled tensors (default: the buffer's)
        :return: the new buffer (``buffer`` is unchanged)
        """
        if isinstance(buffer, DeviceReplayBuffer):
            buffer = buffer.to_numpy_buffer()
        new = cls(
            buffer.buffer_size * buffer.n_copies,
            buffer.observation_space,
            buffer.action_space,
            device=buffer.device if device is None else device,
            n_envs=buffer.n_envs,
            optimize_memory_usage=buffer.optimize_memory_usage,
            handle_timeout_termination=buffer.handle_timeout_termination,
            n_agents=buffer.n_agents,
            storage_device=storage_device,
        )
        for name in ("observations", "actions", "rewards", "dones", "timeouts", "next_obs_index"):
            getattr(new, name).copy_(th.from_numpy(np.ascontiguousarray(getattr(buffer, name))))
        aux = np.concatenate([buffer.pending_next_observations, buffer.extra_next_observations]).astype(new._obs_np_dtype)
        new._aux = th.from_numpy(aux).to(new.storage_device)
        new._next_obs_index_host = np.array(buffer.next_obs_index, dtype=np.int64)
        new._pending_host = np.array(buffer.pending_next_observations, dtype=new._obs_np_dtype)
        new._free_extra = list(buffer._free_extra)
        new._has_pending = buffer._has_pending
        new.pos, new.full = buffer.pos, buffer.full
        return new

    def with_copies(self, n_copies: int, buffer_size: int | None = None) -> "DeviceReplayBuffer":
        """
        ``MultiAgentReplayBuffer.with_copies``, on the same ``storage_device``. It goes through a host copy of the
        buffer (``to_numpy_buffer``), so it needs host memory for about twice the stored transitions.

        :param n_copies: the new number of copies
        :param buffer_size: the new capacity in joint transitions (default: this buffer's)
        :return: a new buffer (this one is unchanged)
        """
        relaid = self.to_numpy_buffer().with_copies(n_copies, buffer_size)
        return DeviceReplayBuffer.from_buffer(relaid, storage_device=self.storage_device)

    def __getstate__(self) -> dict[str, Any]:
        # The tensors go in the pickle as numpy arrays: readable without CUDA, and pickled without torch's storage copy
        state = self.__dict__.copy()
        for name in _TENSORS:
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
        for name in _TENSORS:
            array = state[name]
            if not array.flags.writeable:
                array = array.copy()
            state[name] = th.from_numpy(array).to(storage_device)
        self.__dict__.update(state)
