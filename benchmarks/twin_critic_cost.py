"""
CPU time of one update of MATD3 (twin critics) against MADDPG on the quick start's task, in one process, alternating
rounds so that both see the same machine state.

    taskset -c 1 python benchmarks/twin_critic_cost.py

Both models have ``uav_coverage_cpu_v1``'s network configuration (ReportCNN with padding, coordinate channels and the
position numbers; one quantile; batch 64) and a replay buffer of 600 random timesteps; each round times 20 updates
(``train(gradient_steps=20)``, actor and target updates every second one) of each model with ``time.process_time``.
"""

import argparse
import time

import numpy as np
import torch as th

from sb3_maddpg import MADDPG, MATD3, make_multiagent_vec_env
from sb3_maddpg.zoo.registry import make_multiagent_env

POLICY_KWARGS = dict(
    n_quantiles=1, features_extractor_kwargs=dict(padding=1, coord_channels=True, batch_norm_eps=1e-3, position_channel=1)
)


def main() -> None:
    parser = argparse.ArgumentParser(description="CPU ms per update, MATD3 against MADDPG")
    parser.add_argument("--rounds", type=int, default=6)
    parser.add_argument("--updates", type=int, default=20, help="updates per round")
    args = parser.parse_args()
    th.set_num_threads(1)
    models = {}
    for algorithm in (MADDPG, MATD3):
        venv = make_multiagent_vec_env(lambda: make_multiagent_env("uav_coverage_cpu_v1"), n_envs=1, seed=0)
        model = algorithm("CnnPolicy", venv, batch_size=64, buffer_size=5000, learning_starts=10_000, policy_delay=2,
                          seed=0, device="cpu", policy_kwargs=POLICY_KWARGS)  # fmt: skip
        model.learn(600)  # random actions only (learning_starts): fills the buffer
        models[algorithm.__name__] = model
    times: dict[str, list[float]] = {name: [] for name in models}
    for _ in range(args.rounds):
        for name, model in models.items():
            start = time.process_time()
            model.train(gradient_steps=args.updates, batch_size=64)
            times[name].append((time.process_time() - start) / args.updates * 1000)
    for name, values in times.items():
        print(f"{name}: {np.median(values):.1f} CPU ms per update (median of {args.rounds} rounds)")
    print(f"MATD3 / MADDPG: {np.median(times['MATD3']) / np.median(times['MADDPG']):.2f}")


if __name__ == "__main__":
    main()
