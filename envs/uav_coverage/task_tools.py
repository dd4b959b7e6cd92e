"""
What the UAV coverage task offers ``sb3_maddpg``'s evaluation beyond the PettingZoo API, through the plug-in point
``sb3_maddpg.evaluation.task_tools.TaskTools``: its greedy baselines, a new random start every evaluation episode,
its state images, the coverage heat map and the TensorBoard pictures, and how the table and the figures show its
metrics (c_T, f_T, e_T, eta_T, the report's figures, the hazard events).

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
from .hazards import HAZARD_COUNTS

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
    :ivar map_name: ``coverage_map``: TensorBoard's ``eval/coverage_map``
    :ivar metric_symbols: the report's symbols of the episode-end metrics (docs/environment.md, "Metrics")
    :ivar metric_labels: the figures' axis labels of the episode metrics
    :ivar metric_pairs: fairness against coverage and against energy efficiency (the report's figures 6.5 and 6.6)
    :ivar event_counts: the hazards' events (gusts, crashes, link failures, depletions) where a hazard is switched on;
        wall hits and disconnections are kept per episode, not in the table
    :ivar selection_metric: ``energy_efficiency`` (eta_T), what ``select-checkpoint`` maximises unless told
    """

    baselines: Mapping[str, Callable[[], Any]] = MappingProxyType(
        {"greedy_static": GreedyStaticController, "greedy_step": GreedyStepController}
    )
    default_baselines: tuple[str, ...] = ("greedy_static",)
    evaluation_kwargs: Mapping[str, Any] = MappingProxyType({"start": "random"})
    state_images: bool = True
    can_draw: bool = True
    map_name: str = "coverage_map"
    metric_symbols: Mapping[str, str] = MappingProxyType(
        {"coverage": "c_T", "fairness": "f_T", "energy": "e_T", "energy_efficiency": "eta_T"}
    )
    metric_labels: Mapping[str, str] = MappingProxyType(
        {
            "coverage": "coverage $c_T$",
            "fairness": "fairness $f_T$",
            "energy": "energy $\\bar{e}_T$",
            "energy_efficiency": "energy efficiency $\\eta_T$",
            "wall_hits": "wall hits",
            "disconnections": "disconnections",
        }
    )
    metric_pairs: tuple[tuple[str, str], ...] = (("coverage", "fairness"), ("energy_efficiency", "fairness"))
    event_counts: tuple[str, ...] | None = HAZARD_COUNTS
    selection_metric: str | None = "energy_efficiency"

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
