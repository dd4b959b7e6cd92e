"""
The plug-in point of a task package: what ``evaluate``, its figures and the TensorBoard pictures may ask of a task
beyond the PettingZoo API, without ``sb3_maddpg`` importing the task's package.

A task offers its tools as the attribute ``task_tools`` of its (unwrapped) env, as a Gymnasium env carries its
``metadata`` and ``spec``; :func:`task_tools` reads it. An env without one is evaluated with what every env has
(random actions, returns, lengths, the GIF where it renders to arrays)::

    class MyTaskTools(TaskTools):
        baselines = {"hover": HoverController}  # name -> a class or function that makes a new controller
        default_baselines = ("hover",)


    class MyEnv(ParallelEnv):
        task_tools = MyTaskTools()

``TaskTools`` is a :class:`~typing.Protocol` with defaults: subclass it for the defaults, or give any object with
its members (a task package that does not import ``sb3_maddpg``; the UAV coverage task's is
``sb3_maddpg_envs.uav_coverage.task_tools``).
"""

import os
from collections.abc import Callable, Mapping
from types import MappingProxyType
from typing import Any, Protocol

import numpy as np

# A file writer of the task's: called with the path to write (the format follows its suffix)
FigureWriter = Callable[[str | os.PathLike], None]


class TaskTools(Protocol):
    """
    What a task may offer the evaluation; the defaults offer nothing beyond the PettingZoo API.

    :ivar baselines: the task's own baselines by name (``evaluate --baselines``): a class or function that makes a
        new controller (a :class:`~sb3_maddpg.evaluation.baselines.Controller`: ``name``, ``reset(env, seed)``,
        ``act(observations, env)``), beside the library's ``random``
    :ivar default_baselines: those run, after random actions, when none are named; the first run is the one recorded
        for the figures when there is no model
    :ivar evaluation_kwargs: env arguments an evaluation uses unless given (e.g. a new random start every episode)
    :ivar state_images: whether ``env.state()`` is a (3, H, W) uint8 image, written at the start, middle and end of
        the recorded episode by default
    :ivar can_draw: whether :meth:`draw_map` and :meth:`draw_frame` draw the env (the TensorBoard pictures)
    :ivar map_name: the TensorBoard tag of :meth:`draw_map`'s picture after an evaluation is ``eval/<map_name>``
    :ivar metric_symbols: the evaluation table's column header of each of the task's metrics (a metric without one is
        headed by its name with spaces for underscores)
    :ivar metric_labels: the figures' axis label of each of the task's metrics (a metric without one: its name with
        spaces for underscores)
    :ivar metric_pairs: (x, y) pairs of episode-end metrics drawn against each other, one point per episode, as
        ``<y>_vs_<x>.png`` (where the episodes have both)
    :ivar event_counts: the events per episode that the evaluation table shows after the episode length, where the
        env reports them: team totals, the sum over the agents' infos at the episode's end, read also where the env
        does not declare them in its ``metadata["episode_metrics"]``; None: the per-agent metrics the env declares
        (``metadata["per_agent_episode_metrics"]``)
    :ivar selection_metric: the episode metric that ``select-checkpoint`` maximises unless told, where the episodes
        report it; None: the team return
    """

    baselines: Mapping[str, Callable[[], Any]] = MappingProxyType({})
    default_baselines: tuple[str, ...] = ()
    evaluation_kwargs: Mapping[str, Any] = MappingProxyType({})
    state_images: bool = False
    can_draw: bool = False
    map_name: str = "state_image"
    metric_symbols: Mapping[str, str] = MappingProxyType({})
    metric_labels: Mapping[str, str] = MappingProxyType({})
    metric_pairs: tuple[tuple[str, str], ...] = ()
    event_counts: tuple[str, ...] | None = None
    selection_metric: str | None = None

    def episode_figures(self, env: Any) -> Mapping[str, FigureWriter]:
        """
        The task's own figures of the env as it is now, written beside the recorded episode's.

        :param env: the env of the recorded episode, after its controller's episodes
        :return: file name (``coverage_heatmap.png``) -> writer; the caller prefixes the name and writes atomically
        """
        return {}

    def draw_map(self, env: Any, size_px: tuple[int, int]) -> np.ndarray:
        """
        The env's state as one picture (TensorBoard's evaluation image), when :attr:`can_draw`.

        :param env: the env, at the end of an episode
        :param size_px: (width, height) of the image in pixels
        :return: (height, width, 3) uint8 image
        """
        raise NotImplementedError(f"{type(self).__name__} does not draw its env")

    def draw_frame(self, env: Any, size: int) -> np.ndarray:
        """
        One frame of an episode's video (TensorBoard's evaluation video), when :attr:`can_draw`.

        :param env: the env, at any step
        :param size: side in pixels of the map
        :return: (H, W, 3) uint8 frame
        """
        raise NotImplementedError(f"{type(self).__name__} does not draw its env")


class _NoTaskTools(TaskTools):
    """The tools of an env that offers none: the defaults."""


NO_TASK_TOOLS: TaskTools = _NoTaskTools()
MEMBERS: tuple[str, ...] = (
    "baselines",
    "default_baselines",
    "evaluation_kwargs",
    "state_images",
    "can_draw",
    "map_name",
    "metric_symbols",
    "metric_labels",
    "metric_pairs",
    "event_counts",
    "selection_metric",
    "episode_figures",
    "draw_map",
    "draw_frame",
)


def task_tools(env: Any) -> TaskTools:
    """
    The tools a task offers through its env's ``task_tools`` attribute (the env's or its unwrapped env's).

    :param env: a PettingZoo env
    :return: the task's tools, or the defaults (:data:`NO_TASK_TOOLS`) when it offers none
    :raises TypeError: naming the members that the env's ``task_tools`` lacks
    """
    tools = getattr(env, "task_tools", None)
    if tools is None:
        tools = getattr(getattr(env, "unwrapped", None), "task_tools", None)
    if tools is None:
        return NO_TASK_TOOLS
    missing = [name for name in MEMBERS if not hasattr(tools, name)]
    if missing:
        raise TypeError(
            f"{type(env).__name__}.task_tools ({type(tools).__name__}) lacks {', '.join(missing)}: "
            "see sb3_maddpg.evaluation.task_tools.TaskTools"
        )
    return tools


def episode_limit(env: Any) -> int | None:
    """
    :param env: a multi-agent env (PettingZoo ParallelEnv)
    :return: the most steps an episode has (the env's ``max_cycles``, as MPE's and the UAV envs'), or None if the env
        does not say
    """
    return getattr(getattr(env, "unwrapped", env), "max_cycles", None)
