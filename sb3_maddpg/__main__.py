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
import os
import sys
import zipfile
from typing import Any, NoReturn

from sb3_maddpg.zoo.command_line import (
    DEFAULT_ALGO,
    DEFAULTS_HELP,
    MULTIAGENT_ALGOS,
    PROG,
    QUIET_HELP,
    ZOO_COMMANDS,
    check_env_id,
    check_writable,
    find_trained_model,
    import_gym_packages,
    parse_key_values,
    require_rl_zoo,
    run_zoo_command,
)
from sb3_maddpg.zoo.registry import (
    DEFAULT_ENV_ID,
    DEFAULT_EVALUATION_ENV_ID,
    TrainingStopped,
    UsageError,
    check_env_kwargs,
)


def run_evaluate(args: argparse.Namespace) -> None:
    """
    The ``evaluate`` command.

    :param args: parsed arguments
    """
    from sb3_maddpg.evaluation.progress import wants_progress_bar
    from sb3_maddpg.evaluation.report import (
        ModelEnvMismatchError,
        OpponentEnvMismatchError,
        evaluate_and_report,
        find_run_config,
    )
    from sb3_maddpg.zoo.registry import MULTIAGENT_ENVS

    import_gym_packages(args.gym_packages)
    model_path = _evaluation_model_file(args.model)
    run_env_id, run_env_kwargs = (None, {}) if model_path is None else find_run_config(model_path)
    if args.episodes < 1:
        raise UsageError(f"--episodes must be >= 1, got {args.episodes}")
    env_id = args.env or run_env_id or DEFAULT_EVALUATION_ENV_ID
    if env_id not in MULTIAGENT_ENVS:
        raise UsageError(f"unknown env {env_id!r}; multi-agent envs: {', '.join(sorted(MULTIAGENT_ENVS))}")
    env_kwargs = parse_key_values(args.env_kwargs, "--env-kwargs") or {}
    evaluated_env_kwargs = {**run_env_kwargs, **env_kwargs}  # the run's, then --env-kwargs over them
    check_env_kwargs(env_id, evaluated_env_kwargs, flag="--env-kwargs")
    _check_evaluate_flags(args, model_path, env_id, evaluated_env_kwargs)
    check_writable(args.out, "--out")
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


def _evaluation_model_file(model: str | None) -> str | None:
    """
    :param model: ``evaluate``'s ``--model`` (the ``.zip`` may be left out), or None
    :return: the saved model's file, or None
    """
    if model is None:
        return None
    model_path = model
    if not os.path.isfile(model_path) and os.path.isfile(model_path + ".zip"):
        model_path += ".zip"
    if not os.path.isfile(model_path):
        raise UsageError(f"--model: model file {model} not found")
    if not zipfile.is_zipfile(model_path):
        raise UsageError(f"--model: {model_path} is not a saved model (.zip)")
    return model_path


def _check_evaluate_flags(args: argparse.Namespace, model_path: str | None, env_id: str, env_kwargs: dict[str, Any]) -> None:
    """
    ``evaluate``'s flags that depend on the env (``--state-steps``, ``--baselines``, ``--team``, ``--opponent``),
    checked against one instance of it before any model is loaded or episode run.

    :param args: parsed arguments
    :param model_path: the model's file, or None
    :param env_id: the env evaluated
    :param env_kwargs: its arguments (the run's, then ``--env-kwargs``)
    """
    from sb3_maddpg.evaluation.baselines import make_baselines
    from sb3_maddpg.evaluation.report import check_state_steps
    from sb3_maddpg.evaluation.task_tools import episode_limit, task_tools
    from sb3_maddpg.zoo.registry import make_multiagent_env

    probe = make_multiagent_env(env_id, **env_kwargs)
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
    check_writable(args.out, "--out")
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

    check_writable(args.out, "--out")
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
    check_env_id(args.env, args.algo)
    if args.episodes < 1:
        raise UsageError(f"--episodes must be >= 1, got {args.episodes}")
    env_kwargs = parse_key_values(args.env_kwargs, "--env-kwargs")
    if env_kwargs is not None:
        check_env_kwargs(args.env, env_kwargs, flag="--env-kwargs")
    model_path = find_trained_model(args)
    repo = hub.repo_id(args.organization, args.algo, args.env, args.repo_name)
    local_dir = args.local_dir or os.path.join("hub", repo.split("/", 1)[1])
    check_writable(local_dir, "--local-dir")
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
    check_writable(args.folder, "-f/--folder")
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


def add_evaluate_command(commands: Any) -> None:
    """
    Add the ``evaluate`` command and its options.

    :param commands: the subparsers of :func:`build_parser`
    """
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


def add_plot_command(commands: Any) -> None:
    """
    Add the ``plot`` command and its options.

    :param commands: the subparsers of :func:`build_parser`
    """
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


def add_select_checkpoint_command(commands: Any) -> None:
    """
    Add the ``select-checkpoint`` command and its options.

    :param commands: the subparsers of :func:`build_parser`
    """
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

    add_evaluate_command(commands)
    add_plot_command(commands)
    add_select_checkpoint_command(commands)
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
