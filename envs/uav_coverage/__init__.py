"""
The multi-UAV coverage environment: the numpy core and its config, the PettingZoo wrapper, the tasks' scenarios,
rendering and plots.
"""

from sb3_maddpg_envs.uav_coverage.config import UAVCoverageConfig
from sb3_maddpg_envs.uav_coverage.core import UAVCoverageCore
from sb3_maddpg_envs.uav_coverage.scenarios import SCENARIOS, UAVCoverageScenario
from sb3_maddpg_envs.uav_coverage.uav_coverage import UAVCoverageEnv, env, parallel_env, raw_env

__all__ = [
    "SCENARIOS",
    "UAVCoverageConfig",
    "UAVCoverageCore",
    "UAVCoverageEnv",
    "UAVCoverageScenario",
    "env",
    "parallel_env",
    "raw_env",
]
