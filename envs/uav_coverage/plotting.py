"""Figures of the coverage task: heat map of c_t(k), state images and episode GIFs.

Matplotlib (with the Agg backend, so no display is needed) and Pillow are imported only when a figure is written.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Any

import numpy as np

from .core import UAVCoverageCore

__all__ = ["coverage_grid", "coverage_map", "save_coverage_heatmap", "save_gif", "save_state_image"]


def core_of(env_or_core: Any) -> UAVCoverageCore:
    """The numpy core of a core, a ``UAVCoverageEnv`` or a wrapped env (AEC wrappers, ``parallel_to_aec``)."""
    if isinstance(env_or_core, UAVCoverageCore):
        return env_or_core
    for candidate in (env_or_core, getattr(env_or_core, "unwrapped", None)):
        core = getattr(candidate, "core", None)
        if isinstance(core, UAVCoverageCore):
            return core
    inner = getattr(getattr(env_or_core, "unwrapped", None), "env", None)  # parallel_to_aec keeps the parallel env
    if isinstance(getattr(inner, "core", None), UAVCoverageCore):
        return inner.core
    raise TypeError(f"expected a UAVCoverageCore or an env built on one, got {type(env_or_core).__name__}")


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def coverage_grid(core: UAVCoverageCore) -> np.ndarray:
    """
    c_t(k) over the map's cells (maximum where a cell holds several PoIs, NaN where it holds none).

    :param core: the simulation
    :return: (L, L) float array indexed [y, x] (row 0 is y = 0, the bottom of the map)
    """
    size = core.map_size
    grid = np.full((size, size), np.nan)
    if core.pois is None or not len(core.pois):
        return grid
    cells = np.clip(np.floor(core.pois).astype(np.int64), 0, size - 1)
    scores = core.coverage_scores if len(core.coverage_scores) else np.zeros(len(core.pois))
    filled = np.zeros((size, size))
    np.maximum.at(filled, (cells[:, 1], cells[:, 0]), scores)
    holds = np.zeros((size, size), dtype=bool)
    holds[cells[:, 1], cells[:, 0]] = True
    grid[holds] = filled[holds]
    return grid


def save_coverage_heatmap(core: UAVCoverageCore, path: str | os.PathLike, title: str | None = None) -> None:
    """
    Write the coverage heat map (c_t(k) over the map, with the UAVs' positions) as an image file.

    :param core: the simulation (or an env built on one)
    :param path: output file; the format follows the suffix (``.png``, ``.pdf``, ...)
    :param title: figure title (default: step and coverage metrics)
    """
    core = core_of(core)
    plt = _pyplot()
    size = core.map_size
    fig, ax = plt.subplots(figsize=(5.2, 4.5))
    mesh = ax.imshow(coverage_grid(core), origin="lower", extent=(0, size, 0, size), cmap="viridis", vmin=0.0, vmax=1.0)
    fig.colorbar(mesh, ax=ax, label="coverage score $c_t(k)$")
    ax.scatter(core.positions[:, 0], core.positions[:, 1], c="red", marker="^", s=40, edgecolors="white", label="UAV")
    ax.set_xlim(0, size)
    ax.set_ylim(0, size)
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_title(title or f"t={core.t}  c={core.coverage:.3f}  f={core.fairness:.3f}")
    ax.legend(loc="upper right", fontsize="small")
    fig.tight_layout()
    fig.savefig(os.fspath(path))
    plt.close(fig)


def coverage_map(env_or_core: Any, size_px: tuple[int, int] = (416, 360)) -> np.ndarray:
    """
    The coverage heat map (c_t(k) over the map, as :func:`save_coverage_heatmap` draws it) with the UAVs' positions
    (grey: no longer active) and their communication links, as an RGB array.

    Drawn on a figure of its own with Matplotlib's Agg canvas: no display, and pyplot's global state is left alone.

    :param env_or_core: the simulation, or an env built on one
    :param size_px: (width, height) of the image in pixels
    :return: (height, width, 3) uint8 image
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    core = core_of(env_or_core)
    dpi = 80
    figure = Figure(figsize=(size_px[0] / dpi, size_px[1] / dpi), dpi=dpi)
    canvas = FigureCanvasAgg(figure)
    ax = figure.add_subplot()
    size = core.map_size
    mesh = ax.imshow(coverage_grid(core), origin="lower", extent=(0, size, 0, size), cmap="viridis", vmin=0.0, vmax=1.0)
    figure.colorbar(mesh, ax=ax, label="coverage score $c_t(k)$")
    positions = np.asarray(core.positions)
    for i, j in core.links():
        ax.plot(positions[[i, j], 0], positions[[i, j], 1], color="white", linewidth=1.2, alpha=0.8)
    active = np.asarray(core.active, dtype=bool)
    ax.scatter(*positions[active].T, c="red", marker="^", s=40, edgecolors="white", label="UAV", zorder=3)
    if not active.all():
        ax.scatter(*positions[~active].T, c="grey", marker="^", s=40, edgecolors="white", label="inactive", zorder=3)
    ax.set_xlim(0, size)
    ax.set_ylim(0, size)
    ax.set_title(f"t={core.t}  c={core.coverage:.3f}  f={core.fairness:.3f}", fontsize="medium")
    ax.legend(loc="upper right", fontsize="small")
    figure.tight_layout()
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()


def save_state_image(env_or_core: Any, path: str | os.PathLike, scale: int = 4) -> None:
    """
    Write the global state image (channels PoIs, UAVs, coverage as red, green, blue) as a PNG.

    :param env_or_core: a ``UAVCoverageCore`` or an env built on one
    :param path: output file
    :param scale: each state pixel becomes a ``scale`` x ``scale`` square
    """
    from PIL import Image

    core = core_of(env_or_core)
    rgb = np.transpose(core.state(), (1, 2, 0))
    if scale > 1:
        rgb = np.repeat(np.repeat(rgb, scale, axis=0), scale, axis=1)
    Image.fromarray(np.ascontiguousarray(rgb)).save(os.fspath(path))


def save_gif(frames: Sequence[np.ndarray], path: str | os.PathLike, fps: int = 10) -> None:
    """
    Write RGB frames as an animated GIF.

    :param frames: (H, W, 3) uint8 frames, e.g. from ``env.render()`` with ``render_mode="rgb_array"``
    :param path: output file
    :param fps: frames per second
    :raises ValueError: if there is no frame or fps is not positive
    """
    from PIL import Image

    if len(frames) == 0:
        raise ValueError("save_gif: frames is empty")
    if fps <= 0:
        raise ValueError(f"save_gif: fps must be > 0, got {fps!r}")
    images = [Image.fromarray(np.asarray(frame, dtype=np.uint8)) for frame in frames]
    images[0].save(os.fspath(path), save_all=True, append_images=images[1:], duration=max(1, round(1000 / fps)), loop=0)
