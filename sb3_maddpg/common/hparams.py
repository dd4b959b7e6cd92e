"""
A run's hyperparameters in TensorBoard's HPARAMS tab, through SB3's logger (``stable_baselines3.common.logger.HParam``),
so that runs (and Optuna trials trained again with ``train --trial-id``) can be compared by their settings.

TensorBoard shows, for each metric of the tab, the last value of the scalar of that name in the run: the metrics
named here are the evaluation scalars (``eval/mean_reward``, and the episode-end values the env declares, on the UAV
envs ``eval/coverage`` ... written by :class:`~sb3_maddpg.common.eval_tensorboard.EvalTensorBoardCallback`), so the
tab shows the final evaluation.
"""

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import HParam, Logger, TensorBoardOutputFormat

from sb3_maddpg.common.callbacks import declared_episode_metrics

# The scalars whose last values the HPARAMS tab shows beside each run's settings (a run without one leaves it blank):
# SB3's evaluation scalars, then the env's episode-end values (``default_metrics``), then the training return.
DEFAULT_METRICS: tuple[str, ...] = ("eval/mean_reward", "eval/mean_ep_length", "rollout/ep_rew_mean")
# The model attributes logged when no hyperparameters are given (those an SB3 off-policy algorithm has).
MODEL_ATTRIBUTES: tuple[str, ...] = (
    "learning_rate",
    "gamma",
    "tau",
    "batch_size",
    "buffer_size",
    "learning_starts",
    "train_freq",
    "gradient_steps",
    "seed",
)
# Longer values (e.g. a policy_kwargs dict) are cut: the tab shows one line per value.
MAX_TEXT_LENGTH = 200


def hparam_value(value: Any) -> float | int | str:
    """
    A value as TensorBoard's HPARAMS tab stores it: a number, or else its text.

    :param value: a hyperparameter's value
    :return: ints and floats as they are, bools and everything else as text (``None`` too, which TensorBoard would drop)
    """
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, bool) or value is None:
        return str(value)
    if isinstance(value, int | float):
        return value
    text = str(value)
    return text if len(text) <= MAX_TEXT_LENGTH else text[: MAX_TEXT_LENGTH - 3] + "..."


def flat_hparams(hyperparams: Mapping[str, Any]) -> dict[str, float | int | str]:
    """
    :param hyperparams: name -> value; a dict value (e.g. ``env_kwargs``) gives one entry per key, ``name/key``
    :return: name -> :func:`hparam_value`, sorted by name
    :raises TypeError: if ``hyperparams`` is not a mapping with string keys
    """
    if not isinstance(hyperparams, Mapping):
        raise TypeError(f"hyperparams must be a mapping of names to values, got {type(hyperparams).__name__}")
    flat: dict[str, float | int | str] = {}
    for name, value in hyperparams.items():
        if not isinstance(name, str):
            raise TypeError(f"hyperparameter names must be strings, got {name!r}")
        if isinstance(value, Mapping) and value:
            flat.update({f"{name}/{key}": hparam_value(item) for key, item in value.items()})
        else:
            flat[name] = hparam_value(value)
    return dict(sorted(flat.items()))


def tensorboard_formats(logger: Logger) -> list[TensorBoardOutputFormat]:
    """
    :param logger: SB3's logger
    :return: its TensorBoard writers (none when the run has no ``tensorboard_log``)
    """
    return [output for output in logger.output_formats if isinstance(output, TensorBoardOutputFormat)]


def write_to_tensorboard(logger: Logger, values: Mapping[str, Any], step: int) -> None:
    """
    Write values (images, videos, hyperparameters) to the logger's TensorBoard outputs only, at once.

    A ``record`` and ``dump`` would write them to every output: the stdout and CSV outputs cannot show them and would
    print an empty table (and a warning) or an empty CSV row, and the dump would also flush the means other callbacks
    are accumulating. Each output's ``write`` is SB3's own, as ``dump`` calls it.

    :param logger: SB3's logger
    :param values: tag -> value (``Image``, ``Video``, ``HParam``, numbers)
    :param step: the timestep they belong to
    """
    excluded = dict.fromkeys(values, ("stdout", "log", "json", "csv"))
    for output in tensorboard_formats(logger):
        output.write(dict(values), excluded, step)


def default_metrics(env: object) -> tuple[str, ...]:
    """
    The HPARAMS tab's metrics for a run on this env: :data:`DEFAULT_METRICS` with, before the training return, the
    evaluation's mean of each episode-end value the env declares (``declared_episode_metrics``, the per-agent counts
    left out: on the UAV envs ``eval/coverage``, ``eval/fairness``, ``eval/energy``, ``eval/energy_efficiency``).

    :param env: the model's VecEnv (or None)
    :return: the scalar tags
    """
    keys, per_agent_keys = declared_episode_metrics(env)
    values = tuple(f"eval/{key}" for key in keys if key not in per_agent_keys)
    return (*DEFAULT_METRICS[:-1], *values, DEFAULT_METRICS[-1])


class HParamsCallback(BaseCallback):
    """
    Logs the run's hyperparameters once, when training starts, as SB3's ``HParamCallback`` example does; TensorBoard's
    HPARAMS tab then shows them beside the last value of each metric (the final evaluation). Runs without TensorBoard
    (no ``tensorboard_log``) write nothing.

    :param hyperparams: name -> value (e.g. an RL Zoo entry with the env and the seed); by default the algorithm's
        name and the model's ``learning_rate``, ``gamma``, ``tau``, ``batch_size``... where it has them. Dict values
        give one entry per key (``env_kwargs/n_uavs``).
    :param metrics: the scalar tags shown as metrics (default: :func:`default_metrics` of the model's env)
    :param verbose: verbosity level
    """

    def __init__(
        self, hyperparams: Mapping[str, Any] | None = None, metrics: Sequence[str] | None = None, verbose: int = 0
    ) -> None:
        super().__init__(verbose)
        if metrics is not None and (
            isinstance(metrics, str) or not metrics or not all(isinstance(metric, str) for metric in metrics)
        ):
            raise TypeError(f"metrics must be a non-empty sequence of scalar tags, e.g. {DEFAULT_METRICS[:2]}, got {metrics}")
        self.hyperparams = None if hyperparams is None else flat_hparams(hyperparams)
        self.metrics = None if metrics is None else tuple(metrics)

    def model_hyperparams(self) -> dict[str, float | int | str]:
        """
        :return: the hyperparameters logged: those given, else the algorithm and the model's attributes
        """
        if self.hyperparams is not None:
            return self.hyperparams
        found: dict[str, Any] = {"algo": type(self.model).__name__}
        for name in MODEL_ATTRIBUTES:
            if not hasattr(self.model, name):
                continue
            value = getattr(self.model, name)
            if callable(value):
                # A schedule: its value at the start of training
                value = value(1.0)
            if hasattr(value, "frequency") and hasattr(value, "unit"):
                # SB3's TrainFreq, e.g. "10 step"
                value = f"{value.frequency} {value.unit.value}"
            found[name] = value
        return flat_hparams(found)

    def _on_training_start(self) -> None:
        if not tensorboard_formats(self.logger):
            return
        if self.metrics is None:
            self.metrics = default_metrics(self.model.get_env())
        # The values of metric_dict are not shown: TensorBoard reads each metric from the run's scalar of that name.
        hparam = HParam(self.model_hyperparams(), dict.fromkeys(self.metrics, 0.0))
        write_to_tensorboard(self.logger, {"hparams": hparam}, self.num_timesteps)

    def _on_step(self) -> bool:
        return True
