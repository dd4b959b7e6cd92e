"""
Replay buffer of joint multi-agent transitions: one host-side index (positions, episode ends, the kept next
observations and their free list) over a storage of NumPy arrays in host memory. ``DeviceReplayBuffer``
(``device_buffer.py``) keeps the same index over torch tensors on a device.
"""

import warnings
from typing import Any, NamedTuple, TypeVar

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.buffers import BaseBuffer, ReplayBuffer
from stable_baselines3.common.vec_env import VecNormalize

from sb3_maddpg.common import host_memory
from sb3_maddpg.common.actions import action_width, check_action_space, is_discrete, one_hot
from sb3_maddpg.common.buffer_files import check_loaded_buffer

SelfBuffer = TypeVar("SelfBuffer", bound="MultiAgentReplayBuffer")


# The stored arrays (the storage); the device buffer keeps them as tensors
STORED = ("observations", "actions", "rewards", "dones", "timeouts", "next_obs_index", "_aux")


def to_host(array: np.ndarray | th.Tensor) -> np.ndarray:
    """A NumPy array of a stored array, wherever it is (a copy only when it is not in host memory as NumPy)."""
    return array.detach().cpu().numpy() if isinstance(array, th.Tensor) else array


class MultiAgentReplayBufferSamples(NamedTuple):
    """
    A batch of B joint transitions (N agents each).

    - observations: (B, N, *obs_shape), in the observation dtype (uint8 images stay uint8)
    - actions: (B, N, action_dim), rescaled to [-1, 1] as SB3 stores them; for ``Discrete(n)`` actions, one-hot
      vectors (B, N, n)
    - next_observations: (B, N, *obs_shape)
    - dones: (B, 1), 1.0 where the episode terminated (truncations removed when ``handle_timeout_termination``)
    - rewards: (B, N)
    """

    observations: th.Tensor
    actions: th.Tensor
    next_observations: th.Tensor
    dones: th.Tensor
    rewards: th.Tensor


class MultiAgentReplayBuffer(ReplayBuffer):
    """
    Replay buffer of joint transitions: all N agents of one environment copy at one step.

    SB3's off-policy loop hands ``add`` one row per agent and copy (``n_envs = n_copies * n_agents`` rows,
    row = copy * N + agent); the buffer stores them as joint transitions in arrays with named dimensions:

    - ``observations``: (buffer_size, n_copies, n_agents, *obs_shape), observation dtype
    - ``actions``: (buffer_size, n_copies, n_agents, action_dim); for a ``Discrete(n)`` action space, one-hot
      vectors of width n (float32): ``add`` takes the integers and stores their one-hot vectors (or takes the one-hot
      vectors), so the critics read the stored actions as they are
    - ``rewards``: (buffer_size, n_copies, n_agents)
    - ``dones``, ``timeouts``: (buffer_size, n_copies), one flag per joint step of a copy

    ``buffer_size`` counts joint transitions (timesteps), so there are ``buffer_size // n_copies`` slots.

    The next observation is not stored when it can be derived. The next observation of slot i is

    1. ``extra_next_observations[next_obs_index[i]]`` when one was kept for i: the terminal observation when step i
       ended an episode, or the true successor when the observation that followed in the buffer is not it
       (the environment was reset between two ``learn`` calls, or a saved buffer is resumed with a new environment);
    2. otherwise, if i is the newest step, the pending next observation of the last ``add``;
    3. otherwise ``observations[(i + 1) % buffer_size]``.

    The kept next observations live in a growable array with a free list, so their memory follows the number of
    episode ends currently in the buffer. Sampling is vectorised (no loop over samples).

    The buffer is one host-side index over a storage. The index, in host memory: ``pos``, ``full``, which rows of
    the kept next observations each (slot, copy) uses (``_next_obs_index_host``), their free list, and a copy of the
    pending next observations; ``add`` reads only the index to decide what to keep, then writes the storage. The
    storage: the arrays above, ``next_obs_index``, and ``_aux`` (rows [0, n_copies): the pending next observations,
    then the kept ones, so ``pending_next_observations`` and ``extra_next_observations`` are views of it). Here the
    storage is NumPy arrays in host memory, sampled with NumPy's global generator; ``DeviceReplayBuffer`` overrides
    only how the storage is allocated, written and sampled, to keep it as torch tensors on a device.

    :param buffer_size: maximum number of joint transitions
    :param observation_space: one agent's observation space (a Box)
    :param action_space: one agent's action space (a Box, or a Discrete stored as one-hot vectors)
    :param device: PyTorch device of the sampled tensors
    :param n_envs: number of VecEnv rows, ``n_copies * n_agents``
    :param optimize_memory_usage: accepted for SB3 compatibility; the buffer always derives next observations
    :param handle_timeout_termination: return truncations as non-terminal (bootstrap through time limits)
    :param n_agents: number of agents N
    """

    observations: np.ndarray
    actions: np.ndarray
    rewards: np.ndarray
    dones: np.ndarray
    timeouts: np.ndarray
    next_obs_index: np.ndarray
    _aux: np.ndarray
    # Where the storage lives (host memory here; a DeviceReplayBuffer sets its own)
    storage_device: th.device = th.device("cpu")

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
    ) -> None:
        name = type(self).__name__
        if not isinstance(observation_space, spaces.Box):
            raise TypeError(f"{name} accepts a Box observation space, got {observation_space}")
        check_action_space(action_space, name)
        if n_agents < 1 or n_envs % n_agents != 0:
            raise ValueError(
                f"n_envs (VecEnv rows) must be a positive multiple of n_agents >= 1, got n_envs={n_envs}, n_agents={n_agents}"
            )
        # Skip ReplayBuffer.__init__: it would allocate SB3's per-row arrays (with next observations)
        BaseBuffer.__init__(self, buffer_size, observation_space, action_space, device, n_envs=n_envs)
        self.n_agents = n_agents
        self.n_copies = n_envs // n_agents
        self.buffer_size = max(buffer_size // self.n_copies, 1)
        self.optimize_memory_usage = optimize_memory_usage
        self.handle_timeout_termination = handle_timeout_termination
        self._obs_np_dtype = np.dtype(observation_space.dtype)
        self._action_np_dtype = np.dtype(self._maybe_cast_dtype(action_space.dtype))
        if is_discrete(action_space):
            # One-hot vectors, as the critics read them (SB3 stores the integer, action_dim 1)
            self.action_dim = action_width(action_space)
            self._action_np_dtype = np.dtype(np.float32)
        self._check_memory()

        slots, copies, agents = self.buffer_size, self.n_copies, self.n_agents
        # The host-side index (pos and full are BaseBuffer's)
        self._next_obs_index_host = np.full((slots, copies), -1, dtype=np.int64)
        self._pending_host = np.zeros((copies, agents, *self.obs_shape), dtype=self._obs_np_dtype)
        self._free_extra: list[int] = []
        self._has_pending = False
        # The storage. next_obs_index: row of extra_next_observations kept for (slot, copy), -1 when derived
        self.observations = self._zeros((slots, copies, agents, *self.obs_shape), self._obs_np_dtype)
        self.actions = self._zeros((slots, copies, agents, self.action_dim), self._action_np_dtype)
        self.rewards = self._zeros((slots, copies, agents), np.float32)
        self.dones = self._zeros((slots, copies), np.float32)
        self.timeouts = self._zeros((slots, copies), np.float32)
        (self.next_obs_index,) = self._upload(self._next_obs_index_host)  # the index itself, for NumPy storage
        self._aux = self._zeros((copies, agents, *self.obs_shape), self._obs_np_dtype)

    # --- The storage: NumPy arrays in host memory (DeviceReplayBuffer overrides these) -----------------------------

    def _zeros(self, shape: tuple[int, ...], dtype: np.dtype | type) -> np.ndarray:
        """A zero-filled array of the storage."""
        return np.zeros(shape, dtype=dtype)

    def _upload(self, *arrays: np.ndarray) -> list[np.ndarray]:
        """Host arrays as the storage reads them (NumPy storage: the arrays themselves)."""
        return list(arrays)

    def _index(self, indices: np.ndarray) -> np.ndarray:
        """Indices as the storage takes them."""
        return np.asarray(indices, dtype=np.int64)

    def _storage_kwargs(self) -> dict[str, Any]:
        """The constructor arguments that place a buffer's storage like this one's (none for NumPy storage)."""
        return {}

    @property
    def pending_next_observations(self) -> np.ndarray:
        """Next observation of the newest step, (n_copies, n_agents, *obs_shape), in the storage."""
        return self._aux[: self.n_copies]

    @property
    def extra_next_observations(self) -> np.ndarray:
        """The kept next observations (growable, with a free list), in the storage."""
        return self._aux[self.n_copies :]

    def _check_memory(self) -> None:
        """Warn when the preallocated storage does not fit in the free memory where it lives."""
        total = self.nbytes_per_slot() * self.buffer_size
        if self.storage_device.type == "cuda":
            available = th.cuda.mem_get_info(self.storage_device)[0]
            message = f"The replay buffer storage needs {total / 1e9:.2f}GB but there is {available / 1e9:.2f}GB"
            message += f" free memory on {self.storage_device}"
        elif self.storage_device.type == "cpu" and (host := host_memory.available_host_memory()) is not None:
            available = host
            message = "This system does not have apparently enough memory to store the complete "
            message += f"replay buffer {total / 1e9:.2f}GB > {available / 1e9:.2f}GB"
        else:
            return
        if total > available:
            warnings.warn(message)

    def nbytes_per_slot(self) -> int:
        """Bytes of the preallocated storage per slot (one slot holds ``n_copies`` joint transitions)."""
        copies, agents = self.n_copies, self.n_agents
        return copies * (
            agents * int(np.prod(self.obs_shape)) * self._obs_np_dtype.itemsize
            + agents * self.action_dim * self._action_np_dtype.itemsize
            + agents * 4  # rewards
            + 4  # dones
            + 4  # timeouts
            + 8  # next_obs_index
        )

    def bytes_per_joint_transition(self) -> float:
        """
        Bytes of the preallocated arrays per stored joint transition. Each episode end adds one more joint
        observation (``n_agents * prod(obs_shape)`` elements) while it is in the buffer.
        """
        return self.nbytes_per_slot() / self.n_copies

    # --- Adding: the host-side index decides, then one write of the storage ---------------------------------------

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
        Store one VecEnv step: every copy's joint transition. The arrays are cast to the storage dtypes first (the
        check whether the environment was reset in between compares the cast observations).

        :param obs: (n_copies * n_agents, *obs_shape) in SB3's row layout
        :param next_obs: (n_copies * n_agents, *obs_shape); rows that ended an episode hold the terminal observation
        :param action: (n_copies * n_agents, action_dim); for a Discrete action space, the integers
            (n_copies * n_agents,) or their one-hot vectors (n_copies * n_agents, n)
        :param reward: (n_copies * n_agents,)
        :param done: (n_copies * n_agents,) episode ended (terminated or truncated)
        :param infos: one dict per row; ``TimeLimit.truncated`` marks truncations
        """
        copies = self.n_copies
        obs, next_obs, action, reward, copy_done, copy_timeout = self._joint_step(obs, next_obs, action, reward, done, infos)

        had_pending, prev = self._has_pending, (self.pos - 1) % self.buffer_size
        lost = np.zeros(0, dtype=np.int64)
        if had_pending:
            # The previous step's successor is the observation arriving now, unless the environment was reset
            # in between without an episode end (new learn() call, resumed buffer): then keep the true successor.
            differs = (obs != self._pending_host).reshape(copies, -1).any(axis=1)
            lost = np.flatnonzero(differs & (self._next_obs_index_host[prev] < 0))
        lost_rows = self._claim_rows(prev, lost)
        self._release_slot(self.pos)
        ended = np.flatnonzero(copy_done)
        ended_rows = self._claim_rows(self.pos, ended)

        (obs_s, next_s, action_s, reward_s, done_s, timeout_s, lost_s, lost_rows_s, ended_s, ended_rows_s, prev_s, pos_s) = (
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
            # Keep the old pending next observations (rows [0, n_copies) of _aux) before they are overwritten below
            self._aux[lost_rows_s] = self._aux[lost_s]
        self.observations[self.pos] = obs_s
        self.actions[self.pos] = action_s
        self.rewards[self.pos] = reward_s
        self.dones[self.pos] = done_s
        if self.handle_timeout_termination:
            self.timeouts[self.pos] = timeout_s
        if len(ended) > 0:
            # The next row of `observations` will be the first observation of the next episode
            self._aux[ended_rows_s] = next_s[ended_s]
        self._aux[:copies] = next_s
        if had_pending:
            self.next_obs_index[prev] = prev_s
        self.next_obs_index[self.pos] = pos_s
        self._pending_host[...] = next_obs
        self._has_pending = True

        self.pos += 1
        if self.pos == self.buffer_size:
            self.full = True
            self.pos = 0

    def _joint_step(
        self,
        obs: np.ndarray,
        next_obs: np.ndarray,
        action: np.ndarray,
        reward: np.ndarray,
        done: np.ndarray,
        infos: list[dict[str, Any]],
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """
        A VecEnv step's rows (parameters as in ``add``) as one joint transition per copy, in the storage dtypes.

        :return: obs and next_obs (n_copies, n_agents, *obs_shape), action (n_copies, n_agents, action_dim), reward
            (n_copies, n_agents), and per copy whether its episode ended and whether it was a truncation
        """
        copies, agents = self.n_copies, self.n_agents
        obs = np.asarray(obs).reshape(copies, agents, *self.obs_shape).astype(self._obs_np_dtype, copy=False)
        next_obs = np.asarray(next_obs).reshape(copies, agents, *self.obs_shape).astype(self._obs_np_dtype, copy=False)
        action = np.asarray(action)
        if is_discrete(self.action_space) and action.size == copies * agents and action.dtype.kind in "iu":
            action = one_hot(action, self.action_space)  # type: ignore[arg-type]
        action = action.reshape(copies, agents, self.action_dim).astype(self._action_np_dtype, copy=False)
        reward = np.asarray(reward).reshape(copies, agents).astype(np.float32, copy=False)
        copy_done = np.asarray(done).reshape(copies, agents).any(axis=1)
        truncated = np.array([info.get("TimeLimit.truncated", False) for info in infos], dtype=bool)
        copy_timeout = truncated.reshape(copies, agents).any(axis=1)
        return obs, next_obs, action, reward, copy_done, copy_timeout

    def _claim_rows(self, slot: int, copies: np.ndarray) -> np.ndarray:
        """
        Take rows of ``extra_next_observations`` for ``(slot, copies[i])`` in the index, growing the storage when the
        free list runs out; the caller writes the rows.

        :return: the rows, shape (k,)
        """
        while len(self._free_extra) < len(copies):
            old = len(self._aux) - self.n_copies
            new = max(2 * old, 2 * self.n_copies, 8)
            self._resize_extra(new)
            self._free_extra.extend(range(new - 1, old - 1, -1))
        index = np.array([self._free_extra.pop() for _ in range(len(copies))], dtype=np.int64)
        self._next_obs_index_host[slot, copies] = index
        return index

    def _release_slot(self, slot: int) -> None:
        """Free the kept next observations of a slot that is about to be overwritten (in the index)."""
        index = self._next_obs_index_host[slot]
        self._free_extra.extend(index[index >= 0].tolist())
        self._next_obs_index_host[slot] = -1

    def _resize_extra(self, n_rows: int) -> None:
        """Reallocate ``extra_next_observations`` for ``n_rows`` rows (the pending rows and the first ones are kept)."""
        aux = self._zeros((self.n_copies + n_rows, *self._aux.shape[1:]), self._obs_np_dtype)
        kept = min(len(aux), len(self._aux))
        aux[:kept] = self._aux[:kept]
        self._aux = aux

    def reset(self) -> None:
        super().reset()
        self._next_obs_index_host[...] = -1
        self.next_obs_index[...] = -1
        self._resize_extra(0)  # frees the kept next observations
        self._free_extra = []
        self._has_pending = False

    # --- Sampling from the NumPy storage --------------------------------------------------------------------------

    def sample(self, batch_size: int, env: VecNormalize | None = None) -> MultiAgentReplayBufferSamples:  # type: ignore[override]
        """
        Sample whole joint transitions uniformly over (stored step, copy).

        :param batch_size: number of joint transitions B
        :param env: associated VecNormalize, to normalise observations and rewards
        :return: the batch, shapes in ``MultiAgentReplayBufferSamples``
        """
        upper_bound = self.buffer_size if self.full else self.pos
        if upper_bound == 0:
            raise ValueError("Cannot sample from an empty replay buffer")
        batch_inds = np.random.randint(0, upper_bound, size=batch_size)
        return self._get_samples(batch_inds, env=env)

    def _get_samples(  # type: ignore[override]
        self, batch_inds: np.ndarray, env: VecNormalize | None = None, copy_inds: np.ndarray | None = None
    ) -> MultiAgentReplayBufferSamples:
        """
        :param batch_inds: slots, shape (B,)
        :param env: associated VecNormalize
        :param copy_inds: copies, shape (B,); drawn uniformly when None
        """
        if copy_inds is None:
            copy_inds = np.random.randint(0, high=self.n_copies, size=(len(batch_inds),))
        next_obs = self.next_observations_of(batch_inds, copy_inds)
        dones = self.dones[batch_inds, copy_inds]
        if self.handle_timeout_termination:
            dones = dones * (1 - self.timeouts[batch_inds, copy_inds])
        data = (
            self._normalize_obs(self.observations[batch_inds, copy_inds], env),
            self.actions[batch_inds, copy_inds],
            self._normalize_obs(next_obs, env),
            dones.reshape(-1, 1),
            self._normalize_reward(self.rewards[batch_inds, copy_inds], env),
        )
        # The arrays are fresh copies (fancy indexing), so the tensors can share their memory (SB3 copies again)
        return MultiAgentReplayBufferSamples(*(self.to_torch(array, copy=False) for array in data))  # type: ignore[arg-type]

    def next_observations_of(self, batch_inds: np.ndarray, copy_inds: np.ndarray) -> np.ndarray:
        """
        The next joint observations of stored steps, derived as described in the class docstring.

        :param batch_inds: slots, shape (B,)
        :param copy_inds: copies, shape (B,)
        :return: (B, n_agents, *obs_shape)
        """
        next_obs = self.observations[(batch_inds + 1) % self.buffer_size, copy_inds]
        is_newest = batch_inds == (self.pos - 1) % self.buffer_size
        if is_newest.any():
            next_obs[is_newest] = self.pending_next_observations[copy_inds[is_newest]]
        extra = self.next_obs_index[batch_inds, copy_inds]
        kept = extra >= 0
        if kept.any():
            next_obs[kept] = self.extra_next_observations[extra[kept]]
        return next_obs

    # --- A buffer read from a file ---------------------------------------------------------------------------------

    def check_loaded(self, name: str) -> None:
        """
        Check that a buffer read from a file is whole (``sb3_maddpg.common.buffer_files.check_loaded_buffer``).

        :param name: the file, for the messages
        :raises ValueError: naming the first field that does not fit
        """
        check_loaded_buffer(self, name)

    # --- Copies and layouts: one constructor path ------------------------------------------------------------------

    def stored_transitions(self) -> tuple[np.ndarray, np.ndarray]:
        """
        Where the stored joint transitions are, oldest first within each copy, copy after copy.

        :return: slots and copies, each of shape (n_stored * n_copies,)
        """
        n_stored = self.buffer_size if self.full else self.pos
        start = self.pos if self.full else 0
        slots = (start + np.arange(n_stored)) % self.buffer_size
        return np.tile(slots, self.n_copies), np.repeat(np.arange(self.n_copies), n_stored)

    @classmethod
    def like(
        cls: type[SelfBuffer],
        buffer: "MultiAgentReplayBuffer",
        n_copies: int | None = None,
        buffer_size: int | None = None,
        device: th.device | str | None = None,
        **storage_kwargs: Any,
    ) -> SelfBuffer:
        """
        An empty buffer of this class with the spaces and settings of another: the one place where a buffer is built
        from another (``with_copies``, ``from_buffer``, ``to_numpy_buffer``).

        :param buffer: the buffer whose spaces, agents and settings the new one takes
        :param n_copies: number of environment copies (default: the buffer's)
        :param buffer_size: capacity in joint transitions (default: the buffer's)
        :param device: device of the sampled tensors (default: the buffer's)
        :param storage_kwargs: further arguments of this class's constructor (``storage_device`` of a
            ``DeviceReplayBuffer``)
        :return: the new buffer
        """
        n_copies = buffer.n_copies if n_copies is None else n_copies
        return cls(
            buffer.buffer_size * buffer.n_copies if buffer_size is None else buffer_size,
            buffer.observation_space,
            buffer.action_space,
            device=buffer.device if device is None else device,
            n_envs=n_copies * buffer.n_agents,
            optimize_memory_usage=buffer.optimize_memory_usage,
            handle_timeout_termination=buffer.handle_timeout_termination,
            n_agents=buffer.n_agents,
            **storage_kwargs,
        )

    @classmethod
    def from_buffer(
        cls: type[SelfBuffer],
        buffer: "MultiAgentReplayBuffer",
        storage_device: th.device | str | None = None,
        device: th.device | str | None = None,
    ) -> SelfBuffer:
        """
        A buffer of this class with the contents and state of another joint buffer, from either storage (a full copy;
        for example a ``DeviceReplayBuffer`` of a buffer loaded from a file saved with the NumPy buffer).

        :param buffer: a ``MultiAgentReplayBuffer`` or ``DeviceReplayBuffer``
        :param storage_device: where the new buffer's storage lives, for a ``DeviceReplayBuffer`` (default: its
            constructor's, ``'cuda'``)
        :param device: device of the sampled tensors (default: the buffer's)
        :return: the new buffer (``buffer`` is unchanged)
        """
        new = cls.like(buffer, device=device, **({} if storage_device is None else {"storage_device": storage_device}))
        new._resize_extra(len(buffer._aux) - buffer.n_copies)
        for name in STORED:
            th.as_tensor(getattr(new, name)).copy_(th.as_tensor(getattr(buffer, name)))
        new._next_obs_index_host[...] = buffer._next_obs_index_host
        new._pending_host[...] = buffer._pending_host
        new._free_extra = list(buffer._free_extra)
        new._has_pending, new.pos, new.full = buffer._has_pending, buffer.pos, buffer.full
        return new

    def to_numpy_buffer(self) -> "MultiAgentReplayBuffer":
        """
        A ``MultiAgentReplayBuffer`` with the same contents and state, in host memory (a full copy).

        :return: the NumPy buffer (this one is unchanged)
        """
        return MultiAgentReplayBuffer.from_buffer(self)

    def with_copies(self: SelfBuffer, n_copies: int, buffer_size: int | None = None) -> SelfBuffer:
        """
        The same joint transitions laid out for another number of environment copies (to resume with more or fewer
        copies), in a buffer of the same class and storage. Each copy's history is kept in order; the histories are
        joined one after the other and cut into ``n_copies`` equal pieces. Where a transition's successor in the new
        layout is not its true successor (a join or a cut), its next observation is kept explicitly, so every
        transition is sampled as it was stored. When the transitions do not fill whole slots, or exceed
        ``buffer_size``, the oldest are left out.

        :param n_copies: the new number of copies
        :param buffer_size: the new capacity in joint transitions (default: this buffer's)
        :return: a new buffer (this one is unchanged)
        """
        if isinstance(n_copies, bool) or not isinstance(n_copies, int | np.integer) or n_copies < 1:
            raise ValueError(f"n_copies must be an integer >= 1, got {n_copies!r}")
        n_copies = int(n_copies)
        capacity = None if buffer_size is None else int(buffer_size)
        new = type(self).like(self, n_copies=n_copies, buffer_size=capacity, **self._storage_kwargs())
        slots, copies = self.stored_transitions()
        length = min(len(slots) // n_copies, new.buffer_size)  # slots of the new layout
        if length == 0:
            return new
        keep = slice(len(slots) - length * n_copies, len(slots))
        slots, copies = slots[keep], copies[keep]
        # Sequence element e goes to slot e % length of copy e // length
        new_slots = np.tile(np.arange(length), n_copies)
        new_copies = np.repeat(np.arange(n_copies), length)
        to, at = (new._index(new_slots), new._index(new_copies)), (self._index(slots), self._index(copies))
        for name in ("observations", "actions", "rewards", "dones", "timeouts"):
            getattr(new, name)[to] = getattr(self, name)[at]
        # Next observations that the new layout cannot derive: explicit ones, joins of two histories, cuts
        successor_is_true = np.zeros(len(slots), dtype=bool)
        successor_is_true[:-1] = (copies[1:] == copies[:-1]) & (new_copies[1:] == new_copies[:-1])
        explicit = (self._next_obs_index_host[slots, copies] >= 0) | ~successor_is_true
        new._resize_extra(int(explicit.sum()))
        new._aux[n_copies:] = self.next_observations_of(slots[explicit], copies[explicit])
        new._next_obs_index_host[new_slots[explicit], new_copies[explicit]] = np.arange(int(explicit.sum()))
        (new.next_obs_index,) = new._upload(new._next_obs_index_host)
        last = np.arange(1, n_copies + 1) * length - 1
        new._aux[:n_copies] = self.next_observations_of(slots[last], copies[last])
        new._pending_host[...] = to_host(new._aux[:n_copies])
        new._has_pending = True
        new.pos = length % new.buffer_size
        new.full = length == new.buffer_size
        return new

    def __setstate__(self, state: dict[str, Any]) -> None:
        if "_aux" not in state:
            # Pickled before the two storages shared one index: the pending and the kept next observations were
            # two arrays, and next_obs_index was the index itself
            pending = state.pop("pending_next_observations")
            state["_aux"] = np.concatenate([pending, state.pop("extra_next_observations")])
            state["_pending_host"] = pending.copy()
            state["_next_obs_index_host"] = state["next_obs_index"]
            state["_obs_np_dtype"], state["_action_np_dtype"] = state["observations"].dtype, state["actions"].dtype
        self.__dict__.update(state)
