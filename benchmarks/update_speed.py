"""
Milliseconds per full MADDPG update (every agent's critic and actor step plus the target updates) and bytes per
stored joint transition, at the report's configuration (6 agents, batch 32, 50 quantiles, 3x80x80 images) and at
4 agents with batch 256.

    python benchmarks/update_speed.py                 # CPU, and CUDA when available
    python benchmarks/update_speed.py --device cpu --threads 1 --updates 20

The replay buffer is filled with random images, so only the update itself (sampling included) is timed.
"""

import argparse
import datetime
import platform
import time

import numpy as np
import torch as th
from gymnasium import spaces
from pettingzoo import ParallelEnv

from sb3_maddpg import MADDPG, make_multiagent_vec_env


class RandomImageEnv(ParallelEnv):
    """N agents seeing random uint8 images (3, S, S), acting in [0, 1]^2; only its spaces matter here."""

    metadata = {"render_modes": [], "name": "random_image_v0"}

    def __init__(self, n_agents: int = 6, size: int = 80):
        self.possible_agents = [f"agent_{i}" for i in range(n_agents)]
        self.agents = []
        self.size = size
        self.render_mode = None

    def observation_space(self, agent):
        return spaces.Box(0, 255, (3, self.size, self.size), np.uint8)

    def action_space(self, agent):
        return spaces.Box(0.0, 1.0, (2,), np.float32)

    def _obs(self):
        return {a: np.zeros((3, self.size, self.size), np.uint8) for a in self.agents}

    def reset(self, seed=None, options=None):
        self.agents = list(self.possible_agents)
        return self._obs(), {a: {} for a in self.agents}

    def step(self, actions):
        obs = self._obs()
        return obs, dict.fromkeys(obs, 0.0), dict.fromkeys(obs, False), dict.fromkeys(obs, False), {a: {} for a in obs}


def build(n_agents: int, batch_size: int, device: str, size: int = 80, n_quantiles: int = 50) -> MADDPG:
    venv = make_multiagent_vec_env(RandomImageEnv, n_envs=1, seed=0, env_kwargs=dict(n_agents=n_agents, size=size))
    model = MADDPG(
        "CnnPolicy",
        venv,
        buffer_size=1_000,
        batch_size=batch_size,
        policy_kwargs=dict(n_quantiles=n_quantiles),
        device=device,
        seed=0,
    )
    buffer = model.replay_buffer
    assert buffer is not None
    rng = np.random.default_rng(0)
    buffer.observations[...] = rng.integers(0, 256, buffer.observations.shape, dtype=np.uint8)
    buffer.actions[...] = rng.uniform(-1, 1, buffer.actions.shape)
    buffer.rewards[...] = rng.normal(size=buffer.rewards.shape)
    buffer.dones[::50] = 1.0
    buffer.full = True
    model._setup_learn(total_timesteps=1)  # logger and counters, as learn() would
    return model


def ms_per_update(model: MADDPG, n_updates: int, warmup: int = 3) -> float:
    sync = th.cuda.synchronize if model.device.type == "cuda" else (lambda: None)
    model.train(gradient_steps=warmup, batch_size=model.batch_size)
    sync()
    start = time.perf_counter()
    model.train(gradient_steps=n_updates, batch_size=model.batch_size)
    sync()
    return (time.perf_counter() - start) / n_updates * 1e3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--device", choices=["cpu", "cuda", "all"], default="all", help="device(s) to time")
    parser.add_argument("--threads", type=int, default=None, help="torch intra-op threads on CPU (default: torch's)")
    parser.add_argument("--updates", type=int, default=20, help="timed updates per configuration")
    args = parser.parse_args()
    if args.threads is not None:
        th.set_num_threads(args.threads)

    devices = ["cpu", "cuda"] if args.device == "all" else [args.device]
    if "cuda" in devices and not th.cuda.is_available():
        print("CUDA not available: CUDA not measured")
        devices.remove("cuda")

    cpu = platform.processor() or platform.machine()
    print(f"date: {datetime.date.today().isoformat()}, machine: {platform.node()} ({cpu}), torch {th.__version__}")
    print(f"CPU threads: {th.get_num_threads()}")
    if th.cuda.is_available():
        print(f"GPU: {th.cuda.get_device_name(0)}")
    print()
    print("| device | agents | batch | quantiles | image | ms per update |")
    print("|---|---|---|---|---|---|")
    for device in devices:
        for n_agents, batch_size in ((6, 32), (4, 256)):
            model = build(n_agents, batch_size, device)
            ms = ms_per_update(model, args.updates)
            print(f"| {device} | {n_agents} | {batch_size} | 50 | 3x80x80 | {ms:.1f} |", flush=True)

    model = build(6, 32, "cpu")
    assert model.replay_buffer is not None
    per_transition = model.replay_buffer.bytes_per_joint_transition()
    print()
    print(f"bytes per stored joint transition (6 agents, 3x80x80 uint8): {per_transition:.0f} ({per_transition / 1e3:.1f} KB)")


if __name__ == "__main__":
    main()
