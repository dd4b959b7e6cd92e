from sb3_maddpg.matd3.matd3 import MATD3
from sb3_maddpg.matd3.policies import CnnPolicy, MATD3Policy, MlpPolicy

__all__ = ["MATD3", "CnnPolicy", "MATD3Policy", "MlpPolicy"]
