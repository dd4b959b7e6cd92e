"""
Trained teams on the Hugging Face Hub, as RL Zoo shares its agents (``rl_zoo3.push_to_hub``, ``rl_zoo3.load_from_hub``),
with ``huggingface_hub`` alone (the ``hub`` extra).

:func:`build_repo_folder` packages an RL Zoo run into the folder a model repository holds: the model as
``<algo>-<env_id>.zip``, the run's ``config.yml``, ``args.yml`` and ``env_kwargs.yml``, ``train_eval_metrics.zip``
(RL Zoo's layout, so ``rl_zoo3.load_from_hub`` reads it too), the ``evaluate`` command's results and figures under
``evaluation/``, an episode as ``replay.gif`` and a model card (``README.md``) whose table is the one ``evaluate``
prints for the same episodes; :func:`create_repo` and :func:`upload_folder` push it. :func:`download_run` downloads a
repository (through the Hub's local cache, so ``HF_HUB_OFFLINE=1`` reads a cached copy) and lays it out as an RL Zoo
run folder that ``enjoy`` and ``evaluate`` read, once every file it takes was read without running code: the model
by the restricted loader of model files (``sb3_maddpg.common.model_files``), the YAML files by the safe loader and
``vec_normalize.pkl`` by the restricted unpickler (``sb3_maddpg.zoo.run_files``).

Errors (no ``huggingface_hub``, the Hub unreachable and nothing cached, no token, a repository not found, a file that
would run code) are raised as one-line ``UsageError`` messages.
"""

import contextlib
import os
import shutil
import zipfile
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import yaml

from sb3_maddpg.zoo.registry import UsageError

# The run's files a repository holds beside the model (RL Zoo's names; ``vec_normalize.pkl`` only where the run has one)
RUN_FILES = ("config.yml", "args.yml", "env_kwargs.yml", "train_eval_metrics.zip")
VEC_NORMALIZE = "vec_normalize.pkl"
REPLAY = "replay.gif"
EVALUATION = "evaluation"
INSTALL_HINT = 'install the hub extra: pip install "sb3_maddpg[hub]"'


def model_name(algo: str, env_id: str) -> str:
    """
    The name of a model on the Hub, as RL Zoo names it (``huggingface_sb3.ModelName``).

    :param algo: ``maddpg`` or ``matd3``
    :param env_id: the env id
    :return: ``<algo>-<env_id>`` (a ``/`` in the env id becomes ``-``); the model file is this name with ``.zip``
    """
    return f"{algo}-{env_id.replace('/', '-')}"


def repo_id(organization: str, algo: str, env_id: str, repo_name: str | None = None) -> str:
    """
    :param organization: the Hub user or organisation
    :param algo: ``maddpg`` or ``matd3``
    :param env_id: the env id
    :param repo_name: the repository's name (default: :func:`model_name`, as RL Zoo)
    :return: ``<organization>/<repo_name>``
    """
    return f"{organization}/{repo_name or model_name(algo, env_id)}"


def require_huggingface_hub() -> Any:
    """
    :return: the ``huggingface_hub`` module
    :raises UsageError: when it is not installed (the ``hub`` extra)
    """
    try:
        import huggingface_hub
        import huggingface_hub.constants  # noqa: F401 (a submodule its lazy __getattr__ does not give)
    except ImportError as error:
        raise UsageError(f"the Hugging Face Hub commands need huggingface_hub ({error}); {INSTALL_HINT}") from error
    return huggingface_hub


def _is_connection_error(error: Exception) -> bool:
    """A network failure: Python's own, or the HTTP clients' that huggingface_hub lets through (httpx, requests)."""
    client_modules = ("httpx", "httpx2", "httpcore", "requests", "urllib3")
    return isinstance(error, ConnectionError | TimeoutError) or any(
        cls.__module__.split(".")[0] in client_modules and cls.__name__ in ("TransportError", "ConnectionError", "Timeout")
        for cls in type(error).__mro__
    )


def _first_line(error: Exception) -> str:
    text = str(error).strip()
    return text.splitlines()[0] if text else type(error).__name__


@contextlib.contextmanager
def hub_errors(action: str, repo: str, cache_dir: str | os.PathLike | None = None) -> Iterator[None]:
    """
    Turn what ``huggingface_hub`` raises into one line saying what failed and what to do.

    :param action: what was being done, e.g. ``"download"``
    :param repo: the repository id
    :param cache_dir: the Hub cache read (default: huggingface_hub's)
    :raises UsageError: the message
    """
    from huggingface_hub import constants
    from huggingface_hub.utils import (
        GatedRepoError,
        HfHubHTTPError,
        LocalEntryNotFoundError,
        OfflineModeIsEnabled,
        RepositoryNotFoundError,
        RevisionNotFoundError,
    )

    endpoint = constants.ENDPOINT
    try:
        yield
    except OfflineModeIsEnabled as error:
        raise UsageError(
            f"cannot {action} {repo}: HF_HUB_OFFLINE is set, so the Hub is not contacted (unset it, or use --dry-run "
            "to write the repository's folder only)"
        ) from error
    except LocalEntryNotFoundError as error:
        reason = "HF_HUB_OFFLINE is set" if constants.HF_HUB_OFFLINE else f"the Hub at {endpoint} cannot be reached"
        raise UsageError(
            f"cannot {action} {repo}: {reason} and the Hugging Face cache {os.fspath(cache_dir or constants.HF_HUB_CACHE)} "
            "holds no complete copy of it (HF_HUB_CACHE, HF_HOME or --cache-dir choose the cache)"
        ) from error
    except GatedRepoError as error:
        raise UsageError(
            f"cannot {action} {repo}: it is gated; ask for access on the Hub and log in (hf auth login)"
        ) from error
    except RepositoryNotFoundError as error:
        raise UsageError(
            f"cannot {action} {repo}: no such repository on {endpoint}, or it is private and you are not logged in "
            "with access to it (hf auth login, or HF_TOKEN)"
        ) from error
    except RevisionNotFoundError as error:
        raise UsageError(f"cannot {action} {repo}: the revision asked for does not exist ({_first_line(error)})") from error
    except HfHubHTTPError as error:
        status = getattr(getattr(error, "response", None), "status_code", None)
        if status == 401:
            raise UsageError(
                f"cannot {action} {repo}: the Hub refused the token; log in with a token that may write (hf auth login, "
                "or HF_TOKEN)"
            ) from error
        raise UsageError(f"cannot {action} {repo}: the Hub answered {_first_line(error)}") from error
    except Exception as error:
        if type(error).__name__ == "LocalTokenNotFoundError":
            raise UsageError(
                f"cannot {action} {repo}: no Hugging Face token; log in (hf auth login) or set HF_TOKEN"
            ) from error
        if _is_connection_error(error):
            raise UsageError(
                f"cannot {action} {repo}: the Hub at {endpoint} cannot be reached ({_first_line(error)}); check the network "
                "(HF_ENDPOINT, proxies)"
            ) from error
        raise


# ---------------------------------------------------------------------------------------------------------------------
# push-to-hub
# ---------------------------------------------------------------------------------------------------------------------
def _plain(value: Any) -> Any:
    """A run file's value as plain YAML data (RL Zoo saves tuples and OrderedDicts, which safe YAML cannot write)."""
    if isinstance(value, dict):
        return {key: _plain(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(item) for item in value]
    return value


def _metrics_archive(run_dir: Path, target: Path) -> None:
    """RL Zoo's ``train_eval_metrics.zip``: the run's ``evaluations.npz`` and monitor files."""
    with zipfile.ZipFile(target, "w") as archive:
        for path in sorted(run_dir.iterdir()):
            if path.name == "evaluations.npz" or path.suffix == ".csv":
                archive.write(path, arcname=path.name)


def _prepare_folder(local_dir: Path, model_file: str) -> None:
    """An empty folder to build in; a folder built before for the same model is replaced, anything else is kept."""
    if local_dir.is_dir() and any(local_dir.iterdir()):
        if not ((local_dir / "README.md").is_file() and (local_dir / model_file).is_file()):
            raise UsageError(f"--local-dir {local_dir} is not empty and was not built for {model_file}; choose another folder")
        shutil.rmtree(local_dir)
    local_dir.mkdir(parents=True, exist_ok=True)


def build_repo_folder(
    model_path: str | os.PathLike,
    algo: str,
    env_id: str,
    local_dir: str | os.PathLike,
    repo: str,
    n_episodes: int = 10,
    seed: int = 0,
    env_kwargs: dict[str, Any] | None = None,
    device: str = "auto",
    gif: bool = True,
    verbose: int = 1,
) -> dict[str, Path]:
    """
    Write the folder a model repository holds for a trained run: what ``push-to-hub`` uploads (see the module's
    docstring). The model is evaluated with ``evaluate``'s code (:func:`~sb3_maddpg.evaluation.report.evaluate_and_report`:
    deterministic actions, episode ``e`` seeded ``seed + e``, the baselines beside it), whose table goes into the card.

    :param model_path: the model inside its RL Zoo run folder (``<run>/<env_id>.zip``, ``best_model.zip``, a checkpoint)
    :param algo: ``maddpg`` or ``matd3``
    :param env_id: the env id the run trained on
    :param local_dir: the folder to write (created; one built before for the same model is replaced)
    :param repo: the repository id, for the card's commands
    :param n_episodes: evaluation episodes per method
    :param seed: seed of the first evaluation episode
    :param env_kwargs: env arguments over the run's, for the evaluation
    :param device: device of the model for the evaluation
    :param gif: whether to record an episode as ``replay.gif``
    :param verbose: 0 quiet, 1 the evaluation's table
    :return: name -> path of each file of the repository
    """
    from sb3_maddpg.evaluation.report import evaluate_and_report, read_run_yaml

    params_dir, data, algorithm = _read_run_model(model_path, algo, env_id)
    out = Path(local_dir)
    _copy_run_files(model_path, params_dir, out, model_name(algo, env_id))

    evaluation = evaluate_and_report(
        out / EVALUATION,
        n_episodes=n_episodes,
        model_path=model_path,
        env_id=env_id,
        env_kwargs=env_kwargs,
        seed=seed,
        device=device,
        gif=gif,
        verbose=verbose,
    )
    # The env's arguments of the evaluation (the run's, then env_kwargs), as RL Zoo's env_kwargs.yml
    (out / "env_kwargs.yml").write_text(yaml.safe_dump(_plain(evaluation["env_kwargs"]), sort_keys=True))
    gifs = [path for file, path in evaluation["files"].items() if file.endswith("episode.gif")]
    if gifs:
        shutil.copyfile(gifs[0], out / REPLAY)

    config = _plain(read_run_yaml(params_dir / "config.yml") or {})
    card = model_card(
        algorithm=algorithm,
        algo=algo,
        env_id=env_id,
        repo=repo,
        n_agents=int(data["n_agents"]),
        spaces=(data["observation_space"], data["action_space"]),
        timesteps=int(data.get("num_timesteps") or 0),
        hyperparams=config,
        evaluation=evaluation,
        model_file=Path(model_path).name,
        evaluate_flags=f"--episodes {n_episodes} --seed {seed}" + _env_kwargs_flag(env_kwargs),
        replay=(out / REPLAY).is_file(),
    )
    (out / "README.md").write_text(card)
    return {path.relative_to(out).as_posix(): path for path in sorted(out.rglob("*")) if path.is_file()}


def _read_run_model(model_path: str | os.PathLike, algo: str, env_id: str) -> tuple[Path, dict[str, Any], str]:
    """
    The run folder of a model to push, and what the card needs of the model, refusing a model outside a run folder of
    ``env_id`` or of another algorithm than ``algo`` (parameters as in ``build_repo_folder``).

    :return: the run's parameter folder (``<run>/<env_id>``), the model's saved data and its algorithm's class name
    """
    from sb3_maddpg.common.model_files import read_maddpg_data
    from sb3_maddpg.evaluation.report import run_params_dir, saved_algorithm
    from sb3_maddpg.zoo.run_files import check_run_folder

    params_dir = run_params_dir(model_path)
    if params_dir is None or params_dir.name != env_id:
        raise UsageError(f"{os.fspath(model_path)} is not in an RL Zoo run folder of {env_id} (<run>/{env_id}/args.yml)")
    check_run_folder(params_dir)
    try:
        data = read_maddpg_data(model_path, ("policy_class", "n_agents", "num_timesteps", "observation_space", "action_space"))
    except (ValueError, FileNotFoundError) as error:
        raise UsageError(str(error)) from error
    algorithm = saved_algorithm(data["policy_class"]).__name__
    if algorithm.lower() != algo:
        raise UsageError(
            f"{os.fspath(model_path)} is a {algorithm} model, not a {algo.upper()} one: pass --algo {algorithm.lower()}"
        )
    return params_dir, data, algorithm


def _copy_run_files(model_path: str | os.PathLike, params_dir: Path, out: Path, name: str) -> None:
    """
    Prepare the folder ``out`` and copy the run's files into it: the model as ``<name>.zip``, its ``config.yml`` and
    ``args.yml``, the VecNormalize statistics where the run has them, and the archive of its metrics.
    """
    _prepare_folder(out, f"{name}.zip")
    shutil.copyfile(model_path, out / f"{name}.zip")
    for file in ("config.yml", "args.yml"):
        shutil.copyfile(params_dir / file, out / file)
    if (params_dir / "vecnormalize.pkl").is_file():
        shutil.copyfile(params_dir / "vecnormalize.pkl", out / VEC_NORMALIZE)
    _metrics_archive(params_dir.parent, out / "train_eval_metrics.zip")


def _env_kwargs_flag(env_kwargs: dict[str, Any] | None) -> str:
    """The ``--env-kwargs`` flag that gives these arguments on the command line ('' for none)."""
    if not env_kwargs:
        return ""
    return " --env-kwargs " + " ".join(f"{key}:{value!r}" for key, value in env_kwargs.items())


def card_metadata(algorithm: str, env_id: str, summary_row: dict[str, Any], metrics: Sequence[str] = ()) -> str:
    """
    The card's YAML metadata: tags and the model index the Hub shows (the team return as RL Zoo's ``mean_reward``,
    and the task's episode-end values where the env reports them: on the UAV envs c_T, f_T, e_T, eta_T).

    :param algorithm: ``MADDPG`` or ``MATD3``
    :param env_id: the env id
    :param summary_row: the model's row of ``evaluate``'s summary
    :param metrics: the task's episode-end values (``TaskMetrics.values`` of ``evaluate``'s report)
    :return: the YAML text
    """
    hub = require_huggingface_hub()

    def result(metric: str, key: str) -> Any:
        value = f"{summary_row[f'{key}_mean']:.4f} +/- {summary_row[f'{key}_std']:.4f}"
        return hub.EvalResult(
            task_type="reinforcement-learning",
            task_name="reinforcement-learning",
            dataset_type=env_id,
            dataset_name=env_id,
            metric_type=metric,
            metric_name=metric,
            metric_value=value,
        )

    results = [result("mean_reward", "return")]
    results += [result(key, key) for key in metrics if f"{key}_mean" in summary_row]
    data = hub.ModelCardData(
        library_name="stable-baselines3",
        tags=[
            env_id,
            "deep-reinforcement-learning",
            "reinforcement-learning",
            "multi-agent-reinforcement-learning",
            "stable-baselines3",
            "sb3_maddpg",
            algorithm.lower(),
        ],
        model_name=algorithm,
        eval_results=results,
    )
    return data.to_yaml()


def model_card(
    algorithm: str,
    algo: str,
    env_id: str,
    repo: str,
    n_agents: int,
    spaces: tuple[Any, Any],
    timesteps: int,
    hyperparams: dict[str, Any],
    evaluation: dict[str, Any],
    model_file: str,
    evaluate_flags: str,
    replay: bool,
) -> str:
    """
    The repository's ``README.md``: the task, the algorithm, ``evaluate``'s table, the run's YAML entry, the commands.

    :param algorithm: ``MADDPG`` or ``MATD3``
    :param algo: its command-line name
    :param env_id: the env id
    :param repo: the repository id
    :param n_agents: the team's size
    :param spaces: each agent's observation and action spaces (the widest agent's, for agents with spaces of their own)
    :param timesteps: timesteps the model was trained for
    :param hyperparams: the run's hyperparameters (its ``config.yml``)
    :param evaluation: what ``evaluate_and_report`` returned
    :param model_file: the name of the model file in its run folder (the final model, ``best_model.zip``, a checkpoint)
    :param evaluate_flags: the ``evaluate`` flags that give the same table
    :param replay: whether the repository has ``replay.gif``
    :return: the card
    """
    kwargs = evaluation["env_kwargs"]
    entry = yaml.safe_dump({env_id: hyperparams}, sort_keys=False).rstrip()
    lines = [
        "---",
        card_metadata(algorithm, env_id, evaluation["summary"][0], evaluation["metrics"].values).rstrip(),
        "---",
        "",
        f"# {algorithm} team on {env_id}",
        "",
        f"A team of {n_agents} agents trained with **{algorithm}** for {timesteps} timesteps, with "
        "sb3_maddpg (multi-agent DDPG and TD3 with quantile-CVaR critics for "
        "[Stable-Baselines3](https://github.com/DLR-RM/stable-baselines3), trained through the "
        "[RL Zoo](https://github.com/DLR-RM/rl-baselines3-zoo)).",
        "",
        "## Task",
        "",
        f"`{env_id}` with the arguments `{kwargs}` (also in `env_kwargs.yml`): each agent observes `{spaces[0]}` and "
        f"acts in `{spaces[1]}`.",
        "",
        "## Evaluation",
        "",
        "Deterministic actions, mean ± std over the episodes (episode e of every method seeded alike): the table of "
        f"`python -m sb3_maddpg evaluate --model <run>/{model_file} {evaluate_flags}`, whose files and figures are in "
        f"`{EVALUATION}/`.",
        "",
        evaluation["table"],
        "",
    ]
    if replay:
        lines += [f"![An evaluation episode]({REPLAY})", ""]
    return "\n".join(lines + _card_commands(algo, env_id, repo, timesteps, entry, evaluate_flags))


def _card_commands(algo: str, env_id: str, repo: str, timesteps: int, entry: str, evaluate_flags: str) -> list[str]:
    """
    The card's ``Usage`` and ``Training`` sections: the commands that load, watch and evaluate the model, and the
    run's YAML entry with the commands that train and push such a model (parameters as in ``model_card``).

    :param entry: the run's hyperparameters as an entry for ``-conf``
    :return: the sections' lines
    """
    organization, name = repo.split("/", 1)
    flags = f"--algo {algo} --env {env_id}"
    return [
        "## Usage",
        "",
        "```bash",
        'pip install "sb3_maddpg[zoo,hub]"',
        f"python -m sb3_maddpg load-from-hub {flags} -orga {organization} -name {name} -f logs/",
        f"python -m sb3_maddpg enjoy {flags} -f logs/",
        f"python -m sb3_maddpg evaluate --model logs/{algo}/{env_id}_1/{env_id}.zip {evaluate_flags}",
        "```",
        "",
        "## Training",
        "",
        "The run's hyperparameters (its `config.yml`, an entry for `-conf`):",
        "",
        "```yaml",
        entry,
        "```",
        "",
        "```bash",
        f"python -m sb3_maddpg train {flags} -conf {algo}.yml -n {timesteps} -f logs/",
        f"python -m sb3_maddpg push-to-hub {flags} -f logs/ -orga {organization}",
        "```",
        "",
    ]


def create_repo(repo: str, private: bool = False) -> str:
    """
    Create the repository where missing, before the evaluation: no token, no network or offline mode end the command
    before it evaluates (as ``rl_zoo3.push_to_hub`` creates the repository first).

    :param repo: the repository id
    :param private: create it private
    :return: the repository's URL
    :raises UsageError: one line, when the Hub cannot be reached or refuses
    """
    hub = require_huggingface_hub()
    with hub_errors("push to", repo):
        return str(hub.HfApi().create_repo(repo_id=repo, private=private, exist_ok=True))


def upload_folder(local_dir: str | os.PathLike, repo: str, commit_message: str) -> None:
    """
    Upload a folder built by :func:`build_repo_folder` to the repository, in one commit.

    :param local_dir: the folder
    :param repo: the repository id
    :param commit_message: the commit's message
    :raises UsageError: one line, when the Hub cannot be reached or refuses
    """
    hub = require_huggingface_hub()
    with hub_errors("push to", repo):
        hub.HfApi().upload_folder(repo_id=repo, folder_path=os.fspath(local_dir), commit_message=commit_message)


# ---------------------------------------------------------------------------------------------------------------------
# load-from-hub
# ---------------------------------------------------------------------------------------------------------------------
def _run_folder(folder: str | os.PathLike, algo: str, env_id: str, exp_id: int, force: bool) -> Path:
    """Where the download goes, as RL Zoo's ``load_from_hub`` decides: ``--exp-id`` 0 a new run, -1 no run folder."""
    from stable_baselines3.common.utils import get_latest_run_id

    if exp_id == 0:
        exp_id = get_latest_run_id(os.path.join(folder, algo), env_id) + 1
    log_path = Path(folder, algo, f"{env_id}_{exp_id}") if exp_id > 0 else Path(folder, algo)
    # With no run folder (-1) the algorithm's folder holds other runs: only the model's own files are replaced
    taken = log_path.is_dir() if exp_id > 0 else (log_path / f"{env_id}.zip").exists()
    if taken:
        if not force:
            raise UsageError(f"{log_path} already exists: pass --force to replace it, or --exp-id 0 for a new run folder")
        if exp_id > 0:
            shutil.rmtree(log_path)
    return log_path


def _check_snapshot(snapshot: Path, algo: str, env_id: str, model_file: str) -> None:
    """Every file taken from the repository, read without running code (see the module's docstring)."""
    from sb3_maddpg.common.model_files import read_maddpg_data
    from sb3_maddpg.evaluation.report import read_run_yaml, saved_algorithm
    from sb3_maddpg.zoo.run_files import check_run_folder, load_vec_normalize

    missing = [file for file in (model_file, "config.yml", "args.yml") if not (snapshot / file).is_file()]
    if missing:
        raise UsageError(f"the repository has no {', '.join(missing)}: it is not an RL Zoo model of {algo} on {env_id}")
    try:
        data = read_maddpg_data(snapshot / model_file, None)
    except ValueError as error:
        raise UsageError(f"{model_file} from the Hub is refused: {error}") from error
    algorithm = saved_algorithm(data["policy_class"]).__name__
    if algorithm.lower() != algo:
        raise UsageError(f"{model_file} from the Hub is a {algorithm} model: download it with --algo {algorithm.lower()}")
    check_run_folder(snapshot)
    args = read_run_yaml(snapshot / "args.yml")
    if not isinstance(args, dict) or args.get("env") not in (None, env_id):
        raise UsageError(f"args.yml from the Hub is not the args.yml of a run of {env_id}")
    if (snapshot / "env_kwargs.yml").is_file():
        read_run_yaml(snapshot / "env_kwargs.yml")
    if (snapshot / VEC_NORMALIZE).is_file():
        load_vec_normalize(snapshot / VEC_NORMALIZE)


def _extract_metrics(archive_path: Path, log_path: Path) -> None:
    """The monitor and evaluation files of ``train_eval_metrics.zip``, by plain name only (no path leaves the run)."""
    with zipfile.ZipFile(archive_path) as archive:
        for member in archive.infolist():
            name = member.filename
            if "/" in name or "\\" in name or name.startswith(".") or not (name.endswith(".csv") or name == "evaluations.npz"):
                continue
            (log_path / name).write_bytes(archive.read(member))


def download_run(
    repo: str,
    algo: str,
    env_id: str,
    folder: str | os.PathLike,
    exp_id: int = 0,
    force: bool = False,
    revision: str | None = None,
    cache_dir: str | os.PathLike | None = None,
) -> Path:
    """
    Download a model repository (through the Hub's cache: with ``HF_HUB_OFFLINE=1``, or when the Hub cannot be reached,
    the cached copy is used) and lay it out as the RL Zoo run ``<folder>/<algo>/<env_id>_<N>/``, as
    ``rl_zoo3.load_from_hub`` does, once every file was read without running code.

    :param repo: the repository id
    :param algo: ``maddpg`` or ``matd3``
    :param env_id: the env id
    :param folder: the log folder (RL Zoo's ``-f``)
    :param exp_id: the run's number: 0 the next free one, -1 no run folder (``<folder>/<algo>/``)
    :param force: replace an existing run folder
    :param revision: a branch, tag or commit of the repository (default: ``main``)
    :param cache_dir: the Hub cache (default: ``HF_HUB_CACHE``, else ``HF_HOME/hub``)
    :return: the model file written
    :raises UsageError: one line, when the repository cannot be had or holds a file that is refused
    """
    hub = require_huggingface_hub()
    model_file = f"{model_name(algo, env_id)}.zip"
    with hub_errors("download", repo, cache_dir):
        snapshot = Path(
            hub.snapshot_download(
                repo_id=repo,
                revision=revision,
                cache_dir=None if cache_dir is None else os.fspath(cache_dir),
                allow_patterns=[model_file, *RUN_FILES, VEC_NORMALIZE],
            )
        )
    _check_snapshot(snapshot, algo, env_id, model_file)

    log_path = _run_folder(folder, algo, env_id, exp_id, force)
    params_dir = log_path / env_id
    params_dir.mkdir(parents=True, exist_ok=True)
    model_path = log_path / f"{env_id}.zip"
    shutil.copyfile(snapshot / model_file, model_path)
    for file in ("config.yml", "args.yml", "env_kwargs.yml"):
        if (snapshot / file).is_file():
            shutil.copyfile(snapshot / file, params_dir / file)
    if (snapshot / VEC_NORMALIZE).is_file():
        shutil.copyfile(snapshot / VEC_NORMALIZE, params_dir / "vecnormalize.pkl")
    if (snapshot / "train_eval_metrics.zip").is_file():
        _extract_metrics(snapshot / "train_eval_metrics.zip", log_path)
    return model_path
