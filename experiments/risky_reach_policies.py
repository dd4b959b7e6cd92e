"""
The hand-made policies of the small risky tasks on the episodes the trained teams are evaluated on, as ``python -m
sb3_maddpg evaluate`` writes its results: mean ± std, worst decile (the episode-level CVaR_0.1 of team return) and the
zone counts per episode. Its folder is the reference crosses of ``alpha_sweep_table.py --policies``.
``risky_reach_v0`` (``hand_made_policy``): straight ``through`` the risky zone, or ``around`` it;
``risky_hover_v0``: holding the ``landmark`` (depth 0.1), the hazard's ``edge`` (0), or 0.05, 0.1 or 0.15 outside it.

    taskset -c 1 python experiments/risky_reach_policies.py --episodes 100 --seed 10000 --out runs/risky/policies
    taskset -c 1 python experiments/risky_reach_policies.py --env risky_hover_v0 --out runs/hover/policies
"""

import argparse
import sys

import numpy as np
from pettingzoo import ParallelEnv

from sb3_maddpg.evaluation.evaluate import evaluate_controllers, format_table, summarize, write_results
from sb3_maddpg.evaluation.metrics import task_metrics
from sb3_maddpg_envs import risky_hover_v0, risky_reach_v0

#: env id -> (its module, {policy name: the argument of its ``hand_made_policy``})
POLICIES = {
    "risky_reach_v0": (risky_reach_v0, {"through": "through", "around": "around"}),
    "risky_hover_v0": (
        risky_hover_v0,
        {"landmark": 0.1, "edge": 0.0, "out_0.05": -0.05, "out_0.1": -0.1, "out_0.15": -0.15},
    ),
}


class HandMadeController:
    """
    Every agent follows its task's ``hand_made_policy`` from its own observation.

    :param name: the controller's name
    :param policy: the task's ``hand_made_policy``
    :param argument: its second argument (a way, a depth)
    """

    def __init__(self, name: str, policy, argument) -> None:
        self.name, self.policy, self.argument = name, policy, argument

    def reset(self, env: ParallelEnv, seed: int | None = None) -> None:
        pass  # no state and no randomness

    def act(self, observations: dict[str, np.ndarray], env: ParallelEnv) -> dict[str, np.ndarray]:
        return {agent: self.policy(observation, self.argument) for agent, observation in observations.items()}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env", choices=sorted(POLICIES), default="risky_reach_v0", help="the task")
    parser.add_argument("--episodes", type=int, default=100, help="episodes per policy")
    parser.add_argument("--seed", type=int, default=10000, help="seed of the first episode")
    parser.add_argument("--out", default=None, help="folder for the results files (none written without it)")
    args = parser.parse_args(argv)
    module, policies = POLICIES[args.env]
    controllers = [HandMadeController(name, module.hand_made_policy, argument) for name, argument in policies.items()]
    results, _ = evaluate_controllers(module.parallel_env, controllers, args.episodes, seed=args.seed)
    summary = summarize(results)
    metrics = task_metrics(module.parallel_env())
    print(f"{args.env}, {args.episodes} episodes per policy, seeds {args.seed}..{args.seed + args.episodes - 1}")
    print(format_table(summary, metrics))
    if args.out:
        metadata = {"env_id": args.env, "n_episodes": args.episodes, "seed": args.seed}
        metadata["command"] = " ".join(["python", *sys.argv])
        write_results(args.out, results, summary, metadata, metrics)
        print(f"written to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
