"""
Controllers that act in a multi-agent ParallelEnv: a trained model and baselines that need no training (random
actions anywhere; on a UAV coverage env, v0 or v1, the greedy static placement and the step-by-step greedy of
Liu et al., TMC 2020).

A controller is reset at the start of every episode with the env (so it may read the simulation, ``env.core``) and
returns one action per live agent at each step. Actions are in [0, 1]^2, in the env's encoding: polar (direction
theta = 2 pi a0, distance rho * l_max with rho = a1, SPEC §1.4) or Cartesian (displacement (2 a - 1) l_max).
"""

from collections.abc import Sequence
from typing import Any, Protocol

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from sb3_maddpg.common.callbacks import agent_team, check_team
from sb3_maddpg.common.validation import check_int, check_number


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
        from sb3_maddpg_envs.uav_coverage.hazards import in_zone
        from sb3_maddpg_envs.uav_coverage.validation import check_zone

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
        self.wall_margin = check_number("wall_margin", wall_margin, 0.0)
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

    - the reward has the form the report's reward took from the paper (SPEC §1.4, rule 8, without the report's entropy
      bonus): f' * sum_k (c'(k) - c(k)) / e_i - p_i, with c' and f' the coverage scores and Jain's
      fairness after the step, e_i the UAV's own energy this step as the env charges it (E_h hovering, eta l_max for a
      full move, less for a move the wall rule cuts short) and p_i its penalties: the env's wall rule (refused or
      clipped) and, when N > 1, the comm penalty if no active teammate is within R of where it ends;
    - each UAV decides at once with the others (no order between them) and assumes its teammates hover where they are;
    - no look-ahead;
    - ties go to the first candidate: hovering, then the headings counter-clockwise from east.

    Coverage as in the env: a PoI is covered when an active UAV is within R0 of it after the move; coverage, fairness
    and the reward's coverage term are computed by the env's own functions (``sb3_maddpg_envs.uav_coverage.rewards``).

    :param core: a UAV coverage simulation (``env.core``) after ``reset``
    :param n_headings: number of headings of a full move
    :param eps: added to the energy in the denominator (the env's epsilon)
    :return: scores (N, 1 + n_headings), the candidates' positions (N, 1 + n_headings, 2) and their distance ratios
        rho (1 + n_headings,) (0 hovering, 1 moving)
    """
    from sb3_maddpg_envs.uav_coverage.dynamics import move_within_walls, step_energy
    from sb3_maddpg_envs.uav_coverage.rewards import coverage_score, covering_pairs, energy_weighted_gain, jain_fairness

    n_headings = check_int("n_headings", n_headings, 1)
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
        self.n_headings = check_int("n_headings", n_headings, 1)

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


#: The baselines by name, as ``evaluate --baselines`` takes them.
BASELINES: dict[str, type] = {
    "random": RandomController,
    "greedy_static": GreedyStaticController,
    "greedy_step": GreedyStepController,
}
#: The baselines that read the simulation (``env.core``): only on the UAV coverage envs.
UAV_BASELINES: tuple[str, ...] = ("greedy_static", "greedy_step")
#: What ``evaluate`` runs when no baseline is named (those of SPEC §3): random actions, and on the UAV envs the
#: greedy static placement.
DEFAULT_BASELINES: tuple[str, ...] = ("random", "greedy_static")


def make_baselines(names: Sequence[str] | None, uav_env: bool) -> list[Controller]:
    """
    The baseline controllers named, in the order given (duplicates dropped).

    :param names: names of :data:`BASELINES`; None for :data:`DEFAULT_BASELINES` (less those that need a UAV env
        when ``uav_env`` is False)
    :param uav_env: whether the env is a UAV coverage env (has a simulation core)
    :return: one new controller per name
    :raises ValueError: an unknown name, or a UAV baseline asked for on another env
    """
    if names is None:
        names = [name for name in DEFAULT_BASELINES if uav_env or name not in UAV_BASELINES]
    if isinstance(names, str):
        raise TypeError(f"baselines must be a sequence of names, got the string {names!r}")
    chosen: list[str] = []
    for name in names:
        if name not in BASELINES:
            raise ValueError(f"unknown baseline {name!r}; known: {', '.join(BASELINES)}")
        if name in UAV_BASELINES and not uav_env:
            raise ValueError(f"the baseline {name!r} reads the simulation of a UAV coverage env; this env has none")
        if name not in chosen:
            chosen.append(name)
    return [BASELINES[name]() for name in chosen]


def _core(env: ParallelEnv) -> Any:
    core = getattr(env, "core", None) or getattr(getattr(env, "unwrapped", None), "core", None)
    if core is None:
        raise TypeError(
            f"{type(env).__name__} has no simulation core (`.core`): the greedy baselines need a UAV coverage env (v0 or v1)"
        )
    return core
