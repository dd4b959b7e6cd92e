"""Evaluation of trained models and baselines on multi-agent envs, with the report's figures on the UAV coverage env."""

from sb3_maddpg.evaluation.baselines import (
    Controller,
    GreedyStaticController,
    ModelController,
    RandomController,
    greedy_placement,
)
from sb3_maddpg.evaluation.evaluate import (
    METRICS,
    evaluate_controllers,
    format_table,
    run_episode,
    summarize,
    worst_decile,
    write_results,
)
from sb3_maddpg.evaluation.figures import (
    plot_fairness_vs_coverage,
    plot_fairness_vs_efficiency,
    plot_metrics_vs_episode,
    plot_returns_vs_episode,
    plot_training_logs,
    save_episode_figures,
)
from sb3_maddpg.evaluation.report import evaluate_and_report, find_run_config

__all__ = [
    "METRICS",
    "Controller",
    "GreedyStaticController",
    "ModelController",
    "RandomController",
    "evaluate_and_report",
    "evaluate_controllers",
    "find_run_config",
    "format_table",
    "greedy_placement",
    "plot_fairness_vs_coverage",
    "plot_fairness_vs_efficiency",
    "plot_metrics_vs_episode",
    "plot_returns_vs_episode",
    "plot_training_logs",
    "run_episode",
    "save_episode_figures",
    "summarize",
    "worst_decile",
    "write_results",
]
