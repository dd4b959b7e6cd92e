"""
The risk-neutral and the risk-averse optimum of the hazardous task differ, before any training: two hand-made
policies on ``uav_coverage_hazard_cpu_v1``, both the greedy static placement (fly to greedy maximum-coverage spots
and hover, ``GreedyStaticController``), one with its spots anywhere (``hug_walls``: the greedy spots lie 2.5 cells
from the walls, where a gust can throw a UAV out) and one keeping a margin of 3.5 cells from every wall
(``keep_margin``: less coverage, fewer crashes). The first should have the better mean team return, the second the
better worst decile (the mean of the worst 10 % of the episodes).

On a task with a storm zone (``--env uav_coverage_storm_cpu_v1``, or ``--env-kwargs storm_zone:[x0,y0,x1,y1]
storm_prob:P ...``) the two policies are the greedy
placement anywhere (``enter_storm``: spots inside the zone, where a strike can ground a hovering UAV) and the greedy
placement outside the zone (``avoid_storm``: its inner PoIs lost, no strikes while hovering). On the redesigned storm
task (``--env uav_coverage_storm_cpu_v2``) the greedy placement puts its middle spot inside the zone, so
``enter_storm`` is the placement using the zone's PoIs and ``avoid_storm`` the one restricted outside it; with
``--env-kwargs storm_prob:0`` the same two placements without strikes (the calm control).

    taskset -c 1 python experiments/hazard_policies.py --episodes 200 --out experiments/results/2026-12-04-hazard
    taskset -c 1 python experiments/hazard_policies.py --env uav_coverage_storm_cpu_v2 --episodes 200 --seed 10000 \
        --out experiments/results/2026-12-07-storm-v2/policies

It prints the table of ``python -m sb3_maddpg evaluate`` (mean ± std, worst decile, hazard events per episode) and
writes ``results.csv``, ``results.json``, ``episodes.csv`` and ``results.md`` into ``--out``.
"""

import argparse
import sys
from typing import Any

from sb3_maddpg.evaluation.evaluate import evaluate_controllers, format_table, summarize, write_results
from sb3_maddpg.evaluation.metrics import task_metrics
from sb3_maddpg.zoo.command_line import parse_key_values
from sb3_maddpg.zoo.registry import UsageError, make_multiagent_env
from sb3_maddpg_envs.uav_coverage.baselines import GreedyStaticController

ENV_ID = "uav_coverage_hazard_cpu_v1"
#: How far from every wall the cautious placement keeps its spots, in cells.
MARGIN = 3.5


def policies(margin: float = MARGIN, storm: bool = False) -> list[GreedyStaticController]:
    """
    The two hand-made policies, the risky one first: the greedy placement anywhere, and the greedy placement keeping
    ``margin`` from the walls (or, with ``storm``, keeping out of the storm zone).
    """
    if storm:
        return [GreedyStaticController("enter_storm"), GreedyStaticController("avoid_storm", avoid_storm=True)]
    return [GreedyStaticController("hug_walls"), GreedyStaticController("keep_margin", wall_margin=margin)]


def compare(n_episodes: int, seed: int = 0, margin: float = MARGIN, env_id: str = ENV_ID, **env_kwargs: Any) -> dict[str, Any]:
    """
    Run both policies on the same ``n_episodes`` episodes (episode e has seed ``seed + e``: the same starts and the
    same gusts while the UAVs are in the same places).

    :param n_episodes: episodes per policy
    :param seed: seed of the first episode
    :param margin: the cautious policy's wall margin
    :param env_id: the registered task
    :param env_kwargs: over the registered env's (``start`` is ``"random"`` already, v1's default)
    :return: ``results`` (policy -> per-episode metrics), ``summary`` (rows of ``summarize``) and ``metrics`` (the
        task's, for the table)
    """
    probe = make_multiagent_env(env_id, **env_kwargs)
    # a task with a storm zone compares entering it with avoiding it (with storm_prob 0 too: the calm control)
    storm = probe.core.storm_zone is not None
    results, _ = evaluate_controllers(
        lambda: make_multiagent_env(env_id, **env_kwargs), policies(margin, storm), n_episodes, seed=seed
    )
    return {"results": results, "summary": summarize(results), "metrics": task_metrics(probe)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env", default=ENV_ID, help=f"the registered task (default {ENV_ID})")
    parser.add_argument("--episodes", type=int, default=200, help="episodes per policy")
    parser.add_argument("--seed", type=int, default=0, help="seed of the first episode")
    parser.add_argument("--margin", type=float, default=MARGIN, help="the cautious policy's wall margin (cells)")
    parser.add_argument("--out", default=None, help="folder for the results files (none written without it)")
    parser.add_argument(
        "--crash-energy", type=float, default=None, help="E_c of a crash (default: the registered task's, 200)"
    )
    parser.add_argument(
        "--env-kwargs",
        nargs="*",
        default=[],
        metavar="KEY:VALUE",
        help="other env parameters over the registered task's, e.g. crash_ground_steps:30 grounded_penalty:0.5",
    )
    args = parser.parse_args(argv)
    env_kwargs = {} if args.crash_energy is None else {"crash_energy": args.crash_energy}
    try:
        env_kwargs.update(parse_key_values(args.env_kwargs, "--env-kwargs"))
    except UsageError as error:
        parser.error(str(error))
    report = compare(args.episodes, args.seed, args.margin, args.env, **env_kwargs)
    summary = {row["method"]: row for row in report["summary"]}
    print(f"{args.env} {env_kwargs}, {args.episodes} episodes per policy, seeds {args.seed}..{args.seed + args.episodes - 1}")
    print(format_table(report["summary"], report["metrics"]))
    if args.out:
        metadata = {
            "env_id": args.env,
            "env_kwargs": env_kwargs,
            "n_episodes": args.episodes,
            "seed": args.seed,
            "margin": args.margin,
            "command": " ".join(["python", *sys.argv]),
        }
        write_results(args.out, report["results"], report["summary"], metadata, report["metrics"])
        print(f"written to {args.out}")
    risky, cautious = (summary[row["method"]] for row in report["summary"][:2])
    differ = risky["return_mean"] > cautious["return_mean"] and risky["return_worst_decile"] < cautious["return_worst_decile"]
    print(
        f"mean: {risky['method']} {risky['return_mean']:.1f}, {cautious['method']} {cautious['return_mean']:.1f}; "
        f"worst decile: {risky['method']} {risky['return_worst_decile']:.1f}, "
        f"{cautious['method']} {cautious['return_worst_decile']:.1f}; "
        f"the optima {'differ' if differ else 'do NOT differ'}"
    )
    return 0 if differ else 1


if __name__ == "__main__":
    sys.exit(main())
