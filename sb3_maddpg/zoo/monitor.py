"""VecEnv wrappers that give RL Zoo's single-agent code a per-joint-episode view of a multi-agent VecEnv."""

import time
from collections.abc import Sequence
from typing import Any

import numpy as np
from stable_baselines3.common.monitor import ResultsWriter
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper
from stable_baselines3.common.vec_env.base_vec_env import VecEnvStepReturn

from sb3_maddpg.common.callbacks import declared_episode_metrics, joint_episode_metrics


class JointEpisodeMonitor(VecEnvWrapper):
    """
    Writes one line per joint episode (team return, length, time and the env's episode-end metrics) to a CSV file
    in SB3's ``monitor.csv`` format, so ``stable_baselines3.common.monitor.load_results``, RL Zoo's ``plot_train``
    and ``python -m sb3_maddpg plot`` can read training runs.

    It is not a ``VecMonitor``: SB3's ``evaluate_policy`` would then wait for an ``episode`` key in every agent row.
    The team return and length are the episode statistics that ``make_multiagent_vec_env`` puts in the info of each
    copy's agent-0 row (the team return is the sum of the agents' rewards); each agent's return follows in a column
    ``r_<agent>``.

    :param venv: a VecEnv made by ``make_multiagent_vec_env`` (possibly wrapped), agent-major rows
        (row = copy * n_agents + agent)
    :param filename: where to write (``monitor.csv`` is appended to a folder-like name as SB3 does); None to write
        nothing and only keep the statistics in memory
    :param info_keywords: metric names read from the infos at the end of each joint episode; by default those the
        env declares (``declared_episode_metrics``), whose per-agent counts are summed over the team
    """

    def __init__(
        self,
        venv: VecEnv,
        filename: str | None = None,
        info_keywords: Sequence[str] | None = None,
    ) -> None:
        super().__init__(venv)
        self.n_agents: int = venv.n_agents  # type: ignore[attr-defined]
        declared, self.per_agent_keywords = declared_episode_metrics(venv)
        self.info_keywords = declared if info_keywords is None else tuple(info_keywords)
        self.agent_names = [str(agent) for agent in getattr(venv, "possible_agents", [])]
        self.t_start = time.time()
        self.results_writer: ResultsWriter | None = None
        if filename is not None:
            self.results_writer = ResultsWriter(
                filename,
                header={"t_start": self.t_start, "env_id": "multi-agent"},
                extra_keys=(*(f"r_{agent}" for agent in self.agent_names), *self.info_keywords),
            )
        self.episodes: list[dict[str, Any]] = []

    def reset(self) -> Any:
        return self.venv.reset()

    def step_wait(self) -> VecEnvStepReturn:
        obs, rewards, dones, infos = self.venv.step_wait()
        n_agents = self.n_agents
        for first_row in np.flatnonzero(np.asarray(dones)[::n_agents]) * n_agents:
            metrics = joint_episode_metrics(infos, int(first_row), n_agents, self.info_keywords, self.per_agent_keywords)
            episode = infos[first_row]["episode"]
            row: dict[str, Any] = {
                "r": round(float(episode["r"]), 6),
                "l": int(episode["l"]),
                "t": round(time.time() - self.t_start, 6),
            }
            agent_returns = episode.get("agent_r", {})
            row.update({f"r_{agent}": round(float(agent_returns.get(agent, np.nan)), 6) for agent in self.agent_names})
            # The CSV has a fixed header: an env without a metric leaves its column empty.
            row.update({key: metrics.get(key, "") for key in self.info_keywords})
            self.episodes.append(row)
            if self.results_writer is not None:
                self.results_writer.write_row(row)
        return obs, rewards, dones, infos

    def close(self) -> None:
        if self.results_writer is not None:
            self.results_writer.close()
        super().close()


class _JointDones(np.ndarray):
    """
    The ``dones`` of one environment copy, whose truth value is "the joint episode ended".

    RL Zoo's enjoy loop, written for single-agent envs, tests ``if done`` when it runs one env; a multi-agent copy
    returns one flag per agent, all equal since agents end their episodes together.
    """

    def __bool__(self) -> bool:
        return bool(np.asarray(self).any())


class EnjoyVecEnv(VecEnvWrapper):
    """
    The multi-agent VecEnv as RL Zoo's ``enjoy`` loop expects it: ``dones`` usable as a truth value when one copy
    runs, ``render("human")`` a no-op for envs that only render to arrays, and in every row the *team* reward of its
    copy (the sum of the agents' rewards), so that enjoy's "Episode Reward" is the team return, as
    ``rollout/ep_rew_mean`` and ``eval/mean_reward`` are; each agent's return is printed beside it at the end of
    each of the first copy's episodes (with ``verbose=1``).

    :param venv: a multi-agent VecEnv
    :param can_render_human: whether the env draws on screen itself
    """

    def __init__(self, venv: VecEnv, can_render_human: bool = False, verbose: int = 1) -> None:
        super().__init__(venv)
        self.can_render_human = can_render_human
        self.n_agents: int = venv.n_agents  # type: ignore[attr-defined]
        self.verbose = verbose

    def reset(self) -> Any:
        return self.venv.reset()

    def step_wait(self) -> VecEnvStepReturn:
        obs, rewards, dones, infos = self.venv.step_wait()
        team_rewards = np.asarray(rewards, dtype=np.float32).reshape(-1, self.n_agents).sum(axis=1)
        agent_returns = infos[0].get("episode", {}).get("agent_r")
        if self.verbose and dones[0] and agent_returns:
            print("Agent returns: " + ", ".join(f"{agent} {value:.2f}" for agent, value in agent_returns.items()))
        return obs, np.repeat(team_rewards, self.n_agents), np.asarray(dones, dtype=bool).view(_JointDones), infos

    def render(self, mode: str | None = None) -> np.ndarray | None:
        if mode == "human" and not self.can_render_human:
            return None
        return self.venv.render()
