"""
The two hand-made policies of ``risky_reach_v0`` (``hand_made_policy``: straight ``through`` the risky zone, or
``around`` it) on the episodes the trained teams are evaluated on, as ``python -m sb3_maddpg evaluate`` writes its
results: mean ± std, worst decile (the episode-level CVaR_0.1 of team return) and the zone counts per episode. Its
folder is the reference crosses of ``alpha_sweep_table.py --policies``.

    taskset -c 1 python experiments/risky_reach_policies.py --episodes 100 --seed 10000 --out runs/risky/policies
"""

import argparse
import sys

import numpy as np
from pettingzoo import ParallelEnv

from sb3_maddpg.evaluation.evaluate import evaluate_controllers, format_table, summarize, write_results
from sb3_maddpg.evaluation.metrics import task_metrics
from sb3_maddpg_envs.risky_reach_v0 import hand_made_policy, parallel_env

WAYS = ("through", "around")


class HandMadeController:
    """
    Every agent follows ``hand_made_policy`` from its own observation.

    :param way: ``"through"`` or ``"around"``, also the controller's name
    """

    def __init__(self, way: str) -> None:
        if way not in WAYS:
            raise ValueError(f"way must be one of {WAYS}, got {way!r}")
        self.name = way

    def reset(self, env: ParallelEnv, seed: int | None = None) -> None:
        pass  # no state and no randomness

    def act(self, observations: dict[str, np.ndarray], env: ParallelEnv) -> dict[str, np.ndarray]:
        return {agent: hand_made_policy(observation, self.name) for agent, observation in observations.items()}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--episodes", type=int, default=100, help="episodes per policy")
    parser.add_argument("--seed", type=int, default=10000, help="seed of the first episode")
    parser.add_argument("--out", default=None, help="folder for the results files (none written without it)")
    args = parser.parse_args(argv)
    results, _ = evaluate_controllers(parallel_env, [HandMadeController(way) for way in WAYS], args.episodes, seed=args.seed)
    summary = summarize(results)
    metrics = task_metrics(parallel_env())
    print(f"risky_reach_v0, {args.episodes} episodes per policy, seeds {args.seed}..{args.seed + args.episodes - 1}")
    print(format_table(summary, metrics))
    if args.out:
        metadata = {"env_id": "risky_reach_v0", "n_episodes": args.episodes, "seed": args.seed}
        metadata["command"] = " ".join(["python", *sys.argv])
        write_results(args.out, results, summary, metadata, metrics)
        print(f"written to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
