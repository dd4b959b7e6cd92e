"""
Risky hover: a small task where the risk-averse optimum is a small, local change of the risk-neutral one.

N point agents (default 2) start at the bottom of the square [-1, 1]^2, each at (x_i, -0.8), and must reach and hold
a landmark at (x_i, 0.45). Above y = 0.4 (the hazard's edge) lies a hazard whose strength rises smoothly with the
depth d = y - 0.4: each step ends with a loss of ``hazard_loss`` (1.0) with probability
``hazard_prob * sigmoid(d / hazard_width)`` (0.0072, 0.03), drawn in every observation as the depth and that level.
The landmarks sit 0.05 inside the edge. Each step costs every agent 0.1 times its distance to its landmark (MPE's
dense reward), as in ``risky_reach_v0``.

Why the two optima differ, locally (docs/environment.md, "A risky hover"): moving an agent that hovers by dd deeper
lowers its distance cost by 0.1 dd a step and raises its chance of a loss by ``hazard_loss * p'(d) dd``, whose
largest value, ``hazard_prob / (4 hazard_width)`` = 0.06, is 0.6 of 0.1. So the mean prefers the landmark from every
depth. The lower tail weighs a step's loss chance 3-4 times as much as the mean does (CVaR_0.25 of the discounted
sum of the rare losses, with gamma 0.95), so it prefers to hold where 3.5 p'(d) = 0.1: about 0.05 outside the edge.
Every step towards that point from the landmark lowers the tail, so a deterministic policy gradient can climb it,
unlike ``risky_reach_v0``'s way around. With two agents, over 1 000 episodes of hand-made policies that hold a depth
(``hand_made_policy``; reset seeds 0-999), the team return is -1.598 at the landmark against -1.855 0.1 outside the
edge (the mean prefers the landmark by 16 %), and its CVaR_0.1 (the mean of the worst 100 episodes) -2.530 against
-1.900 (the tail prefers outside); tests/test_risky_hover.py checks both.

Each agent observes 6 + 2 (N - 1) numbers: its position, its landmark relative to it, its depth d, the hazard's level at
its position (``sigmoid(d / hazard_width)``, 0 to 1), and its teammates relative to it. Actions are moves in [-1, 1]^2
scaled by 0.1. Episodes last ``max_cycles`` steps (25, MPE's: about 13 to reach the landmark); each moves the whole
layout by one uniform draw in [-jitter, jitter] on the y axis. Every agent's info holds ``zone_steps`` (its steps
with d > 0, where the hazard is at least half its strength) and ``zone_losses`` (the losses it took so far).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.utils import EzPickle
from pettingzoo.utils import wrappers
from pettingzoo.utils.conversions import parallel_to_aec

from .risky_reach_v0 import SPEED, RiskyReachEnv
from .validation import check_number

__all__ = ["RiskyHoverEnv", "env", "hand_made_policy", "hazard_level", "parallel_env", "raw_env"]

START_Y, EDGE_Y = -0.8, 0.4


def hazard_level(depth: np.ndarray, width: float) -> np.ndarray:
    """The hazard's level at a depth below its edge, ``sigmoid(depth / width)`` in (0, 1) (0.5 at the edge)."""
    return 0.5 * (1.0 + np.tanh(0.5 * np.asarray(depth, dtype=np.float64) / width))  # the logistic without overflow


class RiskyHoverEnv(RiskyReachEnv):
    """
    The risky hover task as a PettingZoo ``ParallelEnv`` (module docstring); the step is ``risky_reach_v0``'s, with
    this task's layout, hazard and observations.

    :param n_agents: number of agents N (1 to 5), spread over x in [-0.5, 0.5]
    :param hazard_prob: the chance of a loss a step deep in the hazard, in [0, 1]
    :param hazard_loss: the cost of a loss (>= 0)
    :param hazard_width: how fast the hazard rises with depth (the logistic's scale), in [0.005, 1]
    :param landmark_depth: how far inside the hazard's edge the landmarks lie, in [-0.5, 0.5]
    :param max_cycles: episode length (>= 1)
    :param jitter: each episode moves the whole layout by the same uniform draw in [-jitter, jitter] on the y axis
    :param render_mode: None (the task does not render)
    """

    metadata = {**RiskyReachEnv.metadata, "name": "risky_hover_v0"}

    def __init__(
        self,
        n_agents: int = 2,
        hazard_prob: float = 0.0072,
        hazard_loss: float = 1.0,
        hazard_width: float = 0.03,
        landmark_depth: float = 0.05,
        max_cycles: int = 25,
        jitter: float = 0.1,
        render_mode: str | None = None,
    ) -> None:
        hazard_prob = check_number("hazard_prob", hazard_prob, 0.0, 1.0)
        hazard_loss = check_number("hazard_loss", hazard_loss, 0.0)
        hazard_width = check_number("hazard_width", hazard_width, 0.005, 1.0)
        landmark_depth = check_number("landmark_depth", landmark_depth, -0.5, 0.5)
        super().__init__(n_agents, hazard_prob, hazard_loss, max_cycles, jitter, render_mode)
        # pickled and copied with this class's own arguments
        EzPickle.__init__(
            self, n_agents, hazard_prob, hazard_loss, hazard_width, landmark_depth, max_cycles, jitter, render_mode
        )
        self.hazard_width, self.landmark_depth = hazard_width, landmark_depth
        self.lanes = np.linspace(-0.5, 0.5, n_agents) if n_agents > 1 else np.zeros(1)
        self._observation_space = spaces.Box(-4.0, 4.0, (6 + 2 * (n_agents - 1),), np.float32)

    def reset(self, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[dict, dict]:
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        self.agents = self.possible_agents[:]
        self.edge = EDGE_Y + self._rng.uniform(-self.jitter, self.jitter)
        shift = self.edge - EDGE_Y
        self.positions = np.stack([self.lanes, np.full_like(self.lanes, START_Y + shift)], axis=1)
        self.landmarks = np.stack([self.lanes, np.full_like(self.lanes, self.edge + self.landmark_depth)], axis=1)
        self.zone_steps = np.zeros(len(self.lanes), dtype=np.int64)
        self.zone_losses = np.zeros(len(self.lanes), dtype=np.int64)
        self.t = 0
        return self._observations(), self._infos()

    def _depths(self) -> np.ndarray:
        return self.positions[:, 1] - self.edge

    def _in_zone(self) -> np.ndarray:
        return self._depths() > 0.0

    def _loss_probabilities(self) -> np.ndarray:
        return self.zone_prob * hazard_level(self._depths(), self.hazard_width)

    def _observations(self) -> dict[str, np.ndarray]:
        depths = self._depths()
        own = np.column_stack(
            [self.positions, self.landmarks - self.positions, depths, hazard_level(depths, self.hazard_width)]
        )
        observations = {}
        for i, agent in enumerate(self.possible_agents):
            teammates = np.delete(self.positions, i, axis=0) - self.positions[i]
            observations[agent] = np.concatenate([own[i], teammates.ravel()]).astype(np.float32)
        return observations


def hand_made_policy(observation: np.ndarray, depth: float) -> np.ndarray:
    """
    A hand-made agent, from its own observation: it flies straight to the point above or below its landmark at
    ``depth`` inside the hazard's edge (negative: outside), and holds it.

    :param observation: the agent's observation (position, landmark relative to it, its depth)
    :param depth: the depth to hold (the landmark's: ``landmark_depth``)
    :return: the action in [-1, 1]^2
    """
    position, to_landmark = observation[:2].astype(np.float64), observation[2:4].astype(np.float64)
    target = np.array([position[0] + to_landmark[0], position[1] - float(observation[4]) + depth])
    move = (target - position) / SPEED
    return np.clip(move / max(1.0, np.abs(move).max()), -1.0, 1.0).astype(np.float32)


def raw_env(**kwargs: Any) -> RiskyHoverEnv:
    """The parallel env (its AEC form: ``env``)."""
    return RiskyHoverEnv(**kwargs)


parallel_env = raw_env


def env(**kwargs: Any):
    """The AEC form, with PettingZoo's standard wrappers."""
    aec = parallel_to_aec(raw_env(**kwargs))
    aec = wrappers.AssertOutOfBoundsWrapper(aec)
    return wrappers.OrderEnforcingWrapper(aec)
