"""
``make_multiagent_vec_env``: an SB3 VecEnv from a PettingZoo ParallelEnv, its copies in this process
(``sb3_maddpg.common.vec_env``) or in worker processes (``sb3_maddpg.common.subproc_vec_env``), as SB3's
``env_util.make_vec_env`` builds a ``DummyVecEnv`` or a ``SubprocVecEnv``.
"""

import os
from collections.abc import Callable
from numbers import Integral
from typing import Any

from pettingzoo.utils.env import ParallelEnv
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecEnv

from sb3_maddpg.common.agent_spaces import read_agent_spaces
from sb3_maddpg.common.subproc_vec_env import SubprocMultiAgentVecEnv
from sb3_maddpg.common.vec_env import MultiAgentVecEnv, in_process_vec_env


def _check_vec_env_cls(vec_env_cls: Any, n_processes: int | None) -> bool:
    """
    :param vec_env_cls: ``None``, ``"dummy"``, ``"subproc"``, or SB3's ``DummyVecEnv`` or ``SubprocVecEnv``
    :param n_processes: the number of worker processes asked for
    :return: whether the copies run in worker processes
    """
    if vec_env_cls in (None, "dummy", DummyVecEnv):
        subproc = False
    elif vec_env_cls in ("subproc", SubprocVecEnv):
        subproc = True
    else:
        raise ValueError(f"vec_env_cls must be None, 'dummy', 'subproc', DummyVecEnv or SubprocVecEnv, got {vec_env_cls!r}")
    if n_processes is not None:
        if isinstance(n_processes, bool) or not isinstance(n_processes, Integral) or n_processes < 1:
            raise ValueError(f"n_processes must be None or an integer >= 1 (worker processes), got {n_processes!r}")
        if not subproc and n_processes > 1:
            raise ValueError(f"n_processes={n_processes} needs vec_env_cls='subproc' (the copies run in this process)")
    return subproc


def make_multiagent_vec_env(
    env_fn: Callable[..., ParallelEnv],
    n_envs: int = 1,
    seed: int | None = None,
    env_kwargs: dict[str, Any] | None = None,
    vec_env_cls: str | type[VecEnv] | None = None,
    n_processes: int | None = None,
    black_death: bool = False,
) -> "MultiAgentVecEnv | SubprocMultiAgentVecEnv":
    """
    Build an SB3 VecEnv from a PettingZoo ParallelEnv with SuperSuit
    (``pettingzoo_env_to_vec_env_v1`` then ``concat_vec_envs_v1(..., base_class="stable_baselines3")``).

    The VecEnv has ``n_envs * n_agents`` rows, agent-major inside each copy (row = copy * n_agents + agent), and the
    attributes ``n_agents``, ``n_copies``, ``possible_agents`` and ``agent_spaces``. See ``MultiAgentVecEnv`` for
    seeding, infos and episode statistics. Observation spaces are Boxes (vectors or images), action spaces Box or
    Discrete (a Discrete env receives one integer per row). Agents may have spaces of their own (MPE2's
    ``simple_speaker_listener``, ``simple_adversary``, ...): the VecEnv's spaces are then the padded ones of
    SuperSuit's ``pad_observations_v0`` and ``pad_action_space_v0``, and ``agent_spaces``
    (:class:`~sb3_maddpg.common.agent_spaces.AgentSpaces`) tells the algorithm which entries are each agent's own.

    :param env_fn: function returning a PettingZoo ParallelEnv, e.g. ``uav_coverage_v0.parallel_env``
    :param n_envs: number of environment copies
    :param seed: base seed; copy c is reset with ``seed + c`` at the first reset
    :param env_kwargs: keyword arguments of ``env_fn``
    :param vec_env_cls: where the copies run: ``None`` or ``"dummy"`` (or SB3's ``DummyVecEnv``) in this process,
        ``"subproc"`` (or ``SubprocVecEnv``) in worker processes (:class:`SubprocMultiAgentVecEnv`), with the same
        per-copy seeds
    :param n_processes: worker processes with ``"subproc"`` (default: one per CPU core, at most ``n_envs``)
    :param black_death: agents may leave before the episode ends (:class:`~sb3_maddpg.common.departures.KeepDepartedAgents`,
        as SuperSuit's ``black_death_v3``): their rows stay, with zero observations and rewards, each vector observation
        gets a last entry that is 1 while its agent is in the episode and 0 after, the env gets no action for an agent
        that has left, and the algorithm leaves its rows out of the losses. The VecEnv's ``departures`` is then True
    :return: the VecEnv
    """
    if not callable(env_fn) or isinstance(env_fn, ParallelEnv):
        raise TypeError(
            f"env_fn must be a function returning a PettingZoo ParallelEnv (e.g. uav_coverage_v0.parallel_env), got {env_fn!r}"
        )
    if isinstance(n_envs, bool) or not isinstance(n_envs, Integral) or n_envs < 1:
        raise ValueError(f"n_envs must be an integer >= 1 (environment copies), got {n_envs!r}")
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, Integral) or not 0 <= seed < 2**32):
        raise ValueError(f"seed must be None or an integer in [0, 2**32), got {seed!r}")
    if env_kwargs is not None and not isinstance(env_kwargs, dict):
        raise TypeError(f"env_kwargs must be a dict of keyword arguments of env_fn or None, got {env_kwargs!r}")
    subproc = _check_vec_env_cls(vec_env_cls, n_processes)
    if not isinstance(black_death, bool):
        raise TypeError(f"black_death must be True or False, got {black_death!r}")
    parallel_env = env_fn(**(env_kwargs or {}))
    if not isinstance(parallel_env, ParallelEnv):
        raise TypeError(
            f"env_fn must return a PettingZoo ParallelEnv, got {type(parallel_env).__name__}; "
            "for an AEC env use pettingzoo.utils.conversions.aec_to_parallel"
        )
    agent_spaces = read_agent_spaces(parallel_env)
    venv: MultiAgentVecEnv | SubprocMultiAgentVecEnv
    if subproc:
        # The env was built and checked here, where its errors are readable, before any worker process starts
        parallel_env.close()
        n_processes = n_processes if n_processes is not None else os.cpu_count() or 1
        venv = SubprocMultiAgentVecEnv(
            env_fn, int(n_envs), env_kwargs=env_kwargs, n_processes=n_processes, black_death=black_death
        )
        if seed is not None:
            venv.seed(seed)
        return venv
    venv = in_process_vec_env(parallel_env, int(n_envs), black_death, agent_spaces)
    if seed is not None:
        venv.seed(seed)
    return venv


def find_multiagent_vec_env(env: VecEnv | None) -> "MultiAgentVecEnv | SubprocMultiAgentVecEnv | None":
    """
    :param env: a VecEnv, possibly wrapped (``VecNormalize``, monitors, ...)
    :return: the :class:`MultiAgentVecEnv` inside it, or None
    """
    while env is not None:
        if isinstance(env, (MultiAgentVecEnv, SubprocMultiAgentVecEnv)):
            return env
        env = getattr(env, "venv", None)
    return None
