"""
The multi-agent VecEnvs of RL Zoo runs: a registered env id's copies (``make_zoo_multiagent_vec_env``, what the
experiment manager trains and evaluates on), the optional wrappers of an RL Zoo entry in RL Zoo's order, and RL Zoo's
``create_test_env`` for the multi-agent envs (``create_multiagent_test_env``: the env that ``enjoy``, ``record-video``
and evaluation act on, wrapped as RL Zoo wraps its own).
"""

import os
import warnings
from collections.abc import Callable
from copy import deepcopy
from typing import Any

from rl_zoo3.utils import get_wrapper_class
from stable_baselines3.common.vec_env import SubprocVecEnv, VecEnv, VecFrameStack

from sb3_maddpg.zoo.monitor import EnjoyVecEnv, JointEpisodeMonitor
from sb3_maddpg.zoo.registry import (
    MULTIAGENT_ENVS,
    UsageError,
    check_env_kwargs,
    is_multiagent_env,
)
from sb3_maddpg.zoo.run_files import load_vec_normalize


def make_zoo_multiagent_vec_env(
    env_id: str,
    n_envs: int,
    seed: int | None,
    env_kwargs: dict[str, Any] | None,
    vec_env_class: type[VecEnv] | None = None,
) -> VecEnv:
    """
    The multi-agent VecEnv of a registered env id, as RL Zoo's ``n_envs`` copies.

    :param env_id: a registered multi-agent env id
    :param n_envs: environment copies (each contributes ``n_agents`` rows)
    :param seed: seed of the first copy
    :param env_kwargs: constructor arguments over the registered defaults
    :param vec_env_class: RL Zoo's ``--vec-env`` choice; ``SubprocVecEnv`` runs the copies in worker processes (one
        per CPU core, at most ``n_envs``), with the per-copy seeds they have in one process
    :return: the VecEnv
    """
    from sb3_maddpg import make_multiagent_vec_env

    check_env_kwargs(env_id, env_kwargs)
    return make_multiagent_vec_env(
        MULTIAGENT_ENVS[env_id].env_fn(),
        n_envs=n_envs,
        seed=seed,
        env_kwargs=dict(env_kwargs or {}),
        vec_env_cls="subproc" if vec_env_class is SubprocVecEnv else None,
    )


def wrap_like_rl_zoo(
    env: VecEnv,
    vec_env_wrapper: Callable | None,
    frame_stack: int | None,
    normalize: Callable[[VecEnv], VecEnv],
) -> VecEnv:
    """
    The optional VecEnv wrappers of an RL Zoo entry (``vec_env_wrapper``, ``normalize``, ``frame_stack``), in RL Zoo's
    order. SB3's VecEnv wrappers forward attribute look-ups, so ``n_agents`` stays visible on the outer one.

    :param env: the multi-agent VecEnv
    :param vec_env_wrapper: the entry's ``vec_env_wrapper``
    :param frame_stack: the entry's ``frame_stack``
    :param normalize: applies ``VecNormalize`` when the entry asks for it
    :return: the wrapped VecEnv
    """
    if vec_env_wrapper is not None:
        env = vec_env_wrapper(env)
    env = normalize(env)
    if frame_stack:
        env = VecFrameStack(env, frame_stack)
    return env


def _set_human_render_mode(env_id: str, env_kwargs: dict[str, Any], should_render: bool) -> bool:
    """
    Only envs that draw on screen get ``render_mode="human"`` (set in ``env_kwargs`` unless it names a render mode);
    for the others ``enjoy``'s rendering is refused with a warning (the UAV env renders to arrays: see ``evaluate``
    for GIFs).

    :param env_id: the env id
    :param env_kwargs: its constructor arguments (changed in place)
    :param should_render: whether ``enjoy`` will render
    :return: whether the env will be shown on screen
    """
    render_modes = check_env_kwargs(env_id, {key: value for key, value in env_kwargs.items() if key != "render_mode"}).get(
        "render_modes", []
    )
    can_render_human = should_render and "human" in render_modes
    if can_render_human and "render_mode" not in env_kwargs:
        env_kwargs["render_mode"] = "human"
    elif should_render and "render_mode" not in env_kwargs:
        warnings.warn(
            f"{env_id} cannot be shown on screen (its render modes: {', '.join(render_modes) or 'none'}); "
            f"write a video instead: sb3_maddpg record-video --env {env_id} (or pass --no-render)",
            stacklevel=3,
        )
    return can_render_human


def create_multiagent_test_env(
    env_id: str,
    n_envs: int = 1,
    stats_path: str | None = None,
    seed: int = 0,
    log_dir: str | None = None,
    should_render: bool = True,
    hyperparams: dict[str, Any] | None = None,
    env_kwargs: dict[str, Any] | None = None,
    vec_env_cls: type[VecEnv] | None = None,
    vec_env_kwargs: dict[str, Any] | None = None,
    *,
    _fallback: Callable[..., VecEnv] | None = None,
) -> VecEnv:
    """
    Drop-in replacement of ``rl_zoo3.utils.create_test_env`` (used by RL Zoo's ``enjoy``) that builds registered
    multi-agent envs with ``make_multiagent_vec_env``; other env ids go to RL Zoo's function.

    :param env_id: the env id
    :param n_envs: environment copies
    :param stats_path: folder holding ``vecnormalize.pkl`` when the run normalised
    :param seed: seed
    :param log_dir: where to write a ``monitor.csv`` of the episodes
    :param should_render: whether ``enjoy`` will render (``render_mode="human"`` where the env supports it)
    :param hyperparams: the run's saved hyperparameters (wrappers, normalisation, frame stacking)
    :param env_kwargs: constructor arguments
    :param vec_env_cls: RL Zoo's VecEnv class choice (``SubprocVecEnv``: the copies in worker processes)
    :param vec_env_kwargs: unused for multi-agent envs
    :param _fallback: RL Zoo's original function, for single-agent env ids
    :return: the VecEnv
    """
    if not is_multiagent_env(env_id):
        if _fallback is None:
            raise ValueError(f"{env_id} is not a registered multi-agent env")
        return _fallback(
            env_id,
            n_envs=n_envs,
            stats_path=stats_path,
            seed=seed,
            log_dir=log_dir,
            should_render=should_render,
            hyperparams=hyperparams,
            env_kwargs=env_kwargs,
            vec_env_cls=vec_env_cls,
            vec_env_kwargs=vec_env_kwargs,
        )
    hyperparams = dict(hyperparams or {})
    env_kwargs = deepcopy(env_kwargs or {})
    can_render_human = _set_human_render_mode(env_id, env_kwargs, should_render)

    env: VecEnv = make_zoo_multiagent_vec_env(env_id, n_envs, seed, env_kwargs, vec_env_cls)
    if log_dir is not None:
        env = JointEpisodeMonitor(env, os.path.join(log_dir, "monitor.csv"))

    def normalize(venv: VecEnv) -> VecEnv:
        if stats_path is None or not hyperparams.get("normalize", False):
            return venv
        path = os.path.join(stats_path, "vecnormalize.pkl")
        if not os.path.exists(path):
            raise UsageError(f"VecNormalize statistics {path} not found")
        venv = load_vec_normalize(path, venv)
        venv.training = False
        venv.norm_reward = False
        return venv

    vec_env_wrapper = get_wrapper_class(hyperparams, "vec_env_wrapper") if "vec_env_wrapper" in hyperparams else None
    frame_stack = hyperparams.get("frame_stack", 0) if stats_path is not None else 0
    env = wrap_like_rl_zoo(env, vec_env_wrapper, frame_stack, normalize)
    return EnjoyVecEnv(env, can_render_human=can_render_human)
