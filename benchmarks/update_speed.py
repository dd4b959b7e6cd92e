"""
Milliseconds per full MADDPG update (every agent's critic and actor step plus the target updates) and bytes per
stored joint transition, at the report's configuration (6 agents, batch 32, 50 quantiles, 3x80x80 images) and at
4 agents with batch 256.

    python benchmarks/update_speed.py                 # CPU, and CUDA when available
    python benchmarks/update_speed.py --device cpu --threads 1 --updates 20
    python benchmarks/update_speed.py --device cpu --threads 1 --updates 2 --image-size 32   # a quick CPU check

The replay buffer is filled with random images, so only the update itself (sampling included) is timed.

In the same run and on the same device, the same update is timed in a per-agent reference implementation with the
structure of the report's code (``per_agent_reference.py``: a loop over agents, each critic with its own CNN for
every agent's observation, N^2 CNN passes); the table gives both and the ratio reference / ours (``--no-reference``
leaves it out). The reference reuses one random batch already on the device: its time excludes sampling, ours
includes it.
"""

import argparse
import datetime
import platform
import sys
import time
from pathlib import Path

import numpy as np
import torch as th
from gymnasium import spaces
from pettingzoo import ParallelEnv

from sb3_maddpg import MADDPG, make_multiagent_vec_env
from sb3_maddpg.common.device_buffer import DeviceReplayBuffer
from sb3_maddpg.common.graphed_update import GraphedUpdate

sys.path.insert(0, str(Path(__file__).resolve().parent))
import per_agent_reference  # noqa: E402  (the sibling file, not a package)

N_QUANTILES = 50
CONFIGURATIONS = per_agent_reference.CONFIGURATIONS  # (agents, batch): (6, 32) as in the report, and (4, 256)


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


# What is timed: (label, MADDPG keyword arguments, replay buffer on the model's device)
VARIANTS = {
    "eager": ({}, False),
    "eager+device-buffer": ({}, True),
    "graph": (dict(cuda_graph=True), True),
    "graph+bf16": (dict(cuda_graph=True, bf16_autocast=True), True),
    "bf16": (dict(bf16_autocast=True), False),
}


def build(
    n_agents: int,
    batch_size: int,
    device: str,
    size: int = 80,
    n_quantiles: int = 50,
    variant: str = "eager",
) -> MADDPG:
    """
    A model at the given configuration with a full replay buffer of random images. On a device without CUDA the
    graph variants run the graph's code path without recording it (``GraphedUpdate(capture=False)``).
    """
    algo_kwargs, device_buffer = VARIANTS[variant]
    algo_kwargs = dict(algo_kwargs)
    record_graph = algo_kwargs.get("cuda_graph", False) and device == "cuda"
    if not record_graph:
        algo_kwargs.pop("cuda_graph", None)
    venv = make_multiagent_vec_env(RandomImageEnv, n_envs=1, seed=0, env_kwargs=dict(n_agents=n_agents, size=size))
    model = MADDPG(
        "CnnPolicy",
        venv,
        buffer_size=1_000,
        batch_size=batch_size,
        policy_kwargs=dict(n_quantiles=n_quantiles),
        device=device,
        seed=0,
        **algo_kwargs,
    )
    buffer = model.replay_buffer
    assert buffer is not None
    rng = np.random.default_rng(0)
    buffer.observations[...] = rng.integers(0, 256, buffer.observations.shape, dtype=np.uint8)
    buffer.actions[...] = rng.uniform(-1, 1, buffer.actions.shape)
    buffer.rewards[...] = rng.normal(size=buffer.rewards.shape)
    buffer.dones[::50] = 1.0
    buffer.full = True
    if device_buffer:
        model.replay_buffer = DeviceReplayBuffer.from_buffer(buffer, storage_device=model.device, device=model.device)
    if VARIANTS[variant][0].get("cuda_graph") and not record_graph:
        model._graphed_update = GraphedUpdate(
            model._gradient_step, [model.critic.optimizer, model.actor.optimizer], capture=False
        )
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
    parser.add_argument("--image-size", type=int, default=80, help="image side S (images are 3 x S x S; the report's 80)")
    parser.add_argument(
        "--reference",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="also time the per-agent reference implementation and print the ratio reference / ours",
    )
    parser.add_argument(
        "--variants",
        default="eager",
        help=f"comma-separated, timed in this order: {', '.join(VARIANTS)} (graph variants without CUDA run the "
        "graph's code path, not recorded)",
    )
    args = parser.parse_args()
    if args.threads is not None:
        th.set_num_threads(args.threads)

    devices = ["cpu", "cuda"] if args.device == "all" else [args.device]
    if "cuda" in devices and not th.cuda.is_available():
        print("CUDA not available: CUDA not measured")
        devices.remove("cuda")

    size = args.image_size
    image = f"3x{size}x{size}"
    cpu = platform.processor() or platform.machine()
    print(f"date: {datetime.date.today().isoformat()}, machine: {platform.node()} ({cpu}), torch {th.__version__}")
    print(f"CPU threads: {th.get_num_threads()}, timed updates per configuration: {args.updates}")
    if th.cuda.is_available():
        print(f"GPU: {th.cuda.get_device_name(0)}")
    if args.reference:
        print("ours: sb3_maddpg's MADDPG.train (sampling included); reference: per_agent_reference.py (sampling excluded)")
    print()
    variants = args.variants.split(",")
    unknown = [v for v in variants if v not in VARIANTS]
    if unknown:
        parser.error(f"unknown variants {unknown}; choose from {list(VARIANTS)}")
    print("| device | variant | agents | batch | quantiles | image | ms per update | reference / this |")
    print("|---|---|---|---|---|---|---|---|")
    for device in devices:
        for n_agents, batch_size in CONFIGURATIONS:
            reference_ms = None
            if args.reference:
                # As many warm-up updates as ours on CUDA; one on CPU, where a reference update at 80x80 takes seconds
                reference_warmup = 3 if device == "cuda" else 1
                reference_ms = per_agent_reference.ms_per_update(
                    n_agents, batch_size, N_QUANTILES, size, device, n_updates=args.updates, warmup=reference_warmup
                )
                print(
                    f"| {device} | per-agent reference | {n_agents} | {batch_size} | {N_QUANTILES} | {image} | "
                    f"{reference_ms:.2f} | 1.0x |",
                    flush=True,
                )
            for variant in variants:
                model = build(n_agents, batch_size, device, size=size, n_quantiles=N_QUANTILES, variant=variant)
                # graphs: 3 eager warm-up steps of each kind, then one capture, before the timed replays
                ms = ms_per_update(model, args.updates, warmup=8 if "graph" in variant else 3)
                del model
                ratio = f"{reference_ms / ms:.1f}x" if reference_ms is not None else ""
                label = variant if device == "cuda" or "graph" not in variant else f"{variant} (code path, not recorded)"
                print(
                    f"| {device} | {label} | {n_agents} | {batch_size} | {N_QUANTILES} | {image} | {ms:.2f} | {ratio} |",
                    flush=True,
                )

    model = build(6, 32, "cpu", size=size)
    assert model.replay_buffer is not None
    per_transition = model.replay_buffer.bytes_per_joint_transition()
    print()
    print(f"bytes per stored joint transition (6 agents, {image} uint8): {per_transition:.0f} ({per_transition / 1e3:.1f} KB)")


if __name__ == "__main__":
    main()
