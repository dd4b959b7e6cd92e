"""
The multi-agent environments the command line knows, by RL Zoo env id.

RL Zoo looks env ids up in Gymnasium's registry (``--env`` is checked there, ``is_atari`` reads the entry point), but
a PettingZoo ``ParallelEnv`` is not a ``gymnasium.Env``: :func:`register_multiagent_env` keeps the real constructor
here and puts a placeholder into Gymnasium's registry whose ``gym.make`` explains how the env is built instead.

The library registers MPE2's tasks itself; a task package registers its own ids through the entry-point group
``sb3_maddpg.envs`` of its distribution (:data:`ENV_ENTRY_POINT_GROUP`), which :func:`load_env_packages` reads once,
when an id is first looked up or registered: installing a task package is all it takes, with no change here. A module
imported with ``--gym-packages`` may also call :func:`register_multiagent_env` itself.
"""

import functools
import importlib
import warnings
from collections.abc import Callable, Iterator, MutableMapping
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
from pettingzoo import ParallelEnv


class UsageError(ValueError):
    """Bad input from the user (config, env id, env kwargs, paths): the command line prints it without a traceback."""


# Exit statuses of a train or optimize run stopped before its end, after its final save: a scheduler can tell them
# from a finished run (status 0). SIGTERM's is the shell's status of a process ended by SIGTERM (128 + 15).
EXIT_SIGTERM = 143
EXIT_ENV_WORKER_ENDED = 3


class TrainingStopped(Exception):
    """
    A ``train`` or ``optimize`` run stopped before its end (SIGTERM, an env worker process that ended), once the
    model (or the study's report) is saved: the command prints the message and exits with ``exit_status``.

    :param message: what stopped the run
    :param exit_status: ``EXIT_SIGTERM`` or ``EXIT_ENV_WORKER_ENDED``
    """

    def __init__(self, message: str, exit_status: int) -> None:
        super().__init__(message)
        self.exit_status = exit_status


@dataclass(frozen=True)
class MultiAgentEnvSpec:
    """
    How to build one multi-agent env id.

    :param env_id: the id used with ``--env`` and as the key of the YAML entries
    :param entry_point: a ``ParallelEnv`` constructor, or its ``"module:attribute"`` path (imported when first used,
        so optional packages such as ``mpe2`` are needed only by the envs that use them)
    :param kwargs: default constructor arguments; the YAML's ``env_kwargs`` and ``--env-kwargs`` override them
    """

    env_id: str
    entry_point: str | Callable[..., ParallelEnv]
    kwargs: dict[str, Any] = field(default_factory=dict)

    def constructor(self) -> Callable[..., ParallelEnv]:
        """
        :return: the ``ParallelEnv`` constructor
        """
        if callable(self.entry_point):
            return self.entry_point
        module_name, _, attribute = self.entry_point.partition(":")
        try:
            module = importlib.import_module(module_name)
        except ImportError as error:
            raise ImportError(
                f"The env {self.env_id!r} needs the package of {module_name!r} ({error}); "
                'install the zoo extra: pip install "sb3_maddpg[zoo]" (from a clone: pip install -e ".[zoo]")'
            ) from error
        return getattr(module, attribute)

    def env_fn(self) -> Callable[..., ParallelEnv]:
        """
        :return: a constructor taking keyword arguments, with this spec's defaults applied first
        """
        # functools.partial: call-time keyword arguments override the defaults, and it pickles (for worker processes)
        return functools.partial(self.constructor(), **self.kwargs)

    def make(self, **kwargs: Any) -> ParallelEnv:
        """
        :param kwargs: constructor arguments over the spec's defaults
        :return: a new ``ParallelEnv``
        """
        return self.env_fn()(**kwargs)


class _NotAGymEnv:
    """Gymnasium entry point of a multi-agent env id: ``gym.make`` cannot build a PettingZoo env, so say how."""

    def __init__(self, env_id: str) -> None:
        self.env_id = env_id

    def __call__(self, **kwargs: Any) -> gym.Env:
        raise TypeError(
            f"{self.env_id!r} is a PettingZoo multi-agent env, not a Gymnasium env: build it with "
            f"sb3_maddpg.zoo.make_multiagent_env({self.env_id!r}) or sb3_maddpg.make_multiagent_vec_env"
        )

    def __repr__(self) -> str:
        return f"sb3_maddpg.zoo.registry:{self.env_id}"


#: The entry-point group of the task packages: each entry names a function of one argument, which it calls with
#: :func:`register_multiagent_env` once per env id of its package, e.g. in the package's setup.cfg::
#:
#:     [options.entry_points]
#:     sb3_maddpg.envs =
#:         my_tasks = my_tasks.registration:register_envs
ENV_ENTRY_POINT_GROUP = "sb3_maddpg.envs"
# The env ids the commands fall back on: train, optimize, enjoy, record-video, push-to-hub and load-from-hub without
# --env (the quick start's CPU configuration), and evaluate and select-checkpoint without --env or a model's run (the
# report's task); both are the UAV coverage task package's (sb3_maddpg_envs), registered through its entry point.
DEFAULT_ENV_ID = "uav_coverage_cpu_v1"
DEFAULT_EVALUATION_ENV_ID = "uav_coverage_v0"

_env_packages_loaded = False


def load_env_packages() -> None:
    """
    Register the env ids of every installed task package, once: each entry point of the group
    :data:`ENV_ENTRY_POINT_GROUP` (in the order of their names) is loaded and called with
    :func:`register_multiagent_env`. An entry that fails is skipped with a warning naming it, so that the other envs
    stay usable. Reading or registering an id calls it first; the ids registered after it (``--gym-packages``) win.
    """
    global _env_packages_loaded
    if _env_packages_loaded:
        return
    _env_packages_loaded = True
    from importlib.metadata import entry_points

    for entry in sorted(entry_points(group=ENV_ENTRY_POINT_GROUP), key=lambda entry: entry.name):
        try:
            entry.load()(register_multiagent_env)
        except Exception as error:  # a broken task package leaves the others usable
            warnings.warn(
                f"the task package {entry.name!r} ({entry.value}, entry-point group {ENV_ENTRY_POINT_GROUP!r}) did not "
                f"register its envs: {type(error).__name__}: {error}",
                stacklevel=2,
            )


class _EnvRegistry(MutableMapping[str, MultiAgentEnvSpec]):
    """
    The registered ids (:data:`MULTIAGENT_ENVS`): a mapping that registers the installed task packages' ids
    (:func:`load_env_packages`) before it is first read or changed. Every method of the mapping (``in``, ``get``,
    ``keys``, ``pop``, ...) goes through the five below, so none can miss them.
    """

    def __init__(self) -> None:
        self.specs: dict[str, MultiAgentEnvSpec] = {}  # the ids registered so far, without reading the task packages

    def __getitem__(self, env_id: str) -> MultiAgentEnvSpec:
        load_env_packages()
        return self.specs[env_id]

    def __setitem__(self, env_id: str, spec: MultiAgentEnvSpec) -> None:
        load_env_packages()
        self.specs[env_id] = spec

    def __delitem__(self, env_id: str) -> None:
        load_env_packages()
        del self.specs[env_id]

    def __iter__(self) -> Iterator[str]:
        load_env_packages()
        return iter(self.specs)

    def __len__(self) -> int:
        load_env_packages()
        return len(self.specs)

    def __repr__(self) -> str:
        return f"MULTIAGENT_ENVS({sorted(self)})"


MULTIAGENT_ENVS = _EnvRegistry()


def _register(env_id: str, entry_point: str | Callable[..., ParallelEnv], kwargs: dict[str, Any] | None) -> MultiAgentEnvSpec:
    """:func:`register_multiagent_env` without reading the task packages first (the library's own ids, at import)."""
    spec = MultiAgentEnvSpec(env_id, entry_point, dict(kwargs or {}))
    MULTIAGENT_ENVS.specs[env_id] = spec
    if env_id not in gym.registry:
        gym.register(env_id, entry_point=_NotAGymEnv(env_id))
    return spec


def register_multiagent_env(
    env_id: str, entry_point: str | Callable[..., ParallelEnv], kwargs: dict[str, Any] | None = None
) -> MultiAgentEnvSpec:
    """
    Make a PettingZoo ``ParallelEnv`` usable with ``--env env_id`` in ``train``, ``enjoy`` and ``optimize``.

    Its agents must share one Box observation space and one action space, Box or Discrete (what MADDPG's VecEnv
    needs).
    Registering an id again replaces it (the installed task packages register theirs first, :func:`load_env_packages`).

    :param env_id: the id, also the key of its YAML entry
    :param entry_point: the ``ParallelEnv`` constructor or its ``"module:attribute"`` path
    :param kwargs: default constructor arguments
    :return: the spec
    """
    load_env_packages()
    return _register(env_id, entry_point, kwargs)


def is_multiagent_env(env_id: str) -> bool:
    """
    :param env_id: an env id
    :return: whether it was registered with :func:`register_multiagent_env`
    """
    return env_id in MULTIAGENT_ENVS


def make_multiagent_env(env_id: str, **kwargs: Any) -> ParallelEnv:
    """
    Build a registered multi-agent env.

    :param env_id: a registered id (``simple_spread_v3``, a task package's ``uav_coverage_v0``, ...)
    :param kwargs: constructor arguments over the registered defaults
    :return: the ``ParallelEnv``
    """
    if env_id not in MULTIAGENT_ENVS:
        raise ValueError(f"Unknown multi-agent env {env_id!r}; registered: {', '.join(sorted(MULTIAGENT_ENVS))}")
    return MULTIAGENT_ENVS[env_id].make(**kwargs)


def check_env_kwargs(env_id: str, env_kwargs: dict[str, Any] | None, flag: str = "env kwargs") -> dict[str, Any]:
    """
    Build the env once with these arguments and turn a ``TypeError``/``ValueError`` into a :class:`UsageError`
    (an unknown argument, a value the env rejects).

    :param env_id: a registered multi-agent env id
    :param env_kwargs: the arguments
    :param flag: where the arguments come from, for the message
    :return: the env's ``metadata``
    """
    try:
        env = make_multiagent_env(env_id, **(env_kwargs or {}))
    except (TypeError, ValueError) as error:
        raise UsageError(f"{flag}: bad arguments {env_kwargs!r} for {env_id}: {error}") from error
    metadata = dict(getattr(env, "metadata", {}))
    env.close()
    return metadata


# MPE2's tasks, which the library adapts (agents with spaces of their own padded, competing teams): an MPE2 task with
# continuous actions, to show nothing is tied to one task package. MPE2 is an optional package (the zoo extra), needed
# only by these envs when they are made. The task packages' ids (the UAV coverage tasks, risky_reach_v0) are theirs:
# sb3_maddpg_envs/registration.py, registered through the entry point ENV_ENTRY_POINT_GROUP.
_register("simple_spread_v3", "mpe2.simple_spread_v3:parallel_env", {"continuous_actions": True})
# The same task with MPE2's default Discrete(5) actions (no-op, left, right, down, up), as in the MADDPG paper: the
# actors learn through the straight-through Gumbel-softmax (docs/algorithm.md, "Discrete actions").
_register("simple_spread_discrete_v3", "mpe2.simple_spread_v3:parallel_env", {"continuous_actions": False})
# MPE2's other multi-agent tasks, the MADDPG paper's (Lowe et al. 2017): cooperative (reference, speaker-listener,
# crypto's alice and bob), competing (adversary, push, tag, world_comm). Each as <task> with continuous actions and
# <name>_discrete_<version> with MPE2's default Discrete ones; agents with spaces of their own are padded
# (sb3_maddpg.common.agent_spaces).
MPE2_TASKS = (
    "simple_adversary_v3",
    "simple_crypto_v3",
    "simple_push_v3",
    "simple_reference_v3",
    "simple_speaker_listener_v4",
    "simple_tag_v3",
    "simple_world_comm_v3",
)
for _task in MPE2_TASKS:
    _name, _version = _task.rsplit("_", 1)
    _register(_task, f"mpe2.{_task}:parallel_env", {"continuous_actions": True})
    _register(f"{_name}_discrete_{_version}", f"mpe2.{_task}:parallel_env", {"continuous_actions": False})
