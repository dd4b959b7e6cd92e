"""
Risky hover: a small task where the risk-averse optimum is a small, local change of the risk-neutral one.

N point agents (default 2) start at the bottom of the square [-1, 1]^2, each at (x_i, -0.8), and must reach and hold
a landmark at (x_i, 0.5). Above y = 0.4 (the hazard's edge) the wind gusts hard: each step, each agent is hit by a
gust with probability ``gust_prob`` (0.02) wherever it is, and a gust costs ``gust_loss * sigmoid(d / hazard_width)``
(1.0, 0.08), where d = y - 0.4 is the depth below the edge: about 0.22 at 0.1 outside the edge, 0.5 at it, 0.78 at the
landmark (0.1 inside). The depth and that level are drawn in every observation. Each step costs every agent 0.1 times
its distance to its landmark (MPE's dense reward), as in ``risky_reach_v0``.

Why the two optima differ, locally (docs/environment.md, "A risky hover"): moving an agent that holds a depth d by dd
deeper lowers its distance cost by 0.1 dd a step and raises its expected gust cost by ``gust_prob * gust_loss *
h'(d) dd`` (h the sigmoid), at most ``gust_prob * gust_loss / (4 hazard_width)`` = 0.0625 dd: the mean prefers the
landmark from every depth. A gust is rare (one in about 4 agent-episodes while holding), so the worst tenth of the
episodes are those with a gust, and their return falls with the gust's cost, by h(d): the lower tail prefers to hold
outside, and every step out lowers it. With two agents, over 1 000 episodes of hand-made policies that hold a depth
(``hand_made_policy``; reset seeds 0-999), the team return and its CVaR_0.1 (the mean of the worst 100 episodes)
trade smoothly against each other from the landmark to 0.15 outside the edge; tests/test_risky_hover.py checks the
order (docs/environment.md has the numbers).

Each agent observes 6 + 2 (N - 1) numbers: its position, its landmark relative to it, its depth d, the gust's level at
its position (``sigmoid(d / hazard_width)``, 0 to 1), and its teammates relative to it. Actions are moves in [-1, 1]^2
scaled by 0.1. Episodes last ``max_cycles`` steps (25, MPE's: about 13 to reach the landmark); each moves the whole
layout by one uniform draw in [-jitter, jitter] on the y axis. Every agent's info holds ``zone_steps`` (its steps
with d > 0, where a gust costs at least half its most) and ``zone_losses`` (the gusts that hit it there so far).
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
    """The hazard's level (a gust's cost over its most) at a depth below its edge, ``sigmoid(depth / width)`` in (0, 1)
    (0.5 at the edge)."""
    return 0.5 * (1.0 + np.tanh(0.5 * np.asarray(depth, dtype=np.float64) / width))  # the logistic without overflow


class RiskyHoverEnv(RiskyReachEnv):
    """
    The risky hover task as a PettingZoo ``ParallelEnv`` (module docstring); the step is ``risky_reach_v0``'s, with
    this task's layout, gusts and observations.

    :param n_agents: number of agents N (1 to 5), spread over x in [-0.5, 0.5]
    :param gust_prob: the chance that a gust hits an agent in a step, in [0, 1]
    :param gust_loss: the most a gust costs, deep in the hazard (>= 0)
    :param hazard_width: how fast a gust's cost rises with depth (the logistic's scale), in [0.005, 1]
    :param landmark_depth: how far inside the hazard's edge the landmarks lie, in [-0.5, 0.5]
    :param max_cycles: episode length (>= 1)
    :param jitter: each episode moves the whole layout by the same uniform draw in [-jitter, jitter] on the y axis
    :param render_mode: None (the task does not render)
    """

    metadata = {**RiskyReachEnv.metadata, "name": "risky_hover_v0"}

    def __init__(
        self,
        n_agents: int = 2,
        gust_prob: float = 0.02,
        gust_loss: float = 1.0,
        hazard_width: float = 0.08,
        landmark_depth: float = 0.1,
        max_cycles: int = 25,
        jitter: float = 0.1,
        render_mode: str | None = None,
    ) -> None:
        gust_prob = check_number("gust_prob", gust_prob, 0.0, 1.0)
        gust_loss = check_number("gust_loss", gust_loss, 0.0)
        hazard_width = check_number("hazard_width", hazard_width, 0.005, 1.0)
        landmark_depth = check_number("landmark_depth", landmark_depth, -0.5, 0.5)
        super().__init__(n_agents, gust_prob, gust_loss, max_cycles, jitter, render_mode)
        # pickled and copied with this class's own arguments
        EzPickle.__init__(self, n_agents, gust_prob, gust_loss, hazard_width, landmark_depth, max_cycles, jitter, render_mode)
        self.hazard_width, self.landmark_depth = hazard_width, landmark_depth
        self.lanes = np.linspace(-0.5, 0.5, n_agents) if n_agents > 1 else np.zeros(1)
        self._observation_space = spaces.Box(-4.0, 4.0, (6 + 2 * (n_agents - 1),), np.float32)

    def _place(self) -> None:
        self.edge = EDGE_Y + self._rng.uniform(-self.jitter, self.jitter)
        shift = self.edge - EDGE_Y
        self.positions = np.stack([self.lanes, np.full_like(self.lanes, START_Y + shift)], axis=1)
        self.landmarks = np.stack([self.lanes, np.full_like(self.lanes, self.edge + self.landmark_depth)], axis=1)

    def _depths(self) -> np.ndarray:
        return self.positions[:, 1] - self.edge

    def inside_zone(self) -> np.ndarray:
        """Whether each agent is deeper than the hazard's edge (d > 0), (N,) booleans."""
        return self._depths() > 0.0

    def loss_probabilities(self) -> np.ndarray:
        """The chance of a gust for each agent this step, (N,): ``gust_prob`` everywhere."""
        return np.full(len(self.positions), self.zone_prob)  # a gust can hit anywhere

    def loss_costs(self) -> np.ndarray:
        """What a gust costs each agent where it stands, (N,): ``gust_loss * hazard_level(d)``."""
        return self.zone_loss * hazard_level(self._depths(), self.hazard_width)

    def _own_observations(self) -> np.ndarray:
        depths = self._depths()
        return np.column_stack(
            [self.positions, self.landmarks - self.positions, depths, hazard_level(depths, self.hazard_width)]
        )


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
