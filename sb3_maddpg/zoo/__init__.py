"""
Integration with RL Baselines3 Zoo (``rl_zoo3``): registers MADDPG and the project's multi-agent environments into
RL Zoo's own train, enjoy and Optuna machinery.

>>> from sb3_maddpg.zoo import register_multiagent_env
>>> register_multiagent_env("my_env_v0", "my_package.my_env:parallel_env")  # then: --env my_env_v0
"""

from sb3_maddpg.zoo.integration import register_with_rl_zoo, run_enjoy, run_record_video, run_train
from sb3_maddpg.zoo.registry import (
    MULTIAGENT_ENVS,
    MultiAgentEnvSpec,
    is_multiagent_env,
    make_multiagent_env,
    register_multiagent_env,
)

__all__ = [
    "MULTIAGENT_ENVS",
    "MultiAgentEnvSpec",
    "is_multiagent_env",
    "make_multiagent_env",
    "register_multiagent_env",
    "register_with_rl_zoo",
    "run_enjoy",
    "run_record_video",
    "run_train",
]
