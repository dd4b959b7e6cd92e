"""The multi-UAV coverage environment: numpy core, PettingZoo wrapper, rendering and plots."""

from sb3_maddpg_envs.uav_coverage.core import UAVCoverageCore
from sb3_maddpg_envs.uav_coverage.uav_coverage import UAVCoverageEnv, env, parallel_env, raw_env

__all__ = ["UAVCoverageCore", "UAVCoverageEnv", "env", "parallel_env", "raw_env"]
