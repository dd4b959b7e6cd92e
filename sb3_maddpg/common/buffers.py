"""Replay buffer of joint multi-agent transitions."""

import warnings
from typing import Any, NamedTuple

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.buffers import BaseBuffer, ReplayBuffer
from stable_baselines3.common.vec_env import VecNormalize

try:
    import psutil
except ImportError:  # pragma: no cover
    psutil = None


class MultiAgentReplayBufferSamples(NamedTuple):
    """
    A batch of B joint transitions (N agents each).

    - observations: (B, N, *obs_shape), in the observation dtype (uint8 images stay uint8)
    - actions: (B, N, action_dim), rescaled to [-1, 1] as SB3 stores them
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
    - ``actions``: (buffer_size, n_copies, n_agents, action_dim)
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

    :param buffer_size: maximum number of joint transitions
    :param observation_space: one agent's observation space (a Box)
    :param action_space: one agent's action space
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
        slots, copies, agents = self.buffer_size, self.n_copies, self.n_agents
        obs_dtype = observation_space.dtype
        self.observations = np.zeros((slots, copies, agents, *self.obs_shape), dtype=obs_dtype)
        self.actions = np.zeros((slots, copies, agents, self.action_dim), dtype=self._maybe_cast_dtype(action_space.dtype))
        self.rewards = np.zeros((slots, copies, agents), dtype=np.float32)
        self.dones = np.zeros((slots, copies), dtype=np.float32)
        self.timeouts = np.zeros((slots, copies), dtype=np.float32)
        # Index into extra_next_observations of the next observation kept for (slot, copy), -1 when derived
        self.next_obs_index = np.full((slots, copies), -1, dtype=np.int64)
        self.extra_next_observations = np.zeros((0, agents, *self.obs_shape), dtype=obs_dtype)
        self._free_extra: list[int] = []
        # Next observation of the newest step, (n_copies, n_agents, *obs_shape)
        self.pending_next_observations = np.zeros((copies, agents, *self.obs_shape), dtype=obs_dtype)
        self._has_pending = False

        if psutil is not None:
            total = self.nbytes_per_slot() * slots
            available = psutil.virtual_memory().available
            if total > available:
                warnings.warn(
                    "This system does not have apparently enough memory to store the complete "
                    f"replay buffer {total / 1e9:.2f}GB > {available / 1e9:.2f}GB"
                )

    def _set_layout(
        self,
        buffer_size: int,
        observation_space: spaces.Space,
        action_space: spaces.Space,
        device: th.device | str,
        n_envs: int,
        optimize_memory_usage: bool,
        handle_timeout_termination: bool,
        n_agents: int,
    ) -> None:
        """Check the spaces and the team, and set the attributes every joint buffer has (parameters as in ``__init__``)."""
        name = type(self).__name__
        if not isinstance(observation_space, spaces.Box):
            raise TypeError(f"{name} accepts a Box observation space, got {observation_space}")
        if not isinstance(action_space, spaces.Box):
            raise TypeError(f"{name} accepts a Box action space, got {action_space}")
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

    def nbytes_per_slot(self) -> int:
        """Bytes of the preallocated arrays per slot (one slot holds ``n_copies`` joint transitions)."""
        arrays = (self.observations, self.actions, self.rewards, self.dones, self.timeouts, self.next_obs_index)
        return sum(a.nbytes // a.shape[0] for a in arrays)

    def bytes_per_joint_transition(self) -> float:
        """
        Bytes of the preallocated arrays per stored joint transition. Each episode end adds one more joint
        observation (``n_agents * prod(obs_shape)`` elements) while it is in the buffer.
        """
        return self.nbytes_per_slot() / self.n_copies

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
        Store one VecEnv step: every copy's joint transition.

        :param obs: (n_copies * n_agents, *obs_shape) in SB3's row layout
        :param next_obs: (n_copies * n_agents, *obs_shape); rows that ended an episode hold the terminal observation
        :param action: (n_copies * n_agents, action_dim)
        :param reward: (n_copies * n_agents,)
        :param done: (n_copies * n_agents,) episode ended (terminated or truncated)
        :param infos: one dict per row; ``TimeLimit.truncated`` marks truncations
        """
        copies, agents = self.n_copies, self.n_agents
        obs = np.asarray(obs).reshape(copies, agents, *self.obs_shape)
        next_obs = np.asarray(next_obs).reshape(copies, agents, *self.obs_shape)
        action = np.asarray(action).reshape(copies, agents, self.action_dim)
        reward = np.asarray(reward).reshape(copies, agents)
        copy_done = np.asarray(done).reshape(copies, agents).any(axis=1)
        truncated = np.array([info.get("TimeLimit.truncated", False) for info in infos], dtype=bool)
        copy_timeout = truncated.reshape(copies, agents).any(axis=1)

        if self._has_pending:
            # The previous step's successor is the observation arriving now, unless the environment was reset
            # in between without an episode end (new learn() call, resumed buffer): then keep the true successor.
            prev = (self.pos - 1) % self.buffer_size
            differs = (obs != self.pending_next_observations).reshape(copies, -1).any(axis=1)
            lost = np.flatnonzero(differs & (self.next_obs_index[prev] < 0))
            if len(lost) > 0:
                self._keep_next_obs(prev, lost, self.pending_next_observations[lost])

        self._release_slot(self.pos)
        self.observations[self.pos] = obs
        self.actions[self.pos] = action
        self.rewards[self.pos] = reward
        self.dones[self.pos] = copy_done
        if self.handle_timeout_termination:
            self.timeouts[self.pos] = copy_timeout
        ended = np.flatnonzero(copy_done)
        if len(ended) > 0:
            # The next row of `observations` will be the first observation of the next episode
            self._keep_next_obs(self.pos, ended, next_obs[ended])
        self.pending_next_observations[...] = next_obs
        self._has_pending = True

        self.pos += 1
        if self.pos == self.buffer_size:
            self.full = True
            self.pos = 0

    def _keep_next_obs(self, slot: int, copies: np.ndarray, values: np.ndarray) -> None:
        """Keep explicit next observations ``values`` (k, n_agents, *obs_shape) for ``(slot, copies[i])``."""
        while len(self._free_extra) < len(copies):
            old = len(self.extra_next_observations)
            new = max(2 * old, 2 * self.n_copies, 8)
            grown = np.zeros((new, *self.extra_next_observations.shape[1:]), dtype=self.extra_next_observations.dtype)
            grown[:old] = self.extra_next_observations
            self.extra_next_observations = grown
            self._free_extra.extend(range(new - 1, old - 1, -1))
        index = np.array([self._free_extra.pop() for _ in range(len(copies))], dtype=np.int64)
        self.extra_next_observations[index] = values
        self.next_obs_index[slot, copies] = index

    def _release_slot(self, slot: int) -> None:
        """Free the explicit next observations of a slot that is about to be overwritten."""
        index = self.next_obs_index[slot]
        self._free_extra.extend(index[index >= 0].tolist())
        self.next_obs_index[slot] = -1

    def reset(self) -> None:
        super().reset()
        self.next_obs_index[...] = -1
        self.extra_next_observations = self.extra_next_observations[:0]
        self._free_extra = []
        self._has_pending = False

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

    def stored_transitions(self) -> tuple[np.ndarray, np.ndarray]:
        """
        Where the stored joint transitions are, oldest first within each copy, copy after copy.

        :return: slots and copies, each of shape (n_stored * n_copies,)
        """
        n_stored = self.buffer_size if self.full else self.pos
        start = self.pos if self.full else 0
        slots = (start + np.arange(n_stored)) % self.buffer_size
        return np.tile(slots, self.n_copies), np.repeat(np.arange(self.n_copies), n_stored)

    def with_copies(self, n_copies: int, buffer_size: int | None = None) -> "MultiAgentReplayBuffer":
        """
        The same joint transitions laid out for another number of environment copies (to resume with more or fewer
        copies). Each copy's history is kept in order; the histories are joined one after the other and cut into
        ``n_copies`` equal pieces. Where a transition's successor in the new layout is not its true successor (a join
        or a cut), its next observation is kept explicitly, so every transition is sampled as it was stored. When the
        transitions do not fill whole slots, or exceed ``buffer_size``, the oldest are left out.

        :param n_copies: the new number of copies
        :param buffer_size: the new capacity in joint transitions (default: this buffer's)
        :return: a new buffer (this one is unchanged)
        """
        if isinstance(n_copies, bool) or not isinstance(n_copies, int | np.integer) or n_copies < 1:
            raise ValueError(f"n_copies must be an integer >= 1, got {n_copies!r}")
        n_copies = int(n_copies)
        capacity = self.buffer_size * self.n_copies if buffer_size is None else int(buffer_size)
        new = MultiAgentReplayBuffer(
            capacity,
            self.observation_space,
            self.action_space,
            device=self.device,
            n_envs=n_copies * self.n_agents,
            optimize_memory_usage=self.optimize_memory_usage,
            handle_timeout_termination=self.handle_timeout_termination,
            n_agents=self.n_agents,
        )
        slots, copies = self.stored_transitions()
        length = min(len(slots) // n_copies, new.buffer_size)  # slots of the new layout
        if length == 0:
            return new
        keep = slice(len(slots) - length * n_copies, len(slots))
        slots, copies = slots[keep], copies[keep]
        # Sequence element e goes to slot e % length of copy e // length
        new_slots = np.tile(np.arange(length), n_copies)
        new_copies = np.repeat(np.arange(n_copies), length)
        for name in ("observations", "actions", "rewards", "dones", "timeouts"):
            getattr(new, name)[new_slots, new_copies] = getattr(self, name)[slots, copies]
        # Next observations that the new layout cannot derive: explicit ones, joins of two histories, cuts
        successor_is_true = np.zeros(len(slots), dtype=bool)
        successor_is_true[:-1] = (copies[1:] == copies[:-1]) & (new_copies[1:] == new_copies[:-1])
        explicit = (self.next_obs_index[slots, copies] >= 0) | ~successor_is_true
        new.extra_next_observations = self.next_observations_of(slots[explicit], copies[explicit])
        new.next_obs_index[new_slots[explicit], new_copies[explicit]] = np.arange(int(explicit.sum()))
        last = np.arange(1, n_copies + 1) * length - 1
        new.pending_next_observations[...] = self.next_observations_of(slots[last], copies[last])
        new._has_pending = True
        new.pos = length % new.buffer_size
        new.full = length == new.buffer_size
        return new
