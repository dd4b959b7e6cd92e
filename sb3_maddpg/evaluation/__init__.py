"""
Evaluation of trained models and baselines on multi-agent envs; a task adds its own baselines and figures through
its env's ``task_tools`` (:class:`TaskTools`).
"""

from sb3_maddpg.evaluation.baselines import Controller, ModelController, RandomController, TeamController, make_baselines
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
from sb3_maddpg.evaluation.task_tools import TaskTools, task_tools

__all__ = [
    "METRICS",
    "Controller",
    "ModelController",
    "RandomController",
    "TaskTools",
    "TeamController",
    "evaluate_and_report",
    "evaluate_controllers",
    "find_run_config",
    "format_table",
    "make_baselines",
    "plot_fairness_vs_coverage",
    "plot_fairness_vs_efficiency",
    "plot_metrics_vs_episode",
    "plot_returns_vs_episode",
    "plot_training_logs",
    "run_episode",
    "save_episode_figures",
    "summarize",
    "task_tools",
    "worst_decile",
    "write_results",
]
