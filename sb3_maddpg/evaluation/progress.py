"""
A progress bar with the time left for long evaluations (``evaluate``, ``select-checkpoint``), drawn with tqdm as SB3's
``progress_bar`` is, on stderr, and only where someone watches: never with ``--quiet`` or when stderr is not a terminal
(a log file, a pipe, a batch job).
"""

import contextlib
import sys
from collections.abc import Callable, Iterator
from typing import TextIO


def wants_progress_bar(quiet: bool = False, stream: TextIO | None = None) -> bool:
    """
    :param quiet: the command's ``--quiet``
    :param stream: where the bar would be drawn (default: the current ``sys.stderr``)
    :return: whether to draw it: not quiet, and the stream is a terminal
    """
    stream = sys.stderr if stream is None else stream
    isatty = getattr(stream, "isatty", None)
    return not quiet and callable(isatty) and bool(isatty())


@contextlib.contextmanager
def episode_progress(total: int, description: str, enabled: bool) -> Iterator[Callable[[], None]]:
    """
    A bar of ``total`` episodes with the rate and the time left.

    :param total: the episodes to run
    :param description: shown before the bar, e.g. ``evaluate``
    :param enabled: draw it (see :func:`wants_progress_bar`); when False, nothing is drawn or imported
    :return: a context manager giving the function to call after each episode
    :raises ValueError: if ``total`` is not a positive integer
    """
    if isinstance(total, bool) or not isinstance(total, int) or total < 1:
        raise ValueError(f"total must be a positive number of episodes, got {total!r}")
    if not enabled:
        yield lambda: None
        return
    from tqdm import tqdm

    with tqdm(total=total, desc=description, unit="episode", file=sys.stderr, dynamic_ncols=True) as bar:
        yield lambda: bar.update(1)
