"""
Checks of the task packages' parameters: every message names the parameter, the value received and what is accepted.
The bounds named ``MAX_*`` are the UAV coverage task's.

``check_int`` and ``check_number`` have the interface of sb3_maddpg's (``sb3_maddpg.common.validation``, which this
package does not import): closed bounds ``low`` and ``high`` unless ``low_open``/``high_open``, None for unbounded.
"""

from __future__ import annotations

import math
import numbers
import warnings
from typing import Any

import numpy as np

__all__ = [
    "MAX_MAP_SIZE",
    "MAX_OBS_SIZE",
    "MAX_REAL",
    "MAX_STEP_BYTES",
    "MAX_STEPS",
    "MAX_UAVS",
    "MIN_POSITIVE",
    "check_choice",
    "check_int",
    "check_number",
    "check_points",
    "check_step_memory",
    "check_zone",
    "warn_without_effect",
]

# Bounds of every real parameter: with them, squared ranges, energies times distances, rewards times reward_scale and
# quotients by eps stay finite and non-zero, so every accepted configuration runs.
MAX_REAL = 1e12
MIN_POSITIVE = 1e-12
# Bounds of the sizes and step counts. A step holds every pair of UAVs, every UAV-PoI distance and every UAV's
# observation image: with more UAVs or a larger area it needs more memory than a machine has. Step counts stay far
# inside int64, whose counters (grounded steps left) they are added to.
MAX_UAVS = 1024
MAX_MAP_SIZE = 1024
MAX_OBS_SIZE = 4096
MAX_STEPS = 10**9
# What one step's largest arrays (the observation images, the UAV-PoI distances) may take
MAX_STEP_BYTES = 2**30


def check_int(name: str, value: Any, low: int | None = None, high: int | None = None) -> int:
    """
    An integer in ``[low, high]`` (the same helper as sb3_maddpg's ``sb3_maddpg.common.validation``, which this package
    does not import).

    :param name: the parameter's name
    :param value: the value given
    :param low: the smallest accepted value (None: unbounded)
    :param high: the largest accepted value (None: unbounded)
    :return: the value as an int
    """
    ok = isinstance(value, numbers.Integral) and not isinstance(value, bool)
    if ok and low is not None:
        ok = int(value) >= low
    if ok and high is not None:
        ok = int(value) <= high
    if not ok:
        if low is not None and high is not None:
            accepted = f"an integer in [{low}, {high}]"
        elif low is not None:
            accepted = f"an integer >= {low}"
        elif high is not None:
            accepted = f"an integer <= {high}"
        else:
            accepted = "an integer"
        raise ValueError(f"{name} must be {accepted}, got {value!r}")
    return int(value)


def check_step_memory(what: str, parameters: str, n_bytes: int) -> None:
    """
    Refuse a configuration whose step would hold more than ``MAX_STEP_BYTES`` in one array.

    :param what: the array and how its size is counted, for the message
    :param parameters: the parameters and values it grows with, for the message
    :param n_bytes: its size
    """
    if n_bytes > MAX_STEP_BYTES:
        raise ValueError(
            f"{parameters}: each step would hold {n_bytes / 2**30:.3g} GiB of {what}, more than the {MAX_STEP_BYTES // 2**30} "
            "GiB accepted; use fewer UAVs or a smaller area or image"
        )


def check_number(
    name: str,
    value: Any,
    low: float | None = None,
    high: float | None = None,
    low_open: bool = False,
    high_open: bool = False,
) -> float:
    """
    A finite real number in ``[low, high]``; ``low_open`` and ``high_open`` exclude the bound (the interface of
    sb3_maddpg's ``check_number``). Beyond it, the simulation's bounds: ``|value| <= MAX_REAL``, and a value above an
    open bound 0 is at least ``MIN_POSITIVE``.

    :param name: the parameter's name
    :param value: the value given
    :param low: the lower bound (None: unbounded)
    :param high: the upper bound (None: unbounded)
    :param low_open: exclude ``low``
    :param high_open: exclude ``high``
    :return: the value as a float
    """
    ok = isinstance(value, numbers.Real) and not isinstance(value, bool) and math.isfinite(float(value))
    if ok and low is not None:
        ok = float(value) > low if low_open else float(value) >= low
    if ok and high is not None:
        ok = float(value) < high if high_open else float(value) <= high
    if not ok:
        accepted = "a finite number" if low is None else f"a finite number {'>' if low_open else '>='} {low:g}"
        if high is not None:
            accepted += f"{' and' if low is not None else ''} {'<' if high_open else '<='} {high:g}"
        raise ValueError(f"{name} must be {accepted}, got {value!r}")
    if abs(float(value)) > MAX_REAL or (low == 0.0 and low_open and float(value) < MIN_POSITIVE):
        lowest = -MAX_REAL if low is None else (MIN_POSITIVE if low_open else 0.0)
        highest = MAX_REAL if high is None else high
        interval = f"[{lowest:g}, {highest:g}{']' if high is None else ')'}"
        raise ValueError(
            f"{name} must lie in {interval} (beyond, the simulation's squares, products and quotients overflow "
            f"or divide by zero), got {value!r}"
        )
    return float(value)


def check_choice(name: str, value: Any, choices: tuple[str, ...]) -> str:
    if not isinstance(value, str) or value not in choices:
        raise ValueError(f"{name} must be one of {', '.join(map(repr, choices))}, got {value!r}")
    return value


def check_points(name: str, value: Any, n_rows: int | None, map_size: int) -> np.ndarray:
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


def check_zone(name: str, value: Any, map_size: int) -> tuple[float, float, float, float] | None:
    """Check a rectangle (x0, y0, x1, y1) of the area [0, L]^2 with x0 < x1 and y0 < y1, or None."""
    if value is None:
        return None
    accepted = f"None or four numbers (x0, y0, x1, y1) with 0 <= x0 < x1 <= {map_size} and 0 <= y0 < y1 <= {map_size}"
    if isinstance(value, (str, bytes)):
        raise ValueError(f"{name} must be {accepted}, got {value!r}")
    try:
        corners = np.array(value, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise ValueError(f"{name} must be {accepted}, got {value!r}") from error
    if corners.shape != (4,) or not np.isfinite(corners).all():
        raise ValueError(f"{name} must be {accepted}, got {value!r}")
    x0, y0, x1, y1 = (float(c) for c in corners)
    if not (0.0 <= x0 < x1 <= map_size and 0.0 <= y0 < y1 <= map_size):
        raise ValueError(f"{name} must be {accepted}, got {value!r}")
    return x0, y0, x1, y1


def warn_without_effect(settings: dict[str, tuple[bool, str]], stacklevel: int = 3) -> None:
    """
    Warn (once per message, Python's default) about each setting given a value that acts only with another setting
    that is off: accepted, since a sweep may set it beside a zero probability, but said.

    :param settings: the setting's name -> (whether it is without effect, what it needs)
    :param stacklevel: the frame the warning names, counted from this function's caller (3: the caller's caller)
    """
    for name, (idle, needs) in settings.items():
        if idle:
            warnings.warn(f"{name} has no effect: {needs}", UserWarning, stacklevel=stacklevel)
