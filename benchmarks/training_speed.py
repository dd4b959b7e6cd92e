"""
End-to-end training speed at the report's configuration (``zoo_configs/maddpg.yml``'s ``uav_coverage_v0`` entry:
6 UAVs, 3 x 80 x 80 images, 300-step episodes, batch 32, 50 quantiles, one update every 5 timesteps), for a fixed
wall-clock budget, with TensorBoard logs: timesteps per second, and the time 500 episodes (150,000 timesteps) would
take at that rate.

    python benchmarks/training_speed.py --device cuda --seconds 120 --cuda-graph --storage-device cuda
    python benchmarks/training_speed.py --device cpu --seconds 20 --obs-size 16     # a dry run on a CPU

Prints one JSON line at the end.
"""

import argparse
import json
import time

import torch as th
import yaml
from stable_baselines3.common.callbacks import BaseCallback

from sb3_maddpg import MADDPG, make_multiagent_vec_env
from sb3_maddpg.common.noise import DecayingGaussianNoise
from sb3_maddpg.zoo.registry import make_multiagent_env

EPISODES_TIMESTEPS = 150_000  # 500 episodes of 300 steps


class StopAfter(BaseCallback):
    """Stop ``learn`` once ``seconds`` of wall clock have passed since the first step."""

    def __init__(self, seconds: float) -> None:
        super().__init__()
        self.seconds = seconds
        self.start = 0.0

    def _on_training_start(self) -> None:
        self.start = time.perf_counter()

    def _on_step(self) -> bool:
        return time.perf_counter() - self.start < self.seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--device", default="cuda")
    parser.add_argument("--seconds", type=float, default=120.0, help="wall-clock budget of the run")
    parser.add_argument("--obs-size", type=int, default=80, help="image side (the report's 80)")
    parser.add_argument("--cuda-graph", action="store_true", help="MADDPG(cuda_graph=True)")
    parser.add_argument("--bf16", action="store_true", help="MADDPG(bf16_autocast=True)")
    parser.add_argument("--storage-device", default=None, help="replay buffer storage device (default: host numpy)")
    parser.add_argument("--tensorboard-log", default="runs/training_speed", help="TensorBoard folder")
    parser.add_argument("--config", default="zoo_configs/maddpg.yml")
    args = parser.parse_args()

    with open(args.config) as file:
        entry = yaml.safe_load(file)["uav_coverage_v0"]
    env_kwargs = {**entry.get("env_kwargs", {}), "obs_size": args.obs_size}
    venv = make_multiagent_vec_env(lambda: make_multiagent_env("uav_coverage_v0", **env_kwargs), n_envs=1, seed=0)
    action_dim = venv.action_space.shape[0]
    noise = DecayingGaussianNoise(
        mean=[0.0] * action_dim, sigma=entry["noise_std"], final_sigma=entry["noise_final_std"], decay=entry["noise_decay"]
    )
    algo = {key: entry[key] for key in ("learning_rate", "learning_starts", "batch_size", "tau", "gamma", "train_freq")}
    algo.update(gradient_steps=entry["gradient_steps"], cvar_alpha=entry["cvar_alpha"])
    replay_buffer_kwargs = None if args.storage_device is None else dict(storage_device=args.storage_device)
    model = MADDPG(
        entry["policy"],
        venv,
        buffer_size=entry["buffer_size"],
        action_noise=noise,
        policy_kwargs=eval(entry["policy_kwargs"]),  # RL Zoo's convention: a Python expression
        replay_buffer_kwargs=replay_buffer_kwargs,
        cuda_graph=args.cuda_graph,
        bf16_autocast=args.bf16,
        tensorboard_log=args.tensorboard_log,
        device=args.device,
        seed=0,
        **algo,
    )
    start = time.perf_counter()
    model.learn(EPISODES_TIMESTEPS, callback=StopAfter(args.seconds), tb_log_name="training_speed")
    if model.device.type == "cuda":
        th.cuda.synchronize()
    elapsed = time.perf_counter() - start
    rate = model.num_timesteps / elapsed
    print(
        json.dumps(
            dict(
                device=str(model.device),
                obs_size=args.obs_size,
                cuda_graph=args.cuda_graph,
                bf16=args.bf16,
                storage_device=args.storage_device,
                timesteps=model.num_timesteps,
                updates=model._n_updates,
                seconds=round(elapsed, 1),
                timesteps_per_s=round(rate, 1),
                projected_minutes_for_500_episodes=round(EPISODES_TIMESTEPS / rate / 60, 1),
                note="the first learning_starts timesteps take random actions without updates",
            )
        )
    )


if __name__ == "__main__":
    main()
