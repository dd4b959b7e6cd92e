from sb3_maddpg.maddpg.gradient_step import GradientStepStats
from sb3_maddpg.maddpg.maddpg import MADDPG
from sb3_maddpg.maddpg.policies import CnnPolicy, MADDPGPolicy, MlpPolicy

__all__ = ["MADDPG", "CnnPolicy", "GradientStepStats", "MADDPGPolicy", "MlpPolicy"]
