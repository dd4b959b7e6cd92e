"""SB3's ``evaluate_policy`` for a team: an episode is a joint episode of one environment copy, its reward the team return."""

import contextlib
import functools
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import stable_baselines3.common.callbacks as sb3_callbacks
from stable_baselines3.common import evaluation as sb3_evaluation
from stable_baselines3.common.callbacks import BaseCallback, CallbackList, EvalCallback, EventCallback
from stable_baselines3.common.vec_env import VecEnv


def evaluate_policy(
    model: Any,
    env: Any,
    n_eval_episodes: int = 10,
    deterministic: bool = True,
    render: bool = False,
    callback: Callable[[dict[str, Any], dict[str, Any]], None] | None = None,
    reward_threshold: float | None = None,
    return_episode_rewards: bool = False,
    warn: bool = True,
) -> tuple[float, float] | tuple[list[float], list[int]]:
    """
    SB3's ``evaluate_policy`` (same arguments, same return values) counting joint episodes on a multi-agent VecEnv
    (``make_multiagent_vec_env``: ``n_agents`` rows per copy): ``n_eval_episodes`` joint episodes are spread over the
    copies, and each episode's reward is the team return (the sum of the agents' rewards, from the ``episode`` info
    of the copy's agent-0 row, unnormalised) and its length the number of joint steps. SB3's own function would count
    every agent row as an episode and report one agent's return. Other envs go to SB3's function unchanged.

    :param model: the model (anything with ``predict``)
    :param env: the env
    :param n_eval_episodes: joint episodes to run
    :param deterministic: deterministic actions
    :param render: render the env at each step
    :param callback: called as in SB3, once per row and step (``locals()``, ``globals()``)
    :param reward_threshold: minimum mean team return, checked as in SB3
    :param return_episode_rewards: return every episode's team return and length instead of the mean and std
    :param warn: passed to SB3's function for other envs
    :return: mean and std of the team returns, or the lists of team returns and lengths
    """
    n_agents = getattr(env, "n_agents", None) if isinstance(env, VecEnv) else None
    if not isinstance(n_agents, int) or env.num_envs % n_agents != 0:
        return sb3_evaluation.evaluate_policy(
            model, env, n_eval_episodes, deterministic, render, callback, reward_threshold, return_episode_rewards, warn
        )
    n_envs = env.num_envs
    n_copies = n_envs // n_agents
    episode_counts = np.zeros(n_copies, dtype=int)
    episode_count_targets = np.array([(n_eval_episodes + copy) // n_copies for copy in range(n_copies)], dtype=int)
    current_returns = np.zeros(n_copies)
    current_lengths = np.zeros(n_copies, dtype=int)
    episode_rewards: list[float] = []
    episode_lengths: list[int] = []
    observations = env.reset()
    states = None
    episode_starts = np.ones((n_envs,), dtype=bool)
    while (episode_counts < episode_count_targets).any():
        actions, states = model.predict(observations, state=states, episode_start=episode_starts, deterministic=deterministic)
        observations, rewards, dones, infos = env.step(actions)
        current_returns += np.asarray(rewards, dtype=np.float64).reshape(n_copies, n_agents).sum(axis=1)
        current_lengths += 1
        for i in range(n_envs):
            copy = i // n_agents
            if episode_counts[copy] < episode_count_targets[copy]:
                reward, done, info = rewards[i], dones[i], infos[i]  # noqa: F841  (SB3's callback reads these locals)
                episode_starts[i] = done
                if callback is not None:
                    callback(locals(), globals())
        for copy in np.flatnonzero(np.asarray(dones).reshape(n_copies, n_agents)[:, 0]):
            if episode_counts[copy] < episode_count_targets[copy]:
                episode = infos[copy * n_agents].get("episode")
                episode_rewards.append(float(episode["r"]) if episode else float(current_returns[copy]))
                episode_lengths.append(int(episode["l"]) if episode else int(current_lengths[copy]))
                episode_counts[copy] += 1
            current_returns[copy] = 0.0
            current_lengths[copy] = 0
        if render:
            env.render()
    mean_reward = float(np.mean(episode_rewards))
    std_reward = float(np.std(episode_rewards))
    if reward_threshold is not None:
        assert mean_reward > reward_threshold, f"Mean reward below threshold: {mean_reward:.2f} < {reward_threshold:.2f}"
    if return_episode_rewards:
        return episode_rewards, episode_lengths
    return mean_reward, std_reward


def _eval_callbacks(callback: BaseCallback) -> Iterator[EvalCallback]:
    if isinstance(callback, EvalCallback):
        yield callback
    if isinstance(callback, CallbackList):
        for child in callback.callbacks:
            yield from _eval_callbacks(child)
    elif isinstance(callback, EventCallback) and callback.callback is not None:
        yield from _eval_callbacks(callback.callback)


@contextlib.contextmanager
def _joint_evaluate_policy() -> Iterator[None]:
    # SB3's EvalCallback calls the `evaluate_policy` of its own module
    saved = sb3_callbacks.evaluate_policy
    sb3_callbacks.evaluate_policy = evaluate_policy  # type: ignore[assignment]
    try:
        yield
    finally:
        sb3_callbacks.evaluate_policy = saved  # type: ignore[assignment]


def _joint_eval_step(step: Callable[[], bool]) -> bool:
    with _joint_evaluate_policy():
        return step()


def evaluate_joint_episodes(callback: BaseCallback) -> None:
    """
    Make every ``EvalCallback`` in a callback tree (SB3's, RL Zoo's ``TrialEvalCallback``, a user's) evaluate with
    :func:`evaluate_policy`: ``eval/mean_reward`` is then the mean team return of ``n_eval_episodes`` joint episodes,
    as ``rollout/ep_rew_mean`` is. Calling it again changes nothing.

    :param callback: the callback given to ``learn``
    """
    for eval_callback in _eval_callbacks(callback):
        if not isinstance(eval_callback._on_step, functools.partial):
            eval_callback._on_step = functools.partial(_joint_eval_step, eval_callback._on_step)  # type: ignore[method-assign]
