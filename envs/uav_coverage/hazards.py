"""
Hazards a team can avoid at a cost (all off by default): wind gusts that push a UAV by a heavy-tailed distance, and
crash it when they throw it against the boundary, radio links that fail at random, and a storm zone where a UAV can
be struck down.

They make rare losses of energy, of connectivity and of coverage (the source report's motivation for CVaR) depend on
where the team flies: a UAV near a wall is the one a gust can crash, a UAV with a single neighbour is the one a link
failure cuts off, a UAV inside the storm zone is the one a strike can ground. Keeping a margin costs coverage on
average and buys a better worst case.

Shapes (N UAVs): ``positions`` (N, 2) float64, ``active`` (N,) bool, ``links`` (N, N) bool. The random numbers are
passed in (drawn by the core from the env's own generator, a fixed number per step), so every function here is a
pure array function that can be checked by hand.

:class:`HazardHook` composes them into the core's step: a core whose config switches a hazard on holds one and calls it
at the phases a hazard touches (grounding, perturbing after the move, the crash's energy, the links, the penalties, the
counters); a calm core holds none and its step runs none of this.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from .config import UAVCoverageConfig

__all__ = [
    "HAZARD_COUNTS",
    "HazardHook",
    "crash_drain",
    "gust_push",
    "in_zone",
    "push_within_walls",
    "storm_strikes",
    "surviving_links",
]

#: The per-agent hazard counters in the infos (only when a hazard is switched on).
HAZARD_COUNTS = ("gusts", "crashes", "link_failures", "depletions")

_TWO_PI = 2.0 * math.pi


def gust_push(
    draws: np.ndarray, active: np.ndarray, *, gust_prob: float, gust_scale: float, gust_tail: float, map_size: int
) -> tuple[np.ndarray, np.ndarray]:
    """
    The gusts of one step.

    UAV i is hit when u_i0 < p_g; the gust has the Lomax (Pareto II) distance d_i = s ((1 - u_i1)^(-1/a) - 1), so
    P(d > x) = (1 + x / s)^(-a): median s (2^(1/a) - 1), and a tail that falls only as x^(-a). Its direction is
    phi_i = 2 pi u_i2. The distance is capped at 2 L, beyond which any push leaves the area anyway.

    :param draws: (N, 3) uniform draws in [0, 1): (hit, distance, direction)
    :param active: (N,) bool, only active UAVs are hit
    :param gust_prob: p_g, the probability that a UAV is hit at a step
    :param gust_scale: s, the distance scale
    :param gust_tail: a, the tail index (smaller: heavier tail)
    :param map_size: L
    :return: hit (N,) bool and the push (N, 2), zero where not hit
    """
    hit = active & (draws[:, 0] < gust_prob)
    distance = np.minimum(gust_scale * ((1.0 - draws[:, 1]) ** (-1.0 / gust_tail) - 1.0), 2.0 * map_size)
    angle = _TWO_PI * draws[:, 2]
    push = np.where(hit[:, None], distance[:, None] * np.stack([np.cos(angle), np.sin(angle)], axis=1), 0.0)
    return hit, push


def push_within_walls(positions: np.ndarray, push: np.ndarray, hit: np.ndarray, map_size: int) -> np.ndarray:
    """
    Move the UAVs hit by a gust, in place; one pushed out of [0, L)^2 stops at the boundary (a crash).

    :param positions: (N, 2), updated in place
    :param push: (N, 2) the gusts' displacements
    :param hit: (N,) bool, the UAVs hit
    :param map_size: L
    :return: crashed (N,) bool
    """
    target = positions + push
    inside = ((target >= 0.0) & (target < map_size)).all(axis=1)
    positions[hit] = np.clip(target[hit], 0.0, np.nextafter(float(map_size), 0.0))
    return hit & ~inside


def crash_drain(crashed: np.ndarray, energy_left: np.ndarray, crash_energy: float) -> np.ndarray:
    """
    Energy a crash costs: E_c for each crashed UAV, never more than it has left.

    :param crashed: (N,) bool
    :param energy_left: (N,) energy after this step's own flight
    :param crash_energy: E_c
    :return: (N,) float64
    """
    return np.where(crashed, np.minimum(crash_energy, energy_left), 0.0)


def surviving_links(links: np.ndarray, draws: np.ndarray, link_failure_prob: float) -> np.ndarray:
    """
    The links that work this step: each link fails on its own with probability p_f, the same for both ends.

    A UAV with one neighbour is then cut off with probability p_f, one with k neighbours with p_f^k.

    :param links: (N, N) bool, symmetric, the links in range (``dynamics.linked``)
    :param draws: (N, N) uniform draws in [0, 1); the one above the diagonal, (min(i, j), max(i, j)), decides link i-j
    :param link_failure_prob: p_f
    :return: (N, N) bool, symmetric
    """
    failed = np.triu(draws < link_failure_prob, k=1)
    return links & ~(failed | failed.T)


def in_zone(positions: np.ndarray, zone: tuple[float, float, float, float]) -> np.ndarray:
    """
    Which UAVs are inside a rectangle of the map, lower edges included and upper edges excluded (as a cell is).

    :param positions: (N, 2)
    :param zone: (x0, y0, x1, y1), x0 < x1 and y0 < y1
    :return: (N,) bool
    """
    x0, y0, x1, y1 = zone
    x, y = positions[:, 0], positions[:, 1]
    return (x >= x0) & (x < x1) & (y >= y0) & (y < y1)


def storm_strikes(
    draws: np.ndarray, positions: np.ndarray, active: np.ndarray, *, zone: tuple[float, float, float, float], storm_prob: float
) -> np.ndarray:
    """
    The storm's strikes of one step: an active UAV inside the zone (where it is at the end of the step) is struck when
    u_i < p_s. Unlike a gust, a strike does not move the UAV: its risk depends only on where the UAV chooses to be.

    :param draws: (N,) uniform draws in [0, 1)
    :param positions: (N, 2) after the step's moves and gusts
    :param active: (N,) bool, only active UAVs are struck
    :param zone: (x0, y0, x1, y1), the storm zone
    :param storm_prob: p_s, the probability that a UAV inside the zone is struck at a step
    :return: struck (N,) bool
    """
    return active & in_zone(positions, zone) & (draws < storm_prob)


class HazardHook:
    """
    The hazards of a core's config in its step: what gusts, crashes, link failures and the storm do at each phase.

    The hook keeps no state of its own: what a hazard leaves behind (grounded steps left, counters, the last gusts and
    crashes) is the core's, so a snapshot of the core holds it. The random draws come from the core's generator, a
    fixed number per step and switched-on hazard, in the order gusts, storm, link failures.

    :param config: the core's config, with ``hazards`` on
    """

    def __init__(self, config: UAVCoverageConfig) -> None:
        self.config = config

    def ground(self, core: Any) -> np.ndarray:
        """
        Start of a step: a grounded UAV sits it out and counts one of its grounded steps.

        :return: (N,) bool, the UAVs grounded during this step
        """
        grounded = core.grounded_steps_left > 0
        core.grounded_steps_left[grounded] -= 1
        return grounded

    def perturb(self, core: Any, step: Any) -> None:
        """
        After the UAVs' own moves: gusts push the UAVs they hit (one thrown out of the area stops at the boundary and
        crashes), then the storm strikes UAVs inside its zone where they are now (a crash without the wall). The UAVs
        downed are grounded from the next step on, for k steps. Sets ``step.hit``, ``step.crashed``, ``step.downed``.
        """
        config = self.config
        crashed = hit = struck = None
        if config.gust_prob > 0.0:
            # three draws per UAV and step whether or not it is hit, so the stream stays aligned
            hit, push = gust_push(
                core._rng.random((config.n_uavs, 3)),
                step.active,
                gust_prob=config.gust_prob,
                gust_scale=config.gust_scale,
                gust_tail=config.gust_tail,
                map_size=config.map_size,
            )
            crashed = push_within_walls(core.positions, push, hit, config.map_size)
            core.last_gust[...] = push
        if config.storm_prob > 0.0:
            # one draw per UAV and step
            draws = core._rng.random(config.n_uavs)
            struck = storm_strikes(draws, core.positions, step.active, zone=config.storm_zone, storm_prob=config.storm_prob)
        downed = crashed if struck is None else struck if crashed is None else crashed | struck
        if downed is not None:
            core.last_crashed[...] = downed
            core.grounded_steps_left[downed] = config.crash_ground_steps
        step.hit, step.crashed, step.struck, step.downed = hit, crashed, struck, downed

    def charge(self, core: Any, step: Any, spent: np.ndarray) -> None:
        """A crash costs E_c more than the flight, never more than what is left: added to ``spent`` in place."""
        if step.downed is not None:
            spent += crash_drain(step.downed, core.energy - spent, self.config.crash_energy)

    def fail_links(self, core: Any, step: Any, links: np.ndarray) -> np.ndarray:
        """
        Each link in range fails on its own with probability p_f (N x N draws); sets ``step.cut_off``, the UAVs whose
        links all failed.

        :return: the links that work
        """
        if self.config.link_failure_prob <= 0.0:
            return links
        n = self.config.n_uavs
        working = surviving_links(links, core._rng.random((n, n)), self.config.link_failure_prob)
        step.cut_off = links.any(axis=1) & ~working.any(axis=1)
        return working

    def penalize(self, step: Any, penalties: np.ndarray) -> np.ndarray:
        """A gust's crash is charged the wall penalty p_w, a strike the storm's penalty p_k (in the strike's step)."""
        if step.crashed is not None:
            penalties = penalties + self.config.wall_penalty * step.crashed
        if step.struck is not None and self.config.storm_penalty > 0.0:
            penalties = penalties + self.config.storm_penalty * step.struck
        return penalties

    def charge_grounded(self, step: Any, rewards: np.ndarray) -> None:
        """A grounded UAV's reward is -``reward_scale`` p_d (before clipping), in place."""
        if self.config.grounded_penalty > 0.0:
            rewards[step.grounded] = -self.config.reward_scale * self.config.grounded_penalty

    def finish(self, core: Any, step: Any, flying: np.ndarray) -> None:
        """
        End of a step: a grounded UAV is not active until its grounded steps are over (it is not depleted); the
        counters of gusts, crashes, link failures and depletions.
        """
        core.active &= core.grounded_steps_left == 0
        counts = core.hazard_counts
        if step.hit is not None:
            counts["gusts"] += step.hit
        if step.downed is not None:
            counts["crashes"] += step.downed
        if step.cut_off is not None:
            counts["link_failures"] += step.cut_off
        counts["depletions"] += step.active & ~flying
