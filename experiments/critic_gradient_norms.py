"""
The critics' gradient norms (before clipping) with one and with 25 quantiles, at the settings of the batch-32
configuration of docs/results.md, after 2 500 timesteps of training (seed 0): how much the config's clipping at norm 1
scales each critic's step, and where the gradient is (the last layer, the encoders).

    taskset -c 0 .venv/bin/python experiments/critic_gradient_norms.py
"""

import numpy as np
import torch as th

th.set_num_threads(1)
from sb3_maddpg import MADDPG, make_multiagent_vec_env
from sb3_maddpg.zoo.registry import make_multiagent_env
for nq in (1, 25):
    pk = dict(n_quantiles=nq, features_extractor_kwargs=dict(padding=1, coord_channels=True, batch_norm_eps=1e-3, position_channel=1))
    venv = make_multiagent_vec_env(lambda **kw: make_multiagent_env("uav_coverage_cpu_v1", **kw), n_envs=1, seed=0)
    m = MADDPG("CnnPolicy", venv, learning_rate=1e-3, actor_learning_rate=3e-4, learning_starts=500, batch_size=32, gamma=0.9,
               critic_warmup_steps=0, policy_delay=2, target_policy_noise=0.05, actor_reg=1e-3, max_grad_norm=1.0, policy_kwargs=pk, seed=0)
    m.learn(2500)
    norms, head, trunk = [], [], []
    m.policy.set_training_mode(True)
    for _ in range(40):
        batch = m.replay_buffer.sample(32)
        loss, _, _ = m.critic_loss(batch)
        m.critic.optimizer.zero_grad(); loss.sum().backward()
        g = lambda ps: float(th.sqrt(sum((p.grad ** 2).sum() for p in ps if p.grad is not None)))
        norms.append(g(m.critic.parameters()))
        head.append(g([m.critic.quantile_nets.net[-1].weight]))
        trunk.append(g(m.critic.features.parameters()))
    print(f"n_quantiles={nq}: critic grad norm median {np.median(norms):.3f} (clipped at 1: {np.mean(np.array(norms) > 1):.0%}); last layer {np.median(head):.3f}; encoders {np.median(trunk):.3f}")
