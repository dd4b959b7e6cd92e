"""The base of the multi-agent off-policy algorithms: SB3's ``OffPolicyAlgorithm`` for a team on one VecEnv.

What every multi-agent off-policy algorithm of this library needs and SB3 does not do lives here, so that an
algorithm file (``maddpg/maddpg.py``, ``matd3/matd3.py``) holds only its arguments, its networks, its losses and
``train``, as SB3's ``td3.py`` does:

- the team: the number of agents and their names, read from the VecEnv of ``make_multiagent_vec_env`` (one row per
  agent and copy, row = copy * n_agents + agent), and the refusal of another team in ``predict``, ``set_env`` and
  ``load(env=...)``;
- the timestep: one joint step of one environment copy, so the rollout loop, the episode count and the progress bar
  count copies, not VecEnv rows;
- the joint replay buffer (host memory, or a torch device with ``replay_buffer_kwargs=dict(storage_device=...)``),
  its saving and loading, laid out again for another number of copies;
- atomic saves that carry the random states, so that a resumed run continues exactly.

Where it overrides SB3's own loop (``collect_rollouts``, ``_sample_action``, ``_init_callback``), the code follows
stable-baselines3 2.9's ``OffPolicyAlgorithm`` and ``BaseAlgorithm`` line for line apart from what is named in each
docstring; compare with those methods when upgrading SB3.
"""

import io
import os
import pathlib
import pickle
import warnings
from collections.abc import Iterable
from typing import Any, ClassVar, TypeVar

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.buffers import ReplayBuffer
from stable_baselines3.common.callbacks import BaseCallback, CallbackList, ConvertCallback, ProgressBarCallback
from stable_baselines3.common.noise import ActionNoise, VectorizedActionNoise
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from stable_baselines3.common.policies import BasePolicy
from stable_baselines3.common.save_util import open_path
from stable_baselines3.common.type_aliases import GymEnv, MaybeCallback, RolloutReturn, Schedule, TrainFreq, TrainFrequencyUnit
from stable_baselines3.common.utils import should_collect_more_steps
from stable_baselines3.common.vec_env import VecEnv

from sb3_maddpg.common.actions import SUPPORTED_ACTION_SPACES, action_width, is_discrete
from sb3_maddpg.common.agent_spaces import AgentSpaces
from sb3_maddpg.common.atomic import atomic_save
from sb3_maddpg.common.buffers import MultiAgentReplayBuffer
from sb3_maddpg.common.callbacks import EpisodeMetricsCallback
from sb3_maddpg.common.denormals import flushed_denormals
from sb3_maddpg.common.device_buffer import DeviceReplayBuffer, resolve_storage_device
from sb3_maddpg.common.evaluation import evaluate_joint_episodes
from sb3_maddpg.common.model_files import READ_ERRORS, read_maddpg_data, restricted_loads
from sb3_maddpg.common.noise import DecayingGaussianNoise, RowBatchedActionNoise, set_noise_timestep
from sb3_maddpg.common.random_state import capture_random_states, restore_random_states
from sb3_maddpg.common.validation import check_int, check_off_policy_arguments
from sb3_maddpg.common.vec_env import is_agent_dict, rows_from_agent_dict

SelfMultiAgentOffPolicyAlgorithm = TypeVar("SelfMultiAgentOffPolicyAlgorithm", bound="MultiAgentOffPolicyAlgorithm")


def default_agent_names(n_agents: int) -> list[str]:
    """The names of a team whose env does not name its agents: ``agent_0``, ``agent_1``, ..."""
    return [f"agent_{i}" for i in range(n_agents)]


def _describe_team(names: list[str]) -> str:
    shown = ", ".join(names) if len(names) <= 8 else f"{', '.join(names[:3])}, ..., {names[-1]}"
    return f"{len(names)} agent{'s' if len(names) != 1 else ''} ({shown})"


def _first_non_finite(values: np.ndarray) -> str:
    """The first NaN or infinite value of an array and its index, for messages."""
    if values.ndim == 0:
        return str(values)
    index = np.unravel_index(int(np.flatnonzero(~np.isfinite(values))[0]), values.shape)
    return f"{values[index]} at index {tuple(int(i) for i in index)}"


def algorithm_of_policy(policy_class: Any) -> type["MultiAgentOffPolicyAlgorithm"] | None:
    """
    The algorithm of this library that saved a model, told by its saved policy class: the algorithm whose
    ``MlpPolicy`` is the most derived base of that class (``MATD3`` for MATD3's twin-critic policies, ``MADDPG`` for
    MADDPG's). An algorithm is known once its module is imported, which unpickling its policy class does (the policy
    module's package imports the algorithm).

    :param policy_class: the model's saved ``policy_class``
    :return: the algorithm class, or None for a class that is no algorithm's policy
    """
    if not isinstance(policy_class, type):
        return None
    candidates: list[tuple[type[MultiAgentOffPolicyAlgorithm], type]] = []
    stack: list[type[MultiAgentOffPolicyAlgorithm]] = [MultiAgentOffPolicyAlgorithm]
    while stack:
        algorithm = stack.pop()
        stack.extend(algorithm.__subclasses__())
        base = algorithm.policy_aliases.get("MlpPolicy")
        if base is not None and issubclass(policy_class, base):
            candidates.append((algorithm, base))
    if not candidates:
        return None
    closest = max((base for _, base in candidates), key=lambda base: len(base.__mro__))
    # the first algorithm with that policy (MATD3, not a subclass of it)
    return min((algorithm for algorithm, base in candidates if base is closest), key=lambda algorithm: len(algorithm.__mro__))


def contains_callback(callback: BaseCallback, callback_class: type[BaseCallback]) -> bool:
    """Whether ``callback`` is, or holds in a (nested) ``CallbackList``, an instance of ``callback_class``."""
    if isinstance(callback, callback_class):
        return True
    return isinstance(callback, CallbackList) and any(contains_callback(c, callback_class) for c in callback.callbacks)


class JointStepProgressBarCallback(ProgressBarCallback):
    """
    SB3's progress bar counting the team's timesteps: one VecEnv step advances it by ``n_copies`` (one timestep per
    joint step of each environment copy), not by the number of VecEnv rows.
    """

    def _on_step(self) -> bool:
        self.pbar.update(self.model.n_copies)  # type: ignore[attr-defined]
        return True


def _count_joint_steps(callback: BaseCallback) -> BaseCallback:
    """
    The callback tree with each of SB3's plain ``ProgressBarCallback`` replaced by a joint-step one, in the lists
    themselves: RL Zoo closes ``self.callbacks[0]``, its progress bar, after ``learn``.
    """
    if type(callback) is ProgressBarCallback:
        return JointStepProgressBarCallback()
    if isinstance(callback, CallbackList):
        callback.callbacks[:] = [_count_joint_steps(child) for child in callback.callbacks]
    return callback


class MultiAgentOffPolicyAlgorithm(OffPolicyAlgorithm):
    """
    SB3's off-policy algorithm for a team of N agents acting in one VecEnv with one row per agent and copy,
    row = copy * n_agents + agent (see ``make_multiagent_vec_env``); row r is acted on by the policy's agent
    r mod N. One timestep is one joint step of one environment copy: each VecEnv step adds ``n_copies`` to
    ``num_timesteps``; ``total_timesteps``, ``learning_starts``, ``buffer_size``, the progress bar and TensorBoard's
    x-axis count these. ``train_freq=(k, "step")`` means every k VecEnv steps, and callbacks are called once per
    VecEnv step, as in SB3.

    A subclass builds its networks in ``_setup_model`` (after calling this class's) and implements ``train``; its
    policy class takes ``n_agents`` (and the keyword arguments of ``_policy_arguments``) beside SB3's arguments.

    :param policy: the policy model to use (MlpPolicy, CnnPolicy, ...)
    :param env: the VecEnv to learn from (can be None to load a trained model)
    :param learning_rate: learning rate, or a schedule of the progress remaining (from 1 to 0)
    :param buffer_size: replay buffer size in joint transitions (timesteps)
    :param learning_starts: timesteps of uniformly random actions before learning starts
    :param batch_size: joint transitions per gradient update
    :param tau: soft update coefficient of the target networks ("Polyak update", between 0 and 1)
    :param gamma: discount factor
    :param train_freq: update the model every ``train_freq`` VecEnv steps; or a tuple like ``(5, "step")`` or,
        with a single environment copy, ``(2, "episode")``
    :param gradient_steps: gradient steps after each rollout; -1 does as many as timesteps collected
    :param action_noise: exploration noise added to the actions rescaled to [-1, 1]; None gives the decaying Gaussian
        noise (``DecayingGaussianNoise``: standard deviation 1.0 decaying towards 0.1); Box actions only (Discrete
        actions explore by sampling the actors' logits)
    :param replay_buffer_class: replay buffer class (``MultiAgentReplayBuffer`` or a subclass; by default
        ``DeviceReplayBuffer`` when ``replay_buffer_kwargs`` name a ``storage_device``, else ``MultiAgentReplayBuffer``)
    :param replay_buffer_kwargs: keyword arguments of the replay buffer
    :param n_agents: number of agents; read from the env's ``n_agents`` attribute when None
    :param policy_kwargs: additional arguments of the policy
    :param stats_window_size: window size of the rollout logging (episodes)
    :param tensorboard_log: the log location for TensorBoard (if None, no logging)
    :param verbose: verbosity level: 0 no output, 1 info messages, 2 debug messages
    :param seed: seed for the pseudo random generators
    :param device: device (cpu, cuda, ...) on which the code should run; "auto" uses the GPU if possible
    :param flush_denormals: while ``learn`` runs, the CPU flushes denormal floats (below 1.2e-38) to zero
        (``torch.set_flush_denormal``; the mode it found is restored afterwards). Adam's averages of weights that get no
        gradient decay into that range, where x86 CPUs compute many times slower (the UAV quick start: 1.2x to 1.35x
        faster with it, the networks' weights unchanged; ``sb3_maddpg.common.denormals``). The mode belongs to the
        thread that calls ``learn``: with ``torch.set_num_threads(n > 1)`` the work of PyTorch's other intra-op
        threads is not flushed. True by default
    """

    policy_aliases: ClassVar[dict[str, type[BasePolicy]]] = {}
    #: class parameters that every saved model of the algorithm has and no SB3 algorithm saves: ``load`` refuses a
    #: file without one of them with a one-line error (a subclass adds its own)
    saved_model_keys: ClassVar[tuple[str, ...]] = ("n_agents",)
    replay_buffer: MultiAgentReplayBuffer | None  # type: ignore[assignment]

    def __init__(
        self,
        policy: str | type[BasePolicy],
        env: GymEnv | str | None,
        learning_rate: float | Schedule,
        buffer_size: int = 1_000_000,
        learning_starts: int = 100,
        batch_size: int = 256,
        tau: float = 0.005,
        gamma: float = 0.99,
        train_freq: int | tuple[int, str] = 1,
        gradient_steps: int = 1,
        action_noise: ActionNoise | None = None,
        replay_buffer_class: type[ReplayBuffer] | None = None,
        replay_buffer_kwargs: dict[str, Any] | None = None,
        n_agents: int | None = None,
        policy_kwargs: dict[str, Any] | None = None,
        stats_window_size: int = 100,
        tensorboard_log: str | None = None,
        verbose: int = 0,
        device: th.device | str = "auto",
        seed: int | None = None,
        flush_denormals: bool = True,
    ) -> None:
        name = type(self).__name__
        check_off_policy_arguments(
            name,
            dict(
                env=env,
                learning_rate=learning_rate,
                buffer_size=buffer_size,
                learning_starts=learning_starts,
                batch_size=batch_size,
                tau=tau,
                gamma=gamma,
                train_freq=train_freq,
                gradient_steps=gradient_steps,
                action_noise=action_noise,
                replay_buffer_class=replay_buffer_class,
                replay_buffer_kwargs=replay_buffer_kwargs,
                stats_window_size=stats_window_size,
                tensorboard_log=tensorboard_log,
                policy_kwargs=policy_kwargs,
                verbose=verbose,
                seed=seed,
                device=device,
                flush_denormals=flush_denormals,
            ),
        )
        super().__init__(
            policy,
            env,  # type: ignore[arg-type]
            learning_rate,
            buffer_size,
            learning_starts,
            batch_size,
            tau,
            gamma,
            train_freq,
            gradient_steps,
            action_noise=action_noise,
            replay_buffer_class=replay_buffer_class,
            replay_buffer_kwargs=replay_buffer_kwargs,
            policy_kwargs=policy_kwargs,
            stats_window_size=stats_window_size,
            tensorboard_log=tensorboard_log,
            verbose=verbose,
            device=device,
            seed=seed,
            sde_support=False,
            supported_action_spaces=SUPPORTED_ACTION_SPACES,
            support_multi_env=True,
        )
        storage = self.replay_buffer_kwargs.get("storage_device")
        if storage is not None and not (isinstance(storage, str) and storage == "auto"):
            storage = resolve_storage_device(storage)  # a clear error when torch cannot use it here
            if storage.type != self.device.type:
                raise ValueError(
                    f"replay_buffer_kwargs' storage_device={str(storage)!r} must be the model's device ({self.device}): "
                    "the buffer is sampled where the networks train"
                )
        self.flush_denormals = flush_denormals
        self.n_agents: int | None = n_agents
        self.agent_names: list[str] | None = None
        # Each agent's own spaces where they differ (the VecEnv's are then padded); None when all agents share them
        self.agent_spaces: AgentSpaces | None = None
        self.departures = False
        if self.env is not None:
            self._read_agents(self.env, n_agents)
            self._check_action_noise(action_noise, self.env.num_envs)

    # ------------------------------------------------------------------------------------------------------------
    # The team
    # ------------------------------------------------------------------------------------------------------------

    @property
    def n_copies(self) -> int:
        """Number of environment copies: VecEnv rows / n_agents."""
        assert self.n_agents is not None
        return self.n_envs // self.n_agents

    def _read_agents(self, env: VecEnv, n_agents: int | None) -> None:
        """Set ``n_agents`` and ``agent_names`` from the env (or the argument) and check the VecEnv's rows and team."""
        env_n_agents = getattr(env, "n_agents", None)
        if n_agents is not None:
            check_int("n_agents", n_agents, 1)
        names = getattr(env, "possible_agents", None)
        if env_n_agents is not None and n_agents is not None and env_n_agents != n_agents:
            if self.agent_names is not None and names is not None:
                # a model that knows its team (loaded, or set_env) on a VecEnv of another team
                self.check_team([str(name) for name in names], "the VecEnv")
            raise ValueError(f"n_agents={n_agents} disagrees with the env's n_agents={env_n_agents}")
        n_agents = n_agents if n_agents is not None else env_n_agents
        if n_agents is None:
            n_agents = self.n_agents  # restored by load()
        if n_agents is None:
            raise ValueError(
                f"{type(self).__name__} needs the number of agents: build the env with "
                "sb3_maddpg.make_multiagent_vec_env (it sets `n_agents`) or pass n_agents=..."
            )
        if env.num_envs % n_agents != 0:
            raise ValueError(
                f"the VecEnv has {env.num_envs} rows, which is not a multiple of n_agents={n_agents}; "
                "rows must be agent-major inside each copy (row = copy * n_agents + agent)"
            )
        env_agent_spaces = getattr(env, "agent_spaces", None)
        if self.agent_names is not None and env_agent_spaces != self.agent_spaces:
            # a model that knows its team's spaces (loaded, or set_env) on a VecEnv whose agents' spaces differ
            raise ValueError(
                f"this {type(self).__name__} model's agents have the spaces {self.agent_spaces or 'of the VecEnv'}, "
                f"but the VecEnv's agents have {env_agent_spaces or 'its spaces'}"
            )
        self.agent_spaces = env_agent_spaces
        # Agents may leave before the episode ends (make_multiagent_vec_env's black_death): the losses read it
        self.departures = bool(getattr(env, "departures", False))
        self.n_agents = int(n_agents)
        if names is not None and len(names) == self.n_agents:
            names = [str(name) for name in names]
            if self.agent_names is not None and self.agent_names != default_agent_names(self.n_agents):
                self.check_team(names, "the VecEnv")
            self.agent_names = names
        elif self.agent_names is None or len(self.agent_names) != self.n_agents:
            self.agent_names = default_agent_names(self.n_agents)

    def _check_action_noise(self, action_noise: ActionNoise | None, n_rows: int) -> None:
        """
        Refuse a noise of another shape than the actions (NumPy would broadcast a 1-D noise silently, or fail at the
        first step), or a ``VectorizedActionNoise`` for another number of VecEnv rows.
        """
        if action_noise is None:
            return
        if is_discrete(self.action_space):
            raise ValueError(
                f"action_noise applies to continuous (Box) actions; with {self.action_space} actions the rollouts explore "
                "by sampling the actors' logits (Gumbel-max): leave action_noise=None"
            )
        action_shape = tuple(self.action_space.shape)  # type: ignore[arg-type]
        if isinstance(action_noise, VectorizedActionNoise):
            if action_noise.n_envs != n_rows:
                raise ValueError(
                    f"action_noise is a VectorizedActionNoise for {action_noise.n_envs} rows, but the VecEnv has {n_rows} "
                    f"rows ({self.n_copies} copies x {self.n_agents} agents); give one noise of shape {action_shape} "
                    "and it is applied to every row"
                )
            action_noise = action_noise.noises[0]
        mean = getattr(action_noise, "_mu", None)
        if mean is not None and np.shape(mean) != action_shape:
            raise ValueError(
                f"action_noise has shape {np.shape(mean)}, but each agent's action has shape {action_shape}: give a "
                f"mean (and sigma) of shape {action_shape}"
            )

    def check_team(self, names: list[str], where: str) -> None:
        """
        Refuse a team other than the model's: a model of N agents reads the rows of a larger team as several copies
        of its own, and would act and report plausible but wrong numbers.

        :param names: the agents of the VecEnv (or observations) the model is asked to act on, in row order
        :param where: what holds them, for the message
        :raises ValueError: naming both teams
        """
        assert self.n_agents is not None
        own = self.agent_names or default_agent_names(self.n_agents)
        same_names = own == names or own == default_agent_names(self.n_agents)
        if len(names) != self.n_agents or not same_names:
            raise ValueError(
                f"this {type(self).__name__} model acts for a team of {_describe_team(own)}, but {where} has a team "
                f"of {_describe_team(names)}; use an env with the model's team (the same agents and n_agents)"
            )

    def set_env(self, env: GymEnv, force_reset: bool = True) -> None:
        names = getattr(env, "possible_agents", None)
        if names is not None:
            self.check_team([str(name) for name in names], "the VecEnv")
        super().set_env(env, force_reset=force_reset)
        assert self.env is not None
        self._read_agents(self.env, self.n_agents)

    def predict(
        self,
        observation: np.ndarray | dict[str, np.ndarray],
        state: tuple[np.ndarray, ...] | None = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = False,
    ) -> tuple[np.ndarray | dict[str, np.ndarray], tuple[np.ndarray, ...] | None]:
        """
        Actions of SB3's rows (row = copy * n_agents + agent; row r is acted on by the policy's agent r mod n_agents),
        or, given a PettingZoo ``ParallelEnv``'s observation dict (agent -> observation), the dict of the agents' actions.

        Observations from ``make_multiagent_vec_env`` carry their team (:class:`~sb3_maddpg.common.vec_env.AgentRows`):
        those of another team than the model's are refused, wherever they come from (``evaluate_policy``, RL Zoo's
        ``enjoy``, a loop of your own).

        :param observation: the observation rows, or a dict agent -> observation of the model's agents (those still
            in the episode; an agent missing from the dict gets no action)
        :param state: unused (no recurrent policy)
        :param episode_start: unused
        :param deterministic: unused: the actors are deterministic, exploration noise is added during ``learn``
        :return: the actions (rows, or a dict agent -> action) and None
        """
        if is_agent_dict(observation):
            assert self.agent_names is not None
            self._check_agent_observations(observation)  # type: ignore[arg-type]
            padded_shape = tuple(self.observation_space.shape) if self.agent_spaces is not None else None  # type: ignore[arg-type]
            rows, agents = rows_from_agent_dict(observation, self.agent_names, padded_shape)  # type: ignore[arg-type]
            actions, state = self.predict(rows, state, episode_start, deterministic)
            return {
                agent: self._own_action(row, actions[row]) for row, agent in enumerate(self.agent_names) if agent in agents
            }, state
        names = getattr(observation, "possible_agents", None)
        if names is not None:
            self.check_team(list(names), "the observations' VecEnv")
        if isinstance(observation, np.ndarray):
            expected = np.dtype(self.observation_space.dtype)
            if expected.kind in "ui" and observation.dtype.kind == "f":
                raise TypeError(
                    f"predict: the observations are {observation.dtype}, but the model's observation space is {expected} "
                    f"(images of 0-255, as the env gives them); pass the env's observations unchanged"
                )
            if observation.dtype.kind == "f" and not np.isfinite(observation).all():
                raise ValueError(f"predict: the observations hold NaN or infinite values ({_first_non_finite(observation)})")
        return super().predict(observation, state, episode_start, deterministic)

    def _check_agent_observations(self, observations: dict[str, Any]) -> None:
        """
        Refuse, naming the agent, an observation of a PettingZoo dict that is not of the agent's own shape: another
        agent's (which may fit the padded rows), or, for a model trained with ``black_death=True``, one without the
        in-episode entry those observations end with.

        :param observations: agent -> observation, as ``predict`` gets them
        """
        assert self.agent_names is not None and self.n_agents is not None
        if self.agent_spaces is not None:
            shapes = [tuple(space.shape) for space in self.agent_spaces.observation_spaces]
        else:
            shapes = [tuple(self.observation_space.shape)] * self.n_agents  # type: ignore[arg-type]
        for agent, value in observations.items():
            if agent not in self.agent_names:
                continue  # named by rows_from_agent_dict, with the team
            shape, own = np.shape(value), shapes[self.agent_names.index(agent)]
            if shape == own:
                continue
            if self.departures and shape[:-1] == own[:-1] and shape[-1:] == (own[-1] - 1,):
                raise ValueError(
                    f"predict: the observation of {agent!r} has {shape[-1]} entries, and the model's {own[-1]}: it was "
                    "trained with black_death=True, whose observations end with an in-episode entry (1.0 while the agent "
                    "is in the episode, 0.0 once it has left); pass np.append(observation, 1.0) for each agent in the "
                    "dict, or step the env made by make_multiagent_vec_env(..., black_death=True)"
                )
            if self.agent_spaces is not None:
                raise ValueError(
                    f"predict: the observation of {agent!r} has the shape {shape}, but {agent!r}'s own observations "
                    f"have the shape {own}; pass each agent its own observation (another agent's width is not accepted, "
                    "even where it fits the padded rows)"
                )

    def _own_action(self, agent: int, action: np.ndarray) -> np.ndarray:
        """Agent ``agent``'s action in its own space: a padded Box action cut to the agent's width."""
        if self.agent_spaces is None or is_discrete(self.action_space):
            return action
        return action[: int(self.agent_spaces.action_widths[agent])]

    def _mask_padded_actions(self, action: np.ndarray, buffer_action: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """
        For agents with action spaces of their own: no padded entry reaches the replay buffer. Box: the padded
        entries (random, or exploration noise) become 0. Discrete: a random action beyond an agent's n is drawn
        again from the agent's own actions (uniformly, with the action space's generator).

        :param action: the env's actions (rows)
        :param buffer_action: the actions to store (rows)
        :return: both, masked
        """
        if self.agent_spaces is None:
            return action, buffer_action
        assert self.n_agents is not None
        widths = np.tile(self.agent_spaces.action_widths, len(action) // self.n_agents)  # (rows,)
        if is_discrete(self.action_space):
            start = int(self.action_space.start)  # type: ignore[attr-defined]
            invalid = np.asarray(action) - start >= widths
            if invalid.any():
                action = np.array(action, copy=True)
                action[invalid] = start + self.action_space.np_random.integers(0, widths[invalid])
            return action, action
        padded = np.arange(buffer_action.shape[-1])[None, :] >= widths[:, None]
        buffer_action = np.where(padded, 0.0, buffer_action).astype(buffer_action.dtype, copy=False)
        return self.policy.unscale_action(buffer_action), buffer_action

    # ------------------------------------------------------------------------------------------------------------
    # Building: the team, the replay buffer, the exploration noise and the policy
    # ------------------------------------------------------------------------------------------------------------

    def _policy_arguments(self) -> dict[str, Any]:
        """Keyword arguments of the algorithm (not ``policy_kwargs``) that its policy class takes."""
        return {}

    def _setup_model(self) -> None:
        # As OffPolicyAlgorithm._setup_model, but the replay buffer is only allocated when there is an env to fill
        # it, so that load() without an env (to act) does not allocate a full-size buffer; and the policy gets the team.
        if self.env is not None:
            self._read_agents(self.env, self.n_agents)
        if self.n_agents is None:
            raise ValueError(f"{type(self).__name__} needs an env or n_agents=... to build its networks")
        if self.agent_names is None:
            self.agent_names = default_agent_names(self.n_agents)
        self._setup_lr_schedule()
        self.set_random_seed(self.seed)

        if self.replay_buffer_class is None:
            # replay_buffer_kwargs=dict(storage_device=...) keeps the buffer on that device (DeviceReplayBuffer)
            on_device = "storage_device" in self.replay_buffer_kwargs
            self.replay_buffer_class = DeviceReplayBuffer if on_device else MultiAgentReplayBuffer
        if "storage_device" in self.replay_buffer_kwargs:
            self._check_storage_device()
        self.replay_buffer_kwargs["n_agents"] = self.n_agents
        if self.replay_buffer is None and self.env is not None:
            self._make_replay_buffer()

        # Discrete actions explore by sampling the actors' logits, without action noise
        if self.action_noise is None and not is_discrete(self.action_space):
            action_dim = int(np.prod(self.action_space.shape))
            self.action_noise = DecayingGaussianNoise(mean=np.zeros(action_dim), sigma=1.0, final_sigma=0.1)

        self.policy = self.policy_class(  # type: ignore[assignment]
            self.observation_space,
            self.action_space,
            self.lr_schedule,
            n_agents=self.n_agents,
            **({} if self.agent_spaces is None else {"agent_spaces": self.agent_spaces}),
            **self._policy_arguments(),
            **self.policy_kwargs,
        )
        self.policy = self.policy.to(self.device)
        self._convert_train_freq()

    def _check_storage_device(self) -> None:
        """
        The device buffer is sampled where the networks train: its storage follows the model's device. A model
        loaded onto another device (a GPU model on a CPU machine) keeps its buffer there instead, with a warning.
        """
        assert self.replay_buffer_class is not None
        if not issubclass(self.replay_buffer_class, DeviceReplayBuffer):
            raise ValueError(
                "replay_buffer_kwargs' storage_device needs the DeviceReplayBuffer (the default when it is given), "
                f"got replay_buffer_class={self.replay_buffer_class.__name__}"
            )
        storage = self.replay_buffer_kwargs["storage_device"]
        if isinstance(storage, str) and storage == "auto":
            storage = self.device
        if th.device(storage).type != self.device.type:
            warnings.warn(
                f"the replay buffer's storage_device {storage} is not this model's device: it is kept on {self.device}"
            )
            storage = self.device
        self.replay_buffer_kwargs["storage_device"] = storage

    def _make_replay_buffer(self) -> None:
        assert self.replay_buffer_class is not None
        try:
            self.replay_buffer = self.replay_buffer_class(  # type: ignore[assignment]
                self.buffer_size,
                self.observation_space,
                self.action_space,
                device=self.device,
                n_envs=self.n_envs,
                optimize_memory_usage=self.optimize_memory_usage,
                **self.replay_buffer_kwargs,
            )
        except MemoryError as error:
            raise ValueError(
                f"buffer_size={self.buffer_size}: the replay buffer cannot be allocated on this machine ({error}); "
                "use a smaller buffer_size"
            ) from error

    # ------------------------------------------------------------------------------------------------------------
    # The rollout loop
    # ------------------------------------------------------------------------------------------------------------

    def _sample_action(
        self, learning_starts: int, action_noise: ActionNoise | None = None, n_envs: int = 1
    ) -> tuple[np.ndarray, np.ndarray]:
        """
        As ``OffPolicyAlgorithm._sample_action`` (random actions before ``learning_starts``, then the actors plus
        the exploration noise, clipped to [-1, 1]), with the actors' [-1, 1] outputs used as they are: SB3 goes
        through ``predict``, which maps them to the action space's bounds, and maps them back at once.
        Discrete actions take SB3's own path: uniform integers before ``learning_starts``, then ``predict`` with
        ``deterministic=False`` (a Gumbel-max sample of each actor's logits) and no action noise; the buffer
        stores the integers as one-hot vectors.

        :param learning_starts: timesteps of random actions before learning starts
        :param action_noise: exploration noise added to the actors' outputs
        :param n_envs: number of VecEnv rows
        :return: the actions to take in the env and the [-1, 1] actions to store in the replay buffer
        """
        if self.num_timesteps < learning_starts or not isinstance(self.action_space, spaces.Box):
            return self._mask_padded_actions(*super()._sample_action(learning_starts, action_noise, n_envs))
        assert self._last_obs is not None, "self._last_obs was not set"
        self.policy.set_training_mode(False)
        observations, _ = self.policy.obs_to_tensor(self._last_obs)
        with th.no_grad():
            scaled_action = self.policy._predict(observations).cpu().numpy().reshape((-1, *self.action_space.shape))
        if action_noise is not None:
            scaled_action = np.clip(scaled_action + action_noise(), -1, 1)
        return self._mask_padded_actions(self.policy.unscale_action(scaled_action), scaled_action)

    def collect_rollouts(
        self,
        env: VecEnv,
        callback: BaseCallback,
        train_freq: TrainFreq,
        replay_buffer: ReplayBuffer,
        action_noise: ActionNoise | None = None,
        learning_starts: int = 0,
        log_interval: int | None = None,
    ) -> RolloutReturn:
        """
        Collect experiences and store them into the replay buffer.

        SB3 2.9's ``OffPolicyAlgorithm.collect_rollouts``, changed only to count the team's timestep (one joint step
        of one env copy: ``num_timesteps += n_copies`` per VecEnv step, where SB3 adds the number of rows), one
        episode per copy (SB3 would count one per agent row) and the noise schedule's timestep; no gSDE.

        :param env: the training environment
        :param callback: callback called at each VecEnv step (and at the beginning and end of the rollout)
        :param train_freq: how much experience to collect: VecEnv steps, or episodes with one env copy
        :param replay_buffer: the replay buffer
        :param action_noise: action noise for exploration
        :param learning_starts: timesteps of random actions before learning starts
        :param log_interval: log data every ``log_interval`` episodes
        :return: timesteps and episodes collected, and whether to continue training
        """
        # Switch to eval mode (this affects batch norm / dropout)
        self.policy.set_training_mode(False)

        num_collected_steps, num_collected_episodes = 0, 0
        n_copies, n_agents = self.n_copies, self.n_agents
        assert n_agents is not None

        assert isinstance(env, VecEnv), "You must pass a VecEnv"
        assert train_freq.frequency > 0, "Should at least collect one step or episode."
        if n_copies > 1 and train_freq.unit != TrainFrequencyUnit.STEP:
            raise ValueError("train_freq in episodes needs a single environment copy; use (k, 'step') with several copies")

        callback.on_rollout_start()
        continue_training = True
        while should_collect_more_steps(train_freq, num_collected_steps, num_collected_episodes):
            # Select action randomly or according to policy; the noise schedule follows the timestep counter
            set_noise_timestep(action_noise, self.num_timesteps)
            actions, buffer_actions = self._sample_action(learning_starts, action_noise, env.num_envs)

            # Rescale and perform action
            new_obs, rewards, dones, infos = env.step(actions)

            self.num_timesteps += n_copies
            num_collected_steps += 1

            # Give access to local variables
            callback.update_locals(locals())
            # Only stop training if return value is False, not when it is None.
            if not callback.on_step():
                return RolloutReturn(num_collected_steps * n_copies, num_collected_episodes, continue_training=False)

            # Retrieve reward and episode length (episode statistics come once per joint episode)
            self._update_info_buffer(infos, dones)

            # Store data in replay buffer (normalized action and unnormalized observation)
            self._store_transition(replay_buffer, buffer_actions, new_obs, rewards, dones, infos)  # type: ignore[arg-type]

            self._update_current_progress_remaining(self.num_timesteps, self._total_timesteps)
            self._on_step()

            for copy in np.flatnonzero(np.asarray(dones).reshape(n_copies, n_agents).any(axis=1)):
                # Update stats: one episode per copy
                num_collected_episodes += 1
                self._episode_num += 1

                if action_noise is not None:
                    kwargs = dict(indices=list(range(copy * n_agents, (copy + 1) * n_agents))) if env.num_envs > 1 else {}
                    action_noise.reset(**kwargs)

                # Log training infos
                if log_interval is not None and self._episode_num % log_interval == 0:
                    self.dump_logs()
        callback.on_rollout_end()

        return RolloutReturn(num_collected_steps * n_copies, num_collected_episodes, continue_training)

    def _store_transition(
        self,
        replay_buffer: ReplayBuffer,
        buffer_action: np.ndarray,
        new_obs: np.ndarray | dict[str, np.ndarray],
        reward: np.ndarray,
        dones: np.ndarray,
        infos: list[dict[str, Any]],
    ) -> None:
        # A NaN or infinite reward or observation makes every weight NaN within a few updates: refuse it where it
        # enters the buffer, naming the agent and the timestep (SB3's VecCheckNan, for the data this loop stores)
        for what, values in (("reward", reward), ("observation", new_obs)):
            values = np.asarray(values)
            if values.dtype.kind == "f" and not np.isfinite(values).all():
                assert self.n_agents is not None and self.agent_names is not None
                row = int(np.flatnonzero(~np.isfinite(values.reshape(len(values), -1)).all(axis=1))[0])
                copy, agent = divmod(row, self.n_agents)
                raise ValueError(
                    f"the env returned a non-finite {what} ({_first_non_finite(values[row])}) for agent "
                    f"{self.agent_names[agent]!r} of env copy {copy} at timestep {self.num_timesteps}: fix the env "
                    "(SB3's VecCheckNan wrapper finds the step that produces it)"
                )
        super()._store_transition(replay_buffer, buffer_action, new_obs, reward, dones, infos)

    def _init_callback(self, callback: MaybeCallback, progress_bar: bool = False) -> BaseCallback:
        # As BaseAlgorithm._init_callback, with a progress bar that counts the team's timesteps, and the
        # environment's episode-end metrics (coverage, fairness, ...) logged in every run unless already asked for
        if isinstance(callback, list):
            callback = CallbackList(callback)
        if not isinstance(callback, BaseCallback):
            callback = ConvertCallback(callback)
        if not contains_callback(callback, EpisodeMetricsCallback):
            callback = CallbackList([callback, EpisodeMetricsCallback()])
        # SB3's progress bar (RL Zoo's -P) would count VecEnv rows; evaluations would count agent rows as episodes
        callback = _count_joint_steps(callback)
        evaluate_joint_episodes(callback)
        if progress_bar and not contains_callback(callback, JointStepProgressBarCallback):
            callback = CallbackList([callback, JointStepProgressBarCallback()])
        callback.init_callback(self)
        return callback

    def _setup_learn(
        self,
        total_timesteps: int,
        callback: MaybeCallback = None,
        reset_num_timesteps: bool = True,
        tb_log_name: str = "run",
        progress_bar: bool = False,
    ) -> tuple[int, BaseCallback]:
        assert self.env is not None, "You must set the environment before calling learn()"
        # A model loaded without an env gets its replay buffer when it is first trained
        if self.replay_buffer is None:
            self._make_replay_buffer()
        if isinstance(self.replay_buffer, DeviceReplayBuffer) and self._vec_normalize_env is not None:
            raise ValueError(
                "the device replay buffer (storage_device) does not normalise with VecNormalize; "
                "use the default replay buffer with a VecNormalize env"
            )
        # A saved per-row noise does not fit an env with another number of rows (load(path, env) with more copies)
        if isinstance(self.action_noise, VectorizedActionNoise) and self.action_noise.n_envs != self.env.num_envs:
            self.action_noise = RowBatchedActionNoise(self.action_noise.noises[0], self.env.num_envs)
        # One noise per VecEnv row, drawn in one call (SB3 would wrap it in VectorizedActionNoise, drawn row by row)
        noise = self.action_noise
        if noise is not None and self.env.num_envs > 1 and not isinstance(noise, VectorizedActionNoise):
            self.action_noise = RowBatchedActionNoise(self.action_noise, self.env.num_envs)
        return super()._setup_learn(total_timesteps, callback, reset_num_timesteps, tb_log_name, progress_bar)

    def learn(
        self: SelfMultiAgentOffPolicyAlgorithm,
        total_timesteps: int,
        callback: MaybeCallback = None,
        log_interval: int = 4,
        tb_log_name: str | None = None,
        reset_num_timesteps: bool = True,
        progress_bar: bool = False,
    ) -> SelfMultiAgentOffPolicyAlgorithm:
        """
        Train the model.

        :param total_timesteps: timesteps to train on (joint steps of one env copy; a lower bound, as in SB3)
        :param callback: callback(s) called at every VecEnv step
        :param log_interval: log every ``log_interval`` episodes (joint episodes of a copy)
        :param tb_log_name: the name of the run for TensorBoard logging (the algorithm's class name by default)
        :param reset_num_timesteps: whether or not to reset the current timestep number (used in logging)
        :param progress_bar: display a progress bar (in timesteps) using tqdm and rich
        :return: the trained model
        """
        check_int("total_timesteps", total_timesteps, 1)
        if log_interval is not None:
            check_int("log_interval (None: no logging)", log_interval, 1)
        with flushed_denormals(self.flush_denormals):
            return super().learn(
                total_timesteps=total_timesteps,
                callback=callback,
                log_interval=log_interval,
                tb_log_name=type(self).__name__ if tb_log_name is None else tb_log_name,
                reset_num_timesteps=reset_num_timesteps,
                progress_bar=progress_bar,
            )

    # ------------------------------------------------------------------------------------------------------------
    # Saving and loading
    # ------------------------------------------------------------------------------------------------------------

    def save(
        self,
        path: str | pathlib.Path | io.BufferedIOBase,
        exclude: Iterable[str] | None = None,
        include: Iterable[str] | None = None,
    ) -> None:
        """
        Save the model as SB3 does (a zip of the class parameters and the networks), atomically: it is written to a
        temporary file in the same folder and moved into place, so an interrupted save leaves the previous file whole.
        The random states (Python, NumPy, PyTorch, the action space, the env copies' last resets) are saved with it,
        and ``load`` restores them: see ``sb3_maddpg.common.random_state``.

        :param path: the file (``.zip`` is added when the name has no suffix), or an open binary file
        :param exclude: names of parameters to leave out, in addition to the default ones
        :param include: names of parameters to save although they are excluded by default
        """
        self._saved_random_states = capture_random_states(self)
        try:
            base_save = super().save
            atomic_save(lambda file: base_save(file, exclude=exclude, include=include), path, suffix="zip")
        finally:
            del self._saved_random_states

    @classmethod
    def load(  # type: ignore[override]
        cls: type[SelfMultiAgentOffPolicyAlgorithm],
        path: str | pathlib.Path | io.BufferedIOBase,
        env: GymEnv | None = None,
        device: th.device | str = "auto",
        custom_objects: dict[str, Any] | None = None,
        print_system_info: bool = False,
        force_reset: bool = True,
        **kwargs: Any,
    ) -> SelfMultiAgentOffPolicyAlgorithm:
        """
        Load a model saved by ``save`` (as SB3's ``load``), after checking that the file is an intact model of this
        library, without running code from it (see ``sb3_maddpg.common.model_files``), and restore the random states
        saved with it (the generators continue where they were when it was saved; call ``set_random_seed`` afterwards
        to reseed instead). With ``env``, the env must have the model's team.

        :param path: the model file (``.zip`` may be left out) or an open binary file
        :param env: the environment to act and learn on (None: only to predict)
        :param device: the device of the networks
        :param custom_objects: objects to use instead of the saved ones (as in SB3), e.g. a learning rate saved as code
        :param print_system_info: print the system info of the saved model and of this one
        :param force_reset: reset the env before the next ``learn`` (as in SB3)
        :param kwargs: attributes to change while loading (as in SB3)
        :return: the model
        :raises ValueError: if the file is not a model of this library or is damaged, or the env's team is not the model's
        """
        # Every pickled class parameter is read here, without running code (model_files.restricted_loads), and handed
        # to SB3 as custom_objects, so that SB3's load unpickles none; those that ``kwargs`` replace are not read.
        given = {**{key: value for key, value in kwargs.items() if key != "policy_kwargs"}, **(custom_objects or {})}
        custom_objects = read_maddpg_data(path, None, given, cls.saved_model_keys)  # type: ignore[arg-type]
        cls._check_saved_algorithm(custom_objects.get("policy_class"), path)
        try:
            model = super().load(path, env, device, custom_objects, print_system_info, force_reset, **kwargs)
        except READ_ERRORS as error:
            first_line = str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
            name = os.fspath(path) if isinstance(path, str | os.PathLike) else "the model file"
            raise ValueError(f"{name} is damaged or was saved by an incompatible version: {first_line}") from error
        states = model.__dict__.pop("_saved_random_states", None)
        if states is not None:
            restore_random_states(model, states)
        return model

    @classmethod
    def _check_saved_algorithm(cls, policy_class: Any, path: str | pathlib.Path | io.BufferedIOBase) -> None:
        """
        Refuse a model saved by another algorithm of this library: a MATD3 model loaded as MADDPG would lose its twin
        critics' delay and smoothing, a MADDPG model loaded as MATD3 would train on with one critic.

        :param policy_class: the saved policy class
        :param path: the model file, for the message
        :raises ValueError: naming both algorithms
        """
        saved = algorithm_of_policy(policy_class)
        if saved is None or saved.policy_aliases.get("MlpPolicy") is cls.policy_aliases.get("MlpPolicy"):
            return
        name = os.fspath(path) if isinstance(path, str | os.PathLike) else "the model file"
        raise ValueError(
            f"{name} is a {saved.__name__} model (its policy is {policy_class.__module__}.{policy_class.__qualname__}), "
            f"not a {cls.__name__} model: load it with {saved.__name__}.load (on the command line: "
            f"--algo {saved.__name__.lower()})"
        )

    def save_replay_buffer(self, path: str | pathlib.Path | io.BufferedIOBase) -> None:
        """
        Save the replay buffer as a pickle file, atomically (see ``save``).

        :param path: the file (``.pkl`` is added when the name has no suffix), or an open binary file
        """
        assert self.replay_buffer is not None, "The replay buffer is not defined"
        atomic_save(super().save_replay_buffer, path, suffix="pkl")  # type: ignore[arg-type]

    def load_replay_buffer(self, path: str | pathlib.Path | io.BufferedIOBase, truncate_last_traj: bool = True) -> None:
        """
        Load a replay buffer saved by ``save_replay_buffer``, after checking that it is whole (its fields agree with
        each other, its rewards are finite: ``MultiAgentReplayBuffer.check_loaded``) and fits this model: the same
        agents, observation shape and dtype, and action size. A buffer from another number of environment copies is laid
        out again for this model's copies (``MultiAgentReplayBuffer.with_copies``): every joint transition is kept,
        up to this model's ``buffer_size``.

        :param path: the pickle file, or an open binary file
        :param truncate_last_traj: unused (only for SB3's ``HerReplayBuffer``)
        :raises ValueError: if the buffer is damaged, or does not fit, naming its shapes and the model's
        """
        name = os.fspath(path) if isinstance(path, str | os.PathLike) else "the replay buffer file"
        try:
            # A pickle file: read without running code (only what a replay buffer of this library is made of)
            with open_path(path, "r", self.verbose, suffix="pkl") as file:
                buffer = restricted_loads(file.read())
        except (pickle.UnpicklingError, EOFError, AttributeError, ImportError) as error:
            raise ValueError(f"{name} is not a replay buffer that can be read here, or is damaged: {error}") from error
        self.replay_buffer = self._fit_replay_buffer(buffer, name)
        self.replay_buffer.device = self.device

    def _fit_replay_buffer(self, buffer: Any, name: str) -> MultiAgentReplayBuffer:
        """Check that a loaded buffer fits the model; lay it out for the model's number of copies."""
        if not isinstance(buffer, MultiAgentReplayBuffer):
            raise TypeError(f"{name} holds a {type(buffer).__name__}, not a MultiAgentReplayBuffer of joint transitions")
        buffer.check_loaded(name)
        assert self.n_agents is not None
        obs_shape, obs_dtype = tuple(self.observation_space.shape), self.observation_space.dtype  # type: ignore[arg-type]
        action_dim = action_width(self.action_space)
        buffer_dtype = np.dtype(buffer.observation_space.dtype)  # type: ignore[arg-type]
        found = (buffer.n_agents, tuple(buffer.obs_shape), buffer_dtype, buffer.action_dim)
        if found != (self.n_agents, obs_shape, obs_dtype, action_dim):
            raise ValueError(
                f"the replay buffer {name} holds joint transitions of {buffer.n_agents} agents with observations "
                f"{tuple(buffer.obs_shape)} {buffer_dtype} and actions ({buffer.action_dim},), but this "
                f"model has {self.n_agents} agents with observations {obs_shape} {obs_dtype} and actions ({action_dim},); "
                "load a buffer saved with the same env configuration"
            )
        n_copies = self.n_envs // self.n_agents
        # Another number of copies, or another buffer_size (e.g. -params buffer_size:... on resume): laid out again
        if buffer.n_copies != n_copies or buffer.buffer_size != max(self.buffer_size // n_copies, 1):
            if self.verbose >= 1:
                print(
                    f"Laying the replay buffer out again: {buffer.n_copies} environment copies -> {n_copies}, "
                    f"{buffer.buffer_size * buffer.n_copies} -> {self.buffer_size} joint transitions"
                )
            buffer = buffer.with_copies(n_copies, self.buffer_size)
        # Storage where this model keeps its buffer: on its device (storage_device) or in host memory
        assert self.replay_buffer_class is not None
        on_device = issubclass(self.replay_buffer_class, DeviceReplayBuffer)
        storage = self.replay_buffer_kwargs.get("storage_device", self.device) if on_device else None
        if isinstance(buffer, DeviceReplayBuffer) != on_device or (on_device and buffer.storage_device != storage):
            target = DeviceReplayBuffer if on_device else MultiAgentReplayBuffer
            buffer = target.from_buffer(buffer, storage_device=storage, device=self.device)
        return buffer
