"""
CPU time of one MADDPG update (every agent's critic and actor step and the target updates, sampling included) with
each critic design (``policy_kwargs=dict(critic=...)``), side by side in one process, and each critic's parameter
count (encoders excluded), at several team sizes:

    python benchmarks/critic_cost.py                                  # simple_spread_v3 at N 4, 8, 20
    python benchmarks/critic_cost.py --task uav --agents 4 8          # uav_coverage_tmc_v1 (images, ReportCNN)

Every model is built, its buffer filled by ``learn`` up to ``learning_starts``, then the designs are timed in
alternating rounds of ``--updates`` updates (CPU time of this process, one torch thread); the table gives the median
round. Pin the process to a core (``taskset -c 1``) and keep the other busy with nothing that shares its cache.
"""

import argparse
import platform
import statistics
import time

import torch as th

from sb3_maddpg import MADDPG, make_multiagent_vec_env
from sb3_maddpg.common.denormals import flushed_denormals
from sb3_maddpg.zoo.registry import MULTIAGENT_ENVS

CRITICS = ("joint", "attention")


def build(task: str, n_agents: int, critic: str, batch_size: int) -> MADDPG:
    """A model of ``task`` with ``n_agents`` agents and the given critic, its buffer filled with a few episodes."""
    if task == "spread":
        spec = MULTIAGENT_ENVS["simple_spread_v3"]
        env_kwargs = dict(N=n_agents, max_cycles=25)
        policy, policy_kwargs = "MlpPolicy", dict(n_quantiles=25)
    else:
        spec = MULTIAGENT_ENVS["uav_coverage_tmc_v1"]
        env_kwargs = dict(n_uavs=n_agents)
        features = dict(padding=1, coord_channels=True, batch_norm_eps=1e-3, position_channel=1)
        policy, policy_kwargs = "CnnPolicy", dict(n_quantiles=1, features_extractor_kwargs=features)
    venv = make_multiagent_vec_env(spec.env_fn(), n_envs=1, seed=0, env_kwargs=env_kwargs)
    model = MADDPG(
        policy,
        venv,
        learning_starts=300,
        batch_size=batch_size,
        buffer_size=10_000,
        seed=0,
        policy_kwargs=dict(policy_kwargs, critic=critic),
    )
    model.learn(300)  # fills the buffer; no update yet
    return model


def critic_parameters(model: MADDPG) -> int:
    return sum(p.numel() for name, p in model.critic.named_parameters() if not name.startswith("features."))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--task", choices=("spread", "uav"), default="spread")
    parser.add_argument("--agents", type=int, nargs="+", default=[4, 8, 20])
    parser.add_argument("--batch-size", type=int, default=None, help="default: 256 (spread), 32 (uav), as the entries")
    parser.add_argument("--updates", type=int, default=10, help="updates per timed round")
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
    th.set_num_threads(1)
    batch_size = args.batch_size or (256 if args.task == "spread" else 32)
    print(f"{args.task}, batch {batch_size}, {platform.processor() or platform.machine()}, torch {th.__version__}")
    print("| N | critic | parameters (critics, no encoders) | ms per update (median of rounds) | against joint |")
    print("|---|---|---|---|---|")
    for n_agents in args.agents:
        models = {critic: build(args.task, n_agents, critic, batch_size) for critic in CRITICS}
        times: dict[str, list[float]] = {critic: [] for critic in CRITICS}
        for _ in range(args.rounds):
            for critic, model in models.items():
                start = time.process_time()
                with flushed_denormals():  # as learn() runs its updates
                    model.train(gradient_steps=args.updates, batch_size=batch_size)
                times[critic].append((time.process_time() - start) / args.updates * 1000)
        joint = statistics.median(times["joint"])
        for critic, model in models.items():
            median = statistics.median(times[critic])
            print(f"| {n_agents} | {critic} | {critic_parameters(model):,} | {median:.2f} | {median / joint:.2f}x |")


if __name__ == "__main__":
    main()
