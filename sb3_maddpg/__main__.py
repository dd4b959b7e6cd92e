"""
The project's command: ``python -m sb3_maddpg <command> ...`` (also installed as ``sb3_maddpg``).

- ``train``, ``optimize`` and ``enjoy`` run RL Zoo's own train, Optuna and enjoy code (every ``rl_zoo3`` flag works)
  with MADDPG, MATD3 and the multi-agent envs registered into it; ``--algo maddpg``, ``--env uav_coverage_cpu_v1`` and
  ``-conf`` the packaged ``zoo_configs/<algo>.yml`` are the defaults. ``record-video`` is RL Zoo's ``record_video``.
- ``evaluate`` compares a trained model with baselines (random actions; on the UAV envs the greedy static placement
  and the step greedy of Liu et al., TMC 2020) and draws the report's figures.
- ``plot`` draws the report's training figures from a run's logs.

Bad input (unknown env, missing file, unknown YAML key, bad ``--env-kwargs``) ends with a one-line message on stderr
and exit status 2, as argparse does.
"""

import argparse
import difflib
import importlib
import os
import sys
import zipfile
from pathlib import Path
from typing import Any, NoReturn

import yaml

from sb3_maddpg.algorithms import ALGORITHM_NAMES
from sb3_maddpg.zoo.registry import (
    DEFAULT_ENV_ID,
    DEFAULT_EVALUATION_ENV_ID,
    TrainingStopped,
    UsageError,
    check_env_kwargs,
)

PROG = "sb3_maddpg"
ZOO_COMMANDS = ("train", "optimize", "enjoy", "record-video")
# The commands that load a trained agent (RL Zoo's enjoy and record_video flags)
PLAY_COMMANDS = ("enjoy", "record-video")
DEFAULT_ALGO = "maddpg"
# The library's algorithms (sb3_maddpg/algorithms.py), each with its RL Zoo hyperparameter file zoo_configs/<algo>.yml
MULTIAGENT_ALGOS = ALGORITHM_NAMES
DEFAULTS_HELP = (
    f"defaults: --algo {DEFAULT_ALGO} --env {DEFAULT_ENV_ID} (the CPU configuration) -conf the algorithm's packaged "
    "zoo_configs/<algo>.yml (maddpg.yml, matd3.yml)"
)


# ---------------------------------------------------------------------------------------------------------------------
# Argument helpers
# ---------------------------------------------------------------------------------------------------------------------
def parse_key_values(items: list[str] | None, flag: str) -> dict[str, Any] | None:
    """
    Parse ``key:value`` items as RL Zoo's ``StoreDict`` does (the value is a Python expression), with a clear error.

    :param items: the items after the flag
    :param flag: the flag's name, for messages
    :return: the dict, or None when the flag was not given
    """
    if items is None:
        return None
    parsed: dict[str, Any] = {}
    for item in items:
        key, separator, value = item.partition(":")
        if not separator or not key:
            raise UsageError(f"{flag}: expected key:value items, got {item!r}")
        try:
            # The same evaluation as RL Zoo's StoreDict, which will parse these arguments again.
            parsed[key] = eval(value)
        except Exception as error:
            raise UsageError(
                f"{flag}: cannot read the value of {key!r} ({value!r}: {error}); "
                f"values are Python expressions, so strings need quotes, e.g. {key}:\"'text'\""
            ) from error
    return parsed


def _has_flag(argv: list[str], *flags: str) -> bool:
    return any(arg == flag or arg.startswith(flag + "=") for arg in argv for flag in flags)


def packaged_config(algo: str) -> Path | None:
    """
    The library's own RL Zoo hyperparameter file of an algorithm, as RL Zoo ships ``rl_zoo3/hyperparams/<algo>.yml``.

    :param algo: ``maddpg`` or ``matd3``
    :return: ``sb3_maddpg/zoo_configs/<algo>.yml`` where the package is installed from a wheel, ``zoo_configs/<algo>.yml``
        beside the package in a source checkout, or None
    """
    package = Path(__file__).resolve().parent
    for folder in (package / "zoo_configs", package.parent / "zoo_configs"):
        if (folder / f"{algo}.yml").is_file():
            return folder / f"{algo}.yml"
    return None


def _default_config(algo: str) -> str:
    """The file ``train`` and ``optimize`` read when no ``-conf`` is given: the one the package ships."""
    config = packaged_config(algo)
    if config is None:
        raise UsageError(f"no -conf given and this installation has no {algo}.yml; pass -conf PATH/TO/{algo}.yml")
    return os.fspath(config)


def _zoo_preparser(command: str) -> argparse.ArgumentParser:
    """The RL Zoo flags the command checks before handing over; every other flag goes to RL Zoo untouched."""
    parser = argparse.ArgumentParser(add_help=False, allow_abbrev=False)
    parser.add_argument("--algo", default=DEFAULT_ALGO)
    parser.add_argument("--env", default=DEFAULT_ENV_ID)
    parser.add_argument("--env-kwargs", nargs="+")
    parser.add_argument("--gym-packages", nargs="+", default=[])
    if command in PLAY_COMMANDS:
        parser.add_argument("-f", "--folder", default="logs")
        parser.add_argument("--exp-id", type=int, default=0)
        parser.add_argument("--load-best", action="store_true")
        parser.add_argument("--load-checkpoint", type=int)
        parser.add_argument("--load-last-checkpoint", action="store_true")
        parser.add_argument("-n", "--n-timesteps", type=int)
        if command == "record-video":
            parser.add_argument("-o", "--output-folder")
    else:
        parser.add_argument("-n", "--n-timesteps", type=int)
        parser.add_argument("-tb", "--tensorboard-log", default="")
        parser.add_argument("-conf", "--conf-file")
        parser.add_argument("--eval-env-kwargs", nargs="+")
        parser.add_argument("-params", "--hyperparams", nargs="+")
        parser.add_argument("-i", "--trained-agent", default="")
        parser.add_argument("-f", "--log-folder", default="logs")
        parser.add_argument("--storage")
        parser.add_argument("--study-name")
        parser.add_argument("--safe-config", action="store_true")
    return parser


def _import_gym_packages(modules: list[str]) -> None:
    """Import the ``--gym-packages`` modules, which register their envs (RL Zoo's flag)."""
    for module in modules:
        try:
            importlib.import_module(module)
        except ImportError as error:
            raise UsageError(f"--gym-packages: cannot import {module!r}: {error}") from error


def _check_env(env_id: str, algo: str) -> None:
    import gymnasium as gym

    from sb3_maddpg.zoo.registry import MULTIAGENT_ENVS, is_multiagent_env, load_env_packages

    load_env_packages()  # the installed task packages' ids, into Gymnasium's registry too
    if env_id not in gym.registry:
        close = difflib.get_close_matches(env_id, list(MULTIAGENT_ENVS) + list(gym.registry), n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise UsageError(
            f"unknown env {env_id!r}{hint}; multi-agent envs: {', '.join(sorted(MULTIAGENT_ENVS))} "
            "(add your own with sb3_maddpg.zoo.register_multiagent_env and --gym-packages)"
        )
    if algo in MULTIAGENT_ALGOS and not is_multiagent_env(env_id):
        raise UsageError(
            f"--algo {algo} needs a multi-agent env, and {env_id!r} is a single-agent Gymnasium env; "
            f"multi-agent envs: {', '.join(sorted(MULTIAGENT_ENVS))}"
        )


def _check_config(config: str, env_id: str, safe: bool = False) -> None:
    """
    The ``-conf`` file: it exists and has an entry for the env.

    :param config: the file
    :param env_id: the env trained
    :param safe: ``--safe-config``: the file must be YAML, and the entry values only (no expression RL Zoo would
        evaluate, no wrapper or callback from a module not loaded; see ``sb3_maddpg.zoo.run_files.read_as_data``)
    """
    from sb3_maddpg.evaluation.report import BoundedSafeLoader
    from sb3_maddpg.zoo.run_files import read_as_data

    if not os.path.isfile(config):
        raise UsageError(f"config file {config} not found")
    if not config.endswith((".yml", ".yaml")):
        if safe:
            raise UsageError(f"--safe-config reads YAML files only: -conf {config} would be run as Python")
        return
    try:
        with open(config) as file:
            entries = yaml.load(file, Loader=BoundedSafeLoader) or {}  # noqa: S506 (a safe loader)
    except (yaml.YAMLError, RecursionError) as error:
        raise UsageError(f"cannot read {config}: {error}".replace("\n", " ")) from error
    if not isinstance(entries, dict):
        raise UsageError(f"{config} must map env ids to hyperparameter entries")
    if env_id not in entries and "default" not in entries:
        raise UsageError(f"{config} has no entry for {env_id!r}; its entries: {', '.join(map(str, entries))}")
    name = env_id if env_id in entries else "default"
    if safe and isinstance(entries[name], dict):
        read_as_data(entries[name], f"the entry {name!r} of {config} (--safe-config)")


def _check_writable(folder: str, flag: str) -> None:
    from sb3_maddpg.common.atomic import check_writable_folder

    try:
        check_writable_folder(folder, flag)
    except ValueError as error:
        raise UsageError(str(error)) from error


def _check_trained_agent(model_path: str, algo: str) -> None:
    """``-i``: a model saved by the algorithm being trained (``load`` refuses another), said before the env is built."""
    from sb3_maddpg.common.model_files import read_maddpg_data
    from sb3_maddpg.evaluation.report import saved_algorithm

    try:
        saved = saved_algorithm(read_maddpg_data(model_path, ("policy_class",))["policy_class"]).__name__
    except ValueError as error:
        raise UsageError(f"--trained-agent: {error}") from error
    if saved.lower() != algo:
        raise UsageError(
            f"--trained-agent: {model_path} is a {saved} model, not a {algo.upper()} one: "
            f"resume it with --algo {saved.lower()}"
        )


def _check_model_fits_env(model_path: str, env_id: str, env_kwargs: dict[str, Any] | None) -> None:
    """The check ``evaluate`` makes, for ``enjoy``: the run's env kwargs (as enjoy reads them) and ``--env-kwargs``."""
    from sb3_maddpg.evaluation.report import ModelEnvMismatchError, check_model_fits_env, find_run_config

    _, run_env_kwargs = find_run_config(model_path)
    try:
        check_model_fits_env(model_path, env_id, {**run_env_kwargs, **(env_kwargs or {})})
    except ModelEnvMismatchError as error:
        raise UsageError(f"{model_path}: {error}") from error


def require_rl_zoo(command: str) -> None:
    """
    :param command: ``train``, ``optimize`` or ``enjoy``
    :raises UsageError: when RL Zoo (the ``zoo`` extra) is not installed
    """
    try:
        importlib.import_module("rl_zoo3")
    except ImportError as error:
        raise UsageError(
            f'{command} runs RL Zoo, which is not installed ({error}); install the zoo extra: pip install "sb3_maddpg[zoo]"'
        ) from error


def find_trained_model(args: argparse.Namespace) -> str:
    """
    The model RL Zoo's ``enjoy`` loads for these flags (``rl_zoo3.utils.get_model_path``), once its run's files are
    checked: RL Zoo reads the run's config.yml and args.yml with YAML's unsafe loader, evaluates a normalize string,
    imports the wrappers they name and unpickles vecnormalize.pkl, so each is checked first (every layout, --exp-id -1
    too).

    :param args: ``folder``, ``algo``, ``env``, ``exp_id``, ``load_best``, ``load_checkpoint``, ``load_last_checkpoint``
    :return: the model file
    """
    from huggingface_sb3 import EnvironmentName
    from rl_zoo3.utils import get_model_path

    from sb3_maddpg.zoo.run_files import check_run_folder

    try:
        _, model_path, log_path = get_model_path(
            args.exp_id,
            args.folder,
            args.algo,
            EnvironmentName(args.env),
            args.load_best,
            args.load_checkpoint,
            args.load_last_checkpoint,
        )
    except (AssertionError, ValueError) as error:
        raise UsageError(f"no trained model to load: {error} (train one first, or pass -f LOG_FOLDER)") from error
    check_run_folder(os.path.join(log_path, str(EnvironmentName(args.env))))
    return model_path


def prepare_zoo_argv(command: str, argv: list[str]) -> list[str]:
    """
    Check what can be checked before RL Zoo runs and add this command's defaults.

    :param command: ``train``, ``optimize`` or ``enjoy``
    :param argv: the arguments after the command
    :return: the arguments RL Zoo's parser gets
    """
    from sb3_maddpg.zoo.registry import is_multiagent_env
    from sb3_maddpg.zoo.storage import check_storage, is_database_url

    argv = list(argv)
    if _has_flag(argv, "-h", "--help"):
        # RL Zoo's help follows, with RL Zoo's own defaults for --algo and --env
        safe = "" if command in PLAY_COMMANDS else "; --safe-config: the -conf entry must hold values only, no code"
        pictures = f"; {', '.join(PICTURE_FLAGS)}: {PICTURE_FLAGS_HELP}" if command == "train" else ""
        print(f"{PROG} {command}: {DEFAULTS_HELP}{safe}{pictures}; RL Zoo's options follow.\n")
        return argv
    args, _ = _zoo_preparser(command).parse_known_args(argv)
    _import_gym_packages(args.gym_packages)

    if not _has_flag(argv, "--algo"):
        argv = ["--algo", DEFAULT_ALGO, *argv]
    if not _has_flag(argv, "--env"):
        argv = ["--env", DEFAULT_ENV_ID, *argv]
    _check_env(args.env, args.algo)

    env_kwargs = parse_key_values(args.env_kwargs, "--env-kwargs")
    if env_kwargs is not None and is_multiagent_env(args.env):
        check_env_kwargs(args.env, env_kwargs, flag="--env-kwargs")

    if command in PLAY_COMMANDS:
        if args.n_timesteps is not None and args.n_timesteps <= 0:
            raise UsageError(f"-n/--n-timesteps must be a positive number of timesteps to play, got {args.n_timesteps}")
        if getattr(args, "output_folder", None):
            _check_writable(args.output_folder, "-o/--output-folder")
        if not _has_flag(argv, "-f", "--folder"):
            # RL Zoo's default folder downloads models from the Hugging Face hub; this project's runs are in logs/.
            argv += ["-f", args.folder]
        model_path = find_trained_model(args)
        if args.algo in MULTIAGENT_ALGOS and is_multiagent_env(args.env):
            _check_model_fits_env(model_path, args.env, env_kwargs)
        return argv

    if args.n_timesteps is not None and args.n_timesteps <= 0:
        raise UsageError(
            f"-n/--n-timesteps must be a positive number of timesteps, got {args.n_timesteps} "
            "(leave it out to train the YAML entry's n_timesteps)"
        )
    for flag, folder in (("-f/--log-folder", args.log_folder), ("-tb/--tensorboard-log", args.tensorboard_log)):
        if folder:
            _check_writable(folder, flag)
    eval_env_kwargs = parse_key_values(args.eval_env_kwargs, "--eval-env-kwargs")
    if eval_env_kwargs is not None and is_multiagent_env(args.env):
        check_env_kwargs(args.env, eval_env_kwargs, flag="--eval-env-kwargs")
    parse_key_values(args.hyperparams, "--hyperparams")
    config = args.conf_file
    if config is None and args.algo in MULTIAGENT_ALGOS:
        config = _default_config(args.algo)
        argv += ["-conf", config]
    if config is not None:
        _check_config(config, args.env, safe=args.safe_config)
    # The library's own flag: RL Zoo's parser does not know it
    argv = [arg for arg in argv if arg != "--safe-config"]
    if args.trained_agent and not (args.trained_agent.endswith(".zip") and os.path.isfile(args.trained_agent)):
        raise UsageError(f"--trained-agent: {args.trained_agent} is not an existing .zip model file")
    if args.trained_agent and args.algo in MULTIAGENT_ALGOS:
        _check_trained_agent(args.trained_agent, args.algo)

    if command == "optimize":
        argv.append("-optimize")
        if not _has_flag(argv, "--no-optim-plots"):
            # Optuna's plots need plotly and open a browser: off unless asked for.
            argv.append("--no-optim-plots")
        storage = args.storage
        if storage is None:
            folder = Path(args.log_folder) / args.algo
            folder.mkdir(parents=True, exist_ok=True)
            storage = f"sqlite:///{folder / 'optuna.db'}"
            argv += ["--storage", storage]
        elif is_database_url(storage):
            check_storage(storage)
        elif not storage.endswith(".log"):
            # A plain file name means a local SQLite database.
            Path(storage).parent.mkdir(parents=True, exist_ok=True)
            argv = [f"--storage=sqlite:///{storage}" if arg == f"--storage={storage}" else arg for arg in argv]
            argv = [f"sqlite:///{storage}" if i > 0 and argv[i - 1] == "--storage" else arg for i, arg in enumerate(argv)]
        if args.study_name is None:
            argv += ["--study-name", f"{args.algo}_{args.env}"]
    return argv


QUIET_HELP = "no progress bar (there is none either when stderr is not a terminal)"
# The library's own train flags, which RL Zoo's parser does not know: what each evaluation draws into TensorBoard
PICTURE_FLAGS = ("--eval-video", "--no-eval-images")
PICTURE_FLAGS_HELP = (
    "with -tb, each evaluation also writes its coverage, fairness, ... and, on the UAV envs, the coverage heat map "
    "(--no-eval-images: none) and, with --eval-video, a video of one episode; every run writes its hyperparameters "
    "(TensorBoard's HPARAMS tab)"
)


def pop_picture_flags(command: str, argv: list[str]) -> tuple[list[str], dict[str, bool]]:
    """
    Take ``--eval-video`` and ``--no-eval-images`` out of ``train``'s arguments.

    :param command: the command
    :param argv: its arguments
    :return: the arguments for RL Zoo, and ``run_train``'s ``eval_images`` and ``eval_video``
    """
    given = [arg for arg in argv if arg in PICTURE_FLAGS]
    if not given:
        return argv, {}
    if command != "train":
        raise UsageError(f"{given[0]} is a train flag (pictures of the evaluations during training)")
    video, images = "--eval-video" in given, "--no-eval-images" not in given
    rest = [arg for arg in argv if arg not in PICTURE_FLAGS]
    if video and not _has_flag(rest, "-tb", "--tensorboard-log", "--track"):
        raise UsageError("--eval-video writes the video into TensorBoard: give -tb/--tensorboard-log FOLDER too")
    return rest, {"eval_images": images, "eval_video": video}


# ---------------------------------------------------------------------------------------------------------------------
# Commands
# ---------------------------------------------------------------------------------------------------------------------
def run_zoo_command(command: str, argv: list[str]) -> None:
    """
    Run RL Zoo's train, Optuna search, enjoy or record_video with MADDPG, MATD3 and the multi-agent envs registered.

    :param command: ``train``, ``optimize`` or ``enjoy``
    :param argv: RL Zoo's arguments
    """
    require_rl_zoo(command)
    from sb3_maddpg.zoo import integration

    integration.register_with_rl_zoo()
    argv, pictures = pop_picture_flags(command, argv)
    zoo_argv = prepare_zoo_argv(command, argv)
    if command == "enjoy":
        integration.run_enjoy(zoo_argv)
    elif command == "record-video":
        integration.run_record_video(zoo_argv)
    else:
        integration.run_train(zoo_argv, **pictures)


def run_evaluate(args: argparse.Namespace) -> None:
    """
    The ``evaluate`` command.

    :param args: parsed arguments
    """
    from sb3_maddpg.evaluation.baselines import make_baselines
    from sb3_maddpg.evaluation.progress import wants_progress_bar
    from sb3_maddpg.evaluation.report import (
        ModelEnvMismatchError,
        OpponentEnvMismatchError,
        check_state_steps,
        evaluate_and_report,
        find_run_config,
    )
    from sb3_maddpg.evaluation.task_tools import episode_limit, task_tools
    from sb3_maddpg.zoo.registry import MULTIAGENT_ENVS, make_multiagent_env

    _import_gym_packages(args.gym_packages)
    model_path = args.model
    run_env_id, run_env_kwargs = None, {}
    if model_path is not None:
        if not os.path.isfile(model_path) and os.path.isfile(model_path + ".zip"):
            model_path += ".zip"
        if not os.path.isfile(model_path):
            raise UsageError(f"--model: model file {args.model} not found")
        if not zipfile.is_zipfile(model_path):
            raise UsageError(f"--model: {model_path} is not a saved model (.zip)")
        run_env_id, run_env_kwargs = find_run_config(model_path)
    if args.episodes < 1:
        raise UsageError(f"--episodes must be >= 1, got {args.episodes}")
    env_id = args.env or run_env_id or DEFAULT_EVALUATION_ENV_ID
    if env_id not in MULTIAGENT_ENVS:
        raise UsageError(f"unknown env {env_id!r}; multi-agent envs: {', '.join(sorted(MULTIAGENT_ENVS))}")
    env_kwargs = parse_key_values(args.env_kwargs, "--env-kwargs") or {}
    check_env_kwargs(env_id, {**run_env_kwargs, **env_kwargs}, flag="--env-kwargs")
    # What the checks below need from the env, before any model is loaded or episode run
    probe = make_multiagent_env(env_id, **{**run_env_kwargs, **env_kwargs})
    tools, agents, max_cycles = task_tools(probe), list(probe.possible_agents), episode_limit(probe)
    probe.close()
    try:
        check_state_steps(args.state_steps, max_cycles)
    except ValueError as error:
        raise UsageError(f"--state-steps: {error} ({env_id})") from error
    if args.baselines is not None:
        try:
            make_baselines(args.baselines, tools)  # its own checks
        except ValueError as error:
            raise UsageError(f"--baselines: {error} ({env_id})") from error
    if args.team is not None and model_path is None:
        raise UsageError("--team needs --model: the model acts for the team")
    if args.opponent != "random":
        if args.team is None:
            raise UsageError("--opponent is for competing teams: give --team as well")
        if not os.path.isfile(args.opponent) or not zipfile.is_zipfile(args.opponent):
            raise UsageError(f"--opponent: {args.opponent} is neither 'random' nor a saved model (.zip)")
    if args.team is not None:
        from sb3_maddpg.common.callbacks import check_team

        try:
            check_team(args.team, agents)
        except ValueError as error:
            raise UsageError(f"--team: {error} ({env_id})") from error
    _check_writable(args.out, "--out")
    try:
        evaluate_and_report(
            args.out,
            n_episodes=args.episodes,
            model_path=model_path,
            env_id=env_id,
            env_kwargs=env_kwargs,
            seed=args.seed,
            device=args.device,
            state_steps=args.state_steps,
            gif=not args.no_gif,
            verbose=args.verbose,
            baselines=args.baselines,
            team=args.team,
            opponent=args.opponent,
            progress=wants_progress_bar(args.quiet),
        )
    except OpponentEnvMismatchError as error:
        raise UsageError(f"--opponent: {error}") from error
    except ModelEnvMismatchError as error:
        raise UsageError(f"--model: {error}") from error


def run_plot(args: argparse.Namespace) -> None:
    """
    The ``plot`` command.

    :param args: parsed arguments
    """
    from sb3_maddpg.evaluation.figures import NotAMonitorFileError
    from sb3_maddpg.evaluation.report import plot_training_logs, training_log_metrics

    if not os.path.exists(args.log):
        raise UsageError(f"--log: {args.log} not found")
    if args.window is not None and args.window < 1:
        raise UsageError(f"--window must be >= 1, got {args.window}")
    _check_writable(args.out, "--out")
    try:
        metrics = training_log_metrics(args.log, args.env)
    except ValueError as error:
        raise UsageError(f"--env: {error}" if args.env is not None else str(error)) from error
    try:
        paths = plot_training_logs(args.log, args.out, window=args.window, metrics=metrics)
    except FileNotFoundError as error:
        raise UsageError(str(error)) from error
    except NotAMonitorFileError as error:
        raise UsageError(f"--log: {error}") from error
    for path in paths:
        print(path)


def run_select_checkpoint(args: argparse.Namespace) -> None:
    """
    The ``select-checkpoint`` command (``sb3_maddpg.evaluation.checkpoints``).

    :param args: parsed arguments
    """
    from sb3_maddpg.evaluation.checkpoints import run_checkpoints, select_checkpoint, write_selection
    from sb3_maddpg.evaluation.progress import wants_progress_bar

    _check_writable(args.out, "--out")
    try:
        models = run_checkpoints(args.model)
        selection = select_checkpoint(
            models,
            metric=args.metric,
            validation_episodes=args.validation_episodes,
            validation_seed=args.validation_seed,
            test_episodes=args.episodes,
            test_seed=args.seed,
            env_kwargs=parse_key_values(args.env_kwargs, "--env-kwargs"),
            device=args.device,
            progress=wants_progress_bar(args.quiet),
        )
    except ValueError as error:
        raise UsageError(str(error)) from error
    print(f"validation {selection['metric']}: " + ", ".join(f"{path.name} {score:.4f}" for path, score in selection["scores"]))
    print(selection["table"])
    for path in write_selection(args.out, selection):
        print(path)


# ---------------------------------------------------------------------------------------------------------------------
# The Hugging Face Hub (sb3_maddpg.hub): RL Zoo's push_to_hub and load_from_hub, with their flags
# ---------------------------------------------------------------------------------------------------------------------
HUB_COMMANDS = ("push-to-hub", "load-from-hub")


def add_hub_commands(commands: Any) -> None:
    """
    :param commands: the subparsers of :func:`build_parser`
    """
    push = commands.add_parser(
        "push-to-hub",
        help="evaluate a trained run and upload it to the Hugging Face Hub with a model card (RL Zoo's push_to_hub)",
        description="Find the run's model as enjoy does, evaluate it as evaluate does, write the repository's folder "
        "(model, config.yml, args.yml, env_kwargs.yml, train_eval_metrics.zip, evaluation/, replay.gif, README.md "
        "with evaluate's table) and upload it. Needs the zoo and hub extras and a token (hf auth login or HF_TOKEN).",
    )
    load = commands.add_parser(
        "load-from-hub",
        help="download a model from the Hugging Face Hub into an RL Zoo run folder (RL Zoo's load_from_hub)",
        description="Download <organization>/<algo>-<env> (through the Hub's cache: HF_HUB_OFFLINE=1 reads a cached "
        "copy), read every file without running code, and lay it out as <folder>/<algo>/<env>_<N>/ for enjoy and "
        "evaluate. Needs the hub extra.",
    )
    for parser in (push, load):
        parser.add_argument("--algo", default=DEFAULT_ALGO, choices=MULTIAGENT_ALGOS, help=f"default: {DEFAULT_ALGO}")
        parser.add_argument("--env", default=DEFAULT_ENV_ID, help=f"env id (default: {DEFAULT_ENV_ID})")
        parser.add_argument("-f", "--folder", default="logs", help="log folder (default: logs)")
        parser.add_argument("-orga", "--organization", required=True, help="the Hub user or organisation")
        parser.add_argument("-name", "--repo-name", help="repository name (default: <algo>-<env>)")
        parser.add_argument("--verbose", type=int, default=1, help="0: quiet, 1: progress")
    push.add_argument("--exp-id", type=int, default=0, help="run number (default: 0, the latest; -1: no run folder)")
    load.add_argument("--exp-id", type=int, default=0, help="run number (default: 0, a new one; -1: no run folder)")
    push.add_argument("--load-best", action="store_true", help="push best_model.zip instead of the final model")
    push.add_argument("--load-checkpoint", type=int, help="push the checkpoint of this many timesteps")
    push.add_argument("--load-last-checkpoint", action="store_true", help="push the last checkpoint")
    push.add_argument("-m", "--commit-message", default="Upload a team trained with sb3_maddpg", help="commit message")
    push.add_argument("--episodes", type=int, default=10, help="evaluation episodes per method (default: 10)")
    push.add_argument("--seed", type=int, default=0, help="seed of the first evaluation episode (default: 0)")
    push.add_argument("--env-kwargs", nargs="+", metavar="KEY:VALUE", help="env arguments over the run's")
    push.add_argument("--device", default="auto", help="device of the model (default: auto)")
    push.add_argument("--no-render", action="store_true", help="no replay.gif")
    push.add_argument("--local-dir", help="where the repository's folder is written (default: hub/<repo name>)")
    push.add_argument("--dry-run", action="store_true", help="write the repository's folder only, upload nothing")
    push.add_argument("--private", action="store_true", help="create the repository private")
    load.add_argument("--force", action="store_true", help="replace the run folder if it exists")
    load.add_argument("--revision", help="branch, tag or commit (default: main)")
    load.add_argument("--cache-dir", help="the Hub cache (default: HF_HUB_CACHE, else HF_HOME/hub)")


def run_push_to_hub(args: argparse.Namespace) -> None:
    """
    The ``push-to-hub`` command.

    :param args: parsed arguments
    """
    from sb3_maddpg import hub
    from sb3_maddpg.evaluation.report import ModelEnvMismatchError

    require_rl_zoo("push-to-hub")  # the run is found as enjoy finds it
    hub.require_huggingface_hub()
    _check_env(args.env, args.algo)
    if args.episodes < 1:
        raise UsageError(f"--episodes must be >= 1, got {args.episodes}")
    env_kwargs = parse_key_values(args.env_kwargs, "--env-kwargs")
    if env_kwargs is not None:
        check_env_kwargs(args.env, env_kwargs, flag="--env-kwargs")
    model_path = find_trained_model(args)
    repo = hub.repo_id(args.organization, args.algo, args.env, args.repo_name)
    local_dir = args.local_dir or os.path.join("hub", repo.split("/", 1)[1])
    _check_writable(local_dir, "--local-dir")
    url = None if args.dry_run else hub.create_repo(repo, private=args.private)
    try:
        files = hub.build_repo_folder(
            model_path,
            args.algo,
            args.env,
            local_dir,
            repo,
            n_episodes=args.episodes,
            seed=args.seed,
            env_kwargs=env_kwargs,
            device=args.device,
            gif=not args.no_render,
            verbose=args.verbose,
        )
    except ModelEnvMismatchError as error:
        raise UsageError(f"{model_path}: {error}") from error
    if args.dry_run:
        print(f"Dry run: {len(files)} files of {repo} written to {local_dir}, nothing uploaded")
        return
    hub.upload_folder(local_dir, repo, args.commit_message)
    print(f"Pushed {len(files)} files to {url}")


def run_load_from_hub(args: argparse.Namespace) -> None:
    """
    The ``load-from-hub`` command.

    :param args: parsed arguments
    """
    from sb3_maddpg import hub

    hub_module = hub.require_huggingface_hub()
    _check_writable(args.folder, "-f/--folder")
    repo = hub.repo_id(args.organization, args.algo, args.env, args.repo_name)
    if args.verbose:
        print(f"Downloading {repo} from {hub_module.constants.ENDPOINT} (or the Hub's cache)")
    model_path = hub.download_run(
        repo, args.algo, args.env, args.folder, args.exp_id, args.force, args.revision, args.cache_dir
    )
    print(f"Saved to {model_path.parent}")
    if args.verbose:
        print(f"Watch it:    python -m {PROG} enjoy --algo {args.algo} --env {args.env} -f {args.folder}")
        print(f"Evaluate it: python -m {PROG} evaluate --model {model_path}")


def build_parser() -> argparse.ArgumentParser:
    """
    :return: the command's parser (``train``, ``optimize`` and ``enjoy`` hand their arguments to RL Zoo's parsers)
    """
    parser = argparse.ArgumentParser(
        prog=PROG,
        description="MADDPG and MATD3 with quantile-CVaR critics for Stable-Baselines3, run through RL Zoo.",
        epilog=f"`{PROG} COMMAND -h` shows a command's options (train, optimize, enjoy and record-video: RL Zoo's). "
        f"For train, optimize, enjoy and record-video, {DEFAULTS_HELP}.",
    )
    from sb3_maddpg import __version__

    parser.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")
    commands.add_parser("train", help="train with RL Zoo (rl_zoo3 train flags)", add_help=False)
    commands.add_parser("optimize", help="tune hyperparameters with RL Zoo's Optuna search (default storage: SQLite)")
    commands.add_parser("enjoy", help="watch a trained agent with RL Zoo's enjoy (rl_zoo3 enjoy flags)")
    commands.add_parser(
        "record-video",
        help="write a video of a trained agent with RL Zoo's record_video (-n timesteps, -o folder, default <run>/videos)",
    )

    evaluate = commands.add_parser(
        "evaluate",
        help="evaluate a model against baselines (random actions; on the UAV envs the greedy static placement and "
        "the step greedy)",
        description="Run N episodes (deterministic actions) for the model and the baselines, print the table "
        "(mean ± std of the team return and the episode length, and on the UAV envs, with start='random', of c_T, "
        "f_T, e_T, eta_T) and write CSV, JSON (with each agent's return) and figures.",
    )
    source = evaluate.add_mutually_exclusive_group(required=True)
    source.add_argument(
        "--model", help="a saved MADDPG or MATD3 model (.zip), e.g. logs/maddpg/uav_coverage_v0_1/uav_coverage_v0.zip"
    )
    source.add_argument("--baselines-only", action="store_true", help="evaluate the baselines only")
    evaluate.add_argument(
        "--baselines",
        nargs="+",
        metavar="NAME",
        help="baselines to run: random, greedy_static (flies to a greedy maximum-coverage layout and hovers), "
        "greedy_step (the greedy of Liu et al., TMC 2020: each step, the best immediate reward of 30 headings and "
        "hovering); the last two on the UAV envs only (default: random and, on the UAV envs, greedy_static)",
    )
    evaluate.add_argument(
        "--team",
        help="competing teams: the model acts for this team's agents only (e.g. adversary: adversary_0, adversary_1, "
        "...), --opponent for the others; random actions for the team against the same opponent are run beside it",
    )
    evaluate.add_argument(
        "--opponent",
        default="random",
        help="with --team: 'random' (default) or a saved model (.zip) that acts for the other agents",
    )
    evaluate.add_argument("--episodes", type=int, default=10, help="episodes per method (default: 10)")
    evaluate.add_argument("--out", default=os.path.join("results", "evaluation"), help="output folder")
    evaluate.add_argument("--env", help=f"env id (default: the model's training env, else {DEFAULT_EVALUATION_ENV_ID})")
    evaluate.add_argument(
        "--gym-packages", nargs="+", default=[], help="modules to import first, which register envs (as in train)"
    )
    evaluate.add_argument(
        "--env-kwargs",
        nargs="+",
        metavar="KEY:VALUE",
        help="env arguments over the model's training ones, e.g. max_cycles:100",
    )
    evaluate.add_argument("--seed", type=int, default=0, help="seed of the first episode (default: 0)")
    evaluate.add_argument("--device", default="auto", help="device of the model (default: auto)")
    evaluate.add_argument(
        "--state-steps", type=int, nargs="+", help="steps of the recorded episode drawn as state images (default: 0, T/2, T)"
    )
    evaluate.add_argument("--no-gif", action="store_true", help="do not write the episode GIF")
    evaluate.add_argument("--verbose", type=int, default=1, help="0: quiet, 1: table, 2: every episode")
    evaluate.add_argument("--quiet", action="store_true", help=QUIET_HELP)

    plot = commands.add_parser(
        "plot",
        help="draw the training figures from a run's logs",
        description="The team return, each agent's return and the episode length vs episode, and on the UAV envs "
        "fairness vs coverage, fairness vs energy efficiency and each metric vs episode, from a training run's "
        "monitor.csv (one point per episode) or its TensorBoard events.",
    )
    plot.add_argument(
        "--log",
        required=True,
        help="an RL Zoo run folder (logs/maddpg/uav_coverage_v0_1), a monitor.csv or a TensorBoard folder",
    )
    plot.add_argument("--out", default=os.path.join("results", "figures"), help="output folder")
    plot.add_argument("--window", type=int, help="moving-average window (default: a twentieth of the episodes)")
    plot.add_argument(
        "--env",
        help="the env the logs come from, whose task's metrics are drawn with their labels and pairs (default: the run "
        "folder's; a bare monitor.csv or TensorBoard folder: each metric of the logs against episode)",
    )

    select = commands.add_parser(
        "select-checkpoint",
        help="the best of a run's checkpoints, chosen on validation episodes, beside the final model on test episodes",
        description="Score the run's checkpoints (train --save-freq) and its final model on validation episodes, pick "
        "the best, and report it and the final model on the test episodes (evaluate's --seed and --episodes).",
    )
    select.add_argument("--model", required=True, help="the run's final model; its checkpoints are the *_steps.zip beside it")
    select.add_argument("--metric", help="metric to maximise (default: energy_efficiency where reported, else return)")
    select.add_argument("--validation-episodes", type=int, default=10, help="episodes per model (default: 10)")
    select.add_argument("--validation-seed", type=int, default=20_000, help="first validation seed (default: 20000)")
    select.add_argument("--episodes", type=int, default=20, help="test episodes (default: 20)")
    select.add_argument("--seed", type=int, default=10_000, help="first test seed (default: 10000)")
    select.add_argument("--env-kwargs", nargs="+", metavar="KEY:VALUE", help="env arguments over the run's")
    select.add_argument("--device", default="auto", help="device of the models (default: auto)")
    select.add_argument("--out", default=os.path.join("results", "checkpoints"), help="output folder")
    select.add_argument("--quiet", action="store_true", help=QUIET_HELP)
    add_hub_commands(commands)
    return parser


def _fail(command: str | None, message: str) -> NoReturn:
    prefix = f"{PROG} {command}" if command else PROG
    sys.stderr.write(f"{prefix}: error: {message}\n")
    raise SystemExit(2)


def main(argv: list[str] | None = None) -> int:
    """
    Entry point of ``python -m sb3_maddpg`` and of the ``sb3_maddpg`` console script.

    :param argv: arguments (default: ``sys.argv[1:]``)
    :return: exit status 0; ``train`` and ``optimize`` stopped by SIGTERM 143 and by an env worker process that ended 3,
        after the final save; errors exit through ``SystemExit`` with status 2
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    if not argv:
        parser.print_help(sys.stderr)
        return 2
    command = argv[0]
    try:
        if command in ZOO_COMMANDS:
            run_zoo_command(command, argv[1:])
            return 0
        args = parser.parse_args(argv)
        if args.command == "evaluate":
            run_evaluate(args)
        elif args.command == "plot":
            run_plot(args)
        elif args.command == "select-checkpoint":
            run_select_checkpoint(args)
        elif args.command == "push-to-hub":
            run_push_to_hub(args)
        elif args.command == "load-from-hub":
            run_load_from_hub(args)
        else:
            parser.print_help(sys.stderr)
            return 2
    except TrainingStopped as stopped:
        sys.stderr.write(f"{PROG} {command}: {stopped}\n")
        return stopped.exit_status
    except UsageError as error:
        _fail(
            command if command in (*ZOO_COMMANDS, "evaluate", "plot", "select-checkpoint", *HUB_COMMANDS) else None, str(error)
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
