"""
The multi-agent environments the command line knows, by RL Zoo env id.

RL Zoo looks env ids up in Gymnasium's registry (``--env`` is checked there, ``is_atari`` reads the entry point), but
a PettingZoo ``ParallelEnv`` is not a ``gymnasium.Env``: :func:`register_multiagent_env` keeps the real constructor
here and puts a placeholder into Gymnasium's registry whose ``gym.make`` explains how the env is built instead.
"""

import functools
import importlib
from collections.abc import Callable
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


MULTIAGENT_ENVS: dict[str, MultiAgentEnvSpec] = {}


def register_multiagent_env(
    env_id: str, entry_point: str | Callable[..., ParallelEnv], kwargs: dict[str, Any] | None = None
) -> MultiAgentEnvSpec:
    """
    Make a PettingZoo ``ParallelEnv`` usable with ``--env env_id`` in ``train``, ``enjoy`` and ``optimize``.

    Its agents must share one Box observation space and one action space, Box or Discrete (what MADDPG's VecEnv
    needs).
    Registering an id again replaces it.

    :param env_id: the id, also the key of its YAML entry
    :param entry_point: the ``ParallelEnv`` constructor or its ``"module:attribute"`` path
    :param kwargs: default constructor arguments
    :return: the spec
    """
    spec = MultiAgentEnvSpec(env_id, entry_point, dict(kwargs or {}))
    MULTIAGENT_ENVS[env_id] = spec
    if env_id not in gym.registry:
        gym.register(env_id, entry_point=_NotAGymEnv(env_id))
    return spec


def is_multiagent_env(env_id: str) -> bool:
    """
    :param env_id: an env id
    :return: whether it was registered with :func:`register_multiagent_env`
    """
    return env_id in MULTIAGENT_ENVS


def make_multiagent_env(env_id: str, **kwargs: Any) -> ParallelEnv:
    """
    Build a registered multi-agent env.

    :param env_id: a registered id (``uav_coverage_v0``, ``uav_coverage_fast_v0``, ``simple_spread_v3``, ...)
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


# The report's environment, its cheap variant (1 pixel per cell instead of 5: about 25 times fewer pixels for the
# CNN) and an MPE2 task with continuous actions, to show nothing is tied to the UAV env.
register_multiagent_env("uav_coverage_v0", "sb3_maddpg_envs.uav_coverage_v0:parallel_env")
register_multiagent_env("uav_coverage_fast_v0", "sb3_maddpg_envs.uav_coverage_v0:parallel_env", {"obs_size": 16})
# Version 1 (the same simulation with the defaults that learn) and its CPU variant: the same task at 1 pixel per cell.
register_multiagent_env("uav_coverage_v1", "sb3_maddpg_envs.uav_coverage_v1:parallel_env")
register_multiagent_env("uav_coverage_cpu_v1", "sb3_maddpg_envs.uav_coverage_v1:parallel_env", {"obs_size": 16})
# The published setting of Liu et al., "Distributed Energy-Efficient Multi-UAV Navigation for Long-Term Communication
# Coverage by Deep Reinforcement Learning", IEEE TMC 19(6), 2020 (docs/results.md, "The published setting"): v1's rules
# on the paper's geometry and energy. A step costs hover_energy + (move_energy * l_max - hover_energy) * rho, so 0.5
# hovering and 1.0 for a full move of one cell, and the energy metric is e_T / (N T * 1.0) as in the paper.
TMC2020_KWARGS: dict[str, Any] = {
    "map_size": 10,  # 10 x 10 area, the 100 grid PoIs
    "n_uavs": 6,  # the paper's default; its sweep is 3 to 8
    "coverage_range": 3.0,
    "comm_range": 5.0,
    "max_distance": 1.0,  # one PoI spacing (inferred from the paper's figures)
    "move_energy": 1.0,
    "hover_energy": 0.5,
    "max_cycles": 500,
    # 2 pixels per cell: obs_size must be a multiple of map_size, and the CNN (ReportCNN, three 3 x 3 stride-2
    # convolutions) needs at least 15 x 15 pixels, so 10 (1 pixel per cell) is too small and 20 the smallest that fits.
    "obs_size": 20,
}
register_multiagent_env("uav_coverage_tmc_v1", "sb3_maddpg_envs.uav_coverage_v1:parallel_env", TMC2020_KWARGS)
# The hazardous task on the CPU variant: wind gusts that crash a UAV near a wall and radio links that fail
# (uav_coverage_v1.HAZARDS), where the risk-neutral and the risk-averse optimum differ (docs/environment.md, "Hazards").
register_multiagent_env("uav_coverage_hazard_cpu_v1", "sb3_maddpg_envs.uav_coverage_v1:hazard_parallel_env", {"obs_size": 16})
# The storm task on the CPU variant: a storm over the middle of the map that grounds a UAV it strikes
# (uav_coverage_v1.STORM; docs/environment.md, "Hazards"), where the risk-neutral and the risk-averse optimum differ.
register_multiagent_env("uav_coverage_storm_cpu_v1", "sb3_maddpg_envs.uav_coverage_v1:storm_parallel_env", {"obs_size": 16})
# The storm task redesigned so that a critic looking about 10 steps ahead sees it (uav_coverage_v1.STORM_V2): the zone
# drawn on channel 0, strikes frequent inside it, each costing at once; the old task stays for comparison.
register_multiagent_env("uav_coverage_storm_cpu_v2", "sb3_maddpg_envs.uav_coverage_v1:storm_v2_parallel_env", {"obs_size": 16})
# A small task where the mean and the lower tail prefer different ways (a visible risky zone across the short way):
# the proving ground of the CVaR actor (sb3_maddpg_envs/risky_reach_v0.py).
register_multiagent_env("risky_reach_v0", "sb3_maddpg_envs.risky_reach_v0:parallel_env")
register_multiagent_env("simple_spread_v3", "mpe2.simple_spread_v3:parallel_env", {"continuous_actions": True})
# The same task with MPE2's default Discrete(5) actions (no-op, left, right, down, up), as in the MADDPG paper: the
# actors learn through the straight-through Gumbel-softmax (docs/algorithm.md, "Discrete actions").
register_multiagent_env("simple_spread_discrete_v3", "mpe2.simple_spread_v3:parallel_env", {"continuous_actions": False})
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
    register_multiagent_env(_task, f"mpe2.{_task}:parallel_env", {"continuous_actions": True})
    register_multiagent_env(f"{_name}_discrete_{_version}", f"mpe2.{_task}:parallel_env", {"continuous_actions": False})
