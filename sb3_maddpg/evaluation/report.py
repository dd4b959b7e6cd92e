"""
Evaluate a trained model against the baselines and write the table, the results files and the figures; draw the
training figures from a run's logs.
"""

import os
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from numbers import Integral
from pathlib import Path
from typing import Any

import yaml

from sb3_maddpg.common.agent_spaces import read_agent_spaces
from sb3_maddpg.common.atomic import check_writable_folder
from sb3_maddpg.evaluation.baselines import Controller, ModelController, RandomController, TeamController, make_baselines
from sb3_maddpg.evaluation.evaluate import evaluate_controllers, format_table, summarize, write_results
from sb3_maddpg.evaluation.figures import (
    Series,
    find_monitor_files,
    load_monitor_series,
    load_tensorboard_series,
    monitor_returns,
    plot_returns_vs_episode,
    plot_task_figures,
    save_episode_figures,
    series_from_results,
)
from sb3_maddpg.evaluation.metrics import TaskMetrics, task_metrics
from sb3_maddpg.evaluation.progress import episode_progress
from sb3_maddpg.evaluation.task_tools import TaskTools, episode_limit, task_tools


class ModelEnvMismatchError(ValueError):
    """The model file cannot be loaded, or it was trained for another number of agents or other observations."""


class OpponentEnvMismatchError(ModelEnvMismatchError):
    """The same, for the opponent's model file (``evaluate --opponent``)."""


# The most values a YAML file may expand to, its aliases followed (a run's args.yml holds about 50): a file of nested
# aliases (1.9 KB for 10**8 values) would otherwise be read as shared references and blow up when printed or copied
MAX_YAML_VALUES = 100_000


class BoundedSafeLoader(yaml.SafeLoader):
    """
    YAML's safe loader, refusing (with a ``yaml.YAMLError``) a document whose aliases expand to more than
    ``MAX_YAML_VALUES`` values, or refer to themselves, before anything is built from it.
    """

    def compose_document(self) -> yaml.Node:
        node = super().compose_document()
        _expanded_size(node, {}, set())
        return node


def _expanded_size(node: yaml.Node, sizes: dict[int, int], open_nodes: set[int]) -> int:
    """The number of values ``node`` stands for with its aliases expanded (shared nodes counted once per use)."""
    if id(node) in sizes:
        return sizes[id(node)]
    if id(node) in open_nodes:
        raise yaml.YAMLError("it holds an alias to a value that contains it (a recursive alias)")
    open_nodes.add(id(node))
    children: list[yaml.Node] = []
    if isinstance(node, yaml.SequenceNode):
        children = node.value
    elif isinstance(node, yaml.MappingNode):
        children = [item for pair in node.value for item in pair]
    size = 1
    for child in children:
        size += _expanded_size(child, sizes, open_nodes)
        if size > MAX_YAML_VALUES:
            raise yaml.YAMLError(f"its aliases expand to more than {MAX_YAML_VALUES} values")
    open_nodes.discard(id(node))
    sizes[id(node)] = size
    return size


class RunFileLoader(BoundedSafeLoader):
    """
    YAML's safe loader and the two Python tags RL Zoo writes in a run's ``args.yml`` and ``config.yml``
    (``collections.OrderedDict``, read as a dict, and ``python/tuple``); any other tag is refused, where RL Zoo's
    ``UnsafeLoader`` would build (or run) what it names; aliases are bounded (:class:`BoundedSafeLoader`).
    """


def _construct_ordered_dict(loader: yaml.SafeLoader, node: yaml.Node) -> dict[Any, Any]:
    (pairs,) = loader.construct_sequence(node, deep=True) or [[]]
    return {key: value for key, value in pairs}


RunFileLoader.add_constructor("tag:yaml.org,2002:python/object/apply:collections.OrderedDict", _construct_ordered_dict)
RunFileLoader.add_constructor(
    "tag:yaml.org,2002:python/tuple", lambda loader, node: tuple(loader.construct_sequence(node, deep=True))
)


def read_run_yaml(path: str | os.PathLike) -> Any:
    """
    Read a run's ``args.yml`` or ``config.yml`` with :class:`RunFileLoader`.

    :param path: the file
    :return: its content
    :raises UsageError: (a ``ValueError``) one line naming the file and what it holds that is not plain YAML
    """
    from sb3_maddpg.zoo.registry import UsageError

    try:
        with open(path) as file:
            return yaml.load(file, Loader=RunFileLoader)  # noqa: S506 (a safe loader)
    except (yaml.YAMLError, ValueError, TypeError, RecursionError) as error:
        reason = " ".join(str(error).split())
        raise UsageError(f"{os.fspath(path)} is not a run file of plain YAML values, it is not read: {reason}") from error


def run_params_dir(model_path: str | os.PathLike) -> Path | None:
    """
    The folder of the run's own ``args.yml`` and ``config.yml`` for a model inside an RL Zoo run folder
    ``<env_id>_<N>[_<uuid>]/``: its sub-folder ``<env_id>/``, never another one.

    :param model_path: a model (final, best or checkpoint)
    :return: the folder, or None when the model is not in a run folder
    """
    run_dir = Path(model_path).resolve().parent
    match = re.fullmatch(r"(.+)_\d+(_[0-9a-f-]{36})?", run_dir.name)
    if match is None or not (run_dir / match.group(1) / "args.yml").is_file():
        return None
    return run_dir / match.group(1)


def find_run_config(model_path: str | os.PathLike) -> tuple[str | None, dict[str, Any]]:
    """
    The env id and env kwargs a model was trained with, read from the RL Zoo run folder that holds it
    (``<run>/<env_id>/config.yml`` and ``args.yml``, as ``enjoy`` reads them: the command line's ``--env-kwargs``
    replace the YAML entry's ``env_kwargs``), with safe YAML loading (:func:`read_run_yaml`).

    :param model_path: a model inside a run folder (final, best or checkpoint)
    :return: the env id (None when the model is not in a run folder) and the env kwargs
    :raises ValueError: when a run file holds more than plain YAML values
    """
    params_dir = run_params_dir(model_path)
    if params_dir is None:
        return None, {}
    args = read_run_yaml(params_dir / "args.yml") or {}
    if not isinstance(args, dict) or args.get("env") not in (None, params_dir.name):
        from sb3_maddpg.zoo.registry import UsageError

        raise UsageError(f"{params_dir / 'args.yml'} is not the args.yml of a run of {params_dir.name}")
    env_kwargs: dict[str, Any] = {}
    config_file = params_dir / "config.yml"
    if config_file.is_file():
        config = read_run_yaml(config_file) or {}
        env_kwargs.update((config.get("env_kwargs") if isinstance(config, dict) else None) or {})
    if args.get("env_kwargs"):
        env_kwargs = dict(args["env_kwargs"])
    return args.get("env"), env_kwargs


def saved_algorithm(policy_class: Any) -> type:
    """
    The library's algorithm that saved a model, told by its saved policy class (``read_maddpg_data`` reads it without
    unpickling code; see ``algorithm_of_policy``): ``MATD3`` for MATD3's twin-critic policies, ``MADDPG`` otherwise.

    :param policy_class: the model's saved ``policy_class``
    :return: the algorithm class to load it with
    """
    from sb3_maddpg.algorithms import algorithm_class
    from sb3_maddpg.common.saving import algorithm_of_policy

    return algorithm_of_policy(policy_class) or algorithm_class("maddpg")


def check_state_steps(state_steps: Sequence[int] | None, max_cycles: int | None) -> None:
    """
    Refuse steps of the recorded episode that no episode has (they would silently give no image).

    :param state_steps: the steps asked for (None: the default)
    :param max_cycles: the most steps an episode has (None: unknown, then only negative steps are refused)
    :raises ValueError: naming the steps refused and the range accepted
    """
    if state_steps is None:
        return
    last = max_cycles if max_cycles is not None else float("inf")
    bad = [step for step in state_steps if isinstance(step, bool) or not isinstance(step, Integral) or not 0 <= step <= last]
    if bad:
        accepted = "integers >= 0" if max_cycles is None else f"integers from 0 (after reset) to {max_cycles} (max_cycles)"
        raise ValueError(f"state steps must be steps of the episode, {accepted}; got {bad}")


def check_model_fits_env(model_path: str | os.PathLike, env_id: str, env_kwargs: dict[str, Any]) -> dict[str, Any]:
    """
    Check, without loading its networks, that a saved model can act on an env: it is an intact MADDPG model, for the
    env's number of agents and observation space. Another number of agents would be read as several copies of the
    team (plausible but wrong numbers); other observations would fail inside the network.

    :param model_path: the saved model
    :param env_id: a registered multi-agent env id
    :param env_kwargs: the env's arguments
    :return: the class parameters read: ``n_agents``, ``observation_space`` and ``policy_class``
    :raises ModelEnvMismatchError: one line naming the model's and the env's agents and observations
    """
    from sb3_maddpg.common.model_files import read_maddpg_data
    from sb3_maddpg.zoo.registry import make_multiagent_env

    try:
        data = read_maddpg_data(model_path, ("n_agents", "observation_space", "policy_class", "agent_spaces"))
    except (ValueError, FileNotFoundError) as error:
        raise ModelEnvMismatchError(str(error)) from error
    kwargs = {key: value for key, value in env_kwargs.items() if key != "render_mode"}
    probe = make_multiagent_env(env_id, **kwargs)
    layout = read_agent_spaces(probe)
    probe.close()
    if layout.homogeneous:
        # The model's observation space is the agents' shared one
        model_observations, env_observations = data.get("observation_space"), layout.observation_spaces[0]
    else:
        # Agents with spaces of their own: the model records each agent's (its observation space is the padded one)
        model_observations, env_observations = data.get("agent_spaces"), layout
    if data.get("n_agents") != layout.n_agents or model_observations != env_observations:
        raise ModelEnvMismatchError(
            f"the model was trained with {data.get('n_agents')} agents and observations {model_observations}, "
            f"but {env_id} with {kwargs} has {layout.n_agents} agents and observations {env_observations}; "
            "pass the training env's settings with --env-kwargs"
        )
    return data


@dataclass(frozen=True)
class EvaluationEnv:
    """
    The env an evaluation plays, as ``evaluation_env`` works it out.

    :param env_id: the registered env
    :param kwargs: its arguments (the run's, the task's ``evaluation_kwargs`` over them, those given over both)
    :param tools: what its task offers beyond the PettingZoo API (:func:`~sb3_maddpg.evaluation.task_tools.task_tools`)
    :param render_mode: ``"rgb_array"`` where the env renders to arrays, else None
    :param max_cycles: the most steps an episode has, or None if the env does not say
    :param metrics: its task's episode metrics (:func:`~sb3_maddpg.evaluation.metrics.task_metrics`)
    """

    env_id: str
    kwargs: dict[str, Any]
    tools: TaskTools
    render_mode: str | None
    max_cycles: int | None
    metrics: TaskMetrics = field(default_factory=TaskMetrics)


def evaluation_env(
    model_path: str | os.PathLike | None, env_id: str | None = None, env_kwargs: dict[str, Any] | None = None
) -> EvaluationEnv:
    """
    The env that ``evaluate`` and ``select-checkpoint`` play: the model's run's env and arguments (``find_run_config``),
    ``env_id`` and ``env_kwargs`` over them, and between the two what the task asks of an evaluation
    (``TaskTools.evaluation_kwargs``: on the UAV envs a new start at random places every episode). One env is made to
    find out what it is.

    :param model_path: the model whose run gives the env (None: ``env_id``, else the registry's
        ``DEFAULT_EVALUATION_ENV_ID``)
    :param env_id: the env; by default the run's
    :param env_kwargs: env arguments over the run's
    :raises ValueError: for an env id that is not a registered multi-agent env
    """
    from sb3_maddpg.zoo.registry import DEFAULT_EVALUATION_ENV_ID, MULTIAGENT_ENVS, make_multiagent_env

    run_env_id, run_env_kwargs = (None, {}) if model_path is None else find_run_config(model_path)
    env_id = env_id or run_env_id or DEFAULT_EVALUATION_ENV_ID
    if env_id not in MULTIAGENT_ENVS:
        raise ValueError(f"unknown env {env_id!r}; registered multi-agent envs: {', '.join(sorted(MULTIAGENT_ENVS))}")
    kwargs = {**run_env_kwargs, **(env_kwargs or {})}
    kwargs.pop("render_mode", None)
    probe = make_multiagent_env(env_id, **kwargs)
    try:
        tools = task_tools(probe)
        render_mode = "rgb_array" if "rgb_array" in probe.metadata.get("render_modes", []) else None
        max_cycles = episode_limit(probe)
        metrics = task_metrics(probe)
    finally:
        probe.close()
    if tools.evaluation_kwargs:
        kwargs = {**run_env_kwargs, **tools.evaluation_kwargs, **(env_kwargs or {})}
        kwargs.pop("render_mode", None)
    return EvaluationEnv(env_id, kwargs, tools, render_mode, max_cycles, metrics)


def _load_controller(model_path: str | os.PathLike, env_id: str, env_kwargs: dict[str, Any], device: str) -> ModelController:
    """A saved model as a controller (``evaluate``'s opponent), named after its file."""
    algorithm = saved_algorithm(check_model_fits_env(model_path, env_id, env_kwargs).get("policy_class"))
    try:
        model = algorithm.load(model_path, device=device)
    except (AssertionError, KeyError, ValueError, TypeError, RuntimeError) as error:
        raise ModelEnvMismatchError(f"{model_path} is not a MADDPG model that can be loaded here: {error}") from error
    return ModelController(model, name=Path(model_path).stem)


def evaluate_and_report(
    out_dir: str | os.PathLike,
    n_episodes: int = 10,
    model_path: str | os.PathLike | None = None,
    env_id: str | None = None,
    env_kwargs: dict[str, Any] | None = None,
    seed: int = 0,
    device: str = "auto",
    state_steps: Sequence[int] | None = None,
    gif: bool = True,
    frame_every: int | None = None,
    verbose: int = 1,
    baselines: Sequence[str] | None = None,
    team: str | None = None,
    opponent: str | os.PathLike = "random",
    progress: bool = False,
) -> dict[str, Any]:
    """
    Run ``n_episodes`` for the model (deterministic actions) and the baselines, print the table and write
    ``results.csv``, ``results.json``, ``episodes.csv``, ``results.md`` and the figures into ``out_dir``.

    Any registered multi-agent env: team return, each agent's return and the episode length, against random actions
    (``returns_vs_episode.png``, and the GIF where the env renders to arrays). A task adds what its env's tools offer
    (:mod:`~sb3_maddpg.evaluation.task_tools`): on the UAV envs, with ``start="random"``, the greedy baselines, the
    state images and the coverage heat map; and where the env declares episode-end metrics, their columns and
    figures (:func:`~sb3_maddpg.evaluation.figures.plot_task_figures`: on the UAV envs c_T, f_T, e_T, eta_T and the
    report's figures).

    :param out_dir: output folder
    :param n_episodes: episodes per method
    :param model_path: a saved MADDPG model; None to evaluate the baselines only
    :param env_id: the env id; by default the model's run's, else the registry's ``DEFAULT_EVALUATION_ENV_ID``
    :param env_kwargs: env arguments over the model's training ones and the task's ``evaluation_kwargs`` (on the UAV
        envs ``start`` is ``"random"`` unless given here)
    :param seed: seed of the first episode (episode e uses seed + e for every method)
    :param device: device of the model
    :param state_steps: steps of the recorded episode whose state images are written (default: start, middle, end
        where the task's state is an image, else none)
    :param gif: whether to write the GIF of the recorded episode
    :param frame_every: keep one GIF frame every this many steps (default: at most about 100 frames)
    :param verbose: 0 silent, 1 table, 2 one line per episode
    :param baselines: names of the baselines to run beside the model: ``random`` and the task's own (on the UAV envs
        ``greedy_static`` and ``greedy_step``); None for random actions and the task's default ones (on the UAV envs
        the greedy static placement)
    :param team: competing teams: the model acts for this team's agents only (``adversary`` for ``adversary_0``,
        ``adversary_1``, ...), ``opponent`` for the others; and, for comparison, random actions for the team against
        the same opponent. None: the model acts for every agent
    :param opponent: with ``team``: ``"random"``, or a saved model (.zip) that acts for the other agents
    :param progress: draw a progress bar of the episodes, with the time left, on stderr
    :return: ``summary``, ``results``, ``table``, ``files`` (name -> path), ``env_kwargs`` and ``metrics`` (the
        task's, :class:`~sb3_maddpg.evaluation.metrics.TaskMetrics`)
    :raises ModelEnvMismatchError: if the model does not fit the env (``OpponentEnvMismatchError``: the opponent)
    """
    target = evaluation_env(model_path, env_id, env_kwargs)
    check_writable_folder(out_dir, "out_dir")
    check_state_steps(state_steps, target.max_cycles)
    controllers = _evaluation_controllers(target, model_path, device, baselines, team, opponent)
    results, record, record_name = _run_episodes(
        target, controllers, model_path is not None, n_episodes, seed, state_steps, frame_every, verbose, progress
    )
    summary = summarize(results)
    table = format_table(summary, target.metrics)
    if verbose:
        print(f"{target.env_id} {target.kwargs}, {n_episodes} episode(s) per method, seeds {seed}..{seed + n_episodes - 1}")
        print(table)
    files = _write_files(Path(out_dir), target, results, summary, model_path, n_episodes, seed, record, record_name, gif)
    if verbose:
        print(f"Results and figures written to {Path(out_dir)}")
    return {
        "summary": summary,
        "results": results,
        "table": table,
        "files": files,
        "env_kwargs": target.kwargs,
        "metrics": target.metrics,
    }


def _evaluation_controllers(
    target: EvaluationEnv,
    model_path: str | os.PathLike | None,
    device: str,
    baselines: Sequence[str] | None,
    team: str | None,
    opponent: str | os.PathLike,
) -> list[Controller]:
    """
    The methods ``evaluate_and_report`` runs (parameters as there): the model (with ``team``: the model's team
    against the opponent, and random actions against the same opponent), then the baselines.
    """
    controllers: list[Controller] = []
    if model_path is not None:
        own_model = _load_controller(model_path, target.env_id, target.kwargs, device)
        own_model.name = type(own_model.model).__name__.lower()
        controllers.append(own_model)
    if team is not None:
        if not controllers:
            raise ValueError("team= needs a model to act for the team")
        try:
            rival = (
                RandomController()
                if os.fspath(opponent) == "random"
                else _load_controller(opponent, target.env_id, target.kwargs, device)
            )
        except ModelEnvMismatchError as error:
            raise OpponentEnvMismatchError(str(error)) from error
        own = controllers.pop()
        controllers = [
            TeamController(team, own, rival),
            TeamController(team, RandomController(), rival, name=f"random ({team}) vs {rival.name}"),
        ]
    controllers.extend(make_baselines(baselines, target.tools))
    if not controllers:
        raise ValueError("nothing to evaluate: give a model or at least one baseline")
    return controllers


def _run_episodes(
    target: EvaluationEnv,
    controllers: list[Controller],
    with_model: bool,
    n_episodes: int,
    seed: int,
    state_steps: Sequence[int] | None,
    frame_every: int | None,
    verbose: int,
    progress: bool,
) -> tuple[Any, Any, str]:
    """
    The episodes of ``evaluate_and_report`` (parameters as there), one method's first episode recorded: the model's
    (``with_model``: the first controller is the model), else that of the task's first default baseline run (on the
    UAV envs the static placement's, the report's figures), else the first baseline's.

    :return: ``evaluate_controllers``' results and recorded episode, and the recorded method's name
    """
    from sb3_maddpg.zoo.registry import make_multiagent_env

    names = [controller.name for controller in controllers]
    task_defaults = [name for name in target.tools.default_baselines if name in names]
    record_name = names[0] if with_model or not task_defaults else task_defaults[0]
    env_id, kwargs, render_mode, max_cycles = target.env_id, target.kwargs, target.render_mode, target.max_cycles
    if state_steps is None:
        state_steps = sorted({0, max_cycles // 2, max_cycles}) if target.tools.state_images else []
    if frame_every is None:
        frame_every = max(1, (max_cycles or 100) // 100)
    with episode_progress(len(controllers) * n_episodes, "evaluate", progress) as advance:
        results, record = evaluate_controllers(
            lambda: make_multiagent_env(env_id, render_mode=render_mode, **kwargs),
            controllers,
            n_episodes,
            seed=seed,
            record_controller=record_name,
            state_steps=state_steps,
            frame_every=frame_every,
            verbose=int(verbose >= 2),
            on_episode=advance,
        )
    return results, record, record_name


def _write_files(
    out: Path,
    target: EvaluationEnv,
    results: Any,
    summary: Any,
    model_path: str | os.PathLike | None,
    n_episodes: int,
    seed: int,
    record: Any,
    record_name: str,
    gif: bool,
) -> dict[str, Path]:
    """
    The files of ``evaluate_and_report`` (parameters as there): the results' tables, the returns of each episode, the
    task's episode-end values, and the recorded episode's figures (its GIF with ``gif``).

    :param record: the recorded episode, or None
    :param record_name: its method's name
    :return: file name -> path
    """
    metadata = {
        "env_id": target.env_id,
        "env_kwargs": target.kwargs,
        "model": None if model_path is None else os.fspath(model_path),
        "n_episodes": n_episodes,
        "seed": seed,
        "deterministic": True,
    }
    files: dict[str, Path] = dict(write_results(out, results, summary, metadata, target.metrics))
    series = series_from_results(results)
    figures = out / "figures"
    figures.mkdir(parents=True, exist_ok=True)
    files["returns_vs_episode.png"] = plot_returns_vs_episode(series, figures / "returns_vs_episode.png")
    # a task that reports episode-end values (the UAV envs: c_T, f_T, e_T, eta_T) gets its figures of them
    for path in plot_task_figures(series, figures, target.metrics, x_label="evaluation episode"):
        files[path.name] = path
    if record is not None:
        if not gif:
            record.frames.clear()
        for path in save_episode_figures(record, figures, prefix=f"{record_name}_"):
            files[path.name] = path
    return files


def training_log_metrics(log_path: str | os.PathLike, env_id: str | None = None) -> TaskMetrics | None:
    """
    The task metrics of the env a run's logs come from: ``env_id``'s, else, in an RL Zoo run folder, the run's env's
    (``find_run_config`` of the folder, or of the folder of a ``monitor.csv`` given), made once with the run's env
    arguments.

    :param log_path: an RL Zoo run folder, a ``monitor.csv`` file, or a TensorBoard log folder
    :param env_id: a registered multi-agent env id, or None
    :return: the metrics, or None where no env is known (a bare ``monitor.csv`` or TensorBoard folder) or the run's env
        is not registered here
    :raises ValueError: for an ``env_id`` given that is not a registered multi-agent env, or a run file of more than
        plain YAML values
    """
    from sb3_maddpg.zoo.registry import MULTIAGENT_ENVS, make_multiagent_env

    kwargs: dict[str, Any] = {}
    if env_id is None:
        path = Path(log_path)
        env_id, kwargs = find_run_config(path if path.is_file() else path / "monitor.csv")
        if env_id not in MULTIAGENT_ENVS:
            return None
    elif env_id not in MULTIAGENT_ENVS:
        raise ValueError(f"unknown env {env_id!r}; registered multi-agent envs: {', '.join(sorted(MULTIAGENT_ENVS))}")
    kwargs.pop("render_mode", None)
    probe = make_multiagent_env(env_id, **kwargs)
    try:
        return task_metrics(probe)
    finally:
        probe.close()


def plot_training_logs(
    log_path: str | os.PathLike,
    out_dir: str | os.PathLike,
    window: int | None = None,
    name: str = "training",
    env_id: str | None = None,
    metrics: TaskMetrics | None = None,
) -> list[Path]:
    """
    The training figures from a run's logs, for any env: the team return, each agent's return and the episode length
    vs episode (``train_returns_vs_episode.png``); for a task with episode-end values, the figures of them
    (:func:`~sb3_maddpg.evaluation.figures.plot_task_figures`: on the UAV envs the report's fairness vs coverage,
    fairness vs energy efficiency and each metric vs episode). Reads the run's ``monitor.csv`` (one point per episode)
    or, failing that, its TensorBoard event files (one point per logger dump, against timesteps).

    Which metrics the task has, their labels and pairs come from its env (:func:`training_log_metrics`: ``env_id``, or
    the run folder's env); logs of an unknown env (a bare ``monitor.csv`` or TensorBoard folder) have each of their
    metrics drawn against episode, labelled by its name.

    :param log_path: an RL Zoo run folder, a ``monitor.csv`` file, or a TensorBoard log folder
    :param out_dir: output folder (created)
    :param window: moving-average window of the metric-vs-episode curves (default: about a twentieth of the run)
    :param name: series label
    :param env_id: the env the logs come from (default: the run folder's, where there is one)
    :param metrics: the task's metrics, over ``env_id``'s
    :return: the paths written
    :raises FileNotFoundError: if no log with the metrics is found
    :raises NotAMonitorFileError: if a monitor file found is not a text CSV file
    """
    if metrics is None:
        metrics = training_log_metrics(log_path, env_id)
    out = Path(out_dir)
    series: Series = {}
    x_label = "episode"
    for monitor_file in find_monitor_files(log_path):
        candidate = load_monitor_series(monitor_file)
        if candidate.get("r") is not None and len(candidate["r"]):
            series = monitor_returns(candidate)
            break
    if not series and Path(log_path).is_dir():
        series = load_tensorboard_series(log_path, metrics=None if metrics is None else metrics.values)
        x_label = "timesteps"
    if not series:
        raise FileNotFoundError(
            f"no training log under {log_path} (expected a monitor.csv from `python -m sb3_maddpg train` or "
            "TensorBoard events with rollout/ep_rew_mean)"
        )
    if metrics is None:
        # an unknown env: every column or scalar beside the returns, the length and the time is an episode-end value
        own = ("x", "return", "length", "t")
        metrics = TaskMetrics(keys=tuple(key for key in series if key not in own and not key.startswith("return_")))
    out.mkdir(parents=True, exist_ok=True)
    n = len(next(values for key, values in series.items() if key != "x"))
    if window is None:
        window = max(1, n // 20)
    runs = {name: series}
    paths = []
    if "return" in series:
        paths.append(plot_returns_vs_episode(runs, out / "train_returns_vs_episode.png", x_label=x_label, window=window))
    paths += plot_task_figures(runs, out, metrics, x_label, window, prefix="train_", episodes="training episodes")
    return paths
