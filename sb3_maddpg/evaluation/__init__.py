"""
Evaluation of trained models and baselines on multi-agent envs; a task adds its own baselines, figures and the way its
metrics are shown through its env's ``task_tools`` (:class:`TaskTools`), its metrics through its env's ``metadata``
(:func:`task_metrics`).
"""

from sb3_maddpg.evaluation.baselines import Controller, ModelController, RandomController, TeamController, make_baselines
from sb3_maddpg.evaluation.evaluate import (
    evaluate_controllers,
    format_table,
    run_episode,
    summarize,
    worst_decile,
    write_results,
)
from sb3_maddpg.evaluation.figures import (
    plot_metric_pair,
    plot_metrics_vs_episode,
    plot_returns_vs_episode,
    plot_task_figures,
    save_episode_figures,
)
from sb3_maddpg.evaluation.metrics import TaskMetrics, task_metrics
from sb3_maddpg.evaluation.report import evaluate_and_report, find_run_config, plot_training_logs
from sb3_maddpg.evaluation.task_tools import TaskTools, task_tools

__all__ = [
    "Controller",
    "ModelController",
    "RandomController",
    "TaskMetrics",
    "TaskTools",
    "TeamController",
    "evaluate_and_report",
    "evaluate_controllers",
    "find_run_config",
    "format_table",
    "make_baselines",
    "plot_metric_pair",
    "plot_metrics_vs_episode",
    "plot_returns_vs_episode",
    "plot_task_figures",
    "plot_training_logs",
    "run_episode",
    "save_episode_figures",
    "summarize",
    "task_metrics",
    "task_tools",
    "worst_decile",
    "write_results",
]
