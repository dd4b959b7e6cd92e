"""Points of interest: the integer lattice, or the cells of a grayscale image (PNG/JPEG file or 2-D array).

Shapes: map side L, K PoIs; PoIs are (K, 2) float64 map coordinates in [0, L)^2.
"""

from __future__ import annotations

import os

import numpy as np

__all__ = ["lattice_pois", "load_poi_image", "pois_from_image"]


def lattice_pois(map_size: int) -> np.ndarray:
    """
    The L x L integer lattice, ``pois="grid"``.

    :param map_size: the map side L
    :return: (L^2, 2) float64, x varying fastest
    """
    lattice = np.arange(map_size, dtype=np.float64)
    xx, yy = np.meshgrid(lattice, lattice, indexing="xy")
    return np.stack([xx.ravel(), yy.ravel()], axis=1)


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
