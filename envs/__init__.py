"""The project's PettingZoo environments, imported as ``sb3_maddpg_envs``.

>>> from sb3_maddpg_envs import uav_coverage_v0
>>> env = uav_coverage_v0.parallel_env(n_uavs=3, obs_size=16)

Importing this package also registers the environment in PettingZoo's registry as ``sb3_maddpg/uav_coverage-v0``
(``pettingzoo.make("parallel", "sb3_maddpg/uav_coverage_v0")`` or ``pettingzoo.make("aec", ...)``).
"""

from pettingzoo import aec_registry, parallel_registry, register

from sb3_maddpg_envs import uav_coverage_v0

__all__ = ["uav_coverage_v0"]

ENV_ID = "sb3_maddpg/uav_coverage-v0"

# Registering twice (a reload) would only warn about overriding; skip it instead.
if ENV_ID not in parallel_registry:
    register("parallel", ENV_ID, entry_point="sb3_maddpg_envs.uav_coverage_v0:parallel_env")
if ENV_ID not in aec_registry:
    register("aec", ENV_ID, entry_point="sb3_maddpg_envs.uav_coverage_v0:env")
