"""
Controllers that act in a multi-agent ParallelEnv: a trained model, random actions, competing teams, and the
baselines a task offers through its tools (:mod:`sb3_maddpg.evaluation.task_tools`; on the UAV coverage envs the
greedy static placement and the step-by-step greedy of Liu et al., TMC 2020).

A controller is reset at the start of every episode with the env (so a task's baseline may read the simulation) and
returns one action per live agent at each step.
"""

from collections.abc import Sequence
from typing import Any, Protocol

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from sb3_maddpg.common.callbacks import agent_team, check_team
from sb3_maddpg.evaluation.task_tools import NO_TASK_TOOLS, TaskTools


class Controller(Protocol):
    """What :func:`~sb3_maddpg.evaluation.evaluate.run_episode` needs from a policy."""

    name: str

    def reset(self, env: ParallelEnv, seed: int | None = None) -> None:
        """
        Called after ``env.reset`` at the start of each episode.

        :param env: the env, already reset
        :param seed: the episode's seed, for controllers with randomness
        """

    def act(self, observations: dict[str, np.ndarray], env: ParallelEnv) -> dict[str, np.ndarray]:
        """
        :param observations: the live agents' observations
        :param env: the env
        :return: one action per live agent
        """


class RandomController:
    """
    Uniform random actions in every agent's action space: in a Box (in the UAV env: [0, 1]^2, a random direction
    and distance) or a Discrete one (uniform integers): the lower baseline.

    :param name: label in tables and figures
    """

    def __init__(self, name: str = "random") -> None:
        self.name = name
        self.rng = np.random.default_rng()

    def reset(self, env: ParallelEnv, seed: int | None = None) -> None:
        self.rng = np.random.default_rng(seed)

    def act(self, observations: dict[str, np.ndarray], env: ParallelEnv) -> dict[str, np.ndarray]:
        actions = {}
        for agent in observations:
            space = env.action_space(agent)
            if isinstance(space, spaces.Discrete):
                actions[agent] = np.int64(space.start + self.rng.integers(space.n))
                continue
            draw = space.low + (space.high - space.low) * self.rng.random(space.shape, dtype=np.float64)
            actions[agent] = draw.astype(space.dtype)
        return actions


class ModelController:
    """
    A trained multi-agent model (MADDPG or any SB3 model whose ``predict`` takes one row per agent, in the order
    of ``env.possible_agents``), acting deterministically by default.

    :param model: the model
    :param name: label in tables and figures
    :param deterministic: whether to act without exploration noise
    """

    def __init__(self, model: Any, name: str = "maddpg", deterministic: bool = True) -> None:
        self.model = model
        self.name = name
        self.deterministic = deterministic

    def reset(self, env: ParallelEnv, seed: int | None = None) -> None:
        pass

    def act(self, observations: dict[str, np.ndarray], env: ParallelEnv) -> dict[str, np.ndarray]:
        if getattr(self.model, "agent_names", None) is not None:
            # A model of this library takes the observation dict itself: each agent's own shapes (agents with spaces
            # of their own), agents that have left the episode, and its team's order
            if getattr(self.model, "departures", False):
                # Trained with black_death=True: each observation ends with "in the episode" (an absent agent's row
                # is zeros, as in training)
                observations = {agent: np.append(obs, 1.0).astype(np.float32) for agent, obs in observations.items()}
            actions, _ = self.model.predict(dict(observations), deterministic=self.deterministic)
            return {agent: np.asarray(action, dtype=env.action_space(agent).dtype) for agent, action in actions.items()}
        # Row r of the batch goes to actor r mod N: stack in the fixed agent order, not in the dict's order.
        agents = [agent for agent in env.possible_agents if agent in observations]
        batch = np.stack([observations[agent] for agent in agents])
        actions, _ = self.model.predict(batch, deterministic=self.deterministic)
        # In each agent's action dtype: float32 in a Box, integers in a Discrete space
        return {
            agent: np.asarray(action, dtype=env.action_space(agent).dtype)
            for agent, action in zip(agents, actions, strict=True)
        }


class TeamController:
    """
    Competing teams: one controller acts for the agents of ``team`` (by PettingZoo's naming, ``adversary_0`` and
    ``adversary_1`` form the team ``adversary``; ``sb3_maddpg.common.callbacks.agent_team``), another for all other
    agents, e.g. a trained model's adversaries against random good agents, or against another model's.

    :param team: the team that ``controller`` plays
    :param controller: acts for the agents of ``team`` (it is asked for all live agents; only theirs are used)
    :param opponent: acts for the others
    :param name: label in tables and figures
    """

    def __init__(self, team: str, controller: "Controller", opponent: "Controller", name: str | None = None) -> None:
        self.team = team
        self.controller = controller
        self.opponent = opponent
        self.name = name or f"{controller.name} ({team}) vs {opponent.name}"

    def reset(self, env: ParallelEnv, seed: int | None = None) -> None:
        check_team(self.team, env.possible_agents)
        self.controller.reset(env, seed=seed)
        self.opponent.reset(env, seed=None if seed is None else seed + 1)

    def act(self, observations: dict[str, np.ndarray], env: ParallelEnv) -> dict[str, np.ndarray]:
        own = self.controller.act(observations, env)
        others = self.opponent.act(observations, env)
        return {agent: own[agent] if agent_team(str(agent)) == self.team else others[agent] for agent in observations}


#: The baselines every env has, by name, as ``evaluate --baselines`` takes them; a task adds its own (``TaskTools``).
BASELINES: dict[str, type] = {"random": RandomController}
#: What ``evaluate`` runs when no baseline is named: random actions, then the task's default baselines.
DEFAULT_BASELINES: tuple[str, ...] = ("random",)


def make_baselines(names: Sequence[str] | None, tools: TaskTools = NO_TASK_TOOLS) -> list[Controller]:
    """
    The baseline controllers named, in the order given (duplicates dropped).

    :param names: names of :data:`BASELINES` or of the task's baselines; None for :data:`DEFAULT_BASELINES` and the
        task's default ones
    :param tools: the env's task tools (``task_tools(env)``), which may offer baselines of the task's own
    :return: one new controller per name
    :raises ValueError: a name that neither the library nor the env's task offers, with the names accepted
    """
    accepted = {**BASELINES, **tools.baselines}
    if names is None:
        names = [*DEFAULT_BASELINES, *tools.default_baselines]
    if isinstance(names, str):
        raise TypeError(f"baselines must be a sequence of names, got the string {names!r}")
    chosen: list[str] = []
    for name in names:
        if name not in accepted:
            raise ValueError(f"unknown baseline {name!r}; this env accepts: {', '.join(accepted)}")
        if name not in chosen:
            chosen.append(name)
    return [accepted[name]() for name in chosen]
