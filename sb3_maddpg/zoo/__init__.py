"""Integration with RL Baselines3 Zoo (``rl_zoo3``): registers MADDPG and the project's environments."""
