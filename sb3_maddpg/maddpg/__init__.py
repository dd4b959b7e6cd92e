from sb3_maddpg.maddpg.maddpg import MADDPG, GradientStepStats
from sb3_maddpg.maddpg.policies import CnnPolicy, MADDPGPolicy, MlpPolicy

__all__ = ["MADDPG", "CnnPolicy", "GradientStepStats", "MADDPGPolicy", "MlpPolicy"]
