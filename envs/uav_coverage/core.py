"""Vectorised numpy simulation of the multi-UAV coverage task: the state of one env and the step that composes the rules.

This module has no Gymnasium or PettingZoo import: the PettingZoo wrapper (``uav_coverage.py``), the rendering
(``rendering.py``) and the benchmarks all sit on top of :class:`UAVCoverageCore`. Its parameters are one checked
:class:`~.config.UAVCoverageConfig` (``config.py``). The rules live beside it, each a module of pure array functions:
``dynamics.py`` (moves, walls, energy, radio links), ``rewards.py`` (coverage, entropy, metrics, rewards),
``hazards.py`` (gusts, crashes, link failures and the storm, off by default, and the :class:`~.hazards.HazardHook` that
brings them into the step), ``observations.py`` (the images), ``pois.py`` (PoIs from a lattice or an image) and
``validation.py`` (the parameter checks). The tasks (v0, v1, the published setting, the hazards, the storm) are
scenarios of ``scenarios.py``: the parameters where each differs from the defaults.

Shapes (N UAVs, K points of interest, map side L, observation side S, block side s = S / L):

- ``positions`` (N, 2) float64, ``energy`` (N,) float64, ``active`` (N,) bool
- ``pois`` (K, 2) float64, ``visits`` (K,) int64 = w(k), ``coverage_scores`` (K,) float64 = c_t(k)
- observations (N, 3, S, S) uint8, ``state()`` (3, S, S) uint8

Every step is one pass of array operations: the UAV-PoI distances are an (N, K) broadcast, the UAV-UAV distances an
(N, N) broadcast, and the observation images are written through reshaped views of an (S, S) image as (L, s, L, s)
blocks, so there is no Python loop over UAVs or PoIs.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from .config import UAVCoverageConfig, config_from_old_state
from .dynamics import ACTION_MODES, WALL_MODES, commanded_move, linked, move_within_walls, step_energy
from .hazards import HAZARD_COUNTS, HazardHook
from .observations import POSITION_MARKS, ObservationDrawer, uav_values
from .pois import MIN_POI_IMAGE_SIDE, load_poi_image, pois_from_image
from .rewards import (
    REWARD_MODES,
    cell_entropy,
    coverage_credit,
    coverage_score,
    covering_pairs,
    energy_cost,
    report_reward,
    team_metrics,
)

__all__ = [
    "ACTION_MODES",
    "MIN_POI_IMAGE_SIDE",
    "POSITION_MARKS",
    "REWARD_MODES",
    "WALL_MODES",
    "StepRecord",
    "UAVCoverageConfig",
    "UAVCoverageCore",
    "load_poi_image",
    "pois_from_image",
]


@dataclass(slots=True)
class StepRecord:
    """What the phases of one step hand on to the next ones (None: not set, or its hazard is off)."""

    #: (N,) bool, the UAVs active at the start of the step: they move, spend energy, cover, link and are rewarded
    active: np.ndarray
    #: (N,) bool, the UAVs grounded during this step (hazards only)
    grounded: np.ndarray | None = None
    #: (N,) the distance ratios flown
    rho: np.ndarray | None = None
    wall_hit: np.ndarray | None = None
    wall_cost: np.ndarray | None = None
    #: hazards: the UAVs a gust hit, those it crashed, those the storm struck, those crashed or struck, those cut off
    #: by failures
    hit: np.ndarray | None = None
    crashed: np.ndarray | None = None
    struck: np.ndarray | None = None
    downed: np.ndarray | None = None
    cut_off: np.ndarray | None = None
    #: (N,) energy spent this step
    spent: np.ndarray | None = None
    #: the team's energy this step
    energy_sum: float = 0.0
    #: sum_k c_{t-1}(k) and sum_k c_t(k)
    previous_sum: float = 0.0
    score_sum: float = 0.0
    #: (N,) each UAV's coverage credit (``reward_mode="coverage"``)
    credit: np.ndarray | None = None
    disconnected: np.ndarray | None = None


class UAVCoverageCore:
    """
    Multi-UAV coverage simulation (N UAVs over an L x L area with K points of interest), all UAVs stepped at once.

    Built from one :class:`~.config.UAVCoverageConfig` or from its parameters as keywords (``map_size``, ``n_uavs``,
    ``pois``, ...: the config's docstring describes each); every parameter reads as an attribute of the core too
    (``core.map_size``), and ``max_cycles`` can be set.

    A step runs the rules of docs/environment.md ("One step") as phases, in order: :meth:`_move` (the commanded move
    under the wall rule),
    :meth:`_perturb` (hazards: gusts and the storm), :meth:`_charge` (energy), :meth:`_cover` (coverage scores),
    :meth:`_link` (connectivity) and :meth:`_reward` (entropy, metrics, rewards), between :meth:`_start_step` (the
    active set) and :meth:`_end_step` (depletion, termination). The hazards enter only through ``hazard_hook``, None
    when the config switches none on.

    :param config: the parameters, checked; or none, and the parameters as keywords
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        if len(args) == 1 and isinstance(args[0], UAVCoverageConfig) and not kwargs:
            config = copy.copy(args[0])  # max_cycles can be set: not shared with another core
        else:
            config = UAVCoverageConfig(*args, **kwargs)
        self.config = config
        #: the hazards' part of the step, or None for a calm task
        self.hazard_hook = HazardHook(config) if config.hazards else None
        self._images = ObservationDrawer(
            config.map_size,
            config.obs_size,
            config.position_mark,
            config.storm_zone if config.show_storm_zone else None,
        )
        #: s, pixels per cell side of the observation images
        self.block = self._images.block
        self.pois: np.ndarray | None = None
        if config.poi_points is not None:
            self._set_pois(config.poi_points)
        self._rng: np.random.Generator | None = None
        self._fixed_start: np.ndarray | None = None
        self._allocate_state(config.n_uavs)
        self.visits = np.zeros(0, dtype=np.int64)
        self.coverage_scores = np.zeros(0, dtype=np.float64)
        if self.pois is not None:
            self._build_poi_tables()

    def _allocate_state(self, n: int) -> None:
        """The state arrays of N UAVs (filled by reset)."""
        self.positions = np.zeros((n, 2), dtype=np.float64)
        self.energy = np.full(n, self.max_energy, dtype=np.float64)
        self.active = np.ones(n, dtype=bool)
        #: Steps each UAV stays grounded after a crash (0: flying; only with ``crash_ground_steps``)
        self.grounded_steps_left = np.zeros(n, dtype=np.int64)
        self.t = 0
        self.total_energy_spent = 0.0
        self.wall_hits = np.zeros(n, dtype=np.int64)
        self.disconnections = np.zeros(n, dtype=np.int64)
        #: Hazard counters per UAV since reset: gusts, crashes, link failures (steps cut off by failed links only) and
        #: depletions (0 or 1)
        self.hazard_counts = {key: np.zeros(n, dtype=np.int64) for key in HAZARD_COUNTS}
        # What happened at the last step, kept for tests, rendering and debugging.
        self.last_energy_spent = np.zeros(n, dtype=np.float64)
        self.last_wall_hit = np.zeros(n, dtype=bool)
        self.last_disconnected = np.zeros(n, dtype=bool)
        self.last_gust = np.zeros((n, 2), dtype=np.float64)
        self.last_crashed = np.zeros(n, dtype=bool)
        self.last_penalties = np.zeros(n, dtype=np.float64)
        self.last_entropy = 0.0
        self.last_shared_reward = 0.0
        self.last_rewards = np.zeros(n, dtype=np.float64)
        self.coverage = 0.0
        self.fairness = 0.0
        self.energy_ratio = 0.0
        self.energy_efficiency = 0.0
        self._needs_reset = True

    def __setstate__(self, state: dict[str, Any]) -> None:
        # A core pickled before it held a config (its parameters were its attributes): read them into one.
        if "config" not in state:
            state = dict(state)
            config = state["config"] = config_from_old_state(state)
            state["hazard_hook"] = HazardHook(config) if config.hazards else None
        self.__dict__.update(state)

    # -----------------------------------------------------------------------------------------------------------------
    # Parameters (read from the config)
    # -----------------------------------------------------------------------------------------------------------------
    @property
    def max_cycles(self) -> int:
        """T, steps per episode (can be set: checked by the config)."""
        return self.config.max_cycles

    @max_cycles.setter
    def max_cycles(self, value: int) -> None:
        self.config.max_cycles = value

    @property
    def _start_array(self) -> np.ndarray | None:
        """The start positions (N, 2) of ``start`` given as an array, else None."""
        return self.config.start_points

    # -----------------------------------------------------------------------------------------------------------------
    # Derived sizes and views
    # -----------------------------------------------------------------------------------------------------------------
    @property
    def n_pois_total(self) -> int:
        """K, the number of PoIs (0 before the first reset when they are drawn from the seed)."""
        return 0 if self.pois is None else len(self.pois)

    @property
    def depletion_level(self) -> float:
        """A UAV whose energy is <= this value is depleted."""
        return self.eps * self.max_energy

    def cells_of(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """
        Cell of each point, as block indices of the observation image.

        :param points: (M, 2) map coordinates
        :return: (block_row, block_col), each (M,) int: block_row = L - 1 - floor(y), block_col = floor(x), clamped
        """
        return self._images.cells_of(points)

    def _set_pois(self, pois: np.ndarray) -> None:
        self.pois = np.ascontiguousarray(pois, dtype=np.float64)

    def _build_poi_tables(self) -> None:
        """Build what depends only on the PoIs: the visit counters, channel 0 and the PoI -> cell grouping."""
        assert self.pois is not None
        k = len(self.pois)
        self.visits = np.zeros(k, dtype=np.int64)
        self.coverage_scores = np.zeros(k, dtype=np.float64)
        self._images.set_pois(self.pois)

    # -----------------------------------------------------------------------------------------------------------------
    # Episode
    # -----------------------------------------------------------------------------------------------------------------
    def reset(self, seed: int | None = None) -> np.ndarray:
        """
        Start an episode.

        :param seed: reseeds the random generator (as in Gymnasium); without it the generator's stream continues,
            and the first reset without a seed draws one from the operating system
        :return: the observations, shape (N, 3, S, S) uint8
        """
        if seed is not None or self._rng is None:
            self._rng = np.random.default_rng(seed)
        rng = self._rng
        size = self.map_size
        # Drawn once, at the first reset: the uniform PoIs, then the fixed start (the report's training mode).
        if self.pois is None:
            assert self.n_pois is not None
            self._set_pois(rng.uniform(0.0, size, size=(self.n_pois, 2)))
            self._build_poi_tables()
        if self.start_mode == "array":
            assert self._start_array is not None
            start = self._start_array
        elif self.start_mode == "fixed":
            if self._fixed_start is None:
                self._fixed_start = rng.uniform(0.0, size, size=(self.n_uavs, 2))
            start = self._fixed_start
        else:
            start = rng.uniform(0.0, size, size=(self.n_uavs, 2))
        # uniform() can return L itself through rounding of a float; keep every start inside [0, L).
        self.positions[...] = np.minimum(start, np.nextafter(float(size), 0.0))
        self.energy.fill(self.max_energy)
        self.active.fill(True)
        self.grounded_steps_left.fill(0)
        self.t = 0
        self.total_energy_spent = 0.0
        self.wall_hits.fill(0)
        self.disconnections.fill(0)
        for counts in self.hazard_counts.values():
            counts.fill(0)
        self.last_gust.fill(0.0)
        self.last_crashed.fill(False)
        self.last_energy_spent.fill(0.0)
        self.last_wall_hit.fill(False)
        self.last_disconnected.fill(False)
        self.last_penalties.fill(0.0)
        self.last_rewards.fill(0.0)
        self.last_entropy = 0.0
        self.last_shared_reward = 0.0
        self.visits.fill(0)
        self.coverage_scores.fill(0.0)
        self.coverage = self.fairness = self.energy_ratio = self.energy_efficiency = 0.0
        self._images.clear_coverage()
        self._needs_reset = False
        return self.observations()

    # -----------------------------------------------------------------------------------------------------------------
    # The step, in phases
    # -----------------------------------------------------------------------------------------------------------------
    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool, bool]:
        """
        Move every UAV at once (docs/environment.md, "One step").

        :param actions: (N, 2) array, a_i = (direction, distance ratio) in [0, 1]^2; values outside are clipped
        :return: observations (N, 3, S, S) uint8, rewards (N,) float64, terminated, truncated
        :raises ValueError: if the actions have the wrong shape or hold NaN or infinite values
        """
        if self._needs_reset:
            raise RuntimeError("reset() must be called before step() (and again after the episode has ended)")
        actions = self._checked_actions(actions)
        step = self._start_step()
        self._move(step, actions)
        self._perturb(step)
        self._charge(step)
        self._cover(step)
        self._link(step)
        rewards = self._reward(step)
        terminated, truncated = self._end_step(step)
        self._images.draw_coverage(self.coverage_scores)
        return self.observations(), rewards, terminated, truncated

    def _checked_actions(self, actions: np.ndarray) -> np.ndarray:
        actions = np.asarray(actions, dtype=np.float64)
        if actions.shape != (self.n_uavs, 2):
            raise ValueError(f"actions must have shape ({self.n_uavs}, 2), got {actions.shape}")
        if not np.isfinite(actions).all():
            raise ValueError(f"actions must be finite, got {actions.tolist()!r}")
        return np.clip(actions, 0.0, 1.0)

    def _start_step(self) -> StepRecord:
        """
        Rule 2: only UAVs active at the start of the step move, spend energy, cover, count for connectivity and are
        rewarded; a UAV that runs out during this step still does all of this once. A grounded UAV (hazard) sits
        this step out and counts one of its grounded steps.
        """
        active = self.energy > self.depletion_level
        grounded = None
        if self.hazard_hook is not None:
            grounded = self.hazard_hook.ground(self)
            active &= ~grounded
        self.active[...] = active
        return StepRecord(active=active, grounded=grounded)

    def _move(self, step: StepRecord, actions: np.ndarray) -> None:
        """
        Rules 1 and 3: the commanded displacement (polar or Cartesian); a move that would leave [0, L)^2 is refused
        and charged p_w (the report's), or stopped at the boundary and charged p_w * overshoot / l_max (v1), in which
        case the energy is that of the distance actually flown.
        """
        displacement, rho = commanded_move(actions, self.max_distance, self.action_mode)
        step.wall_hit, step.wall_cost, step.rho = move_within_walls(
            self.positions,
            displacement,
            rho,
            step.active,
            map_size=self.map_size,
            max_distance=self.max_distance,
            wall_mode=self.wall_mode,
            wall_penalty=self.wall_penalty,
        )

    def _perturb(self, step: StepRecord) -> None:
        """Hazards after the UAVs' own moves: gusts push and crash UAVs, the storm strikes them (``HazardHook``)."""
        if self.hazard_hook is not None:
            self.hazard_hook.perturb(self, step)

    def _charge(self, step: StepRecord) -> None:
        """Rule 4: energy, charged also for a refused move, never more than what is left; a crash costs E_c more."""
        spent = step_energy(
            step.rho,
            step.active,
            self.energy,
            max_distance=self.max_distance,
            move_energy=self.move_energy,
            hover_energy=self.hover_energy,
        )
        if self.hazard_hook is not None:
            self.hazard_hook.charge(self, step, spent)
        self.energy -= spent
        step.spent = spent
        step.energy_sum = float(spent.sum())
        self.total_energy_spent += step.energy_sum

    def _cover(self, step: StepRecord) -> None:
        """Rule 5: a PoI is covered when some active UAV is within R0; the coverage scores c_t(k) = w(k) / t."""
        self.t += 1
        step.previous_sum = float(self.coverage_scores.sum())
        covering = covering_pairs(self.positions, self.pois, step.active, self.coverage_range)
        self.visits += covering.any(axis=0)
        # Weights of the coverage reward use c_{t-1}(k), read before this step's update.
        if self.reward_mode == "coverage":
            step.credit = coverage_credit(covering, self.coverage_scores, self.fairness_coef)
        coverage_score(self.visits, self.t, out=self.coverage_scores)
        step.score_sum = float(self.coverage_scores.sum())

    def _link(self, step: StepRecord) -> None:
        """
        Rule 6: an active UAV with no other active UAV within R is disconnected (never when N = 1); with the hazard,
        each link in range fails on its own with probability p_f.
        """
        if self.n_uavs > 1:
            # self.active still holds this step's active set (depletion takes effect at the end of the step)
            links = self._linked()
            if self.hazard_hook is not None:
                links = self.hazard_hook.fail_links(self, step, links)
            step.disconnected = step.active & ~links.any(axis=1)
        else:
            step.disconnected = np.zeros(1, dtype=bool)

    def _reward(self, step: StepRecord) -> np.ndarray:
        """Rules 7, 1.5 and 8: the entropy of the active UAVs' cells, the team metrics, the rewards."""
        active = step.active
        entropy = cell_entropy(self.positions, active, self.map_size)
        self.coverage, self.fairness, self.energy_ratio, self.energy_efficiency = team_metrics(
            self.coverage_scores,
            self.total_energy_spent,
            self.t,
            n_uavs=self.n_uavs,
            move_energy=self.move_energy,
            max_distance=self.max_distance,
            eps=self.eps,
        )
        penalties = step.wall_cost + self.comm_penalty * step.disconnected
        if self.hazard_hook is not None:
            penalties = self.hazard_hook.penalize(step, penalties)
        if self.reward_mode == "report":
            shared = report_reward(
                self.fairness,
                step.score_sum - step.previous_sum,
                step.energy_sum,
                entropy,
                entropy_coef=self.entropy_coef,
                eps=self.eps,
            )
            rewards = self.reward_scale * (shared - penalties)
        else:
            shared = float(step.credit.mean())
            own_energy = energy_cost(step.spent, self.energy_coef, self.move_energy, self.max_distance)
            rewards = self.reward_scale * (step.credit - own_energy - penalties)
        rewards[~active] = 0.0
        if self.hazard_hook is not None:
            self.hazard_hook.charge_grounded(step, rewards)
        # after the inactive UAVs' zeros, which clipping leaves as they are
        if self.reward_clip is not None:
            np.clip(rewards, -self.reward_clip, self.reward_clip, out=rewards)
        self.last_penalties[...] = penalties
        self.last_entropy = entropy
        self.last_shared_reward = shared
        self.last_rewards[...] = rewards
        return rewards

    def _end_step(self, step: StepRecord) -> tuple[bool, bool]:
        """
        Rule 9: the step's counters; termination when every UAV is depleted, truncation at t = T (termination wins
        when both happen). A grounded UAV is not active until its grounded steps are over, but it is not depleted.
        """
        self.wall_hits += step.wall_hit
        self.disconnections += step.disconnected
        self.last_energy_spent[...] = step.spent
        self.last_wall_hit[...] = step.wall_hit
        self.last_disconnected[...] = step.disconnected
        flying = self.energy > self.depletion_level
        self.active[...] = flying
        if self.hazard_hook is not None:
            self.hazard_hook.finish(self, step, flying)
        terminated = not flying.any()
        truncated = (not terminated) and self.t >= self.max_cycles
        self._needs_reset = terminated or truncated
        return terminated, truncated

    # -----------------------------------------------------------------------------------------------------------------
    # Observations and state
    # -----------------------------------------------------------------------------------------------------------------
    def observations(self) -> np.ndarray:
        """
        Every agent's observation, in a new array (the env never writes into an array it has returned).

        :return: (N, C, S, S) uint8; channel 0 PoIs, channel 1 the agent's own cell, channel 2 coverage history and,
            with ``teammate_channel``, channel 3 the active teammates within R (C = ``n_obs_channels``)
        """
        links = self._linked() if self.teammate_channel else None
        return self._images.observations(self.positions, self._uav_values(), links)

    def state(self) -> np.ndarray:
        """
        Global view for centralised critics: the observation image with channel 1 showing every active UAV.

        :return: (3, S, S) uint8 (maximum value where UAVs share a cell)
        """
        return self._images.state(self.positions, self._uav_values())

    def _uav_values(self) -> np.ndarray:
        """
        Channel-1 value of each UAV: round(255 E_i / E_max), at least 1 while active, 0 once depleted or while
        grounded; with ``show_grounded``, a grounded UAV's grounded steps left (1 to k, at most 255).
        """
        values = uav_values(self.energy, self.max_energy, self.active)
        if self.show_grounded:
            grounded = (self.grounded_steps_left > 0) & (self.energy > self.depletion_level)
            values[grounded] = np.minimum(self.grounded_steps_left[grounded], 255)
        return values

    # -----------------------------------------------------------------------------------------------------------------
    # Helpers for the wrapper, rendering and evaluation
    # -----------------------------------------------------------------------------------------------------------------
    def _linked(self) -> np.ndarray:
        """(N, N) bool: active UAVs i != j within R of each other (the communication graph)."""
        return linked(self.positions, self.active, self.comm_range)

    def links(self) -> np.ndarray:
        """
        Communication links between active UAVs.

        :return: (M, 2) int array of pairs (i, j), i < j, of active UAVs within R of each other
        """
        return np.argwhere(np.triu(self._linked(), k=1))

    def metrics(self) -> dict[str, float]:
        """Team metrics after the last step (docs/environment.md, "Metrics"): coverage, fairness, energy, energy_efficiency."""
        return {
            "coverage": self.coverage,
            "fairness": self.fairness,
            "energy": self.energy_ratio,
            "energy_efficiency": self.energy_efficiency,
        }

    def infos(self) -> list[dict[str, float | int]]:
        """
        One info dict per UAV: the team metrics plus this UAV's ``wall_hits`` and ``disconnections`` so far and, when a
        hazard is switched on, its ``gusts``, ``crashes``, ``link_failures`` and ``depletions`` so far.
        """
        shared = self.metrics()
        walls = self.wall_hits.tolist()
        disconnections = self.disconnections.tolist()
        infos = [{**shared, "wall_hits": walls[i], "disconnections": disconnections[i]} for i in range(self.n_uavs)]
        if self.hazards:
            for key, counts in self.hazard_counts.items():
                for info, value in zip(infos, counts.tolist(), strict=True):
                    info[key] = value
        return infos


def _config_property(name: str) -> property:
    return property(lambda core: getattr(core.config, name), doc=f"``{name}`` of the config (read only).")


# Every parameter of the config (and what it reads from them) is an attribute of the core, read from its config;
# ``pois`` is the core's own (uniform PoIs are drawn at the first reset), ``start`` reads as ``start_mode``.
for _field in fields(UAVCoverageConfig):
    if _field.name not in ("pois", "start", "poi_points", "start_points", "max_cycles"):
        setattr(UAVCoverageCore, _field.name, _config_property(_field.name))
del _field
