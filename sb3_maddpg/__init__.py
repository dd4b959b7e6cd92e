"""sb3_maddpg: multi-agent DDPG and TD3 with centralised quantile-CVaR critics for Stable-Baselines3."""

from sb3_maddpg.common.vec_env import make_multiagent_vec_env
from sb3_maddpg.maddpg import MADDPG
from sb3_maddpg.matd3 import MATD3

__version__ = "0.1.0"

__all__ = ["MADDPG", "MATD3", "__version__", "make_multiagent_vec_env"]
