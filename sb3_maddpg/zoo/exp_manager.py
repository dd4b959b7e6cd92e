"""RL Zoo's ``ExperimentManager`` and ``create_test_env`` taught to build multi-agent VecEnvs."""

import contextlib
import functools
import inspect
import os
import pickle
import re
import shutil
import socket
import warnings
from collections import OrderedDict
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from copy import deepcopy
from typing import Any

import numpy as np
import optuna
from gymnasium import spaces
from rl_zoo3.exp_manager import ExperimentManager
from rl_zoo3.hyperparams_opt import HYPERPARAMS_CONVERTER
from rl_zoo3.utils import ALGOS
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import CheckpointCallback, EvalCallback
from stable_baselines3.common.vec_env import VecEnv

from sb3_maddpg.common.atomic import atomic_save
from sb3_maddpg.common.callbacks import EpisodeMetricsCallback
from sb3_maddpg.common.eval_tensorboard import EvalTensorBoardCallback
from sb3_maddpg.common.hparams import HParamsCallback
from sb3_maddpg.common.off_policy_algorithm import MultiAgentOffPolicyAlgorithm
from sb3_maddpg.zoo.monitor import JointEpisodeMonitor
from sb3_maddpg.zoo.registry import (
    EXIT_ENV_WORKER_ENDED,
    TrainingStopped,
    UsageError,
    is_multiagent_env,
    make_multiagent_env,
)
from sb3_maddpg.zoo.run_files import load_vec_normalize, read_as_data
from sb3_maddpg.zoo.storage import (
    HEARTBEAT_GRACE_S,
    HEARTBEAT_INTERVAL_S,
    MAX_RETRY,
    beyond_max_total_trials,
    create_shared_study,
    fail_dead_workers_trials,
    is_database_url,
    mask_password,
)
from sb3_maddpg.zoo.vec_envs import make_zoo_multiagent_vec_env, wrap_like_rl_zoo

# Keys of an RL Zoo YAML entry that RL Zoo consumes itself; every other key is an argument of the algorithm.
ZOO_KEYS = frozenset(
    {
        "n_timesteps",
        "n_envs",
        "env_kwargs",
        "normalize",
        "frame_stack",
        "env_wrapper",
        "vec_env_wrapper",
        "callback",
        "monitor_kwargs",
        "noise_type",
        "noise_std",
        # with noise_type "decaying-normal" (MADDPG's decaying Gaussian noise, docs/algorithm.md, "6. Exploration noise")
        "noise_final_std",
        "noise_decay",
    }
)
DECAYING_NOISE = "decaying-normal"
# Algorithm arguments RL Zoo passes itself, so a YAML entry must not.
_RESERVED_ALGO_ARGS = frozenset({"self", "env", "tensorboard_log", "seed", "verbose", "device", "_init_setup_model"})


def accepted_hyperparameters(algo_class: type[BaseAlgorithm]) -> set[str]:
    """
    The keys a YAML entry may hold for an algorithm.

    :param algo_class: the algorithm
    :return: RL Zoo's own keys and the algorithm's constructor arguments
    """
    parameters = inspect.signature(algo_class.__init__).parameters
    return set(ZOO_KEYS) | {name for name in parameters if name not in _RESERVED_ALGO_ARGS}


def check_hyperparameter_keys(hyperparams: dict[str, Any], algo: str, where: str) -> None:
    """
    Raise a :class:`UsageError` naming any key the algorithm would not accept (instead of a ``TypeError`` deep
    inside its constructor).

    :param hyperparams: the YAML entry, possibly updated by ``-params``
    :param algo: the RL Zoo algorithm name
    :param where: where the entry comes from, for the message
    """
    algo_class = ALGOS[algo]
    if any(kind.kind == inspect.Parameter.VAR_KEYWORD for kind in inspect.signature(algo_class.__init__).parameters.values()):
        return
    accepted = accepted_hyperparameters(algo_class)
    unknown = sorted(set(hyperparams) - accepted)
    if unknown:
        raise UsageError(
            f"unknown hyperparameter(s) {', '.join(map(repr, unknown))} for {algo} in {where}; "
            f"accepted keys: {', '.join(sorted(accepted))}"
        )


def check_zoo_values(hyperparams: dict[str, Any], where: str, n_timesteps_given: bool = False) -> None:
    """
    Raise a :class:`UsageError` naming a YAML value RL Zoo would take without a word (``n_timesteps: 0`` trains
    nothing) or fail on with an unrelated error (``n_envs: 0``: ZeroDivisionError; ``learning_rate: "fast"``: "not
    enough values to unpack"). The algorithm checks its own arguments.

    :param hyperparams: the YAML entry, possibly updated by ``-params``
    :param where: where the entry comes from, for the message
    :param n_timesteps_given: whether ``-n`` replaces the entry's ``n_timesteps``
    """
    n_timesteps = hyperparams.get("n_timesteps")
    if not n_timesteps_given and n_timesteps is not None:
        if isinstance(n_timesteps, bool) or not isinstance(n_timesteps, int | float) or not n_timesteps >= 1:
            raise UsageError(f"n_timesteps must be a positive number of timesteps, got {n_timesteps!r} in {where}")
    n_envs = hyperparams.get("n_envs", 1)
    if isinstance(n_envs, bool) or not isinstance(n_envs, int) or n_envs < 1:
        raise UsageError(f"n_envs must be an integer >= 1 (environment copies), got {n_envs!r} in {where}")
    learning_rate = hyperparams.get("learning_rate")
    if isinstance(learning_rate, str) and not re.fullmatch(r"lin_(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?", learning_rate):
        raise UsageError(
            "learning_rate must be a number or 'lin_<initial value>' (RL Zoo's linear schedule, e.g. lin_0.001), "
            f"got {learning_rate!r} in {where}"
        )


class ZooRDBStorage(optuna.storages.RDBStorage):
    """
    Optuna's ``RDBStorage`` with the heartbeat of running trials: a trial whose worker died (killed, out of memory, a
    node lost) stops beating, is failed after the grace period and its parameters are tried again
    (``RetryHeartbeatStaleTrialCallback``), instead of staying RUNNING and counting towards ``--max-total-trials`` for ever.
    RL Zoo's ``hyperparameters_optimization`` takes it where it expects a storage string (it only asks
    ``storage.endswith(".log")``), and it is pickled without the URL's password (RL Zoo pickles the study, with its
    storage, into ``report_*.pkl``).

    :param url: a SQLAlchemy database URL
    """

    def __init__(self, url: str) -> None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)  # Optuna's heartbeat API
            retry = optuna.storages.RetryHeartbeatStaleTrialCallback(max_retry=MAX_RETRY)
        super().__init__(
            url, heartbeat_interval=HEARTBEAT_INTERVAL_S, grace_period=HEARTBEAT_GRACE_S, heartbeat_stale_trial_callback=retry
        )

    def endswith(self, suffix: str) -> bool:
        return False

    def __getstate__(self) -> dict[str, Any]:
        state = super().__getstate__()
        state["url"] = mask_password(state["url"])
        return state


class MultiAgentExperimentManager(ExperimentManager):
    """
    RL Zoo's experiment manager (train and Optuna search) for multi-agent envs registered with
    :func:`~sb3_maddpg.zoo.registry.register_multiagent_env`: it builds their VecEnv with ``make_multiagent_vec_env``
    (``n_envs`` copies of the env, ``n_agents`` rows each) and writes one ``monitor.csv`` line per joint episode.
    Everything else (hyperparameters, schedules, callbacks, checkpoints, evaluation, saving, Optuna) is RL Zoo's.
    Single-agent Gymnasium envs go through RL Zoo's own code unchanged.

    With ``-tb``, a trained run also writes its hyperparameters (TensorBoard's HPARAMS tab) and, after each evaluation
    on a multi-agent env, the evaluation's episode-end metrics and, on a task that can draw itself (the UAV envs), the
    pictures of :class:`~sb3_maddpg.common.eval_tensorboard.EvalTensorBoardCallback` (``eval_images``, ``eval_video``).
    """

    #: Draw the task's picture after each evaluation, on the UAV envs the coverage heat map (``train --no-eval-images``
    #: turns it off)
    eval_images: bool = True
    #: Record a video of one evaluation episode (``train --eval-video``)
    eval_video: bool = False

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        # The Optuna trials this process has run (a shared study also holds other workers')
        self._worker_trials: list[Any] = []
        # Why training stopped before its end (an env worker process that ended), once the model is saved
        self._stopped: str | None = None
        if self.optimize_hyperparameters and self.n_jobs > 1:
            # Optuna would run the trials as threads of this one manager, which holds each trial's state
            # (hyperparameters, action noise, envs) in its attributes: the trials would overwrite each other's.
            raise UsageError(
                f"--n-jobs {self.n_jobs}: trials would run as threads sharing one experiment manager; run several "
                "processes instead, each with --n-jobs 1 and the same --storage and --study-name (they share the study)"
            )

    def read_hyperparameters(self) -> tuple[dict[str, Any], dict[str, Any]]:
        if not os.path.isfile(self.config) and (self.config.endswith(".yml") or self.config.endswith(".yaml")):
            raise UsageError(f"config file {self.config} not found")
        # RL Zoo applies --trial-id only when it is truthy (trial 0 was ignored) and ends in a traceback for a missing
        # study or trial: the trial's parameters are read here, between the YAML entry's and -params'.
        trial_id, self.trial_id = self.trial_id, None
        try:
            hyperparams, saved_hyperparams = super().read_hyperparameters()
        except ValueError as error:
            # "Hyperparameters not found for <algo>-<env> in <config>"
            raise UsageError(str(error)) from error
        finally:
            self.trial_id = trial_id
        if trial_id is not None:
            hyperparams = {**hyperparams, **self._trial_hyperparameters(trial_id), **(self.custom_hyperparams or {})}
            saved_hyperparams = OrderedDict((key, hyperparams[key]) for key in sorted(hyperparams))
        where = f"the entry {self.env_name.gym_id!r} of {self.config} (or -params)"
        check_hyperparameter_keys(hyperparams, self.algo, where)
        check_zoo_values(hyperparams, where, n_timesteps_given=self.n_timesteps > 0)
        if "env_wrapper" in hyperparams and is_multiagent_env(self.env_name.gym_id):
            # RL Zoo would take it and never use it: make_multiagent_vec_env builds the env, not gym.make
            raise UsageError(
                f"env_wrapper wraps a single-agent Gymnasium env and would have no effect on the multi-agent env "
                f"{self.env_name.gym_id} (in {where}); remove it, or wrap the VecEnv with vec_env_wrapper"
            )
        return hyperparams, saved_hyperparams

    def _trial_hyperparameters(self, trial_id: int) -> dict[str, Any]:
        """The hyperparameters of trial ``trial_id`` of ``--study-name`` in ``--storage`` (``train --trial-id``)."""
        if not self.storage or not self.study_name:
            raise UsageError(f"--trial-id {trial_id} needs the study's --storage and --study-name")
        where = f"study {self.study_name!r} in {mask_password(self.storage)}"
        storage: Any = self.storage
        if storage.endswith(".log"):
            storage = optuna.storages.JournalStorage(optuna.storages.journal.JournalFileBackend(storage))
        try:
            study = optuna.load_study(storage=storage, study_name=self.study_name)
        except KeyError as error:
            raise UsageError(f"--study-name: there is no {where}") from error
        numbers = [trial.number for trial in study.get_trials(deepcopy=False)]
        if trial_id not in numbers:
            shown = f"trials 0 to {max(numbers)}" if numbers else "no trials"
            raise UsageError(f"--trial-id {trial_id}: the {where} has {shown}")
        params = study.trials[numbers.index(trial_id)].params
        print(f"Loading the hyperparameters of trial {trial_id} of {where}")
        # A study may come from someone else (a shared database): its parameters are data, never code RL Zoo evaluates
        return read_as_data(HYPERPARAMS_CONVERTER[self.algo](params), f"trial {trial_id} of the {where}")

    def _save_config(self, saved_hyperparams: dict[str, Any]) -> None:
        # The --storage password is not written into args.yml (command.txt gets the masked command line, see run_train)
        storage = getattr(self.args, "storage", None)
        if isinstance(storage, str):
            self.args.storage = mask_password(storage)
        try:
            super()._save_config(saved_hyperparams)
        finally:
            if isinstance(storage, str):
                self.args.storage = storage

    def setup_experiment(self) -> tuple[BaseAlgorithm, dict[str, Any]] | None:
        # RL Zoo creates the run folder before it builds the algorithm: a refused value must not leave it behind
        folder_existed = os.path.exists(self.save_path)
        try:
            result = super().setup_experiment()
            if result is not None:
                self._check_eval_env(result[0])
                self.callbacks.append(HParamsCallback(self.run_hyperparameters(result[1])))
            return result
        except (ValueError, TypeError) as error:
            if not folder_existed:
                shutil.rmtree(self.save_path, ignore_errors=True)
            if isinstance(error, UsageError):
                raise
            # A hyperparameter value the algorithm refuses (e.g. cvar_alpha: 2.0): its own message, no traceback
            raise UsageError(f"{self.algo} on {self.env_name.gym_id}: {error}") from error

    def create_log_folder(self) -> None:
        # RL Zoo numbers the run folder in __init__ (the latest number + 1) and creates it with exist_ok=True, so runs
        # started together on one log folder would share (and overwrite) one folder. Take the number with mkdir,
        # which fails when another run has taken it, and move on to the next.
        os.makedirs(self.log_path, exist_ok=True)
        prefix = os.path.join(self.log_path, f"{self.env_name}_")
        number, suffix = re.fullmatch(r"(\d+)(.*)", self.save_path[len(prefix) :]).groups()  # type: ignore[union-attr]
        number = int(number)
        while True:
            try:
                os.mkdir(self.save_path)
                break
            except FileExistsError:
                number += 1
                self.save_path = f"{prefix}{number}{suffix}"
                self.params_path = f"{self.save_path}/{self.env_name}"
        os.makedirs(self.params_path, exist_ok=True)

    def run_hyperparameters(self, saved_hyperparams: dict[str, Any]) -> dict[str, Any]:
        """
        What TensorBoard's HPARAMS tab shows of a run: the algorithm, the env, the seed, the YAML entry as trained
        (``config.yml``: after ``-params``, with its ``env_kwargs``), the timesteps and, for ``--trial-id``, the study.

        :param saved_hyperparams: the entry as RL Zoo saves it
        :return: name -> value
        """
        hyperparams: dict[str, Any] = {"algo": self.algo, "env": self.env_name.gym_id, "seed": self.seed}
        hyperparams.update(saved_hyperparams)
        hyperparams["n_timesteps"] = self.n_timesteps
        hyperparams["env_kwargs"] = dict(self.env_kwargs)
        if self.trial_id is not None:
            hyperparams.update({"study_name": self.study_name, "trial_id": self.trial_id})
        return hyperparams

    def _check_eval_env(self, model: BaseAlgorithm) -> None:
        """
        Refuse, before training, an evaluation env the model cannot act on (e.g. ``--eval-env-kwargs`` with another
        number of agents or observation size), which would otherwise fail at the first evaluation.
        """
        for callback in self.callbacks:
            if not isinstance(callback, EvalCallback):
                continue
            eval_env = callback.eval_env
            found = (eval_env.observation_space, eval_env.action_space, getattr(eval_env, "n_agents", None))
            expected = (model.observation_space, model.action_space, getattr(model, "n_agents", None))
            if found != expected:
                raise UsageError(
                    f"--eval-env-kwargs: the evaluation env has {found[2]} agents, observations {found[0]} and actions "
                    f"{found[1]}, but the model trains on {expected[2]} agents, observations {expected[0]} and actions "
                    f"{expected[1]}; give the evaluation env the training env's team and spaces"
                )

    def _load_pretrained_agent(self, hyperparams: dict[str, Any], env: VecEnv) -> BaseAlgorithm:
        # A resumed run keeps the saved action noise, whose schedule has advanced with the saved run (RL Zoo would pass
        # the YAML's, restarting the decay); the rest of the YAML entry applies as in RL Zoo.
        if "action_noise" in hyperparams:
            hyperparams = {key: value for key, value in hyperparams.items() if key != "action_noise"}
            print("Resuming: the saved action noise continues its schedule (the YAML's noise settings are not used)")
        # RL Zoo loads <folder>/replay_buffer.pkl beside any model it resumes, the final buffer into a checkpoint too;
        # here only the buffer saved with that model: replay_buffer.pkl with the final model, and
        # rl_model_replay_buffer_<N>_steps.pkl with the checkpoint rl_model_<N>_steps.zip.
        folder, name = os.path.split(self.trained_agent)
        checkpoint = re.fullmatch(r"(.*)_(\d+)_steps\.zip", name)
        buffer = f"{checkpoint.group(1)}_replay_buffer_{checkpoint.group(2)}_steps.pkl" if checkpoint else "replay_buffer.pkl"
        own = name == f"{self.env_name}.zip" or checkpoint is not None
        buffer_path = os.path.join(folder, buffer)
        print("Loading pretrained agent")
        model = ALGOS[self.algo].load(
            self.trained_agent,
            env=env,
            seed=self.seed,
            tensorboard_log=self.tensorboard_log,
            verbose=self.verbose,
            device=self.device,
            **{key: value for key, value in hyperparams.items() if key not in ("policy", "policy_kwargs")},
        )
        if own and os.path.exists(buffer_path):
            print(f"Loading the replay buffer saved with this model: {buffer_path}")
            model.load_replay_buffer(buffer_path, truncate_last_traj=self.truncate_last_trajectory)
        elif os.path.exists(os.path.join(folder, "replay_buffer.pkl")):
            print(f"Not loading {os.path.join(folder, 'replay_buffer.pkl')}: it was saved with the final model, not {name}")
        return model

    def learn(self, model: BaseAlgorithm) -> None:
        # A resumed run (-i model.zip) continues the saved run's timestep counter (learning_starts, schedules,
        # TensorBoard's x-axis) and trains n_timesteps more, instead of starting again at 0.
        try:
            super().learn(_ContinuedLearning(model) if self.continue_training else model)  # type: ignore[arg-type]
        except (EOFError, ConnectionError) as error:
            # An env worker process ended (killed, out of memory): stop as Ctrl-C does, save what was learnt (RL Zoo's
            # save_trained_model follows), then end with EXIT_ENV_WORKER_ENDED
            self._stopped = (
                f"An env worker process ended ({type(error).__name__}: {error}): training stopped at timestep "
                f"{model.num_timesteps}; the model is saved"
            )
            print(self._stopped)

    def _maybe_normalize(self, env: VecEnv, eval_env: bool) -> VecEnv:
        # RL Zoo unpickles <folder of -i>/<env>/vecnormalize.pkl (also without -i: ./<env>/vecnormalize.pkl); here it is
        # read with the restricted unpickler, and only beside the model given with -i
        path = os.path.join(os.path.dirname(self.trained_agent), str(self.env_name), "vecnormalize.pkl")
        if not (self.trained_agent and os.path.exists(path)):
            with _no_saved_statistics(self):
                return super()._maybe_normalize(env, eval_env)
        print("Loading saved VecNormalize stats")
        env = load_vec_normalize(path, env)
        if eval_env:
            # Deactivate training and reward normalization
            env.training = False
            env.norm_reward = False
        return env

    def save_trained_model(self, model: BaseAlgorithm) -> None:
        # As RL Zoo's, with every file written atomically (MADDPG's own saves are; other algorithms' are made so here)
        print(f"Saving to {self.save_path}")
        atomic_save(model.save, f"{self.save_path}/{self.env_name}", suffix="zip")
        if hasattr(model, "save_replay_buffer") and self.save_replay_buffer:
            print("Saving replay buffer")
            atomic_save(model.save_replay_buffer, os.path.join(self.save_path, "replay_buffer.pkl"), suffix="pkl")
        if self.normalize:
            # Important: save the running average, for testing the agent we need that normalization
            vec_normalize = model.get_vec_normalize_env()
            assert vec_normalize is not None
            atomic_save(lambda file: pickle.dump(vec_normalize, file), os.path.join(self.params_path, "vecnormalize.pkl"))
        if self._stopped is not None:
            raise TrainingStopped(self._stopped, EXIT_ENV_WORKER_ENDED)

    def _preprocess_hyperparams(
        self, hyperparams: dict[str, Any]
    ) -> tuple[dict[str, Any], Callable | None, list, Callable | None]:
        try:
            processed = super()._preprocess_hyperparams(hyperparams)
        except (KeyError, SyntaxError, NameError) as error:
            # a missing n_timesteps, or a policy_kwargs string that does not evaluate
            raise UsageError(f"bad entry {self.env_name.gym_id!r} in {self.config}: {error!r}") from error
        # RL Zoo moves the entry's env_kwargs into self.env_kwargs here but leaves the evaluation env with the
        # kwargs given on the command line (none, unless --env-kwargs or --eval-env-kwargs was used): evaluation
        # episodes would run another configuration (other lengths, even other spaces) than training.
        if self._eval_env_kwargs_args is None:
            self.eval_env_kwargs = self.env_kwargs
        return processed

    def _preprocess_action_noise(
        self, hyperparams: dict[str, Any], saved_hyperparams: dict[str, Any], env: VecEnv
    ) -> dict[str, Any]:
        # RL Zoo knows "normal" and "ornstein-uhlenbeck"; "decaying-normal" is the report's schedule
        # (noise_std decaying geometrically towards noise_final_std by noise_decay per timestep).
        if "noise_type" in hyperparams and isinstance(env.action_space, spaces.Discrete):
            raise UsageError(
                f"noise_type applies to continuous (Box) actions; {self.env_name.gym_id} has {env.action_space} actions, "
                f"which explore by sampling the actors' logits: remove noise_type and the noise settings (in {self.config})"
            )
        if hyperparams.get("noise_type") == DECAYING_NOISE:
            from sb3_maddpg.common.noise import DecayingGaussianNoise

            hyperparams = dict(hyperparams)
            del hyperparams["noise_type"]
            n_actions = env.action_space.shape[0]
            kwargs = {"sigma": hyperparams.pop("noise_std", 1.0), "final_sigma": hyperparams.pop("noise_final_std", 0.1)}
            if "noise_decay" in hyperparams:
                kwargs["decay"] = hyperparams.pop("noise_decay")
            try:
                hyperparams["action_noise"] = DecayingGaussianNoise(mean=np.zeros(n_actions), **kwargs)
            except ValueError as error:
                raise UsageError(f"bad noise settings in {self.config}: {error}") from error
            print(f"Applying {DECAYING_NOISE} noise {hyperparams['action_noise']}")
        for key in ("noise_final_std", "noise_decay"):
            if key in hyperparams:
                raise UsageError(f"{key} applies only with noise_type: {DECAYING_NOISE} (in {self.config})")
        return super()._preprocess_action_noise(hyperparams, saved_hyperparams, env)

    @property
    def worker_name(self) -> str:
        """This process in a shared study: ``host:pid``, stored in each trial's ``worker`` user attribute."""
        return f"{socket.gethostname()}:{os.getpid()}"

    def hyperparameters_optimization(self) -> None:
        # Workers started together on a database storage would race to create Optuna's tables and the study, and all
        # but one could crash; create (or load) the study here, safely, so that RL Zoo's create_study only loads it.
        url = self.storage
        if is_database_url(url):
            create_shared_study(url, self.study_name)
            # Opened once the tables exist (building an RDBStorage creates them: the race create_shared_study retries)
            self.storage = ZooRDBStorage(url)  # type: ignore[assignment]
            study = optuna.load_study(storage=self.storage, study_name=self.study_name)
            # A dead worker's trial is failed (and retried) now, before RL Zoo counts the RUNNING trials
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
                optuna.storages.fail_stale_trials(study)
        elif url is not None and url.endswith(".log") and os.path.isfile(url):
            # A journal file keeps no heartbeat: the trials of workers of this machine that died are failed here
            journal = optuna.storages.JournalStorage(optuna.storages.journal.JournalFileBackend(url))
            with contextlib.suppress(KeyError):  # no study of that name yet
                fail_dead_workers_trials(optuna.load_study(storage=journal, study_name=self.study_name))
        self._worker_trials = []
        try:
            super().hyperparameters_optimization()
        except ValueError as error:
            # RL Zoo asks for the best trial even when none has completed (every trial of the study pruned or failed,
            # or SIGTERM during the first): Optuna's in-memory storage says so, its database storage "Record does not
            # exist."
            if not any(message in str(error) for message in ("No trials are completed yet", "Record does not exist")):
                raise
            print(f"No trial of the study {self.study_name!r} has completed yet (all were pruned or failed): no best trial")
        finally:
            self.storage = url
        self._report_worker_trials()

    def _report_worker_trials(self) -> None:
        """Print the trials this worker ran, as they are in the study now (RL Zoo prints the study's best trial)."""
        if not self._worker_trials:
            print(f"Trials run by this worker ({self.worker_name}): none (--max-total-trials was reached)")
            return
        study = self._worker_trials[0].study
        numbers = {trial.number for trial in self._worker_trials}
        trials = [trial for trial in study.get_trials(deepcopy=False) if trial.number in numbers]
        print(f"Trials run by this worker ({self.worker_name}): {len(trials)} of the study's {len(study.trials)}")
        for trial in trials:
            note = f" (not run: {trial.user_attrs['not_run']})" if "not_run" in trial.user_attrs else ""
            print(f"    trial {trial.number}: {trial.state.name}{note} value={trial.value} params={trial.params}")

    def objective(self, trial: Any) -> float:
        self._worker_trials.append(trial)
        trial.set_user_attr("worker", self.worker_name)
        if isinstance(trial.study._storage, optuna.storages.JournalStorage):
            # Before counting the running trials: those of workers that died since this one started are not running
            fail_dead_workers_trials(trial.study)
        if beyond_max_total_trials(trial, self.max_total_trials):
            # Not run: recorded as failed (a NaN value), which RL Zoo's count leaves out, and this worker stops
            trial.set_user_attr("not_run", f"--max-total-trials {self.max_total_trials} reached by other workers")
            trial.study.stop()
            return float("nan")
        # Each trial gets a fresh copy of the YAML's action noise: the decaying noise counts its calls, and a shared
        # object would start every trial after the first with the previous trials' decay.
        noise = self._hyperparams.get("action_noise")
        if noise is None:
            return super().objective(trial)
        self._hyperparams["action_noise"] = deepcopy(noise)
        try:
            return super().objective(trial)
        finally:
            self._hyperparams["action_noise"] = noise

    def create_callbacks(self) -> None:
        super().create_callbacks()
        if is_multiagent_env(self.env_name.gym_id):
            # The env's declared episode-end metrics in TensorBoard next to SB3's scalars (the library's
            # algorithms add this callback themselves; other algorithms trained on a multi-agent env get it here).
            if not issubclass(ALGOS[self.algo], MultiAgentOffPolicyAlgorithm):
                self.callbacks.append(EpisodeMetricsCallback())
            for callback in self.callbacks:
                if isinstance(callback, CheckpointCallback):
                    # --save-replay-buffer: each checkpoint with its buffer (rl_model_replay_buffer_<N>_steps.pkl),
                    # so that a run stopped at a time limit resumes from the checkpoint with its experience
                    callback.save_replay_buffer = self.save_replay_buffer
                if isinstance(callback, EvalCallback):
                    # evaluate_policy asks for a Monitor; without one it counts each agent row's return, which is
                    # what it should report here (the mean return of an agent), so the warning is noise.
                    callback.warn = False
                    if callback.callback is None:
                        self._add_eval_tensorboard(callback)

    def _add_eval_tensorboard(self, eval_callback: EvalCallback) -> None:
        """After each evaluation, its metrics and pictures in TensorBoard (RL Zoo's EvalCallback has no after-eval one)."""
        drawn = self.eval_images or self.eval_video
        make_env = functools.partial(make_multiagent_env, self.env_name.gym_id, **self.eval_env_kwargs) if drawn else None
        after_eval = EvalTensorBoardCallback(
            make_env, images=self.eval_images, video=self.eval_video, seed=self.seed, verbose=self.verbose
        )
        # What EvalCallback(callback_after_eval=...) does when it is given one
        eval_callback.callback = after_eval
        after_eval.parent = eval_callback

    def create_envs(self, n_envs: int, eval_env: bool = False, no_log: bool = False) -> VecEnv:
        if not is_multiagent_env(self.env_name.gym_id):
            return super().create_envs(n_envs, eval_env=eval_env, no_log=no_log)

        # Do not log the eval env: it would write into the same file
        log_dir = None if eval_env or no_log else self.save_path
        env_kwargs = self.eval_env_kwargs if eval_env else self.env_kwargs
        env = make_zoo_multiagent_vec_env(self.env_name.gym_id, n_envs, self.seed, env_kwargs, self.vec_env_class)
        # Wrapped also without a file, so that training and evaluation envs have the same type (EvalCallback checks)
        env = JointEpisodeMonitor(env, None if log_dir is None else os.path.join(log_dir, "monitor.csv"))
        return wrap_like_rl_zoo(
            env, self.vec_env_wrapper, self.frame_stack, lambda venv: self._maybe_normalize(venv, eval_env)
        )


@contextmanager
def _no_saved_statistics(manager: ExperimentManager) -> Iterator[None]:
    """
    RL Zoo's ``_maybe_normalize`` looks for saved statistics beside ``trained_agent`` (beside ``""``: in the current
    folder): it sees ``os.devnull`` instead, a file with no statistics beside it, while it runs.

    :param manager: the experiment manager
    """
    trained_agent, manager.trained_agent = manager.trained_agent, os.devnull
    try:
        yield
    finally:
        manager.trained_agent = trained_agent


class _ContinuedLearning:
    """
    The model as RL Zoo's ``ExperimentManager.learn`` sees it when a run is resumed: ``learn`` continues the model's
    timestep counter (``reset_num_timesteps=False``); every other attribute is the model's.

    :param model: the loaded model
    """

    def __init__(self, model: BaseAlgorithm) -> None:
        self._model = model

    def learn(self, total_timesteps: int, **kwargs: Any) -> BaseAlgorithm:
        return self._model.learn(total_timesteps, reset_num_timesteps=False, **kwargs)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._model, name)
