"""sb3_maddpg: multi-agent DDPG with centralised quantile-CVaR critics for Stable-Baselines3."""

__version__ = "0.1.0"
