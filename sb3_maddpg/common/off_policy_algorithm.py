"""The base of the multi-agent off-policy algorithms: SB3's ``OffPolicyAlgorithm`` for a team on one VecEnv.

What every multi-agent off-policy algorithm of this library needs and SB3 does not do lives here and in the two
mixins of its bases, so that an algorithm file (``maddpg/maddpg.py``, ``matd3/matd3.py``) holds only its arguments,
its networks, its losses and ``train``, as SB3's ``td3.py`` does:

- the team (``sb3_maddpg.common.team``): the number of agents and their names, read from the VecEnv of
  ``make_multiagent_vec_env`` (one row per agent and copy, row = copy * n_agents + agent), and the refusal of another
  team in ``predict``, ``set_env`` and ``load(env=...)``;
- the timestep (here): one joint step of one environment copy, so the rollout loop, the episode count and the
  progress bar count copies, not VecEnv rows;
- the joint replay buffer (here: host memory, or a torch device with ``replay_buffer_kwargs=dict(storage_device=...)``),
  its saving and loading, laid out again for another number of copies (``sb3_maddpg.common.saving``);
- atomic saves that carry the random states, so that a resumed run continues exactly (``sb3_maddpg.common.saving``).

Where it overrides SB3's own loop (``collect_rollouts``, ``_sample_action``, ``_init_callback``), the code follows
stable-baselines3 2.9's ``OffPolicyAlgorithm`` and ``BaseAlgorithm`` line for line apart from what is named in each
docstring; compare with those methods when upgrading SB3.
"""

import warnings
from typing import Any, ClassVar, TypeVar

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.buffers import ReplayBuffer
from stable_baselines3.common.callbacks import BaseCallback, CallbackList, ConvertCallback
from stable_baselines3.common.noise import ActionNoise, VectorizedActionNoise
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from stable_baselines3.common.policies import BasePolicy
from stable_baselines3.common.type_aliases import GymEnv, MaybeCallback, RolloutReturn, Schedule, TrainFreq, TrainFrequencyUnit
from stable_baselines3.common.utils import should_collect_more_steps
from stable_baselines3.common.vec_env import VecEnv

from sb3_maddpg.common.actions import SUPPORTED_ACTION_SPACES, is_discrete
from sb3_maddpg.common.agent_spaces import AgentSpaces
from sb3_maddpg.common.buffers import MultiAgentReplayBuffer
from sb3_maddpg.common.callbacks import (
    EpisodeMetricsCallback,
    JointStepProgressBarCallback,
    contains_callback,
    count_joint_steps,
)
from sb3_maddpg.common.denormals import flushed_denormals
from sb3_maddpg.common.device_buffer import DeviceReplayBuffer, resolve_storage_device
from sb3_maddpg.common.evaluation import evaluate_joint_episodes
from sb3_maddpg.common.noise import DecayingGaussianNoise, RowBatchedActionNoise, set_noise_timestep
from sb3_maddpg.common.saving import SavedMultiAgentModel
from sb3_maddpg.common.team import MultiAgentTeam, default_agent_names, first_non_finite
from sb3_maddpg.common.validation import (
    check_action_noise,
    check_bool,
    check_device,
    check_gradient_steps,
    check_int,
    check_learning_rate,
    check_number,
    check_optional_dict,
    check_policy_kwargs,
    check_replay_buffer_class,
    check_seed,
    check_tensorboard_log,
    check_train_freq,
    check_vec_env,
)

SelfMultiAgentOffPolicyAlgorithm = TypeVar("SelfMultiAgentOffPolicyAlgorithm", bound="MultiAgentOffPolicyAlgorithm")


class MultiAgentOffPolicyAlgorithm(MultiAgentTeam, SavedMultiAgentModel, OffPolicyAlgorithm):
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
        # Each argument that SB3's OffPolicyAlgorithm stores is checked as it is handed over (SB3 would accept some bad
        # values silently or fail deep inside); the ones this class stores, where it stores them
        name = type(self).__name__
        super().__init__(
            policy,
            check_vec_env(name, env),
            check_learning_rate("learning_rate", learning_rate),
            check_int("buffer_size", buffer_size, low=1),
            check_int("learning_starts", learning_starts, low=0),
            check_int("batch_size", batch_size, low=1),
            check_number("tau", tau, low=0.0, high=1.0),
            check_number("gamma", gamma, low=0.0, high=1.0),
            check_train_freq(train_freq),
            check_gradient_steps(gradient_steps),
            action_noise=check_action_noise(action_noise),
            replay_buffer_class=check_replay_buffer_class(name, replay_buffer_class),
            replay_buffer_kwargs=check_optional_dict("replay_buffer_kwargs", replay_buffer_kwargs),
            policy_kwargs=check_policy_kwargs(policy_kwargs),
            stats_window_size=check_int("stats_window_size", stats_window_size, low=1),
            tensorboard_log=check_tensorboard_log(tensorboard_log),
            verbose=check_int("verbose", verbose, low=0),
            device=check_device(device),
            seed=check_seed("seed", seed),
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
        self.flush_denormals = check_bool("flush_denormals", flush_denormals)
        self.n_agents: int | None = n_agents
        self.agent_names: list[str] | None = None
        # Each agent's own spaces where they differ (the VecEnv's are then padded); None when all agents share them
        self.agent_spaces: AgentSpaces | None = None
        self.departures = False
        if self.env is not None:
            self._read_agents(self.env, n_agents)
            self._check_action_noise(action_noise, self.env.num_envs)

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
        n_copies = self.n_copies

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

            # Update stats, reset the noise and log: one episode per copy
            num_collected_episodes += self._on_episode_ends(dones, action_noise, env.num_envs, log_interval)
        callback.on_rollout_end()

        return RolloutReturn(num_collected_steps * n_copies, num_collected_episodes, continue_training)

    def _on_episode_ends(
        self, dones: np.ndarray, action_noise: ActionNoise | None, n_rows: int, log_interval: int | None
    ) -> int:
        """
        The end-of-episode bookkeeping of SB3's ``collect_rollouts``, once per env copy whose episode ended (SB3 would
        do it once per agent row): the episode count, the reset of the copy's rows of the action noise, the logs.

        :param dones: the VecEnv step's done flags, one per row
        :param action_noise: action noise for exploration
        :param n_rows: number of VecEnv rows
        :param log_interval: log data every ``log_interval`` episodes
        :return: the number of episodes that ended
        """
        n_agents = self.n_agents
        assert n_agents is not None
        ended = np.flatnonzero(np.asarray(dones).reshape(self.n_copies, n_agents).any(axis=1))
        for copy in ended:
            self._episode_num += 1

            if action_noise is not None:
                kwargs = dict(indices=list(range(copy * n_agents, (copy + 1) * n_agents))) if n_rows > 1 else {}
                action_noise.reset(**kwargs)

            # Log training infos
            if log_interval is not None and self._episode_num % log_interval == 0:
                self.dump_logs()
        return len(ended)

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
                    f"the env returned a non-finite {what} ({first_non_finite(values[row])}) for agent "
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
        callback = count_joint_steps(callback)
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
        check_int("total_timesteps", total_timesteps, low=1)
        if log_interval is not None:
            check_int("log_interval (None: no logging)", log_interval, low=1)
        with flushed_denormals(self.flush_denormals):
            return super().learn(
                total_timesteps=total_timesteps,
                callback=callback,
                log_interval=log_interval,
                tb_log_name=type(self).__name__ if tb_log_name is None else tb_log_name,
                reset_num_timesteps=reset_num_timesteps,
                progress_bar=progress_bar,
            )
