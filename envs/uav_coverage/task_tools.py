"""
What the UAV coverage task offers ``sb3_maddpg``'s evaluation beyond the PettingZoo API, through the plug-in point
``sb3_maddpg.evaluation.task_tools.TaskTools``: its greedy baselines, a new random start every evaluation episode,
its state images, the coverage heat map and the TensorBoard pictures.

Every ``UAVCoverageEnv`` carries :data:`TASK_TOOLS` as ``env.task_tools``. The class has the protocol's members
without importing ``sb3_maddpg``: the env package stands on PettingZoo alone.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from types import MappingProxyType
from typing import Any

import numpy as np

from .baselines import GreedyStaticController, GreedyStepController

__all__ = ["TASK_TOOLS", "UAVCoverageTools"]


class UAVCoverageTools:
    """
    The UAV coverage task's tools (``sb3_maddpg.evaluation.task_tools.TaskTools``).

    :ivar baselines: ``greedy_static`` (a greedy maximum-coverage layout, flown to and hovered over) and
        ``greedy_step`` (the greedy of Liu et al., TMC 2020)
    :ivar default_baselines: ``greedy_static``, the report's baseline, which is also the episode recorded
    :ivar evaluation_kwargs: ``start="random"``: every evaluation episode starts from new positions
    :ivar state_images: the global state is a (3, S, S) image: PoIs, UAVs, coverage
    :ivar can_draw: the coverage map and the rendered frames
    """

    baselines: Mapping[str, Callable[[], Any]] = MappingProxyType(
        {"greedy_static": GreedyStaticController, "greedy_step": GreedyStepController}
    )
    default_baselines: tuple[str, ...] = ("greedy_static",)
    evaluation_kwargs: Mapping[str, Any] = MappingProxyType({"start": "random"})
    state_images: bool = True
    can_draw: bool = True

    def episode_figures(self, env: Any) -> Mapping[str, Callable[[str | os.PathLike], None]]:
        """
        :param env: a UAV coverage env
        :return: ``coverage_heatmap.png``: the heat map of c_t(k) with the UAVs, as the env is now
        """
        from .plotting import save_coverage_heatmap

        return {"coverage_heatmap.png": lambda path: save_coverage_heatmap(env, path)}

    def draw_map(self, env: Any, size_px: tuple[int, int]) -> np.ndarray:
        """
        :param env: a UAV coverage env
        :param size_px: (width, height) in pixels
        :return: the coverage heat map with the UAVs and their links (``plotting.coverage_map``)
        """
        from .plotting import coverage_map

        return coverage_map(env, size_px)

    def draw_frame(self, env: Any, size: int) -> np.ndarray:
        """
        :param env: a UAV coverage env
        :param size: side in pixels of the map
        :return: the rendered frame (``rendering.render_frame``), with its text panel
        """
        from .plotting import core_of
        from .rendering import render_frame

        return render_frame(core_of(env), size=size)


#: The tools every UAV coverage env carries (stateless: one object serves them all).
TASK_TOOLS = UAVCoverageTools()
