"""
This package's env ids for ``sb3_maddpg``'s command line (``--env``): the UAV coverage tasks, ``risky_reach_v0`` and
``risky_hover_v0``.

``sb3_maddpg`` finds them through the entry point that setup.cfg declares in the group ``sb3_maddpg.envs``: when an
id is first looked up, it calls :func:`register_envs` with its ``register_multiagent_env``, so this package needs no
import of ``sb3_maddpg`` and the library names none of these ids. Each constructor is a ``"module:attribute"`` string,
imported when an env is made (as Gymnasium's registry does).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from .uav_coverage.scenarios import TMC2020_KWARGS

__all__ = ["ENVS", "register_envs"]

#: env id -> (its constructor as ``"module:attribute"``, its default arguments)
ENVS: dict[str, tuple[str, dict[str, Any]]] = {
    # The report's environment and its cheap variant (1 pixel per cell instead of 5: about 25 times fewer pixels for
    # the CNN)
    "uav_coverage_v0": ("sb3_maddpg_envs.uav_coverage_v0:parallel_env", {}),
    "uav_coverage_fast_v0": ("sb3_maddpg_envs.uav_coverage_v0:parallel_env", {"obs_size": 16}),
    # Version 1 (the same simulation with the defaults that learn) and its CPU variant: the same task at 1 pixel per
    # cell
    "uav_coverage_v1": ("sb3_maddpg_envs.uav_coverage_v1:parallel_env", {}),
    "uav_coverage_cpu_v1": ("sb3_maddpg_envs.uav_coverage_v1:parallel_env", {"obs_size": 16}),
    # The published setting of Liu et al., "Distributed Energy-Efficient Multi-UAV Navigation for Long-Term
    # Communication Coverage by Deep Reinforcement Learning", IEEE TMC 19(6), 2020 (docs/results.md, "The published
    # setting"): v1's rules on the paper's geometry and energy (scenarios.TMC2020_KWARGS)
    "uav_coverage_tmc_v1": ("sb3_maddpg_envs.uav_coverage_v1:parallel_env", TMC2020_KWARGS),
    # The hazardous task on the CPU variant: wind gusts that crash a UAV near a wall and radio links that fail
    # (uav_coverage_v1.HAZARDS), where the risk-neutral and the risk-averse optimum differ (docs/environment.md,
    # "Hazards")
    "uav_coverage_hazard_cpu_v1": ("sb3_maddpg_envs.uav_coverage_v1:hazard_parallel_env", {"obs_size": 16}),
    # The storm task on the CPU variant: a storm over the middle of the map that grounds a UAV it strikes
    # (uav_coverage_v1.STORM; docs/environment.md, "Hazards"), where the risk-neutral and the risk-averse optimum differ
    "uav_coverage_storm_cpu_v1": ("sb3_maddpg_envs.uav_coverage_v1:storm_parallel_env", {"obs_size": 16}),
    # The storm task redesigned so that a critic looking about 10 steps ahead sees it (uav_coverage_v1.STORM_V2): the
    # zone drawn on channel 0, strikes frequent inside it, each costing at once; the old task stays for comparison
    "uav_coverage_storm_cpu_v2": ("sb3_maddpg_envs.uav_coverage_v1:storm_v2_parallel_env", {"obs_size": 16}),
    # A small task where the mean and the lower tail prefer different ways (a visible risky zone across the short
    # way): the proving ground of the CVaR actor (risky_reach_v0.py)
    "risky_reach_v0": ("sb3_maddpg_envs.risky_reach_v0:parallel_env", {}),
    # A small task where the lower tail prefers to hold a little outside a hazard that the mean enters: a local change,
    # which a deterministic policy gradient can climb (risky_hover_v0.py)
    "risky_hover_v0": ("sb3_maddpg_envs.risky_hover_v0:parallel_env", {}),
}


def register_envs(register: Callable[[str, str, dict[str, Any]], Any]) -> None:
    """
    Register every id of :data:`ENVS` (the entry point of the group ``sb3_maddpg.envs``).

    :param register: ``sb3_maddpg.zoo.registry.register_multiagent_env``, called as
        ``register(env_id, "module:attribute", kwargs)``
    """
    for env_id, (entry_point, kwargs) in ENVS.items():
        register(env_id, entry_point, dict(kwargs))
