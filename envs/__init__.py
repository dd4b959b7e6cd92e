"""The project's PettingZoo environments, imported as ``sb3_maddpg_envs``.

>>> from sb3_maddpg_envs import uav_coverage_v0
>>> env = uav_coverage_v0.parallel_env(n_uavs=3, obs_size=16)
"""
