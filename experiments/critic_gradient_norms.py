"""
The critics' gradient norms (before clipping) with one and with 25 quantiles, at the settings of the batch-32
configuration of docs/results.md, after 2 500 timesteps of training (seed 0): how much the config's clipping at norm 1
scales each critic's step, and where the gradient is (the last layer, the encoders).

    taskset -c 0 .venv/bin/python experiments/critic_gradient_norms.py
"""

from collections.abc import Iterable

import numpy as np
import torch as th

from sb3_maddpg import MADDPG, make_multiagent_vec_env
from sb3_maddpg.zoo.registry import make_multiagent_env

ENCODER = dict(padding=1, coord_channels=True, batch_norm_eps=1e-3, position_channel=1)
SETTINGS = dict(
    learning_rate=1e-3,
    actor_learning_rate=3e-4,
    learning_starts=500,
    batch_size=32,
    gamma=0.9,
    critic_warmup_steps=0,
    policy_delay=2,
    target_policy_noise=0.05,
    actor_reg=1e-3,
    max_grad_norm=1.0,
)


def gradient_norm(parameters: Iterable[th.nn.Parameter]) -> float:
    """The L2 norm of the parameters' gradients together (those that have one)."""
    return float(th.sqrt(sum((p.grad**2).sum() for p in parameters if p.grad is not None)))


def main() -> None:
    th.set_num_threads(1)
    for n_quantiles in (1, 25):
        venv = make_multiagent_vec_env(lambda **kw: make_multiagent_env("uav_coverage_cpu_v1", **kw), n_envs=1, seed=0)
        policy_kwargs = dict(n_quantiles=n_quantiles, features_extractor_kwargs=ENCODER)
        model = MADDPG("CnnPolicy", venv, policy_kwargs=policy_kwargs, seed=0, **SETTINGS)
        model.learn(2500)
        model.policy.set_training_mode(True)
        whole, last_layer, encoders = [], [], []
        for _ in range(40):
            loss, _, _ = model.critic_loss(model.replay_buffer.sample(32))
            model.critic.optimizer.zero_grad()
            loss.sum().backward()
            whole.append(gradient_norm(model.critic.parameters()))
            last_layer.append(gradient_norm([model.critic.quantile_nets.net[-1].weight]))
            encoders.append(gradient_norm(model.critic.features.parameters()))
        print(
            f"n_quantiles={n_quantiles}: critic gradient norm median {np.median(whole):.3f} "
            f"(above the clipping norm 1: {np.mean(np.array(whole) > 1):.0%}); "
            f"last layer {np.median(last_layer):.3f}; encoders {np.median(encoders):.3f}"
        )


if __name__ == "__main__":
    main()
