"""
The RL Zoo commands of ``python -m sb3_maddpg``: ``train``, ``optimize``, ``enjoy`` and ``record-video``. Their
arguments are checked here, where a mistake can be named in one line (unknown env or algorithm, missing or unsafe
YAML file, bad ``--env-kwargs``, a model that does not fit the env), then handed to RL Zoo's own parsers and code with
the library's algorithms and multi-agent envs registered (``sb3_maddpg.zoo.integration``).
"""

import argparse
import difflib
import importlib
import os
from pathlib import Path
from typing import Any

import yaml

from sb3_maddpg.algorithms import ALGORITHM_NAMES
from sb3_maddpg.zoo.registry import (
    DEFAULT_ENV_ID,
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
    package = Path(__file__).resolve().parent.parent  # sb3_maddpg/
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


def import_gym_packages(modules: list[str]) -> None:
    """Import the ``--gym-packages`` modules, which register their envs (RL Zoo's flag)."""
    for module in modules:
        try:
            importlib.import_module(module)
        except ImportError as error:
            raise UsageError(f"--gym-packages: cannot import {module!r}: {error}") from error


def check_env_id(env_id: str, algo: str) -> None:
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


def check_config(config: str, env_id: str, safe: bool = False) -> None:
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


def check_writable(folder: str, flag: str) -> None:
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

    argv = list(argv)
    if _has_flag(argv, "-h", "--help"):
        # RL Zoo's help follows, with RL Zoo's own defaults for --algo and --env
        safe = "" if command in PLAY_COMMANDS else "; --safe-config: the -conf entry must hold values only, no code"
        pictures = f"; {', '.join(PICTURE_FLAGS)}: {PICTURE_FLAGS_HELP}" if command == "train" else ""
        print(f"{PROG} {command}: {DEFAULTS_HELP}{safe}{pictures}; RL Zoo's options follow.\n")
        return argv
    args, _ = _zoo_preparser(command).parse_known_args(argv)
    import_gym_packages(args.gym_packages)

    if not _has_flag(argv, "--algo"):
        argv = ["--algo", DEFAULT_ALGO, *argv]
    if not _has_flag(argv, "--env"):
        argv = ["--env", DEFAULT_ENV_ID, *argv]
    check_env_id(args.env, args.algo)

    env_kwargs = parse_key_values(args.env_kwargs, "--env-kwargs")
    if env_kwargs is not None and is_multiagent_env(args.env):
        check_env_kwargs(args.env, env_kwargs, flag="--env-kwargs")

    if command in PLAY_COMMANDS:
        return _prepare_play_argv(args, argv, env_kwargs)

    if args.n_timesteps is not None and args.n_timesteps <= 0:
        raise UsageError(
            f"-n/--n-timesteps must be a positive number of timesteps, got {args.n_timesteps} "
            "(leave it out to train the YAML entry's n_timesteps)"
        )
    for flag, folder in (("-f/--log-folder", args.log_folder), ("-tb/--tensorboard-log", args.tensorboard_log)):
        if folder:
            check_writable(folder, flag)
    eval_env_kwargs = parse_key_values(args.eval_env_kwargs, "--eval-env-kwargs")
    if eval_env_kwargs is not None and is_multiagent_env(args.env):
        check_env_kwargs(args.env, eval_env_kwargs, flag="--eval-env-kwargs")
    parse_key_values(args.hyperparams, "--hyperparams")
    config = args.conf_file
    if config is None and args.algo in MULTIAGENT_ALGOS:
        config = _default_config(args.algo)
        argv += ["-conf", config]
    if config is not None:
        check_config(config, args.env, safe=args.safe_config)
    # The library's own flag: RL Zoo's parser does not know it
    argv = [arg for arg in argv if arg != "--safe-config"]
    if args.trained_agent and not (args.trained_agent.endswith(".zip") and os.path.isfile(args.trained_agent)):
        raise UsageError(f"--trained-agent: {args.trained_agent} is not an existing .zip model file")
    if args.trained_agent and args.algo in MULTIAGENT_ALGOS:
        _check_trained_agent(args.trained_agent, args.algo)

    if command == "optimize":
        argv = _prepare_optimize_argv(args, argv)
    return argv


def _prepare_play_argv(args: argparse.Namespace, argv: list[str], env_kwargs: dict[str, Any] | None) -> list[str]:
    """
    ``prepare_zoo_argv`` for ``enjoy`` and ``record-video``: the play flags checked, the run's folder added, and the
    trained model found and checked against the env.

    :param args: the arguments parsed by ``_zoo_preparser``
    :param argv: the arguments so far
    :param env_kwargs: ``--env-kwargs`` parsed
    :return: the arguments RL Zoo's parser gets
    """
    from sb3_maddpg.zoo.registry import is_multiagent_env

    if args.n_timesteps is not None and args.n_timesteps <= 0:
        raise UsageError(f"-n/--n-timesteps must be a positive number of timesteps to play, got {args.n_timesteps}")
    if getattr(args, "output_folder", None):
        check_writable(args.output_folder, "-o/--output-folder")
    if not _has_flag(argv, "-f", "--folder"):
        # RL Zoo's default folder downloads models from the Hugging Face hub; this project's runs are in logs/.
        argv += ["-f", args.folder]
    model_path = find_trained_model(args)
    if args.algo in MULTIAGENT_ALGOS and is_multiagent_env(args.env):
        _check_model_fits_env(model_path, args.env, env_kwargs)
    return argv


def _prepare_optimize_argv(args: argparse.Namespace, argv: list[str]) -> list[str]:
    """
    ``prepare_zoo_argv``'s additions for ``optimize``: RL Zoo's ``-optimize``, no Optuna plots unless asked for, a
    local SQLite storage by default (a plain file name: a SQLite database; a database URL checked), and a study name.

    :param args: the arguments parsed by ``_zoo_preparser``
    :param argv: the arguments so far
    :return: the arguments RL Zoo's parser gets
    """
    from sb3_maddpg.zoo.storage import check_storage, is_database_url

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
