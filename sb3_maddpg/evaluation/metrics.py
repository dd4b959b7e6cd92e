"""
A task's episode metrics as the evaluation records and shows them. Which metrics an env has, and in what order, comes
from its declaration (``metadata["episode_metrics"]`` and ``["per_agent_episode_metrics"]``, read by
:func:`~sb3_maddpg.common.callbacks.declared_episode_metrics`, as a training run logs them); how the table and the
figures show them comes from its task's tools (:class:`~sb3_maddpg.evaluation.task_tools.TaskTools`: column headers,
axis labels, the pairs drawn against each other, the event counts shown). The library names no task's metric.
"""

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from sb3_maddpg.common.callbacks import declared_episode_metrics
from sb3_maddpg.evaluation.task_tools import task_tools


def metric_name(key: str) -> str:
    """
    :param key: a metric's info key (``link_failures``)
    :return: its name in words (``link failures``), what a table or a figure shows where the task gives nothing else
    """
    return key.replace("_", " ")


@dataclass(frozen=True)
class TaskMetrics:
    """
    The episode metrics of one task, as :func:`task_metrics` reads them from its env.

    :param keys: the info keys read at the end of an episode, in the order the episode's metrics keep them: those the
        env declares, then the tools' event counts it does not declare
    :param summed: those among ``keys`` that count one agent's events: the episode's value is the team total, the
        sum over the agents' infos; the others are the same in every agent's info and read from the first one
    :param table_counts: the event counts the table shows after the episode length
    :param symbols: the table's column header of a metric (default: :func:`metric_name`)
    :param labels: the figures' axis label of a metric (default: :func:`metric_name`)
    :param pairs: (x, y) pairs of episode-end values drawn against each other, one point per episode
    :param selection_metric: the metric ``select-checkpoint`` maximises unless told (None: the team return)
    """

    keys: tuple[str, ...] = ()
    summed: tuple[str, ...] = ()
    table_counts: tuple[str, ...] = ()
    symbols: Mapping[str, str] = field(default_factory=dict)
    labels: Mapping[str, str] = field(default_factory=dict)
    pairs: tuple[tuple[str, str], ...] = ()
    selection_metric: str | None = None

    @property
    def values(self) -> tuple[str, ...]:
        """
        The episode-end values (the keys that are neither summed nor an event count of the table): the table's
        columns before the team return, the panels of the metrics-vs-episode figure, the model card's results.
        """
        return tuple(key for key in self.keys if key not in self.summed and key not in self.table_counts)

    def symbol(self, key: str) -> str:
        """:return: the table's column header of a metric"""
        return self.symbols.get(key, metric_name(key))

    def label(self, key: str) -> str:
        """:return: the figures' axis label of a metric"""
        return self.labels.get(key, metric_name(key))


def task_metrics(env: Any) -> TaskMetrics:
    """
    The episode metrics of an env's task: what its ``metadata`` declares and how its tools show them.

    :param env: a PettingZoo env (its ``metadata`` and its ``task_tools``, or its unwrapped env's)
    :return: the metrics; an env that declares none and has no tools: none
    :raises TypeError: a declaration that is not a list of info keys (``declared_episode_metrics``), tools that lack a
        member (``task_tools``)
    """
    keys, per_agent_keys = declared_episode_metrics(env)
    tools = task_tools(env)
    counts = tuple(per_agent_keys if tools.event_counts is None else tools.event_counts)
    undeclared = tuple(key for key in counts if key not in keys)
    return TaskMetrics(
        keys=(*keys, *undeclared),
        summed=(*per_agent_keys, *undeclared),
        table_counts=counts,
        symbols=dict(tools.metric_symbols),
        labels=dict(tools.metric_labels),
        pairs=tuple((str(x), str(y)) for x, y in tools.metric_pairs),
        selection_metric=tools.selection_metric,
    )
