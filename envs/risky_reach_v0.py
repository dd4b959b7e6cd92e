"""
Risky reach: a small task where the risk-neutral and the risk-averse optimum differ, and the risk is visible.

N point agents (default 2) start on the left of the square [-1, 1]^2, each at (-0.8, y_i), and must reach a landmark
on the right at (0.8, y_i). Between them lies a risky zone, |x| < 0.2 and |y| < 0.8, drawn in every observation:
each step that ends inside it costs the agent ``zone_loss`` (1.0) with probability ``zone_prob`` (0.04). Each step
costs every agent 0.1 times its distance to its landmark (MPE's dense reward), so the short way straight through the
zone is the cheaper one on average, and the way around it (over the top or under the bottom) the one with no tail:

- through: 4 steps inside an agent, an expected loss of 4 x 0.04 = 0.16, and at least one loss in
  1 - 0.96^4 = 15 % of the agent-episodes;
- around: about 0.11 more distance cost an agent, never a loss.

With two agents, over 1 000 episodes of the two hand-made policies (``hand_made_policy``; reset seeds 0-999), the team
return is -2.733 through against -2.957 around (the mean prefers the way through by 8 %), and its CVaR_0.1 (the mean
of the worst 100 episodes) -3.870 through against -3.053 around (the tail prefers the way around);
tests/test_risky_reach.py checks both. The loss lands at the step that enters, inside any critic's horizon.

Each agent observes 9 + 2 (N - 1) numbers: its position, its landmark relative to it, its distances to the zone's four
edges (all positive inside), whether it is inside, and its teammates relative to it. Actions are moves in [-1, 1]^2
scaled by 0.1. Episodes last ``max_cycles`` steps (40). Every agent's info holds ``zone_steps`` (its steps inside so
far) and ``zone_losses`` (the losses it took so far).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.utils import EzPickle
from pettingzoo import ParallelEnv
from pettingzoo.utils import wrappers
from pettingzoo.utils.conversions import parallel_to_aec

from .validation import check_int, check_number

__all__ = ["RiskyReachEnv", "env", "hand_made_policy", "parallel_env", "raw_env"]

START_X, LANDMARK_X = -0.8, 0.8
ZONE = (-0.2, 0.2, -0.8, 0.8)  # x_min, x_max, y_min, y_max
SPEED = 0.1  # the largest move a step, per axis
DISTANCE_COST = 0.1  # the reward of a step is -DISTANCE_COST times the distance to the landmark


class RiskyReachEnv(ParallelEnv, EzPickle):
    """
    The risky reach task as a PettingZoo ``ParallelEnv`` (module docstring).

    :param n_agents: number of agents N (1 to 5), spread over y in [-0.3, 0.3]
    :param zone_prob: the chance that a step ending inside the zone costs ``zone_loss``, in [0, 1]
    :param zone_loss: that cost (>= 0)
    :param max_cycles: episode length (>= 1)
    :param jitter: each episode moves every agent's start and landmark by the same uniform draw in [-jitter, jitter]
        on the y axis
    :param render_mode: None (the task does not render)
    """

    metadata = {
        "render_modes": [],
        "name": "risky_reach_v0",
        "is_parallelizable": True,
        # logged at an episode's end by a training run (each agent's count; the team's is their sum)
        "episode_metrics": ("zone_steps", "zone_losses"),
        "per_agent_episode_metrics": ("zone_steps", "zone_losses"),
    }

    def __init__(
        self,
        n_agents: int = 2,
        zone_prob: float = 0.04,
        zone_loss: float = 1.0,
        max_cycles: int = 40,
        jitter: float = 0.1,
        render_mode: str | None = None,
    ) -> None:
        EzPickle.__init__(self, n_agents, zone_prob, zone_loss, max_cycles, jitter, render_mode)
        n_agents = check_int("n_agents", n_agents, 1, 5)
        zone_prob = check_number("zone_prob", zone_prob, 0.0, 1.0)
        zone_loss = check_number("zone_loss", zone_loss, 0.0)
        jitter = check_number("jitter", jitter, 0.0, 0.2)
        max_cycles = check_int("max_cycles", max_cycles, 1, 10_000)
        if render_mode is not None:
            raise ValueError(f"{self.metadata['name']} does not render: render_mode must be None, got {render_mode!r}")
        self.render_mode = render_mode
        self.zone_prob, self.zone_loss, self.jitter = zone_prob, zone_loss, jitter
        self.max_cycles = max_cycles
        self.possible_agents = [f"agent_{i}" for i in range(n_agents)]
        self.agents: list[str] = []
        self.lanes = np.linspace(-0.3, 0.3, n_agents) if n_agents > 1 else np.zeros(1)
        n_obs = 9 + 2 * (n_agents - 1)
        self._observation_space = spaces.Box(-4.0, 4.0, (n_obs,), np.float32)
        self._action_space = spaces.Box(-1.0, 1.0, (2,), np.float32)
        self._rng = np.random.default_rng()

    def observation_space(self, agent: str) -> spaces.Box:
        return self._observation_space

    def action_space(self, agent: str) -> spaces.Box:
        return self._action_space

    def reset(self, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[dict, dict]:
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        self.agents = self.possible_agents[:]
        self._place()
        self.zone_steps = np.zeros(len(self.positions), dtype=np.int64)
        self.zone_losses = np.zeros(len(self.positions), dtype=np.int64)
        self.t = 0
        return self._observations(), self._infos()

    def _place(self) -> None:
        """This episode's starts and landmarks (``positions``, ``landmarks``), with the layout's jitter drawn."""
        lanes = self.lanes + self._rng.uniform(-self.jitter, self.jitter)
        self.positions = np.stack([np.full_like(lanes, START_X), lanes], axis=1)
        self.landmarks = np.stack([np.full_like(lanes, LANDMARK_X), lanes], axis=1)

    def step(self, actions: dict[str, np.ndarray]) -> tuple[dict, dict, dict, dict, dict]:
        if not self.agents:
            raise RuntimeError("the episode has ended: call reset() before step()")
        missing = [agent for agent in self.agents if agent not in actions]
        if missing:
            raise ValueError(f"every agent acts each step: no action for {missing}")
        moves = np.stack([np.asarray(actions[agent], dtype=np.float64).reshape(2) for agent in self.agents])
        if not np.isfinite(moves).all():
            raise ValueError(f"actions must be finite numbers, got {actions!r}")
        self.positions = np.clip(self.positions + SPEED * np.clip(moves, -1.0, 1.0), -1.0, 1.0)
        inside = self.inside_zone()
        # One draw per agent and step, inside or not, so that the random stream does not depend on the path
        losses = self._rng.random(len(inside)) < self.loss_probabilities()
        self.zone_steps += inside
        self.zone_losses += losses & inside
        distances = np.linalg.norm(self.landmarks - self.positions, axis=1)
        rewards = -DISTANCE_COST * distances - losses * self.loss_costs()
        self.t += 1
        truncated = self.t >= self.max_cycles
        agents = self.agents
        observations, infos = self._observations(), self._infos()
        if truncated:
            self.agents = []
        return (
            observations,
            {agent: float(rewards[i]) for i, agent in enumerate(agents)},
            dict.fromkeys(agents, False),
            dict.fromkeys(agents, truncated),
            infos,
        )

    def inside_zone(self) -> np.ndarray:
        """Whether each agent's position lies in the zone (counted in ``zone_steps``), (N,) booleans."""
        return in_zone(self.positions)

    def loss_probabilities(self) -> np.ndarray:
        """The chance of a loss at each agent's position, (N,): ``zone_prob`` inside the zone, 0 outside."""
        return self.zone_prob * self.inside_zone()

    def loss_costs(self) -> np.ndarray:
        """What a loss costs each agent where it stands, (N,): ``zone_loss``."""
        return np.full(len(self.positions), self.zone_loss)

    def _own_observations(self) -> np.ndarray:
        """What each agent observes of itself, (N, 9): the part of its observation before its teammates."""
        x, y = self.positions[:, 0], self.positions[:, 1]
        x_min, x_max, y_min, y_max = ZONE
        return np.column_stack(
            [
                self.positions,
                self.landmarks - self.positions,
                x - x_min,
                x_max - x,
                y - y_min,
                y_max - y,
                in_zone(self.positions).astype(np.float64),
            ]
        )

    def _observations(self) -> dict[str, np.ndarray]:
        own = self._own_observations()
        observations = {}
        for i, agent in enumerate(self.possible_agents):
            teammates = np.delete(self.positions, i, axis=0) - self.positions[i]
            observations[agent] = np.concatenate([own[i], teammates.ravel()]).astype(np.float32)
        return observations

    def _infos(self) -> dict[str, dict[str, int]]:
        return {
            agent: {"zone_steps": int(self.zone_steps[i]), "zone_losses": int(self.zone_losses[i])}
            for i, agent in enumerate(self.possible_agents)
        }

    def render(self) -> None:
        """The task draws nothing (``render_mode`` is None): no frame."""
        return None

    def close(self) -> None:
        pass


def in_zone(positions: np.ndarray) -> np.ndarray:
    """Whether each position (N, 2) lies strictly inside the risky zone, (N,) booleans."""
    x_min, x_max, y_min, y_max = ZONE
    x, y = positions[:, 0], positions[:, 1]
    return (x > x_min) & (x < x_max) & (y > y_min) & (y < y_max)


def hand_made_policy(observation: np.ndarray, way: str, margin: float = 0.05) -> np.ndarray:
    """
    A hand-made agent, from its own observation: ``"through"`` heads straight for its landmark; ``"around"`` flies to
    the zone's near corner on its side (above for y >= 0, below otherwise), along the zone's edge, then to the landmark.

    :param observation: the agent's observation (its first four numbers: position, landmark relative to it)
    :param way: ``"through"`` or ``"around"``
    :param margin: how far outside the zone's edge the way around keeps
    :return: the action in [-1, 1]^2
    """
    position, to_landmark = observation[:2].astype(np.float64), observation[2:4].astype(np.float64)
    target = position + to_landmark
    if way == "around":
        x_min, x_max, _, y_max = ZONE
        side = 1.0 if target[1] >= 0.0 else -1.0
        edge = side * (y_max + margin)
        x, on_edge = position[0], side * position[1] >= y_max + margin - 1e-6
        if x >= x_max + margin - 1e-6:
            pass  # past the zone: to the landmark
        elif on_edge:
            target = np.array([x_max + margin, edge])  # along the edge to the far corner
        elif x <= x_min - margin:
            target = np.array([x_min - margin, edge])  # to the near corner
        else:
            target = np.array([x, edge])  # beside or in the zone's band: straight out of it
    elif way != "through":
        raise ValueError(f"way must be 'through' or 'around', got {way!r}")
    move = (target - position) / SPEED
    return np.clip(move / max(1.0, np.abs(move).max()), -1.0, 1.0).astype(np.float32)


def raw_env(**kwargs: Any) -> RiskyReachEnv:
    """The parallel env (its AEC form: ``env``)."""
    return RiskyReachEnv(**kwargs)


parallel_env = raw_env


def env(**kwargs: Any):
    """The AEC form, with PettingZoo's standard wrappers."""
    aec = parallel_to_aec(raw_env(**kwargs))
    aec = wrappers.AssertOutOfBoundsWrapper(aec)
    return wrappers.OrderEnforcingWrapper(aec)
