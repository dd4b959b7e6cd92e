"""On the hazardous task the risk-neutral and the risk-averse optimum differ before any training: the greedy placement
hugging the walls has the better mean team return, the one keeping a margin of 3.5 cells the better worst decile
(experiments/hazard_policies.py measures it on 200 episodes; here the same seeds, fewer episodes)."""

from sb3_maddpg.evaluation import GreedyStaticController, evaluate_controllers, summarize
from sb3_maddpg.zoo.registry import make_multiagent_env

N_EPISODES = 40


def test_hugging_the_walls_has_the_better_mean_and_a_margin_the_better_worst_decile() -> None:
    results, _ = evaluate_controllers(
        lambda: make_multiagent_env("uav_coverage_hazard_cpu_v1"),
        [GreedyStaticController("hug_walls"), GreedyStaticController("keep_margin", wall_margin=3.5)],
        N_EPISODES,
        seed=0,
    )
    summary = {row["method"]: row for row in summarize(results)}
    hug, margin = summary["hug_walls"], summary["keep_margin"]
    assert hug["return_mean"] > margin["return_mean"]
    assert hug["return_worst_decile"] < margin["return_worst_decile"]
    # the difference is made by the crashes: rare for the margin, several times as frequent near the walls
    assert hug["crashes_mean"] > 2 * margin["crashes_mean"]
