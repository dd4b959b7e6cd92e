"""Agents that leave before the episode ends: the joint layout is kept, and each observation says whether its agent is in.

PettingZoo removes an agent from ``env.agents`` (and from the step's dicts) once it is done; SB3's VecEnv and the joint
replay buffer need every agent's row at every step. :class:`KeepDepartedAgents` keeps the rows, as SuperSuit's
``black_death_v3`` does (zero observations and rewards for an agent that has left), and appends to every vector
observation one entry: 1 while the agent is in the episode, 0 once it has left. The algorithm reads that entry to
leave the agent's rows out of its actor's and its critic's losses and out of every critic's input, and to end the
agent's return at its departure (no bootstrap past it). The env receives no action for an agent that has left.
"""

from typing import Any

import numpy as np
from gymnasium import spaces
from pettingzoo.utils.env import ParallelEnv
from pettingzoo.utils.wrappers import BaseParallelWrapper


class KeepDepartedAgents(BaseParallelWrapper):
    """
    Every agent of ``possible_agents`` in every step's dicts until the episode ends, with an "in the episode" entry
    appended to its observation (the last entry: 1.0 in, 0.0 left). An agent that has left gets a zero observation,
    a reward of 0, empty infos and no action; the episode ends when the wrapped env has no agent left.

    :param env: a ParallelEnv whose observation spaces are 1-D Boxes
    """

    def __init__(self, env: ParallelEnv) -> None:
        super().__init__(env)
        self._spaces: dict[str, spaces.Box] = {}
        for agent in env.possible_agents:
            space = env.observation_space(agent)
            if not isinstance(space, spaces.Box) or len(space.shape) != 1:
                raise ValueError(
                    f"agents that leave are supported with vector observations (1-D Box) only; {agent!r} has {space}"
                )
            self._spaces[agent] = spaces.Box(
                np.append(space.low, 0.0).astype(space.dtype),
                np.append(space.high, 1.0).astype(space.dtype),
                dtype=space.dtype,
            )
        self._running = False

    @property
    def possible_agents(self) -> list[str]:  # type: ignore[override]
        return self.env.possible_agents

    @property
    def agents(self) -> list[str]:  # type: ignore[override]
        return list(self.env.possible_agents) if self._running else []

    def observation_space(self, agent: str) -> spaces.Box:
        return self._spaces[agent]

    def _observations(self, observations: dict[str, Any]) -> dict[str, np.ndarray]:
        result = {}
        for agent in self.env.possible_agents:
            space = self._spaces[agent]
            if agent in observations:
                result[agent] = np.append(np.asarray(observations[agent], dtype=space.dtype), space.dtype.type(1.0))
            else:
                result[agent] = np.zeros(space.shape, dtype=space.dtype)
        return result

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        observations, infos = self.env.reset(seed=seed, options=options)
        self._running = True
        return self._observations(observations), {agent: dict(infos.get(agent, {})) for agent in self.env.possible_agents}

    def step(self, actions: dict) -> tuple[dict, dict, dict, dict, dict]:
        live = set(self.env.agents)
        observations, rewards, terminations, truncations, infos = self.env.step(
            {agent: action for agent, action in actions.items() if agent in live}
        )
        still_in = set(self.env.agents)
        over = not still_in
        out_obs = self._observations({agent: obs for agent, obs in observations.items() if agent in still_in})
        if over:
            # The final observations as the env gave them, each marked "in" as its agent was until this step
            out_obs.update(self._observations({agent: obs for agent, obs in observations.items() if agent in live}))
        out_rewards = {agent: float(rewards.get(agent, 0.0)) for agent in self.env.possible_agents}
        # Every agent is done together at the episode's end (SuperSuit ends a copy's episode when all its agents are);
        # before that, an agent that has left is neither terminated nor truncated: its observation says it is out
        out_terms = {agent: over and bool(terminations.get(agent, agent not in live)) for agent in self.env.possible_agents}
        out_truncs = {agent: over and bool(truncations.get(agent, False)) for agent in self.env.possible_agents}
        out_infos = {agent: dict(infos.get(agent, {})) for agent in self.env.possible_agents}
        if over:
            self._running = False
        return out_obs, out_rewards, out_terms, out_truncs, out_infos
