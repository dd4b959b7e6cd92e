"""Points of interest: the integer lattice, or the cells of a grayscale image (PNG/JPEG file or 2-D array).

Shapes: map side L, K PoIs; PoIs are (K, 2) float64 map coordinates in [0, L)^2.
"""

from __future__ import annotations

import os

import numpy as np

from ..validation import MAX_MAP_SIZE, check_int, check_points

__all__ = ["MIN_POI_IMAGE_SIDE", "lattice_pois", "load_poi_image", "pois_from_image", "resolve_pois"]

# The smallest side of a PoI image array: narrower arrays (a (K, 3) table, a 2 x 2 "image") are ambiguous
MIN_POI_IMAGE_SIDE = 4


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


def resolve_pois(
    pois: str | os.PathLike | np.ndarray | list, n_pois: int | None, map_size: int, threshold: float
) -> tuple[str, np.ndarray | None, int | None]:
    """
    Read the env's ``pois`` and ``n_pois`` parameters.

    :param pois: ``"grid"``, ``"uniform"``, an array (K, 2) of coordinates, an image path or a 2-D image array of at
        least ``MIN_POI_IMAGE_SIDE`` pixels a side (other 2-D arrays are refused as ambiguous)
    :param n_pois: the number of uniform PoIs (default L^2); only with ``pois="uniform"``
    :param map_size: the map side L
    :param threshold: ``poi_threshold``, for image PoIs
    :return: the mode (``"grid"``, ``"uniform"``, ``"array"`` or ``"image"``), the PoIs (K, 2) (None for uniform ones,
        drawn at the first reset) and the number of uniform PoIs (None for the other modes)
    """
    points: np.ndarray | None = None
    n_uniform: int | None = None
    if isinstance(pois, str) and pois in ("grid", "uniform"):
        mode = pois
        if pois == "uniform":
            n_uniform = check_int("n_pois", map_size**2 if n_pois is None else n_pois, low=1, high=MAX_MAP_SIZE**2)
        else:
            points = lattice_pois(map_size)
    elif isinstance(pois, str | os.PathLike):
        mode = "image"
        points = pois_from_image(load_poi_image(pois), map_size, threshold, f"pois={os.fspath(pois)!r}")
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
            mode = "array"
            points = check_points("pois", array, None, map_size)
        elif array.ndim == 2 and min(array.shape) >= MIN_POI_IMAGE_SIDE:
            mode = "image"
            points = pois_from_image(array, map_size, threshold, "pois image array")
        else:
            raise ValueError(
                f"pois: an array must have shape (K, 2) (x, y coordinates) or (H, W) with H, W >= "
                f"{MIN_POI_IMAGE_SIDE} (a grayscale image), got shape {array.shape}; weighted PoIs (x, y, weight) "
                "are not supported"
            )
    if n_pois is not None and mode != "uniform":
        raise ValueError(f"n_pois is only used with pois='uniform', got n_pois={n_pois!r} with pois={mode!r}")
    return mode, points, n_uniform
