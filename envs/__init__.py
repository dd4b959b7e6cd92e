"""The project's PettingZoo environments, imported as ``sb3_maddpg_envs``.

>>> from sb3_maddpg_envs import uav_coverage_v0
>>> env = uav_coverage_v0.parallel_env(n_uavs=3, obs_size=16)

Importing this package also registers the environments in PettingZoo's registry as ``sb3_maddpg/uav_coverage-v0``,
``sb3_maddpg/uav_coverage-v1``, ``sb3_maddpg/risky_reach-v0`` and ``sb3_maddpg/risky_hover-v0``
(``pettingzoo.make("parallel", "sb3_maddpg/uav_coverage-v1")`` or ``pettingzoo.make("aec", ...)``).
"""

from pettingzoo import aec_registry, parallel_registry, register

from sb3_maddpg_envs import risky_hover_v0, risky_reach_v0, uav_coverage_v0, uav_coverage_v1

__all__ = ["risky_hover_v0", "risky_reach_v0", "uav_coverage_v0", "uav_coverage_v1"]

ENV_IDS = {
    "sb3_maddpg/uav_coverage-v0": "uav_coverage_v0",
    "sb3_maddpg/uav_coverage-v1": "uav_coverage_v1",
    "sb3_maddpg/risky_reach-v0": "risky_reach_v0",
    "sb3_maddpg/risky_hover-v0": "risky_hover_v0",
}

# Registering twice (a reload) would only warn about overriding; skip it instead.
for env_id, module in ENV_IDS.items():
    if env_id not in parallel_registry:
        register("parallel", env_id, entry_point=f"sb3_maddpg_envs.{module}:parallel_env")
    if env_id not in aec_registry:
        register("aec", env_id, entry_point=f"sb3_maddpg_envs.{module}:env")
