"""
How the UAVs move (docs/environment.md, "One step"): the commanded displacement and the wall rule (step 1), the
energy of a step (step 2) and the radio links between UAVs (step 4).

Shapes (N UAVs): ``actions`` (N, 2) in [0, 1]^2, ``positions`` (N, 2) float64, ``energy`` (N,) float64, ``active``
(N,) bool. Every function works on all UAVs at once; none draws random numbers.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["ACTION_MODES", "WALL_MODES", "commanded_move", "linked", "move_within_walls", "step_energy"]

#: The action encodings; the first is the report's (``uav_coverage_v0``), the second v1's.
ACTION_MODES = ("polar", "cartesian")
#: The wall rules; the first is the report's (``uav_coverage_v0``), the second v1's.
WALL_MODES = ("refuse", "clip")

_TWO_PI = 2.0 * math.pi


def commanded_move(actions: np.ndarray, max_distance: float, action_mode: str) -> tuple[np.ndarray, np.ndarray]:
    """
    Commanded displacement of every UAV (before the wall rule).

    :param actions: (N, 2) in [0, 1]^2
    :param max_distance: l_max, the longest move per step
    :param action_mode: ``"polar"`` or ``"cartesian"``
    :return: displacement (N, 2) and distance ratio rho = length / l_max (N,); polar:
        rho l_max (cos 2 pi a_0, sin 2 pi a_0) with rho = a_1; Cartesian: (2 a - 1) l_max, scaled down to length
        l_max where it is longer
    """
    if action_mode == "polar":
        theta = _TWO_PI * actions[:, 0]
        rho = actions[:, 1]
        displacement = (rho * max_distance)[:, None] * np.stack([np.cos(theta), np.sin(theta)], axis=1)
        return displacement, rho
    displacement = (2.0 * actions - 1.0) * max_distance
    norm = np.sqrt(np.einsum("nd,nd->n", displacement, displacement))
    rho = np.minimum(norm / max_distance, 1.0)
    return displacement * (rho * max_distance / np.maximum(norm, 1e-12))[:, None], rho


def move_within_walls(
    positions: np.ndarray,
    displacement: np.ndarray,
    rho: np.ndarray,
    active: np.ndarray,
    *,
    map_size: int,
    max_distance: float,
    wall_mode: str,
    wall_penalty: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """
    Move the active UAVs, in place, by their commanded displacement under the wall rule.

    A move that would leave [0, L)^2 is refused and charged p_w (``"refuse"``, the report's), or stopped at the
    boundary and charged p_w * overshoot / l_max (``"clip"``), in which case rho becomes that of the distance actually
    flown.

    :param positions: (N, 2), updated in place
    :param displacement: (N, 2) commanded displacement
    :param rho: (N,) commanded distance ratio
    :param active: (N,) bool, the UAVs that move
    :param map_size: L
    :param max_distance: l_max
    :param wall_mode: ``"refuse"`` or ``"clip"``
    :param wall_penalty: p_w
    :return: wall_hit (N,) bool, wall_cost (N,) float64 and the distance ratio flown (N,)
    """
    target = positions + displacement
    inside = ((target >= 0.0) & (target < map_size)).all(axis=1)
    wall_hit = active & ~inside
    if wall_mode == "refuse":
        moved = active & inside
        positions[moved] = target[moved]
        return wall_hit, wall_penalty * wall_hit, rho
    clipped = np.clip(target, 0.0, np.nextafter(float(map_size), 0.0))
    overshoot = np.sqrt(np.einsum("nd,nd->n", target - clipped, target - clipped))
    flown = np.sqrt(np.einsum("nd,nd->n", clipped - positions, clipped - positions))
    positions[active] = clipped[active]
    rho = np.where(active, np.minimum(flown / max_distance, 1.0), rho)
    return wall_hit, np.where(wall_hit, wall_penalty * overshoot / max_distance, 0.0), rho


def step_energy(
    rho: np.ndarray,
    active: np.ndarray,
    energy: np.ndarray,
    *,
    max_distance: float,
    move_energy: float,
    hover_energy: float,
) -> np.ndarray:
    """
    Energy each UAV spends this step: eta l + E_h (1 - rho) with l = rho l_max, charged also for a refused move,
    never more than what is left, 0 for an inactive UAV.

    :param rho: (N,) distance ratio flown (or commanded, for a refused move)
    :param active: (N,) bool
    :param energy: (N,) energy left before the step
    :return: (N,) float64
    """
    length = rho * max_distance
    return np.where(active, np.minimum(move_energy * length + hover_energy * (1.0 - rho), energy), 0.0)


def linked(positions: np.ndarray, active: np.ndarray, comm_range: float) -> np.ndarray:
    """
    The communication graph.

    :param positions: (N, 2)
    :param active: (N,) bool
    :param comm_range: R
    :return: (N, N) bool, active UAVs i != j within R of each other
    """
    pair = positions[:, None, :] - positions[None, :, :]
    links = (np.einsum("ijd,ijd->ij", pair, pair) <= comm_range**2) & active[None, :] & active[:, None]
    np.fill_diagonal(links, False)
    return links
