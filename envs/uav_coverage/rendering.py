"""Off-screen RGB frames of the coverage map, drawn with Pillow (imported only when a frame is drawn)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .core import UAVCoverageCore

__all__ = ["render_frame"]

# A distinct colour per UAV (cycled when there are more UAVs).
UAV_COLOURS = [
    (31, 119, 180),
    (255, 127, 14),
    (44, 160, 44),
    (214, 39, 40),
    (148, 103, 189),
    (140, 86, 75),
    (227, 119, 194),
    (23, 190, 207),
]


def _import_pil():
    try:
        from PIL import Image, ImageDraw
    except ImportError as error:  # pragma: no cover - Pillow is a dependency of the project
        raise ImportError("Rendering needs Pillow: pip install pillow") from error
    return Image, ImageDraw


def coverage_colour(scores: np.ndarray) -> np.ndarray:
    """
    Colour of PoIs by coverage score: red (never covered) through yellow to green (always covered).

    :param scores: (K,) values c_t(k) in [0, 1]
    :return: (K, 3) uint8 RGB colours
    """
    scores = np.clip(np.asarray(scores, dtype=np.float64), 0.0, 1.0)
    red = np.where(scores < 0.5, 1.0, 2.0 * (1.0 - scores))
    green = np.where(scores < 0.5, 2.0 * scores, 1.0)
    return (np.stack([red, green, np.zeros_like(scores)], axis=1) * 220).astype(np.uint8)


def render_frame(core: UAVCoverageCore, size: int = 512, panel: int = 44) -> np.ndarray:
    """
    Draw the current state: PoIs coloured by c_t(k), UAVs, coverage discs, communication links, the step's metrics
    and, under them, the key of the PoI colours (a bar from c_t(k) = 0, red, to 1, green).

    :param core: the simulation to draw
    :param size: side in pixels of the map part of the frame
    :param panel: height in pixels of the text panel under the map
    :return: (size + panel, size, 3) uint8 RGB frame
    """
    Image, ImageDraw = _import_pil()
    length = core.map_size
    scale = size / length

    def to_px(points: np.ndarray) -> np.ndarray:
        # Map y grows upwards, image rows grow downwards.
        return np.stack([points[:, 0] * scale, size - points[:, 1] * scale], axis=1)

    image = Image.new("RGB", (size, size + panel), (250, 250, 250))
    draw = ImageDraw.Draw(image, "RGBA")
    # Grid lines at cell boundaries.
    for i in range(length + 1):
        v = round(i * scale)
        draw.line([(v, 0), (v, size)], fill=(225, 225, 225))
        draw.line([(0, v), (size, v)], fill=(225, 225, 225))

    positions = to_px(core.positions)
    active = core.active
    # Coverage discs first so everything else stays visible on top of them.
    radius = core.coverage_range * scale
    for i, (x, y) in enumerate(positions):
        if active[i]:
            colour = UAV_COLOURS[i % len(UAV_COLOURS)]
            draw.ellipse([x - radius, y - radius, x + radius, y + radius], fill=(*colour, 40), outline=(*colour, 160))

    if core.pois is not None and len(core.pois):
        poi_px = to_px(core.pois)
        colours = coverage_colour(core.coverage_scores if len(core.coverage_scores) else np.zeros(len(core.pois)))
        dot = max(1.5, 0.12 * scale)
        for (x, y), colour in zip(poi_px, colours.tolist(), strict=True):
            draw.ellipse([x - dot, y - dot, x + dot, y + dot], fill=tuple(colour))

    for i, j in core.links():
        draw.line([tuple(positions[i]), tuple(positions[j])], fill=(60, 60, 60, 200), width=2)

    body = max(3.0, 0.3 * scale)
    for i, (x, y) in enumerate(positions):
        colour = UAV_COLOURS[i % len(UAV_COLOURS)] if active[i] else (150, 150, 150)
        draw.rectangle([x - body, y - body, x + body, y + body], fill=colour, outline=(0, 0, 0))
        draw.text((x + body + 1, y - body - 1), str(i), fill=(0, 0, 0))

    text = (
        f"t={core.t}  coverage={core.coverage:.3f}  fairness={core.fairness:.3f}  "
        f"energy={core.energy_ratio:.3f}  efficiency={core.energy_efficiency:.3f}"
    )
    draw.rectangle([0, size, size, size + panel], fill=(235, 235, 235))
    draw.text((4, size + 4), text, fill=(0, 0, 0))
    # The key of the PoI colours
    top, bar_left, bar_width = size + panel - 16, 150, 120
    draw.text((4, top), "PoI coverage c_t(k):  0", fill=(0, 0, 0))
    bar = coverage_colour(np.linspace(0.0, 1.0, bar_width))
    for offset, colour in enumerate(bar.tolist()):
        draw.line([(bar_left + offset, top + 1), (bar_left + offset, top + 10)], fill=tuple(colour))
    draw.text((bar_left + bar_width + 4, top), "1  (never covered -> always covered)", fill=(0, 0, 0))
    return np.asarray(image, dtype=np.uint8).copy()
