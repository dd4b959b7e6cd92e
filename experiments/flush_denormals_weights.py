"""
Whether flushing denormal floats changes what training computes: short runs of MADDPG and MATD3 on simple_spread_v3
(8 copies, batch 256, 25 quantiles) and of MADDPG on uav_coverage_storm_cpu_v1 (25 mean-anchored quantiles, CVaR 0.5),
each with ``flush_denormals`` True and False from the same seed; prints how many tensors of the policies differ and
which of them are not BatchNorm running statistics.

    python experiments/flush_denormals_weights.py
"""

from typing import Any

import torch as th

from sb3_maddpg import MADDPG, MATD3, make_multiagent_vec_env
from sb3_maddpg.zoo.registry import make_multiagent_env

SPREAD = dict(n_envs=8, batch_size=256, learning_starts=500, policy_kwargs=dict(n_quantiles=25, net_arch=[64, 64]))
STORM_ENCODER = dict(padding=1, coord_channels=True, batch_norm_eps=1e-3, position_channel=1)
STORM = dict(
    policy="CnnPolicy",
    batch_size=64,
    learning_starts=500,
    policy_delay=2,
    mean_anchored_quantiles=True,
    cvar_alpha=0.5,
    max_grad_norm=1.0,
    policy_kwargs=dict(n_quantiles=25, features_extractor_kwargs=STORM_ENCODER),
)
CASES = [
    (MADDPG, "simple_spread_v3", 4000, SPREAD),
    (MATD3, "simple_spread_v3", 4000, SPREAD),
    (MADDPG, "uav_coverage_storm_cpu_v1", 2500, STORM),
]


def trained_policy(algorithm: type[MADDPG], env_id: str, timesteps: int, flush: bool, **kwargs: Any) -> dict:
    """The policy's state dict after ``timesteps`` of training from seed 0."""
    venv = make_multiagent_vec_env(lambda **kw: make_multiagent_env(env_id, **kw), n_envs=kwargs.pop("n_envs", 1), seed=0)
    model = algorithm(kwargs.pop("policy", "MlpPolicy"), venv, seed=0, flush_denormals=flush, **kwargs)
    model.learn(timesteps)
    return model.policy.state_dict()


def main() -> None:
    th.set_num_threads(1)
    for algorithm, env_id, timesteps, settings in CASES:
        flushed = trained_policy(algorithm, env_id, timesteps, True, **settings)
        kept = trained_policy(algorithm, env_id, timesteps, False, **settings)
        differing = [name for name in flushed if not th.equal(flushed[name], kept[name])]
        weights = [name for name in differing if "running_" not in name]
        print(
            f"{algorithm.__name__} {env_id}: {len(differing)} of {len(flushed)} tensors differ, "
            f"not BatchNorm running statistics: {weights}"
        )


if __name__ == "__main__":
    main()
