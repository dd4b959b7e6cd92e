"""Callbacks shared by the library and the command line."""

from collections.abc import Iterable, Sequence

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback, CallbackList, ProgressBarCallback

# The metadata keys by which an env declares its episode-end metrics (``declared_episode_metrics``)
EPISODE_METRICS_KEY = "episode_metrics"
PER_AGENT_EPISODE_METRICS_KEY = "per_agent_episode_metrics"


def declared_episode_metrics(env: object) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """
    The episode-end metrics an environment declares in its ``metadata``: under ``"episode_metrics"`` the info keys that
    every agent reports (read when an episode ends), under ``"per_agent_episode_metrics"`` those among them that count
    one agent's events (the team value is their sum over the agents; the others are the same in every agent's info).
    The library knows no task's metrics by name: an env that declares none has its returns logged only.

    :param env: a VecEnv (the metadata of the env behind its first row, as ``get_attr`` gives it), an env with a
        ``metadata`` dict, or None
    :return: ``(keys, per_agent_keys)``, empty where the env declares nothing
    :raises TypeError: if the declaration is not a list of strings, or names a per-agent key that is not among the keys
    """
    if env is None:
        return (), ()
    metadata = None
    get_attr = getattr(env, "get_attr", None)
    if callable(get_attr):
        try:
            metadata = get_attr("metadata", [0])[0]
        except (AttributeError, NotImplementedError):
            # a VecEnv that cannot reach its envs' attributes (SuperSuit's own, without make_multiagent_vec_env)
            metadata = None
    if not isinstance(metadata, dict):
        metadata = getattr(env, "metadata", None)
    if not isinstance(metadata, dict):
        return (), ()
    declared = []
    for name in (EPISODE_METRICS_KEY, PER_AGENT_EPISODE_METRICS_KEY):
        keys = metadata.get(name, ())
        if isinstance(keys, str) or not isinstance(keys, Sequence) or not all(isinstance(key, str) for key in keys):
            raise TypeError(f"the env's metadata[{name!r}] must be a list of info keys (strings), got {keys!r}")
        declared.append(tuple(keys))
    keys, per_agent_keys = declared
    if not set(per_agent_keys) <= set(keys):
        raise TypeError(
            f"the env's metadata[{PER_AGENT_EPISODE_METRICS_KEY!r}] names keys that are not among its "
            f"{EPISODE_METRICS_KEY!r}: {sorted(set(per_agent_keys) - set(keys))}"
        )
    return keys, per_agent_keys


def joint_episode_metrics(
    infos: Sequence[dict],
    first_row: int,
    n_agents: int,
    keys: Sequence[str],
    per_agent_keys: Sequence[str] = (),
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
    Logs the environment's episode-end metrics (those it declares, ``declared_episode_metrics``: on the UAV tasks
    coverage, fairness, energy, energy efficiency, wall hits, disconnections) through SB3's logger, next to
    ``rollout/ep_rew_mean``.

    It reads the infos once per *joint* episode (the row of agent 0 of each copy, agent-major rows as made by
    ``make_multiagent_vec_env``), not once per agent row, and logs each agent's return of the episode as
    ``<prefix>/ep_rew_<agent>`` beside SB3's team return ``rollout/ep_rew_mean``; where the agents' names make
    several teams (``team_returns``: ``adversary_0``, ``adversary_1`` against ``agent_0``), each team's return as
    ``<prefix>/ep_rew_team_<team>``. Each logged value is the mean over
    the episodes that ended since the last dump of the logger (``logger.record_mean``), SB3 style. Envs that declare
    no metrics (e.g. ``simple_spread_v3``) log only the agents' returns.

    :param info_keys: metric names to read from the infos; by default those the model's env declares
    :param per_agent_keys: the names among ``info_keys`` that count one agent's events; their team value
        (the sum over the copy's agents) is logged; by default those the model's env declares
    :param prefix: logger section, e.g. ``"rollout"`` gives ``rollout/coverage``
    :param n_agents: agents per environment copy; by default read from the model or the VecEnv (``n_agents``),
        or 1 for single-agent envs
    :param verbose: verbosity level
    """

    def __init__(
        self,
        info_keys: Sequence[str] | None = None,
        per_agent_keys: Sequence[str] | None = None,
        prefix: str = "rollout",
        n_agents: int | None = None,
        verbose: int = 0,
    ) -> None:
        super().__init__(verbose)
        self.info_keys = None if info_keys is None else tuple(info_keys)
        self.per_agent_keys = None if per_agent_keys is None else tuple(per_agent_keys)
        self.prefix = prefix
        self.n_agents = n_agents
        self.n_episodes = 0

    def _init_callback(self) -> None:
        env = self.model.get_env()
        if self.n_agents is None:
            self.n_agents = _find_n_agents(self.model, env)
        if self.info_keys is None or self.per_agent_keys is None:
            keys, per_agent_keys = declared_episode_metrics(env)
            self.info_keys = keys if self.info_keys is None else self.info_keys
            self.per_agent_keys = per_agent_keys if self.per_agent_keys is None else self.per_agent_keys

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
            metrics = joint_episode_metrics(infos, int(first_row), n_agents, self.info_keys or (), self.per_agent_keys or ())
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
        if any(key.startswith(f"{self.prefix}/") and key.split("/", 1)[1] in (self.info_keys or ()) for key in pending):
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


def count_joint_steps(callback: BaseCallback) -> BaseCallback:
    """
    The callback tree with each of SB3's plain ``ProgressBarCallback`` replaced by a joint-step one, in the lists
    themselves: RL Zoo closes ``self.callbacks[0]``, its progress bar, after ``learn``.
    """
    if type(callback) is ProgressBarCallback:
        return JointStepProgressBarCallback()
    if isinstance(callback, CallbackList):
        callback.callbacks[:] = [count_joint_steps(child) for child in callback.callbacks]
    return callback
