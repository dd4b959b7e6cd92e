"""Vectorised numpy simulation of the multi-UAV coverage task: the state of one env and the step that composes the rules.

This module has no Gymnasium or PettingZoo import: the PettingZoo wrapper (``uav_coverage.py``), the rendering
(``rendering.py``) and the benchmarks all sit on top of :class:`UAVCoverageCore`. The rules live beside it, each a
module of pure array functions: ``dynamics.py`` (moves, walls, energy, radio links), ``rewards.py`` (coverage,
entropy, metrics, rewards), ``hazards.py`` (gusts, crashes and link failures, off by default), ``observations.py`` (the
images), ``pois.py`` (PoIs from a lattice or an image) and ``validation.py`` (the parameter checks).

Shapes (N UAVs, K points of interest, map side L, observation side S, block side s = S / L):

- ``positions`` (N, 2) float64, ``energy`` (N,) float64, ``active`` (N,) bool
- ``pois`` (K, 2) float64, ``visits`` (K,) int64 = w(k), ``coverage_scores`` (K,) float64 = c_t(k)
- observations (N, 3, S, S) uint8, ``state()`` (3, S, S) uint8

Every step is one pass of array operations: the UAV-PoI distances are an (N, K) broadcast, the UAV-UAV distances an
(N, N) broadcast, and the observation images are written through reshaped views of an (S, S) image as (L, s, L, s)
blocks, so there is no Python loop over UAVs or PoIs.
"""

from __future__ import annotations

import os

import numpy as np

from .dynamics import ACTION_MODES, WALL_MODES, commanded_move, linked, move_within_walls, step_energy
from .hazards import HAZARD_COUNTS, crash_drain, gust_push, push_within_walls, storm_strikes, surviving_links
from .observations import POSITION_MARKS, ObservationDrawer, uav_values
from .pois import lattice_pois, load_poi_image, pois_from_image
from .rewards import REWARD_MODES, cell_entropy, coverage_credit, covering_pairs, energy_cost, report_reward, team_metrics
from .validation import (
    MAX_MAP_SIZE,
    MAX_OBS_SIZE,
    MAX_STEPS,
    MAX_UAVS,
    check_choice,
    check_int,
    check_points,
    check_real,
    check_step_memory,
    check_zone,
    warn_without_effect,
)

__all__ = [
    "ACTION_MODES",
    "POSITION_MARKS",
    "REWARD_MODES",
    "WALL_MODES",
    "UAVCoverageCore",
    "load_poi_image",
    "pois_from_image",
]

# The smallest side of a PoI image array: narrower arrays (a (K, 3) table, a 2 x 2 "image") are ambiguous
MIN_POI_IMAGE_SIDE = 4


class UAVCoverageCore:
    """
    Multi-UAV coverage simulation (N UAVs over an L x L area with K points of interest), all UAVs stepped at once.

    :param map_size: L, the area is [0, L)^2 in cell units (at most 1024)
    :param n_uavs: N, number of UAVs (at most 1024; with the PoIs and the observation images, a step's arrays must fit
        in 1 GiB each)
    :param pois: ``"grid"`` (the L x L integer lattice), ``"uniform"`` (``n_pois`` points drawn from the seed),
        an array (K, 2) of coordinates, or a grayscale image (path to a PNG/JPEG, or a 2-D array of at least 4 x 4
        pixels; other 2-D arrays are refused as ambiguous)
    :param n_pois: number of PoIs for ``pois="uniform"`` (default L^2); only used there
    :param poi_threshold: for image PoIs, a cell holds a PoI when its mean intensity exceeds this fraction of the
        image's maximum intensity
    :param max_energy: E_max, each UAV's battery at reset
    :param max_distance: l_max, longest move per step
    :param move_energy: eta, energy per unit of distance flown
    :param hover_energy: E_h, energy of a step spent hovering
    :param coverage_range: R0, a PoI within R0 of an active UAV is covered
    :param comm_range: R, an active UAV with no other active UAV within R is disconnected
    :param wall_penalty: p_w, charged for a move that would leave the area
    :param comm_penalty: p_c, charged for each step disconnected
    :param entropy_coef: lambda, weight of the spatial entropy of the UAVs in the shared reward
    :param eps: epsilon in denominators; a UAV is depleted when its energy is <= eps * E_max
    :param max_cycles: T, steps per episode (truncation; at most 10**9)
    :param obs_size: S, observation side in pixels, a positive multiple of L (at most 4096)
    :param start: ``"fixed"`` (drawn once at the first reset, then reused), ``"random"`` (drawn at every reset) or an
        array (N, 2) of start positions
    :param reward_scale: every agent's reward is multiplied by this
    :param reward_clip: if set, rewards are clipped into [-reward_clip, reward_clip]
    :param action_mode: ``"polar"`` (the report's: a = (direction / 2 pi, distance / l_max)) or ``"cartesian"``
        (displacement (dx, dy) = (2 a - 1) l_max, shortened to l_max when longer; a = (0.5, 0.5) hovers)
    :param wall_mode: ``"refuse"`` (the report's: a move that would leave the area is not made and is charged
        ``wall_penalty``) or ``"clip"`` (the UAV stops at the boundary and is charged ``wall_penalty`` times the
        overshoot / l_max, so the penalty grows continuously from 0 with how far the move would have gone out)
    :param reward_mode: ``"report"`` (the report's shared reward: fairness-weighted coverage gain per unit of energy
        plus ``entropy_coef`` times the spatial entropy) or ``"coverage"`` (per-agent credit of order 1: each PoI
        covered this step is worth ``1 - fairness_coef * c_{t-1}(k)``, split equally between the UAVs covering it and
        scaled by N / K, so the agents' rewards sum to N times the team's weighted coverage fraction; minus
        ``energy_coef`` times the UAV's own energy this step / (eta l_max))
    :param fairness_coef: with ``reward_mode="coverage"``, how much less a PoI is worth
        the more it has been covered so far, in [0, 1] (0: every covered PoI counts 1; 1: only the uncovered share of
        its history counts)
    :param energy_coef: with ``reward_mode="coverage"``, the weight of the UAV's own energy (>= 0)
    :param teammate_channel: if True, observations get a fourth channel showing the active teammates within radio
        range R (``comm_range``) of the agent, each on its cell block with its channel-1 value; what a decentralised
        UAV can learn from its links. The state keeps its three channels (it already shows every UAV).
    :param position_mark: how a UAV is drawn on channel 1 of the observations and of the state: ``"cell"`` (the
        report's: its cell's block, so the image tells only which cell it is in) or ``"exact"`` (a square of one
        cell's size centred on its exact position, anti-aliased: each pixel holds the value times the fraction of it
        the square covers, so the mark's centre of mass is the position itself, to the uint8 rounding). Which PoIs a
        disc of radius R0 covers depends on where in its cell the UAV is (29 to 32 lattice PoIs at R0 = 3), so a
        policy that only knows the cell cannot place its disc well
    :param gust_prob: p_g, hazard: the probability that a wind gust hits an active UAV at a step (0, the default, is
        no gusts). A gust pushes the UAV after its own move by a heavy-tailed distance (``gust_scale``,
        ``gust_tail``) in a uniformly random direction; one pushed out of the area stops at the boundary and crashes:
        it is charged ``wall_penalty`` and loses ``crash_energy``
    :param gust_scale: s, the gusts' distance scale: P(distance > x) = (1 + x / s)^(-a)
    :param gust_tail: a, the gusts' tail index (>= 0.5; smaller is heavier: the distance has a finite mean only for
        a > 1 and a finite variance only for a > 2)
    :param crash_energy: E_c, energy a UAV loses when a gust crashes it (never more than it has left); it counts as
        energy spent in the reward and in the energy metric
    :param link_failure_prob: p_f, hazard: the probability that a radio link in range fails at a step, each link on its
        own (0, the default, is no failures); a UAV whose links all fail is disconnected (charged ``comm_penalty``)
    :param crash_ground_steps: k, hazard: a UAV that a gust crashes (or the storm strikes) is grounded for the k steps
        after the crash (0, the default, is never; at most 10**9): it stays where it stopped and does not fly, cover,
        link or spend energy, its observations and teammates' show it as absent, and then it takes off again from
        there. A crash's loss is then spread over k steps of lost coverage instead of one step's energy
        (``crash_energy``)
    :param grounded_penalty: p_d, charged to a grounded UAV at each of its grounded steps (its reward is then
        -``reward_scale`` p_d where a depleted UAV's is 0); needs ``crash_ground_steps`` > 0
    :param show_grounded: if True, a grounded UAV's own observation (and the state) shows its mark with the number of
        grounded steps it has left (1 to k) as its channel-1 value, instead of no mark: where it sits and when it
        flies again are then observable, so its return while grounded is a function of its observation (it stays
        absent from its teammates' teammate channel: it has no links)
    :param storm_zone: hazard: a rectangle (x0, y0, x1, y1) of the area where a storm can strike a UAV down (None, the
        default, is no zone); the same in every episode, like terrain, and not drawn in the observations: a policy
        learns where it is from its own position
    :param storm_prob: p_s, hazard: the probability that an active UAV inside ``storm_zone`` at the end of a step is
        struck (0, the default, is never). A strike does not move the UAV; it is a crash: it loses ``crash_energy``
        and is grounded for ``crash_ground_steps`` (one of the two must be set), counted in the ``crashes``. So the
        zone's PoIs are worth covering on average and costly in the worst case
    """

    def __init__(
        self,
        map_size: int = 16,
        n_uavs: int = 6,
        pois: str | os.PathLike | np.ndarray | list = "grid",
        n_pois: int | None = None,
        poi_threshold: float = 0.1,
        max_energy: float = 500.0,
        max_distance: float = 3.0,
        move_energy: float = 1.0 / 3.0,
        hover_energy: float = 0.5,
        coverage_range: float = 3.0,
        comm_range: float = 6.0,
        wall_penalty: float = 10.0,
        comm_penalty: float = 1.0,
        entropy_coef: float = 0.1,
        eps: float = 1e-4,
        max_cycles: int = 300,
        obs_size: int = 80,
        start: str | np.ndarray | list = "fixed",
        reward_scale: float = 1.0,
        reward_clip: float | None = None,
        action_mode: str = "polar",
        wall_mode: str = "refuse",
        reward_mode: str = "report",
        fairness_coef: float = 0.5,
        energy_coef: float = 0.5,
        teammate_channel: bool = False,
        position_mark: str = "cell",
        gust_prob: float = 0.0,
        gust_scale: float = 1.0,
        gust_tail: float = 2.0,
        crash_energy: float = 0.0,
        link_failure_prob: float = 0.0,
        crash_ground_steps: int = 0,
        grounded_penalty: float = 0.0,
        show_grounded: bool = False,
        storm_zone: tuple[float, float, float, float] | list[float] | None = None,
        storm_prob: float = 0.0,
    ) -> None:
        # --- configuration, validated where it enters -------------------------------------------------------------
        self.map_size = check_int("map_size", map_size, 1, MAX_MAP_SIZE)
        self.n_uavs = check_int("n_uavs", n_uavs, 1, MAX_UAVS)
        self.max_energy = check_real("max_energy", max_energy)
        self.max_distance = check_real("max_distance", max_distance)
        self.move_energy = check_real("move_energy", move_energy)
        self.hover_energy = check_real("hover_energy", hover_energy)
        self.coverage_range = check_real("coverage_range", coverage_range)
        self.comm_range = check_real("comm_range", comm_range)
        if self.coverage_range > self.comm_range:
            raise ValueError(
                f"coverage_range must be <= comm_range (R0 <= R), got coverage_range={coverage_range!r} "
                f"and comm_range={comm_range!r}"
            )
        self.wall_penalty = check_real("wall_penalty", wall_penalty, low_inclusive=True)
        self.comm_penalty = check_real("comm_penalty", comm_penalty, low_inclusive=True)
        self.entropy_coef = check_real("entropy_coef", entropy_coef, low_inclusive=True)
        self.eps = check_real("eps", eps, high=1.0)
        self.max_cycles = check_int("max_cycles", max_cycles, 1, MAX_STEPS)
        self.obs_size = check_int("obs_size", obs_size, 1, MAX_OBS_SIZE)
        if self.obs_size % self.map_size != 0:
            raise ValueError(f"obs_size must be a positive multiple of map_size={self.map_size}, got {obs_size!r}")
        self.reward_scale = check_real("reward_scale", reward_scale)
        self.reward_clip = None if reward_clip is None else check_real("reward_clip", reward_clip)
        self.poi_threshold = check_real("poi_threshold", poi_threshold, low_inclusive=True, high=1.0)
        self.action_mode = check_choice("action_mode", action_mode, ACTION_MODES)
        self.wall_mode = check_choice("wall_mode", wall_mode, WALL_MODES)
        self.reward_mode = check_choice("reward_mode", reward_mode, REWARD_MODES)
        self.fairness_coef = check_real("fairness_coef", fairness_coef, low_inclusive=True, high=1.0, high_inclusive=True)
        self.energy_coef = check_real("energy_coef", energy_coef, low_inclusive=True)
        if not isinstance(teammate_channel, bool | np.bool_):
            raise TypeError(f"teammate_channel must be a bool, got {teammate_channel!r}")
        self.teammate_channel = bool(teammate_channel)
        self.position_mark = check_choice("position_mark", position_mark, POSITION_MARKS)
        # Hazards (all off by default, and then no random number is drawn: v0 and v1 are unchanged).
        self.gust_prob = check_real("gust_prob", gust_prob, low_inclusive=True, high=1.0, high_inclusive=True)
        self.gust_scale = check_real("gust_scale", gust_scale)
        # a >= 0.5: below, a single gust's distance is so heavy-tailed that almost every gust crosses the map
        self.gust_tail = check_real("gust_tail", gust_tail, low=0.5, low_inclusive=True)
        self.crash_energy = check_real("crash_energy", crash_energy, low_inclusive=True)
        # p_f < 1: with certain failure there would be no links at all, a comm_range of 0 in disguise
        self.link_failure_prob = check_real("link_failure_prob", link_failure_prob, low_inclusive=True, high=1.0)
        self.crash_ground_steps = check_int("crash_ground_steps", crash_ground_steps, 0, MAX_STEPS)
        self.grounded_penalty = check_real("grounded_penalty", grounded_penalty, low_inclusive=True)
        if self.grounded_penalty > 0.0 and self.crash_ground_steps == 0:
            raise ValueError(
                f"grounded_penalty={grounded_penalty!r} needs crash_ground_steps >= 1 (without grounding no UAV is "
                "ever grounded); set crash_ground_steps or leave grounded_penalty at 0"
            )
        if not isinstance(show_grounded, (bool, np.bool_)):
            raise TypeError(f"show_grounded must be True or False, got {show_grounded!r}")
        self.show_grounded = bool(show_grounded)
        self.storm_zone = check_zone("storm_zone", storm_zone, self.map_size)
        self.storm_prob = check_real("storm_prob", storm_prob, low_inclusive=True, high=1.0, high_inclusive=True)
        if self.storm_prob > 0.0 and self.storm_zone is None:
            raise ValueError(
                f"storm_prob={storm_prob!r} needs a storm_zone (x0, y0, x1, y1) where the storm strikes; set storm_zone "
                "or leave storm_prob at 0"
            )
        if self.storm_prob > 0.0 and self.crash_ground_steps == 0 and self.crash_energy == 0.0:
            raise ValueError(
                f"storm_prob={storm_prob!r} needs crash_ground_steps >= 1 or crash_energy > 0 (a strike costs what a "
                "crash costs, and with both at 0 it would cost nothing); set one of them or leave storm_prob at 0"
            )
        # Settings that act only with another one: accepted (a sweep may set them beside a zero probability), but said
        crashing = self.gust_prob > 0.0 or self.storm_prob > 0.0
        no_crash = "nothing crashes a UAV without gusts (gust_prob > 0) or a storm (storm_prob > 0)"
        warn_without_effect(
            {
                "storm_zone": (self.storm_zone is not None and self.storm_prob == 0.0, "storm_prob is 0, so no storm strikes"),
                "crash_ground_steps": (self.crash_ground_steps > 0 and not crashing, no_crash),
                "crash_energy": (self.crash_energy > 0.0 and not crashing, no_crash),
                "show_grounded": (
                    self.show_grounded and self.crash_ground_steps == 0,
                    "crash_ground_steps is 0",
                ),
            }
        )
        #: Whether a hazard is switched on (the infos then hold the hazard counters).
        self.hazards = self.gust_prob > 0.0 or self.link_failure_prob > 0.0 or self.storm_prob > 0.0
        #: Channels of an agent's observation: 3, or 4 with the teammate channel.
        self.n_obs_channels = 4 if self.teammate_channel else 3
        check_step_memory(
            "observation images (n_uavs x channels x obs_size^2 bytes)",
            f"n_uavs={self.n_uavs}, obs_size={self.obs_size}",
            self.n_uavs * self.n_obs_channels * self.obs_size**2,
        )
        self._images = ObservationDrawer(self.map_size, self.obs_size, self.position_mark)
        #: s, pixels per cell side of the observation images
        self.block = self._images.block

        # --- PoIs ---------------------------------------------------------------------------------------------------
        self.pois_mode: str
        self.n_pois: int | None = None
        self.pois: np.ndarray | None = None
        if isinstance(pois, str) and pois in ("grid", "uniform"):
            self.pois_mode = pois
            if pois == "uniform":
                self.n_pois = check_int("n_pois", self.map_size**2 if n_pois is None else n_pois, 1, MAX_MAP_SIZE**2)
            else:
                self._set_pois(lattice_pois(self.map_size))
        elif isinstance(pois, str | os.PathLike):
            self.pois_mode = "image"
            self._set_pois(
                pois_from_image(load_poi_image(pois), self.map_size, self.poi_threshold, f"pois={os.fspath(pois)!r}")
            )
        else:
            try:
                array = np.asarray(pois, dtype=np.float64)
            except (TypeError, ValueError) as error:
                raise ValueError(
                    f"pois must be 'grid', 'uniform', an array (K, 2), an image path or a 2-D image array, got {pois!r}"
                ) from error
            # The rule: 2 columns are (x, y) coordinates; an image has at least MIN_POI_IMAGE_SIDE pixels on each side.
            # A (K, 3) array (x, y, weight?) or a tiny image is neither: refused rather than guessed.
            if array.ndim == 2 and array.shape[1] == 2:
                self.pois_mode = "array"
                self._set_pois(check_points("pois", array, None, self.map_size))
            elif array.ndim == 2 and min(array.shape) >= MIN_POI_IMAGE_SIDE:
                self.pois_mode = "image"
                self._set_pois(pois_from_image(array, self.map_size, self.poi_threshold, "pois image array"))
            else:
                raise ValueError(
                    f"pois: an array must have shape (K, 2) (x, y coordinates) or (H, W) with H, W >= "
                    f"{MIN_POI_IMAGE_SIDE} (a grayscale image), got shape {array.shape}; weighted PoIs (x, y, weight) "
                    "are not supported"
                )
        if n_pois is not None and self.pois_mode != "uniform":
            raise ValueError(f"n_pois is only used with pois='uniform', got n_pois={n_pois!r} with pois={self.pois_mode!r}")
        n_pois_total = self.n_pois if self.pois_mode == "uniform" else self.n_pois_total
        check_step_memory(
            "UAV-PoI distances (n_uavs x PoIs x 16 bytes)",
            f"n_uavs={self.n_uavs} with {n_pois_total} PoIs (pois={self.pois_mode!r}, map_size={self.map_size})",
            self.n_uavs * int(n_pois_total or 0) * 16,
        )

        # --- start positions ----------------------------------------------------------------------------------------
        self._start_array: np.ndarray | None = None
        if isinstance(start, str):
            if start not in ("fixed", "random"):
                raise ValueError(f"start must be 'fixed', 'random' or an array of shape ({self.n_uavs}, 2), got {start!r}")
            self.start_mode = start
        else:
            self.start_mode = "array"
            self._start_array = check_points("start", start, self.n_uavs, self.map_size)

        # --- state (filled by reset) --------------------------------------------------------------------------------
        self._rng: np.random.Generator | None = None
        self._fixed_start: np.ndarray | None = None
        n = self.n_uavs
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

        self.visits = np.zeros(0, dtype=np.int64)
        self.coverage_scores = np.zeros(0, dtype=np.float64)
        if self.pois is not None:
            self._build_poi_tables()

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

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool, bool]:
        """
        Move every UAV at once (SPEC rules 1-9).

        :param actions: (N, 2) array, a_i = (direction, distance ratio) in [0, 1]^2; values outside are clipped
        :return: observations (N, 3, S, S) uint8, rewards (N,) float64, terminated, truncated
        :raises ValueError: if the actions have the wrong shape or hold NaN or infinite values
        """
        if self._needs_reset:
            raise RuntimeError("reset() must be called before step() (and again after the episode has ended)")
        actions = np.asarray(actions, dtype=np.float64)
        if actions.shape != (self.n_uavs, 2):
            raise ValueError(f"actions must have shape ({self.n_uavs}, 2), got {actions.shape}")
        if not np.isfinite(actions).all():
            raise ValueError(f"actions must be finite, got {actions.tolist()!r}")
        actions = np.clip(actions, 0.0, 1.0)

        # 2. Only UAVs that are active at the start of the step move, spend energy, cover, count for connectivity and
        # are rewarded; a UAV that runs out during this step still does all of this once. A grounded UAV (hazard)
        # sits this step out and counts one of its grounded steps.
        grounded = self.grounded_steps_left > 0
        active = (self.energy > self.depletion_level) & ~grounded
        self.active[...] = active
        self.grounded_steps_left[grounded] -= 1

        # 1. The commanded displacement: polar (the report's) or Cartesian.
        displacement, rho = commanded_move(actions, self.max_distance, self.action_mode)

        # 3. A move that would leave [0, L)^2: refused and charged p_w (the report's), or stopped at the boundary and
        # charged p_w * overshoot / l_max (v1), in which case the energy is that of the distance actually flown.
        wall_hit, wall_cost, rho = move_within_walls(
            self.positions,
            displacement,
            rho,
            active,
            map_size=self.map_size,
            max_distance=self.max_distance,
            wall_mode=self.wall_mode,
            wall_penalty=self.wall_penalty,
        )

        # 3b. Hazard: a gust pushes each UAV it hits (after its own move); one thrown out of the area stops at the
        # boundary and crashes. Three draws per UAV and step whether or not it is hit, so the stream stays aligned.
        crashed = hit = None
        if self.gust_prob > 0.0:
            hit, push = gust_push(
                self._rng.random((self.n_uavs, 3)),
                active,
                gust_prob=self.gust_prob,
                gust_scale=self.gust_scale,
                gust_tail=self.gust_tail,
                map_size=self.map_size,
            )
            crashed = push_within_walls(self.positions, push, hit, self.map_size)
            self.last_gust[...] = push

        # 3c. Hazard: the storm strikes UAVs inside its zone where they are now; a strike is a crash without the wall
        # (no p_w). One draw per UAV and step, so the stream stays aligned.
        struck = None
        if self.storm_prob > 0.0:
            struck = storm_strikes(
                self._rng.random(self.n_uavs), self.positions, active, zone=self.storm_zone, storm_prob=self.storm_prob
            )
        downed = crashed if struck is None else struck if crashed is None else crashed | struck
        if downed is not None:
            self.last_crashed[...] = downed
            # grounded from the next step on, for k steps
            self.grounded_steps_left[downed] = self.crash_ground_steps

        # 4. Energy, charged also for a refused move, never more than what is left; a crash costs E_c more.
        spent = step_energy(
            rho,
            active,
            self.energy,
            max_distance=self.max_distance,
            move_energy=self.move_energy,
            hover_energy=self.hover_energy,
        )
        if downed is not None:
            spent += crash_drain(downed, self.energy - spent, self.crash_energy)
        self.energy -= spent
        step_energy_sum = float(spent.sum())
        self.total_energy_spent += step_energy_sum

        # 5. Coverage: a PoI is covered when some active UAV is within R0.
        self.t += 1
        previous_sum = float(self.coverage_scores.sum())
        covering = covering_pairs(self.positions, self.pois, active, self.coverage_range)
        self.visits += covering.any(axis=0)
        # Weights of the coverage reward use c_{t-1}(k), read before this step's update.
        if self.reward_mode == "coverage":
            credit = coverage_credit(covering, self.coverage_scores, self.fairness_coef)
        np.divide(self.visits, self.t, out=self.coverage_scores)
        score_sum = float(self.coverage_scores.sum())

        # 6. Connectivity: an active UAV with no other active UAV within R is charged p_c (never when N = 1).
        # Hazard: each link in range fails on its own with probability p_f; a UAV whose links all failed is cut off.
        cut_off = None
        if self.n_uavs > 1:
            # self.active still holds this step's active set (depletion takes effect below, at the end of the step)
            links = self._linked()
            if self.link_failure_prob > 0.0:
                working = surviving_links(links, self._rng.random((self.n_uavs, self.n_uavs)), self.link_failure_prob)
                cut_off = links.any(axis=1) & ~working.any(axis=1)
                links = working
            disconnected = active & ~links.any(axis=1)
        else:
            disconnected = np.zeros(1, dtype=bool)

        # 7. Entropy of the active UAVs' cell histogram.
        entropy = cell_entropy(self.positions, active, self.map_size)

        # 1.5 Metrics.
        self.coverage, self.fairness, self.energy_ratio, self.energy_efficiency = team_metrics(
            self.coverage_scores,
            self.total_energy_spent,
            self.t,
            n_uavs=self.n_uavs,
            move_energy=self.move_energy,
            max_distance=self.max_distance,
            eps=self.eps,
        )

        # 8. Shared reward and per-agent rewards.
        penalties = wall_cost + self.comm_penalty * disconnected
        if crashed is not None:
            penalties = penalties + self.wall_penalty * crashed
        if self.reward_mode == "report":
            shared = report_reward(
                self.fairness,
                score_sum - previous_sum,
                step_energy_sum,
                entropy,
                entropy_coef=self.entropy_coef,
                eps=self.eps,
            )
            rewards = self.reward_scale * (shared - penalties)
        else:
            shared = float(credit.mean())
            own_energy = energy_cost(spent, self.energy_coef, self.move_energy, self.max_distance)
            rewards = self.reward_scale * (credit - own_energy - penalties)
        rewards[~active] = 0.0
        if self.grounded_penalty > 0.0:
            rewards[grounded] = -self.reward_scale * self.grounded_penalty
        # after the inactive UAVs' zeros, which clipping leaves as they are
        if self.reward_clip is not None:
            np.clip(rewards, -self.reward_clip, self.reward_clip, out=rewards)

        self.wall_hits += wall_hit
        self.disconnections += disconnected
        self.last_energy_spent[...] = spent
        self.last_wall_hit[...] = wall_hit
        self.last_disconnected[...] = disconnected
        self.last_penalties[...] = penalties
        self.last_entropy = entropy
        self.last_shared_reward = shared
        self.last_rewards[...] = rewards

        # 9. Termination when every UAV is depleted; truncation at t = T (termination wins when both happen).
        # A grounded UAV is not active until its grounded steps are over, but it is not depleted.
        flying = self.energy > self.depletion_level
        self.active[...] = flying & (self.grounded_steps_left == 0)
        if self.hazards:
            counts = self.hazard_counts
            if hit is not None:
                counts["gusts"] += hit
            if downed is not None:
                counts["crashes"] += downed
            if cut_off is not None:
                counts["link_failures"] += cut_off
            counts["depletions"] += active & ~flying
        terminated = not flying.any()
        truncated = (not terminated) and self.t >= self.max_cycles
        self._needs_reset = terminated or truncated

        self._images.draw_coverage(self.coverage_scores)
        return self.observations(), rewards, terminated, truncated

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
        """Team metrics of SPEC 1.5 after the last step: coverage, fairness, energy and energy_efficiency."""
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
