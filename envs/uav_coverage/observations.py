"""
The observation images and the state: an (S, S) image of an L x L map, s = S / L pixels per cell.

Channels: 0 the PoIs (255 on every cell holding one, drawn once per set of PoIs), 1 the UAVs (round(255 E / E_max),
at least 1 while active; the agent itself in an observation, every UAV in the state), 2 the coverage history
(round(255 c_t(k)), the maximum over a cell's PoIs), and in observations with the teammate channel 3 the active
teammates within radio range R. Row 0 is the top of the map (the largest y). With a storm zone shown, channel 0
holds 128 on the zone's PoI cells and 64 on its other pixels (a pixel is in the zone when its centre is).

Images are written through reshaped views of (S, S) as (L, s, L, s) cell blocks, so there is no Python loop over
UAVs or PoIs.
"""

from __future__ import annotations

import numpy as np

from .hazards import in_zone

__all__ = ["POSITION_MARKS", "ZONE_EMPTY_VALUE", "ZONE_POI_VALUE", "ObservationDrawer", "uav_values", "zone_pixels"]

#: How a UAV is drawn on channel 1; the first is the report's (``uav_coverage_v0``), the second v1's.
POSITION_MARKS = ("cell", "exact")
#: Channel 0 inside a shown storm zone: a PoI cell's pixels (255 outside the zone) and the other pixels (0 outside).
#: Both are apart from 0 and 255, so the zone and the PoIs stay readable at once.
ZONE_POI_VALUE = 128
ZONE_EMPTY_VALUE = 64


def zone_pixels(zone: tuple[float, float, float, float], map_size: int, obs_size: int) -> np.ndarray:
    """
    The pixels of an (S, S) image whose centre lies in a rectangle of the map (lower edges included, upper ones
    excluded, as for the storm's strikes). Pixel (r, c) has its centre at map point ((c + 1/2) / s, (S - r - 1/2) / s),
    s = S / L.

    :param zone: (x0, y0, x1, y1)
    :param map_size: L
    :param obs_size: S
    :return: (S, S) bool, row 0 at the top (the largest y)
    """
    centres = (np.arange(obs_size, dtype=np.float64) + 0.5) * (map_size / obs_size)
    xx, yy = np.meshgrid(centres, centres[::-1], indexing="xy")
    return in_zone(np.stack([xx.ravel(), yy.ravel()], axis=1), zone).reshape(obs_size, obs_size)


def uav_values(energy: np.ndarray, max_energy: float, active: np.ndarray) -> np.ndarray:
    """Channel-1 value of each UAV: round(255 E_i / E_max), at least 1 while active, 0 once depleted; (N,) uint8."""
    values = np.rint(255.0 * energy / max_energy)
    values = np.where(active, np.maximum(values, 1.0), 0.0)
    return values.astype(np.uint8)


class ObservationDrawer:
    """
    Draws the observations and the state of one env. Channels 0 and 2, shared by every agent and the state, live in
    a template: channel 0 is drawn by :meth:`set_pois`, channel 2 by :meth:`draw_coverage` after every step.

    :param map_size: L
    :param obs_size: S, a positive multiple of L
    :param position_mark: ``"cell"`` (a UAV fills its cell's block) or ``"exact"`` (an anti-aliased square of one
        cell's size centred on its exact position)
    :param storm_zone: a rectangle (x0, y0, x1, y1) drawn on channel 0 (:data:`ZONE_POI_VALUE`,
        :data:`ZONE_EMPTY_VALUE`), or None to draw none
    """

    #: a class default, so that a drawer pickled before the zone could be drawn reads as drawing none
    storm_zone: tuple[float, float, float, float] | None = None

    def __init__(
        self, map_size: int, obs_size: int, position_mark: str, storm_zone: tuple[float, float, float, float] | None = None
    ) -> None:
        self.map_size = map_size
        self.obs_size = obs_size
        self.position_mark = position_mark
        self.storm_zone = storm_zone
        #: s, pixels per cell side
        self.block = obs_size // map_size
        self.template = np.zeros((3, obs_size, obs_size), dtype=np.uint8)

    def blocks(self, image: np.ndarray) -> np.ndarray:
        """View of an (..., S, S) image as (..., L, s, L, s): index [..., row_cell, :, col_cell, :] is one cell block."""
        size, block = self.map_size, self.block
        return image.reshape(*image.shape[:-2], size, block, size, block)

    def cells_of(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """
        Cell of each point, as block indices of the image.

        :param points: (M, 2) map coordinates
        :return: (block_row, block_col), each (M,) int: block_row = L - 1 - floor(y), block_col = floor(x), clamped
        """
        cells = np.clip(np.floor(points).astype(np.int64), 0, self.map_size - 1)
        return self.map_size - 1 - cells[:, 1], cells[:, 0]

    def set_pois(self, pois: np.ndarray) -> None:
        """Draw channel 0 and group the PoIs by cell for channel 2 (what depends only on the PoIs, (K, 2))."""
        k = len(pois)
        rows, cols = self.cells_of(pois)
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
        self.blocks(self.template[0])[...] = poi_grid.reshape(self.map_size, 1, self.map_size, 1)
        if self.storm_zone is not None:
            inside = zone_pixels(self.storm_zone, self.map_size, self.obs_size)
            self.template[0][inside] = np.where(self.template[0][inside] > 0, ZONE_POI_VALUE, ZONE_EMPTY_VALUE)
        self.template[1:] = 0

    def clear_coverage(self) -> None:
        """Empty channel 2 (at reset)."""
        self.template[2] = 0

    def draw_coverage(self, coverage_scores: np.ndarray) -> None:
        """Rewrite channel 2: round(255 c_t(k)) on each PoI's block (max within a cell); ``coverage_scores`` (K,)."""
        values = np.rint(coverage_scores * 255.0).astype(np.uint8)
        if self._one_poi_per_cell:
            self._cell_values[self._poi_cells] = values[self._poi_order]
        else:
            self._cell_values[self._poi_cells] = np.maximum.reduceat(values[self._poi_order], self._cell_starts)
        size = self.map_size
        self.blocks(self.template[2])[...] = self._cell_values.reshape(size, 1, size, 1)

    def observations(self, positions: np.ndarray, values: np.ndarray, links: np.ndarray | None) -> np.ndarray:
        """
        Every agent's observation, in a new array.

        :param positions: (N, 2) the UAVs' positions
        :param values: (N,) uint8 their channel-1 values (:func:`uav_values`)
        :param links: (N, N) bool communication graph for the teammate channel, or None for no teammate channel
        :return: (N, C, S, S) uint8, C = 3, or 4 with the teammate channel
        """
        n = len(positions)
        n_channels = 3 if links is None else 4
        obs = np.empty((n, n_channels, self.obs_size, self.obs_size), dtype=np.uint8)
        obs[:, :3] = self.template  # channels 0 and 2 are shared; channel 1 of the template is all zeros
        rows, cols = self.cells_of(positions)
        blocks = self.blocks(obs)
        if self.position_mark == "exact":
            obs[:, 1] = self.exact_marks(positions, values)
        else:
            # Advanced indices split by slices: the selection has shape (N, s, s), one block per agent.
            blocks[np.arange(n), 1, rows, :, cols, :] = values[:, None, None]
        if links is not None:
            observer, seen = np.nonzero(links)
            grid = np.zeros((n, self.map_size, self.map_size), dtype=np.uint8)
            # Teammates sharing a cell write the same block; the largest value wins, as in the state.
            np.maximum.at(grid, (observer, rows[seen], cols[seen]), values[seen])
            blocks[:, 3] = grid[:, :, None, :, None]
        return obs

    def state(self, positions: np.ndarray, values: np.ndarray) -> np.ndarray:
        """
        Global view: the observation image with channel 1 showing every active UAV.

        :param positions: (N, 2)
        :param values: (N,) uint8 channel-1 values
        :return: (3, S, S) uint8 (maximum value where UAVs share a cell)
        """
        image = self.template.copy()
        if self.position_mark == "exact":
            image[1] = self.exact_marks(positions, values).max(axis=0)
            return image
        rows, cols = self.cells_of(positions)
        grid = np.zeros((self.map_size, self.map_size), dtype=np.uint8)
        np.maximum.at(grid, (rows, cols), values)
        self.blocks(image[1])[...] = grid[:, None, :, None]
        return image

    def exact_marks(self, points: np.ndarray, values: np.ndarray) -> np.ndarray:
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
