"""Vectorised numpy simulation of the multi-UAV coverage task.

This module has no Gymnasium or PettingZoo import: the PettingZoo wrapper (``uav_coverage.py``), the rendering
(``rendering.py``) and the benchmarks all sit on top of :class:`UAVCoverageCore`.

Shapes (N UAVs, K points of interest, map side L, observation side S, block side s = S / L):

- ``positions`` (N, 2) float64, ``energy`` (N,) float64, ``active`` (N,) bool
- ``pois`` (K, 2) float64, ``visits`` (K,) int64 = w(k), ``coverage_scores`` (K,) float64 = c_t(k)
- observations (N, 3, S, S) uint8, ``state()`` (3, S, S) uint8

Every step is one pass of array operations: the UAV-PoI distances are an (N, K) broadcast, the UAV-UAV distances an
(N, N) broadcast, and the observation images are written through reshaped views of an (S, S) image as (L, s, L, s)
blocks, so there is no Python loop over UAVs or PoIs.
"""

from __future__ import annotations

import math
import numbers
import os
from typing import Any

import numpy as np

__all__ = ["UAVCoverageCore", "load_poi_image", "pois_from_image"]

_TWO_PI = 2.0 * math.pi
# Bounds of every real parameter: with them, squared ranges, energies times distances, rewards times reward_scale and
# quotients by eps stay finite and non-zero, so every accepted configuration runs.
_MAX_REAL = 1e12
_MIN_POSITIVE = 1e-12

#: The rules a v1 env may switch; the first of each is the report's (``uav_coverage_v0``).
ACTION_MODES = ("polar", "cartesian")
WALL_MODES = ("refuse", "clip")
REWARD_MODES = ("report", "coverage")
POSITION_MARKS = ("cell", "exact")


# ---------------------------------------------------------------------------------------------------------------------
# Validation helpers: every message names the parameter, the value received and what is accepted.
# ---------------------------------------------------------------------------------------------------------------------
def _check_int(name: str, value: Any, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or int(value) < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def _check_real(
    name: str,
    value: Any,
    *,
    low: float = 0.0,
    low_inclusive: bool = False,
    high: float | None = None,
    high_inclusive: bool = False,
) -> float:
    ok = isinstance(value, numbers.Real) and not isinstance(value, bool) and math.isfinite(float(value))
    if ok:
        value_f = float(value)
        ok = value_f >= low if low_inclusive else value_f > low
        if high is not None:
            ok = ok and (value_f <= high if high_inclusive else value_f < high)
    if not ok:
        accepted = f"a finite number {'>=' if low_inclusive else '>'} {low:g}"
        if high is not None:
            accepted += f" and {'<=' if high_inclusive else '<'} {high:g}"
        raise ValueError(f"{name} must be {accepted}, got {value!r}")
    if abs(float(value)) > _MAX_REAL or (low == 0.0 and not low_inclusive and float(value) < _MIN_POSITIVE):
        lowest, highest = (0.0 if low_inclusive else _MIN_POSITIVE), (_MAX_REAL if high is None else high)
        interval = f"[{lowest:g}, {highest:g}{']' if high is None else ')'}"
        raise ValueError(
            f"{name} must lie in {interval} (beyond, the simulation's squares, products and quotients overflow "
            f"or divide by zero), got {value!r}"
        )
    return float(value)


def _check_choice(name: str, value: Any, choices: tuple[str, ...]) -> str:
    if not isinstance(value, str) or value not in choices:
        raise ValueError(f"{name} must be one of {', '.join(map(repr, choices))}, got {value!r}")
    return value


def _check_points(name: str, value: Any, n_rows: int | None, map_size: int) -> np.ndarray:
    """Check an array of map points of shape (n_rows, 2) (any number of rows when ``n_rows`` is None)."""
    try:
        points = np.array(value, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise ValueError(f"{name} must be an array of shape ({n_rows or 'K'}, 2) of numbers, got {value!r}") from error
    expected = f"({n_rows if n_rows is not None else 'K'}, 2)"
    if points.ndim != 2 or points.shape[1] != 2 or points.shape[0] < 1 or (n_rows is not None and points.shape[0] != n_rows):
        raise ValueError(f"{name} must be an array of shape {expected}, got shape {points.shape}")
    if not np.isfinite(points).all() or (points < 0).any() or (points >= map_size).any():
        raise ValueError(f"{name} must lie inside the area [0, {map_size})^2, got {points.tolist()!r}")
    return points


# ---------------------------------------------------------------------------------------------------------------------
# PoIs from a grayscale image
# ---------------------------------------------------------------------------------------------------------------------
def load_poi_image(path: str | os.PathLike) -> np.ndarray:
    """
    Read a PNG/JPEG (or any image Pillow reads) as a 2-D float64 grayscale array, at the image's own depth.

    8-bit images give their luminance (0-255); 16-bit and 32-bit grayscale and float images give their values unchanged
    (a 16-bit PNG is not cut down to 8 bits, which would saturate it). An image with an alpha channel whose colour is
    the same everywhere (PoIs marked only by transparency) gives its alpha channel.

    :param path: the image file
    :return: array of shape (H, W), the intensity of each pixel
    :raises ValueError: if the file is missing, is a folder or is not an image
    """
    path = os.fspath(path)
    if os.path.isdir(path):
        raise ValueError(f"pois: {path!r} is a directory, not an image file (give the path of a PNG/JPEG file)")
    if not os.path.isfile(path):
        raise ValueError(
            f"pois: image file {path!r} does not exist (pois accepts 'grid', 'uniform', an array (K, 2), "
            "an image path or a 2-D image array)"
        )
    # Pillow is only needed for image files, so it is imported here.
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(path) as image:
            if image.mode in ("I", "F") or image.mode.startswith("I;16"):
                return np.asarray(image, dtype=np.float64)
            luminance = np.asarray(image.convert("L"), dtype=np.float64)
            if "A" in image.getbands() or (image.mode == "P" and "transparency" in image.info):
                alpha = np.asarray(image.convert("RGBA").getchannel("A"), dtype=np.float64)
                if luminance.min() == luminance.max() and alpha.min() != alpha.max():
                    return alpha
            return luminance
    except (UnidentifiedImageError, OSError) as error:
        raise ValueError(f"pois: file {path!r} is not an image Pillow can read ({error})") from error


def _area_weights(n_in: int, n_out: int) -> np.ndarray:
    """(n_out, n_in) matrix whose row i averages the input pixels over output cell i, weighted by overlap length."""
    # Input pixel j covers [j, j + 1) * n_out / n_in on the output axis; output cell i covers [i, i + 1).
    edges = np.arange(n_in + 1, dtype=np.float64) * (n_out / n_in)
    lo = np.maximum(edges[None, :-1], np.arange(n_out, dtype=np.float64)[:, None])
    hi = np.minimum(edges[None, 1:], np.arange(1, n_out + 1, dtype=np.float64)[:, None])
    overlap = np.clip(hi - lo, 0.0, None)
    return overlap / overlap.sum(axis=1, keepdims=True)


def pois_from_image(image: np.ndarray, map_size: int, threshold: float, name: str = "pois") -> np.ndarray:
    """
    Turn a grayscale image into PoIs: one PoI at the centre of each map cell whose mean intensity is high enough.

    The image is resized to ``map_size`` x ``map_size`` cells by area averaging (each cell is the overlap-weighted mean
    of the pixels it covers). Image column j is x, image row 0 is the top of the map (y near L).

    :param image: array of shape (H, W)
    :param map_size: the map side L
    :param threshold: a cell holds a PoI when its mean exceeds ``threshold`` times the image's maximum intensity
    :param name: what to call the image in error messages
    :return: PoI coordinates of shape (K, 2)
    :raises ValueError: if the image has the wrong shape or no cell exceeds the threshold
    """
    image = np.asarray(image, dtype=np.float64)
    if image.ndim != 2 or min(image.shape) < 1:
        raise ValueError(f"{name}: a grayscale image must be a 2-D array, got shape {image.shape}")
    if not np.isfinite(image).all():
        raise ValueError(f"{name}: the image holds NaN or infinite values")
    height, width = image.shape
    cells = _area_weights(height, map_size) @ image @ _area_weights(width, map_size).T  # (L rows, L cols)
    peak = float(image.max())
    rows, cols = np.nonzero(cells > threshold * peak) if peak > 0 else (np.array([], int), np.array([], int))
    if rows.size == 0:
        raise ValueError(f"{name}: no cell of the image has a mean intensity above poi_threshold={threshold} of its maximum")
    # Row 0 is the top of the map, so image row i is the cell row y = L - 1 - i.
    return np.stack([cols + 0.5, (map_size - 1 - rows) + 0.5], axis=1).astype(np.float64)


# ---------------------------------------------------------------------------------------------------------------------
# The simulation
# ---------------------------------------------------------------------------------------------------------------------
class UAVCoverageCore:
    """
    Multi-UAV coverage simulation (N UAVs over an L x L area with K points of interest), all UAVs stepped at once.

    :param map_size: L, the area is [0, L)^2 in cell units
    :param n_uavs: N, number of UAVs
    :param pois: ``"grid"`` (the L x L integer lattice), ``"uniform"`` (``n_pois`` points drawn from the seed),
        an array (K, 2) of coordinates, or a grayscale image (path to a PNG/JPEG, or a 2-D array)
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
    :param max_cycles: T, steps per episode (truncation)
    :param obs_size: S, observation side in pixels, a positive multiple of L
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
    ) -> None:
        # --- configuration, validated where it enters -------------------------------------------------------------
        self.map_size = _check_int("map_size", map_size, 1)
        self.n_uavs = _check_int("n_uavs", n_uavs, 1)
        self.max_energy = _check_real("max_energy", max_energy)
        self.max_distance = _check_real("max_distance", max_distance)
        self.move_energy = _check_real("move_energy", move_energy)
        self.hover_energy = _check_real("hover_energy", hover_energy)
        self.coverage_range = _check_real("coverage_range", coverage_range)
        self.comm_range = _check_real("comm_range", comm_range)
        if self.coverage_range > self.comm_range:
            raise ValueError(
                f"coverage_range must be <= comm_range (R0 <= R), got coverage_range={coverage_range!r} "
                f"and comm_range={comm_range!r}"
            )
        self.wall_penalty = _check_real("wall_penalty", wall_penalty, low_inclusive=True)
        self.comm_penalty = _check_real("comm_penalty", comm_penalty, low_inclusive=True)
        self.entropy_coef = _check_real("entropy_coef", entropy_coef, low_inclusive=True)
        self.eps = _check_real("eps", eps, high=1.0)
        self.max_cycles = _check_int("max_cycles", max_cycles, 1)
        self.obs_size = _check_int("obs_size", obs_size, 1)
        if self.obs_size % self.map_size != 0:
            raise ValueError(f"obs_size must be a positive multiple of map_size={self.map_size}, got {obs_size!r}")
        self.reward_scale = _check_real("reward_scale", reward_scale)
        self.reward_clip = None if reward_clip is None else _check_real("reward_clip", reward_clip)
        self.poi_threshold = _check_real("poi_threshold", poi_threshold, low_inclusive=True, high=1.0)
        self.action_mode = _check_choice("action_mode", action_mode, ACTION_MODES)
        self.wall_mode = _check_choice("wall_mode", wall_mode, WALL_MODES)
        self.reward_mode = _check_choice("reward_mode", reward_mode, REWARD_MODES)
        self.fairness_coef = _check_real("fairness_coef", fairness_coef, low_inclusive=True, high=1.0, high_inclusive=True)
        self.energy_coef = _check_real("energy_coef", energy_coef, low_inclusive=True)
        if not isinstance(teammate_channel, bool | np.bool_):
            raise TypeError(f"teammate_channel must be a bool, got {teammate_channel!r}")
        self.teammate_channel = bool(teammate_channel)
        self.position_mark = _check_choice("position_mark", position_mark, POSITION_MARKS)
        #: Channels of an agent's observation: 3, or 4 with the teammate channel.
        self.n_obs_channels = 4 if self.teammate_channel else 3

        # --- PoIs ---------------------------------------------------------------------------------------------------
        self.pois_mode: str
        self.n_pois: int | None = None
        self.pois: np.ndarray | None = None
        if isinstance(pois, str) and pois in ("grid", "uniform"):
            self.pois_mode = pois
            if pois == "uniform":
                self.n_pois = _check_int("n_pois", self.map_size**2 if n_pois is None else n_pois, 1)
            else:
                lattice = np.arange(self.map_size, dtype=np.float64)
                xx, yy = np.meshgrid(lattice, lattice, indexing="xy")
                self._set_pois(np.stack([xx.ravel(), yy.ravel()], axis=1))
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
            if array.ndim == 2 and array.shape[1] == 2:
                self.pois_mode = "array"
                self._set_pois(_check_points("pois", array, None, self.map_size))
            elif array.ndim == 2:
                self.pois_mode = "image"
                self._set_pois(pois_from_image(array, self.map_size, self.poi_threshold, "pois image array"))
            else:
                raise ValueError(
                    f"pois: an array must have shape (K, 2) (coordinates) or (H, W) (grayscale image), got shape {array.shape}"
                )
        if n_pois is not None and self.pois_mode != "uniform":
            raise ValueError(f"n_pois is only used with pois='uniform', got n_pois={n_pois!r} with pois={self.pois_mode!r}")

        # --- start positions ----------------------------------------------------------------------------------------
        self._start_array: np.ndarray | None = None
        if isinstance(start, str):
            if start not in ("fixed", "random"):
                raise ValueError(f"start must be 'fixed', 'random' or an array of shape ({self.n_uavs}, 2), got {start!r}")
            self.start_mode = start
        else:
            self.start_mode = "array"
            self._start_array = _check_points("start", start, self.n_uavs, self.map_size)

        # --- state (filled by reset) --------------------------------------------------------------------------------
        self._rng: np.random.Generator | None = None
        self._fixed_start: np.ndarray | None = None
        n = self.n_uavs
        self.positions = np.zeros((n, 2), dtype=np.float64)
        self.energy = np.full(n, self.max_energy, dtype=np.float64)
        self.active = np.ones(n, dtype=bool)
        self.t = 0
        self.total_energy_spent = 0.0
        self.wall_hits = np.zeros(n, dtype=np.int64)
        self.disconnections = np.zeros(n, dtype=np.int64)
        # What happened at the last step, kept for tests, rendering and debugging.
        self.last_energy_spent = np.zeros(n, dtype=np.float64)
        self.last_wall_hit = np.zeros(n, dtype=bool)
        self.last_disconnected = np.zeros(n, dtype=bool)
        self.last_penalties = np.zeros(n, dtype=np.float64)
        self.last_entropy = 0.0
        self.last_shared_reward = 0.0
        self.last_rewards = np.zeros(n, dtype=np.float64)
        self.coverage = 0.0
        self.fairness = 0.0
        self.energy_ratio = 0.0
        self.energy_efficiency = 0.0
        self._needs_reset = True

        # Block geometry of the observation: an (S, S) image is an (L, s, L, s) view of cell blocks.
        self.block = self.obs_size // self.map_size
        self._arange_n = np.arange(n)
        self._template = np.zeros((3, self.obs_size, self.obs_size), dtype=np.uint8)
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

    def _blocks(self, image: np.ndarray) -> np.ndarray:
        """View of an (..., S, S) image as (..., L, s, L, s): index [..., row_cell, :, col_cell, :] is one cell block."""
        size, block = self.map_size, self.block
        return image.reshape(*image.shape[:-2], size, block, size, block)

    def cells_of(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """
        Cell of each point, as block indices of the observation image.

        :param points: (M, 2) map coordinates
        :return: (block_row, block_col), each (M,) int: block_row = L - 1 - floor(y), block_col = floor(x), clamped
        """
        cells = np.clip(np.floor(points).astype(np.int64), 0, self.map_size - 1)
        return self.map_size - 1 - cells[:, 1], cells[:, 0]

    def _set_pois(self, pois: np.ndarray) -> None:
        self.pois = np.ascontiguousarray(pois, dtype=np.float64)

    def _build_poi_tables(self) -> None:
        """Build what depends only on the PoIs: channel 0 and the PoI -> cell grouping used by channel 2."""
        assert self.pois is not None
        k = len(self.pois)
        self.visits = np.zeros(k, dtype=np.int64)
        self.coverage_scores = np.zeros(k, dtype=np.float64)
        rows, cols = self.cells_of(self.pois)
        flat = rows * self.map_size + cols
        # Channel 2 takes the maximum c_t(k) over the PoIs of a cell: sort the PoIs by cell once, then one
        # np.maximum.reduceat per step gives every cell's maximum.
        self._poi_order = np.argsort(flat, kind="stable")
        sorted_flat = flat[self._poi_order]
        self._cell_starts = np.flatnonzero(np.r_[True, sorted_flat[1:] != sorted_flat[:-1]])
        self._poi_cells = sorted_flat[self._cell_starts]  # flat index of each cell holding at least one PoI
        self._one_poi_per_cell = len(self._poi_cells) == k
        self._cell_values = np.zeros(self.map_size * self.map_size, dtype=np.uint8)
        # Channel 0 is constant for the whole run: 255 on every cell block holding a PoI.
        poi_grid = np.zeros(self.map_size * self.map_size, dtype=np.uint8)
        poi_grid[self._poi_cells] = 255
        self._blocks(self._template[0])[...] = poi_grid.reshape(self.map_size, 1, self.map_size, 1)
        self._template[1:] = 0

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
        self.t = 0
        self.total_energy_spent = 0.0
        self.wall_hits.fill(0)
        self.disconnections.fill(0)
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
        self._template[2] = 0
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
        # are rewarded; a UAV that runs out during this step still does all of this once.
        active = self.energy > self.depletion_level
        self.active[...] = active

        # 1. The commanded displacement: polar (the report's) or Cartesian.
        displacement, rho = self._displacement(actions)
        target = self.positions + displacement

        # 3. A move that would leave [0, L)^2: refused and charged p_w (the report's), or stopped at the boundary and
        # charged p_w * overshoot / l_max (v1), in which case the energy is that of the distance actually flown.
        inside = ((target >= 0.0) & (target < self.map_size)).all(axis=1)
        wall_hit = active & ~inside
        if self.wall_mode == "refuse":
            moved = active & inside
            self.positions[moved] = target[moved]
            wall_cost = self.wall_penalty * wall_hit
        else:
            clipped = np.clip(target, 0.0, np.nextafter(float(self.map_size), 0.0))
            overshoot = np.sqrt(np.einsum("nd,nd->n", target - clipped, target - clipped))
            flown = np.sqrt(np.einsum("nd,nd->n", clipped - self.positions, clipped - self.positions))
            self.positions[active] = clipped[active]
            rho = np.where(active, np.minimum(flown / self.max_distance, 1.0), rho)
            wall_cost = np.where(wall_hit, self.wall_penalty * overshoot / self.max_distance, 0.0)
        length = rho * self.max_distance

        # 4. Energy, charged also for a refused move, never more than what is left.
        spent = np.where(active, np.minimum(self.move_energy * length + self.hover_energy * (1.0 - rho), self.energy), 0.0)
        self.energy -= spent
        step_energy = float(spent.sum())
        self.total_energy_spent += step_energy

        # 5. Coverage: (N, K) squared distances, a PoI is covered when some active UAV is within R0.
        self.t += 1
        previous_sum = float(self.coverage_scores.sum())
        diff = self.pois[None, :, :] - self.positions[:, None, :]
        sq_dist = np.einsum("nkd,nkd->nk", diff, diff)
        covering = (sq_dist <= self.coverage_range**2) & active[:, None]
        self.visits += covering.any(axis=0)
        # Weights of the coverage reward use c_{t-1}(k), read before this step's update.
        if self.reward_mode == "coverage":
            credit = self._coverage_credit(covering)
        np.divide(self.visits, self.t, out=self.coverage_scores)
        score_sum = float(self.coverage_scores.sum())

        # 6. Connectivity: an active UAV with no other active UAV within R is charged p_c (never when N = 1).
        if self.n_uavs > 1:
            # self.active still holds this step's active set (depletion takes effect below, at the end of the step)
            disconnected = active & ~self._linked().any(axis=1)
        else:
            disconnected = np.zeros(1, dtype=bool)

        # 7. Entropy of the active UAVs' cell histogram.
        entropy = 0.0
        n_active = int(active.sum())
        if n_active > 1:
            cells = np.floor(self.positions[active]).astype(np.int64)
            _, counts = np.unique(cells[:, 0] * self.map_size + cells[:, 1], return_counts=True)
            p = counts / n_active
            entropy = float(-(p * np.log(p)).sum())

        # 1.5 Metrics.
        k = len(self.coverage_scores)
        square_sum = float(np.dot(self.coverage_scores, self.coverage_scores))
        self.coverage = score_sum / k
        # Jain's index is <= 1 exactly; min() only removes a last-bit rounding excess.
        self.fairness = min(score_sum * score_sum / (k * square_sum), 1.0) if square_sum > 0.0 else 0.0
        self.energy_ratio = self.total_energy_spent / (self.n_uavs * self.t * self.move_energy * self.max_distance)
        self.energy_efficiency = self.fairness * self.coverage / (self.energy_ratio + self.eps)

        # 8. Shared reward and per-agent rewards.
        penalties = wall_cost + self.comm_penalty * disconnected
        if self.reward_mode == "report":
            shared = self.fairness * (score_sum - previous_sum) / (step_energy + self.eps) + self.entropy_coef * entropy
            rewards = self.reward_scale * (shared - penalties)
        else:
            shared = float(credit.mean())
            own_energy = self.energy_coef * spent / (self.move_energy * self.max_distance)
            rewards = self.reward_scale * (credit - own_energy - penalties)
        if self.reward_clip is not None:
            np.clip(rewards, -self.reward_clip, self.reward_clip, out=rewards)
        rewards[~active] = 0.0

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
        self.active[...] = self.energy > self.depletion_level
        terminated = not self.active.any()
        truncated = (not terminated) and self.t >= self.max_cycles
        self._needs_reset = terminated or truncated

        self._update_coverage_channel()
        return self.observations(), rewards, terminated, truncated

    def _displacement(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """
        Commanded displacement of every UAV (before the wall rule).

        :param actions: (N, 2) in [0, 1]^2
        :return: displacement (N, 2) and distance ratio rho = length / l_max (N,); polar:
            rho l_max (cos 2 pi a_0, sin 2 pi a_0) with rho = a_1; Cartesian: (2 a - 1) l_max, scaled down to length
            l_max where it is longer
        """
        if self.action_mode == "polar":
            theta = _TWO_PI * actions[:, 0]
            rho = actions[:, 1]
            displacement = (rho * self.max_distance)[:, None] * np.stack([np.cos(theta), np.sin(theta)], axis=1)
            return displacement, rho
        displacement = (2.0 * actions - 1.0) * self.max_distance
        norm = np.sqrt(np.einsum("nd,nd->n", displacement, displacement))
        rho = np.minimum(norm / self.max_distance, 1.0)
        return displacement * (rho * self.max_distance / np.maximum(norm, 1e-12))[:, None], rho

    def _coverage_credit(self, covering: np.ndarray) -> np.ndarray:
        """
        Each UAV's credit for this step's weighted coverage (``reward_mode="coverage"``): each covered PoI's worth
        is split equally between the UAVs covering it.

        :param covering: (N, K) bool, PoI k within R0 of UAV i after the move, UAV i active this step
        :return: (N,) credit: (N / K) sum_k [i covers k] (1 - fairness_coef c_{t-1}(k)) / (number of UAVs covering k)
        """
        # c_{t-1}(k) = visits before this step / (t - 1); coverage_scores still holds it (0 at the first step).
        weight = 1.0 - self.fairness_coef * self.coverage_scores
        weight = weight / np.maximum(covering.sum(axis=0), 1)
        return covering @ weight * (self.n_uavs / len(weight))

    # -----------------------------------------------------------------------------------------------------------------
    # Observations and state
    # -----------------------------------------------------------------------------------------------------------------
    def _update_coverage_channel(self) -> None:
        """Rewrite channel 2 of the shared template: round(255 c_t(k)) on each PoI's block (max within a cell)."""
        values = np.rint(self.coverage_scores * 255.0).astype(np.uint8)
        if self._one_poi_per_cell:
            self._cell_values[self._poi_cells] = values[self._poi_order]
        else:
            self._cell_values[self._poi_cells] = np.maximum.reduceat(values[self._poi_order], self._cell_starts)
        size = self.map_size
        self._blocks(self._template[2])[...] = self._cell_values.reshape(size, 1, size, 1)

    def _self_values(self) -> np.ndarray:
        """Channel-1 value of each UAV: round(255 E_i / E_max), at least 1 while active, 0 once depleted."""
        values = np.rint(255.0 * self.energy / self.max_energy)
        values = np.where(self.active, np.maximum(values, 1.0), 0.0)
        return values.astype(np.uint8)

    def observations(self) -> np.ndarray:
        """
        Every agent's observation, in a new array (the env never writes into an array it has returned).

        :return: (N, C, S, S) uint8; channel 0 PoIs, channel 1 the agent's own cell, channel 2 coverage history and,
            with ``teammate_channel``, channel 3 the active teammates within R (C = ``n_obs_channels``)
        """
        obs = np.empty((self.n_uavs, self.n_obs_channels, self.obs_size, self.obs_size), dtype=np.uint8)
        obs[:, :3] = self._template  # channels 0 and 2 are shared; channel 1 of the template is all zeros
        rows, cols = self.cells_of(self.positions)
        values = self._self_values()
        blocks = self._blocks(obs)
        if self.position_mark == "exact":
            obs[:, 1] = self._exact_marks(self.positions, values)
        else:
            # Advanced indices split by slices: the selection has shape (N, s, s), one block per agent.
            blocks[self._arange_n, 1, rows, :, cols, :] = values[:, None, None]
        if self.teammate_channel:
            observer, seen = np.nonzero(self._linked())
            grid = np.zeros((self.n_uavs, self.map_size, self.map_size), dtype=np.uint8)
            # Teammates sharing a cell write the same block; the largest value wins, as in the state.
            np.maximum.at(grid, (observer, rows[seen], cols[seen]), values[seen])
            blocks[:, 3] = grid[:, :, None, :, None]
        return obs

    def state(self) -> np.ndarray:
        """
        Global view for centralised critics: the observation image with channel 1 showing every active UAV.

        :return: (3, S, S) uint8 (maximum value where UAVs share a cell)
        """
        image = self._template.copy()
        if self.position_mark == "exact":
            image[1] = self._exact_marks(self.positions, self._self_values()).max(axis=0)
            return image
        rows, cols = self.cells_of(self.positions)
        grid = np.zeros((self.map_size, self.map_size), dtype=np.uint8)
        np.maximum.at(grid, (rows, cols), self._self_values())
        self._blocks(image[1])[...] = grid[:, None, :, None]
        return image

    def _exact_marks(self, points: np.ndarray, values: np.ndarray) -> np.ndarray:
        """
        Anti-aliased marks of ``position_mark="exact"``: a square of one cell's size centred on each point.

        In pixel units (x s, y s) the square spans [x s - s/2, x s + s/2] on each axis; a pixel's weight is the
        product of its overlaps with the square on the two axes, in [0, 1], and the mark is round(value x weight).
        Inside the image the weights sum to s^2 and their centre of mass, in pixel indices, is (x s - 1/2) along the
        columns and (S - 1/2 - y s) along the rows; within half a cell of a wall the square is cut, and the centre
        of mass still moves monotonically with the point.

        :param points: (M, 2) map coordinates
        :param values: (M,) mark values (uint8 range)
        :return: (M, S, S) uint8, row 0 at the top (the largest y), as every channel
        """
        half, size = self.block / 2.0, self.obs_size
        edges = np.arange(size + 1, dtype=np.float64)

        def overlaps(centres: np.ndarray) -> np.ndarray:
            low, high = centres[:, None] - half, centres[:, None] + half
            return np.clip(np.minimum(edges[None, 1:], high) - np.maximum(edges[None, :-1], low), 0.0, 1.0)

        by_col = overlaps(points[:, 0] * self.block)  # (M, S), column j covers x s in [j, j + 1]
        by_row = overlaps(points[:, 1] * self.block)[:, ::-1]  # row r covers y s in [S - 1 - r, S - r]
        marks = values.astype(np.float64)[:, None, None] * by_row[:, :, None] * by_col[:, None, :]
        return np.rint(marks).astype(np.uint8)

    # -----------------------------------------------------------------------------------------------------------------
    # Helpers for the wrapper, rendering and evaluation
    # -----------------------------------------------------------------------------------------------------------------
    def _linked(self) -> np.ndarray:
        """(N, N) bool: active UAVs i != j within R of each other (the communication graph)."""
        pair = self.positions[:, None, :] - self.positions[None, :, :]
        linked = (np.einsum("ijd,ijd->ij", pair, pair) <= self.comm_range**2) & self.active[None, :] & self.active[:, None]
        np.fill_diagonal(linked, False)
        return linked

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
        """One info dict per UAV: the team metrics plus this UAV's ``wall_hits`` and ``disconnections`` so far."""
        shared = self.metrics()
        walls = self.wall_hits.tolist()
        disconnections = self.disconnections.tolist()
        return [{**shared, "wall_hits": walls[i], "disconnections": disconnections[i]} for i in range(self.n_uavs)]
