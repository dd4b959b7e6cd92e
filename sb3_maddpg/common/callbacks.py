"""Callbacks shared by the library and the command line."""

from collections.abc import Iterable, Sequence

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback

# The per-step metrics of ``uav_coverage_v0`` (SPEC §1.5), as they appear in every agent's info.
EPISODE_METRIC_KEYS: tuple[str, ...] = ("coverage", "fairness", "energy", "energy_efficiency", "wall_hits", "disconnections")
# Metrics that count one agent's events: the team value is the sum over the agents of a copy.
# The others are global (the same in every agent's info), so the agent-0 row gives them.
PER_AGENT_METRIC_KEYS: tuple[str, ...] = ("wall_hits", "disconnections")


def joint_episode_metrics(
    infos: Sequence[dict],
    first_row: int,
    n_agents: int,
    keys: Sequence[str] = EPISODE_METRIC_KEYS,
    per_agent_keys: Sequence[str] = PER_AGENT_METRIC_KEYS,
) -> dict[str, float]:
    """
    The metrics of one environment copy at a joint step, read from its agents' infos.

    Global metrics come from the first agent's row; per-agent counts are summed over the copy's rows.
    Keys missing from the infos are left out, so an env without these metrics gives an empty dict.

    :param infos: the infos of every row of the VecEnv at this step
    :param first_row: the row of the copy's first agent (``copy * n_agents``)
    :param n_agents: number of agents per copy
    :param keys: metric names to read
    :param per_agent_keys: the subset of ``keys`` that are per-agent counts
    :return: metric name -> value
    """
    rows = infos[first_row : first_row + n_agents]
    metrics: dict[str, float] = {}
    for key in keys:
        if key not in rows[0]:
            continue
        if key in per_agent_keys:
            metrics[key] = float(sum(float(info.get(key, 0.0)) for info in rows))
        else:
            metrics[key] = float(rows[0][key])
    return metrics


def agent_team(agent: str) -> str:
    """
    The team of an agent by PettingZoo's naming: its name without the trailing ``_<index>`` (``adversary_1`` ->
    ``adversary``; MPE2's ``leadadversary_0`` is a team of its own).

    :param agent: the agent's name
    :return: the team's name
    """
    name, _, index = agent.rpartition("_")
    return name if name and index.isdigit() else agent


def check_team(team: str, agents: Iterable[str]) -> None:
    """
    :param team: a team's name, as :func:`agent_team` makes it
    :param agents: the env's agents (``possible_agents``)
    :raises ValueError: no agent is of that team (the message lists the env's teams)
    """
    teams = sorted({agent_team(str(agent)) for agent in agents})
    if team not in teams:
        raise ValueError(f"no agent of the team {team!r} in this env; its teams: {', '.join(teams)}")


def team_returns(agent_returns: dict[str, float]) -> dict[str, float]:
    """
    :param agent_returns: agent -> its return of an episode
    :return: team -> the sum of its agents' returns, in the order the teams first appear
    """
    teams: dict[str, float] = {}
    for agent, value in agent_returns.items():
        team = agent_team(str(agent))
        teams[team] = teams.get(team, 0.0) + float(value)
    return teams


class EpisodeMetricsCallback(BaseCallback):
    """
    Logs the environment's episode-end metrics (coverage, fairness, energy, energy efficiency, wall hits,
    disconnections) through SB3's logger, next to ``rollout/ep_rew_mean``.

    It reads the infos once per *joint* episode (the row of agent 0 of each copy, agent-major rows as made by
    ``make_multiagent_vec_env``), not once per agent row, and logs each agent's return of the episode as
    ``<prefix>/ep_rew_<agent>`` beside SB3's team return ``rollout/ep_rew_mean``; where the agents' names make
    several teams (``team_returns``: ``adversary_0``, ``adversary_1`` against ``agent_0``), each team's return as
    ``<prefix>/ep_rew_team_<team>``. Each logged value is the mean over
    the episodes that ended since the last dump of the logger (``logger.record_mean``), SB3 style. Envs whose infos
    lack the metric keys (e.g. ``simple_spread_v3``) log only the agents' returns.

    :param info_keys: metric names to read from the infos
    :param per_agent_keys: the names among ``info_keys`` that count one agent's events; their team value
        (the sum over the copy's agents) is logged
    :param prefix: logger section, e.g. ``"rollout"`` gives ``rollout/coverage``
    :param n_agents: agents per environment copy; by default read from the model or the VecEnv (``n_agents``),
        or 1 for single-agent envs
    :param verbose: verbosity level
    """

    def __init__(
        self,
        info_keys: Sequence[str] = EPISODE_METRIC_KEYS,
        per_agent_keys: Sequence[str] = PER_AGENT_METRIC_KEYS,
        prefix: str = "rollout",
        n_agents: int | None = None,
        verbose: int = 0,
    ) -> None:
        super().__init__(verbose)
        self.info_keys = tuple(info_keys)
        self.per_agent_keys = tuple(per_agent_keys)
        self.prefix = prefix
        self.n_agents = n_agents
        self.n_episodes = 0

    def _init_callback(self) -> None:
        if self.n_agents is None:
            self.n_agents = _find_n_agents(self.model, self.model.get_env())

    def _on_step(self) -> bool:
        dones = self.locals.get("dones")
        infos = self.locals.get("infos")
        if dones is None or infos is None:
            return True
        n_agents = self.n_agents or 1
        # All agents of a copy end their joint episode together, so agent 0's row says whether the copy ended.
        for first_row in np.flatnonzero(np.asarray(dones)[::n_agents]) * n_agents:
            # Beside SB3's rollout/ep_rew_mean (the team return), each agent's return
            agent_returns = infos[first_row].get("episode", {}).get("agent_r", {})
            for agent, value in agent_returns.items():
                self.logger.record_mean(f"{self.prefix}/ep_rew_{agent}", value)
            # Competing teams (MPE2's adversaries against good agents): each team's return, where there are several
            teams = team_returns(agent_returns)
            if len(teams) > 1:
                for team, value in teams.items():
                    self.logger.record_mean(f"{self.prefix}/ep_rew_team_{team}", value)
            metrics = joint_episode_metrics(infos, int(first_row), n_agents, self.info_keys, self.per_agent_keys)
            if not metrics:
                continue
            self.n_episodes += 1
            for key, value in metrics.items():
                self.logger.record_mean(f"{self.prefix}/{key}", value)
        return True

    def _on_training_end(self) -> None:
        # Off-policy algorithms dump the logger every `log_interval` episodes only: flush what the last
        # episodes recorded so that short runs still leave these scalars in TensorBoard.
        pending = getattr(self.logger, "name_to_value", {})
        if any(key.startswith(f"{self.prefix}/") and key.split("/", 1)[1] in self.info_keys for key in pending):
            self.logger.dump(self.num_timesteps)


def _find_n_agents(model: object, env: object) -> int:
    """
    The number of agents per environment copy, from the model (``n_agents``) or the VecEnv.

    :param model: the algorithm
    :param env: its training VecEnv (or None)
    :return: the number of agents, 1 when neither says
    """
    for owner in (model, env):
        value = getattr(owner, "n_agents", None)
        if isinstance(value, (int, np.integer)) and value > 0:
            return int(value)
    return 1
