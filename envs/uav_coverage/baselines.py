"""
The UAV coverage task's own baselines, which read the simulation (``env.core``) a learned policy does not see: the
greedy static placement and the step-by-step greedy of Liu et al. (TMC 2020).

Each is a controller as ``sb3_maddpg`` evaluates them (``name``, ``reset(env, seed)``, ``act(observations, env)``),
reached through the task's tools (:mod:`.task_tools`), so the library needs no import of this package. Actions are in
[0, 1]^2, in the env's encoding: polar (direction theta = 2 pi a0, distance rho * l_max with rho = a1) or Cartesian
(displacement (2 a - 1) l_max).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pettingzoo import ParallelEnv

from ..validation import check_int, check_number, check_zone
from .dynamics import move_within_walls, step_energy
from .hazards import in_zone
from .rewards import coverage_score, covering_pairs, energy_weighted_gain, jain_fairness

__all__ = [
    "GREEDY_STEP_HEADINGS",
    "GreedyStaticController",
    "GreedyStepController",
    "assign_targets",
    "fly_to",
    "greedy_placement",
    "greedy_step_scores",
    "step_actions",
]


def greedy_placement(
    pois: np.ndarray,
    n_uavs: int,
    map_size: int,
    coverage_range: float,
    comm_range: float | None = None,
    link_margin: float = 0.05,
    wall_margin: float = 0.0,
    avoid_zone: tuple[float, float, float, float] | None = None,
) -> np.ndarray:
    """
    Hover spots chosen greedily for maximum coverage: among the centres of the map's cells, pick one spot at a time
    that covers the most PoIs not yet covered by the spots already chosen (ties: the first in the lattice order).
    When ``comm_range`` is given, each spot after the first is taken, where possible, within ``comm_range`` of an
    already chosen spot, so that the UAVs hovering there stay connected.

    Greedy selection is the classic (1 - 1/e)-approximation of maximum coverage.

    :param pois: (K, 2) PoI coordinates
    :param n_uavs: number of spots to choose
    :param map_size: L, the area is [0, L)^2
    :param coverage_range: R0, a PoI within R0 of a spot is covered
    :param comm_range: R, the link range, or None to ignore connectivity
    :param link_margin: linked spots are at most ``comm_range - link_margin`` apart, so that the float rounding of
        the flights there cannot put two UAVs just out of range
    :param wall_margin: only cell centres at least this far from every wall are candidates (0: all of them); a
        margin keeps the UAVs away from where a gust can throw them against the boundary, at a cost in coverage
    :param avoid_zone: a rectangle (x0, y0, x1, y1) whose cell centres are not candidates (None: none), e.g. the storm
        zone of the hazardous task: its PoIs are then covered from its edges only
    :return: (n_uavs, 2) spots
    """
    centres = np.arange(map_size, dtype=np.float64) + 0.5
    centres = centres[(centres >= wall_margin) & (map_size - centres >= wall_margin)]
    if len(centres) == 0:
        raise ValueError(f"wall_margin={wall_margin!r} leaves no cell centre of a {map_size} x {map_size} map as a spot")
    xx, yy = np.meshgrid(centres, centres, indexing="xy")
    candidates = np.stack([xx.ravel(), yy.ravel()], axis=1)  # (C, 2)
    if avoid_zone is not None:
        # the env's own check of a storm zone: a bad rectangle gets its clear error here, not an unpacking one
        candidates = candidates[~in_zone(candidates, check_zone("avoid_zone", avoid_zone, map_size))]
        if len(candidates) == 0:
            raise ValueError(f"avoid_zone={avoid_zone!r} leaves no cell centre of a {map_size} x {map_size} map as a spot")
    diff = candidates[:, None, :] - np.asarray(pois, dtype=np.float64)[None, :, :]
    covers = np.einsum("ckd,ckd->ck", diff, diff) <= coverage_range**2  # (C, K)

    chosen: list[int] = []
    covered = np.zeros(covers.shape[1], dtype=bool)
    reachable = np.ones(len(candidates), dtype=bool)
    for _ in range(n_uavs):
        gains = (covers & ~covered[None, :]).sum(axis=1)
        if comm_range is not None and chosen:
            # Keep the team connected when that costs nothing in feasibility: restrict to spots in range of the team.
            allowed = reachable.copy()
            if not allowed.any():
                allowed[:] = True
            gains = np.where(allowed, gains, -1)
        best = int(np.argmax(gains))
        chosen.append(best)
        covered |= covers[best]
        if comm_range is not None:
            to_best = candidates - candidates[best]
            in_range = np.einsum("cd,cd->c", to_best, to_best) <= (comm_range - link_margin) ** 2
            reachable = in_range if len(chosen) == 1 else (reachable | in_range)
    return candidates[chosen]


def assign_targets(positions: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """
    Give each UAV a distinct target, shortest pairs first (a greedy matching; N is small).

    :param positions: (N, 2) UAV positions
    :param targets: (N, 2) spots
    :return: (N, 2) the target of each UAV
    """
    diff = positions[:, None, :] - targets[None, :, :]
    distances = np.sqrt(np.einsum("ijd,ijd->ij", diff, diff))
    assigned = np.full(len(positions), -1)
    free_uav = np.ones(len(positions), dtype=bool)
    free_target = np.ones(len(targets), dtype=bool)
    for flat in np.argsort(distances, axis=None, kind="stable"):
        uav, target = divmod(int(flat), len(targets))
        if free_uav[uav] and free_target[target]:
            assigned[uav] = target
            free_uav[uav] = False
            free_target[target] = False
    return targets[assigned]


def fly_to(
    positions: np.ndarray,
    targets: np.ndarray,
    max_distance: float,
    tolerance: float = 1e-3,
    action_mode: str = "polar",
) -> np.ndarray:
    """
    Actions that fly each UAV straight toward its target, at most ``max_distance`` per step, and hover once there.

    :param positions: (N, 2) positions
    :param targets: (N, 2) targets
    :param max_distance: l_max
    :param tolerance: distance under which a UAV hovers (rho = 0) instead of correcting float rounding
    :param action_mode: the env's action encoding, ``"polar"`` or ``"cartesian"``
    :return: (N, 2) float32 actions in [0, 1]^2: (theta / 2 pi, rho) when polar, (dx, dy) / (2 l_max) + 0.5 when
        Cartesian
    """
    delta = targets - positions
    distance = np.hypot(delta[:, 0], delta[:, 1])
    if action_mode == "cartesian":
        step = np.where(distance > tolerance, np.minimum(1.0, max_distance / np.maximum(distance, 1e-12)), 0.0)
        return np.clip(0.5 + delta * step[:, None] / (2.0 * max_distance), 0.0, 1.0).astype(np.float32)
    direction = np.mod(np.arctan2(delta[:, 1], delta[:, 0]) / (2.0 * np.pi), 1.0)
    rho = np.where(distance > tolerance, np.minimum(distance / max_distance, 1.0), 0.0)
    return np.stack([direction, rho], axis=1).astype(np.float32)


class GreedyStaticController:
    """
    The static placement baseline: at reset, choose N hover spots greedily for maximum coverage
    (:func:`greedy_placement`), give each UAV the nearest free spot, fly straight there and hover.

    It reads the simulation (``env.core``: PoIs, positions, ranges), which a learned policy does not see.

    :param name: label in tables and figures
    :param connected: keep the spots within communication range of each other where possible
    :param wall_margin: only spots at least this far from every wall (0: anywhere); on an env with wind gusts a
        margin trades coverage for fewer crashes
    :param avoid_storm: only spots outside the env's storm zone (``storm_zone``; anywhere when it has none), which
        trades the coverage of the zone's inner PoIs for no strikes while hovering
    """

    def __init__(
        self, name: str = "greedy_static", connected: bool = True, wall_margin: float = 0.0, avoid_storm: bool = False
    ) -> None:
        self.name = name
        self.connected = connected
        self.wall_margin = check_number("wall_margin", wall_margin, low=0.0)
        self.avoid_storm = bool(avoid_storm)
        self.targets: np.ndarray | None = None

    def reset(self, env: ParallelEnv, seed: int | None = None) -> None:
        core = _core(env)
        spots = greedy_placement(
            core.pois,
            core.n_uavs,
            core.map_size,
            core.coverage_range,
            core.comm_range if self.connected else None,
            wall_margin=self.wall_margin,
            avoid_zone=getattr(core, "storm_zone", None) if self.avoid_storm else None,
        )
        self.targets = assign_targets(core.positions, spots)

    def act(self, observations: dict[str, np.ndarray], env: ParallelEnv) -> dict[str, np.ndarray]:
        if self.targets is None:
            raise RuntimeError("GreedyStaticController.reset() must be called at the start of each episode")
        core = _core(env)
        actions = fly_to(core.positions, self.targets, core.max_distance, action_mode=core.action_mode)
        return {agent: actions[env.possible_agents.index(agent)] for agent in observations}


#: The paper's greedy: 30 headings, evenly spaced from 0 (east), each a full move of l_max.
GREEDY_STEP_HEADINGS = 30


def greedy_step_scores(
    core: Any, n_headings: int = GREEDY_STEP_HEADINGS, eps: float = 1e-4
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """
    The immediate reward of each UAV's candidate moves, as the greedy of Liu et al. (TMC 2020) scores them: hovering
    (candidate 0) and a full move of l_max at each of ``n_headings`` headings 2 pi j / n_headings (candidate j + 1).

    The paper defines this greedy in one line ("the action with the best immediate reward"); what it leaves open is
    decided here (docs/results.md, "The published setting"):

    - the reward has the form the report's reward took from the paper (docs/environment.md, "One step", step 6,
      without the report's entropy bonus): f' * sum_k (c'(k) - c(k)) / e_i - p_i, with c' and f' the coverage scores and Jain's
      fairness after the step, e_i the UAV's own energy this step as the env charges it (E_h hovering, eta l_max for a
      full move, less for a move the wall rule cuts short) and p_i its penalties: the env's wall rule (refused or
      clipped) and, when N > 1, the comm penalty if no active teammate is within R of where it ends;
    - each UAV decides at once with the others (no order between them) and assumes its teammates hover where they are;
    - no look-ahead;
    - ties go to the first candidate: hovering, then the headings counter-clockwise from east.

    Coverage as in the env: a PoI is covered when an active UAV is within R0 of it after the move; coverage, fairness
    and the reward's coverage term are computed by the env's own functions (:mod:`.rewards`).

    :param core: a UAV coverage simulation (``env.core``) after ``reset``
    :param n_headings: number of headings of a full move
    :param eps: added to the energy in the denominator (the env's epsilon)
    :return: scores (N, 1 + n_headings), the candidates' positions (N, 1 + n_headings, 2) and their distance ratios
        rho (1 + n_headings,) (0 hovering, 1 moving)
    """
    n_headings = check_int("n_headings", n_headings, low=1)
    n, n_candidates = core.n_uavs, 1 + n_headings
    positions, active, pois = core.positions, core.active, core.pois  # pois (K, 2)
    angles = 2.0 * np.pi * np.arange(n_headings) / n_headings
    # (C, 2) displacements and (C,) distance ratios: hovering, then the headings at l_max
    moves = np.concatenate([np.zeros((1, 2)), core.max_distance * np.stack([np.cos(angles), np.sin(angles)], axis=1)])
    rho = np.concatenate([[0.0], np.ones(n_headings)])

    # Every (UAV, candidate) pair moved at once under the env's wall rule: flattened to (N C, 2).
    flat_positions = np.repeat(positions, n_candidates, axis=0)
    flat_active = np.repeat(active, n_candidates)
    _, wall_cost, flown = move_within_walls(
        flat_positions,
        np.tile(moves, (n, 1)),
        np.tile(rho, n),
        flat_active,
        map_size=core.map_size,
        max_distance=core.max_distance,
        wall_mode=core.wall_mode,
        wall_penalty=core.wall_penalty,
    )
    energy = step_energy(
        flown,
        np.ones(n * n_candidates, dtype=bool),
        np.full(n * n_candidates, np.inf),
        max_distance=core.max_distance,
        move_energy=core.move_energy,
        hover_energy=core.hover_energy,
    ).reshape(n, n_candidates)
    candidates = flat_positions.reshape(n, n_candidates, 2)

    # Coverage after the step: the teammates (hovering where they are) and UAV i at its candidate.
    covers_now = covering_pairs(positions, pois, active, core.coverage_range)  # (N, K)
    by_others = (covers_now.sum(axis=0)[None, :] - covers_now) > 0  # (N, K) covered by a teammate of i
    covers_after = covering_pairs(flat_positions, pois, flat_active, core.coverage_range).reshape(n, n_candidates, -1)
    covered = covers_after | by_others[:, None, :]
    scores_after = coverage_score(core.visits[None, None, :] + covered, core.t + 1)  # c'(k), (N, C, K)
    total = scores_after.sum(axis=2)
    gain = total - core.coverage_scores.sum()
    fairness = jain_fairness(total, np.einsum("nck,nck->nc", scores_after, scores_after), len(pois))

    penalties = wall_cost.reshape(n, n_candidates)
    if n > 1:
        # Disconnected when no active teammate (where it is now) is within R of the candidate.
        pair = candidates[:, :, None, :] - positions[None, None, :, :]  # (N, C, N, 2)
        near = (np.einsum("ncjd,ncjd->ncj", pair, pair) <= core.comm_range**2) & active[None, None, :]
        near[np.arange(n), :, np.arange(n)] = False
        penalties = penalties + core.comm_penalty * ~near.any(axis=2)
    return energy_weighted_gain(fairness, gain, energy, eps) - penalties, candidates, rho


class GreedyStepController:
    """
    The greedy baseline of Liu et al. (TMC 2020): at every step each UAV takes, of hovering and a full move of l_max
    at each of 30 headings, the one with the best immediate reward (:func:`greedy_step_scores` says how the reward
    is read). Unlike :class:`GreedyStaticController` it plans no layout: it climbs the reward one step at a time.

    It reads the simulation (``env.core``: PoIs, coverage history, positions, ranges), which a learned policy does
    not see.

    :param name: label in tables and figures
    :param n_headings: number of headings of a full move (the paper's 30)
    """

    def __init__(self, name: str = "greedy_step", n_headings: int = GREEDY_STEP_HEADINGS) -> None:
        self.name = name
        self.n_headings = check_int("n_headings", n_headings, low=1)

    def reset(self, env: ParallelEnv, seed: int | None = None) -> None:
        _core(env)  # fails early on an env without a simulation core

    def act(self, observations: dict[str, np.ndarray], env: ParallelEnv) -> dict[str, np.ndarray]:
        core = _core(env)
        scores, _, _ = greedy_step_scores(core, self.n_headings, eps=core.eps)
        best = np.argmax(scores, axis=1)  # the first best: hovering wins ties
        actions = step_actions(best, self.n_headings, core.action_mode)
        return {agent: actions[env.possible_agents.index(agent)] for agent in observations}


def step_actions(choice: np.ndarray, n_headings: int, action_mode: str = "polar") -> np.ndarray:
    """
    The env actions of the greedy's candidates: 0 hovers, j + 1 is a full move at heading 2 pi j / n_headings.

    :param choice: (N,) int, the candidate of each UAV
    :param n_headings: number of headings
    :param action_mode: the env's action encoding, ``"polar"`` or ``"cartesian"``
    :return: (N, 2) float32 actions in [0, 1]^2
    """
    choice = np.asarray(choice)
    moving = choice > 0
    heading = np.where(moving, choice - 1, 0) / n_headings  # in [0, 1): theta / 2 pi
    if action_mode == "cartesian":
        theta = 2.0 * np.pi * heading
        unit = np.stack([np.cos(theta), np.sin(theta)], axis=1) * moving[:, None]
        return np.clip(0.5 + 0.5 * unit, 0.0, 1.0).astype(np.float32)
    return np.stack([heading, moving.astype(np.float64)], axis=1).astype(np.float32)


def _core(env: ParallelEnv) -> Any:
    core = getattr(env, "core", None) or getattr(getattr(env, "unwrapped", None), "core", None)
    if core is None:
        raise TypeError(
            f"{type(env).__name__} has no simulation core (`.core`): the greedy baselines need a UAV coverage env (v0 or v1)"
        )
    return core
