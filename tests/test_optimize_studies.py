"""Shared Optuna studies on SQLite: start-up races, dead workers, ``train --trial-id`` and the storage's password."""

import pickle
import sys
import time
from pathlib import Path

import optuna
import pytest
import sqlalchemy
import torch
from cli_testing import fails_with

from sb3_maddpg.__main__ import main
from sb3_maddpg.zoo import exp_manager, storage

ROOT = Path(__file__).resolve().parent.parent
CONFIG = str(ROOT / "zoo_configs" / "maddpg.yml")
ENV = "uav_coverage_fast_v0"
TINY = ["--env", ENV, "-conf", CONFIG, "--env-kwargs", "obs_size:16", "max_cycles:10", "n_uavs:2", "--seed", "0"]
TINY += ["-params", "learning_starts:20", "train_freq:10", "policy_kwargs:dict(n_quantiles=4, net_arch=[16])"]
PARAMS = {"one_minus_gamma": 0.05, "batch_size_pow": 4, "learning_rate": 1e-3, "tau": 0.01, "train_freq": 3}
PARAMS |= {"cvar_alpha": 0.5}


def test_a_worker_losing_the_sqlite_table_race_retries(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    create = optuna.create_study
    calls = []

    def lose_once(**kwargs):
        calls.append(kwargs)
        if len(calls) == 1:
            raise sqlalchemy.exc.OperationalError("CREATE TABLE studies", {}, Exception("table studies already exists"))
        return create(**kwargs)

    monkeypatch.setattr(optuna, "create_study", lose_once)
    monkeypatch.setattr(storage.time, "sleep", lambda seconds: None)
    study = storage.create_shared_study(f"sqlite:///{tmp_path / 'optuna.db'}", "race")
    assert study.study_name == "race" and len(calls) == 2


def test_a_dead_workers_trial_is_failed_retried_and_not_counted(tmp_path: Path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    url = f"sqlite:///{tmp_path / 'optuna.db'}"
    # A worker that started trial 0 and was killed: the trial stays RUNNING, its heartbeat stops
    dead = optuna.storages.RDBStorage(url, heartbeat_interval=1, grace_period=1)
    study = optuna.create_study(storage=dead, study_name="shared", direction="maximize")
    trial = study.ask()
    dead.record_heartbeat(trial._trial_id)
    time.sleep(2.5)
    monkeypatch.setattr(exp_manager, "HEARTBEAT_GRACE_S", 1)
    argv = ["optimize", *TINY, "-n", "40", "--storage", url, "--study-name", "shared", "--max-total-trials", "1"]
    assert main([*argv, "--eval-episodes", "1", "--n-evaluations", "1"]) == 0
    trials = optuna.load_study(study_name="shared", storage=url).get_trials(deepcopy=False)
    states = [trial.state for trial in trials]
    assert states[0] == optuna.trial.TrialState.FAIL and optuna.trial.TrialState.COMPLETE in states, states
    # the dead worker's parameters are tried again
    assert any(trial.system_attrs.get("failed_trial") == 0 for trial in trials)


def _study_with_trials(url: str) -> None:
    study = optuna.create_study(storage=url, study_name="tuned", direction="maximize")
    for value, tau in ((1.0, 0.02), (2.0, 0.03)):
        study.enqueue_trial({**PARAMS, "tau": tau})
        trial = study.ask()
        for name, default in PARAMS.items():
            trial.suggest_int(name, 1, 10) if isinstance(default, int) else trial.suggest_float(name, 1e-5, 1.0)
        study.tell(trial, value)


def test_train_trial_id_0_loads_trial_0(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import yaml

    monkeypatch.chdir(tmp_path)
    url = f"sqlite:///{tmp_path / 'optuna.db'}"
    _study_with_trials(url)
    assert (
        main(["train", *TINY, "-n", "10", "--eval-freq", "-1", "--storage", url, "--study-name", "tuned", "--trial-id", "0"])
        == 0
    )
    config = (tmp_path / "logs" / "maddpg" / f"{ENV}_1" / ENV / "config.yml").read_text()
    saved = dict(yaml.load(config, Loader=yaml.UnsafeLoader))  # noqa: S506 (written by this test's run)
    assert saved["tau"] == 0.02 and saved["train_freq"] == 10  # the trial's tau; -params' train_freq wins


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--study-name", "tuned", "--trial-id", "7"], "--trial-id 7: the study 'tuned' in sqlite:///"),
        (
            ["--study-name", "no_such_study", "--trial-id", "0"],
            "--study-name: there is no study 'no_such_study' in sqlite:///",
        ),
    ],
    ids=["missing-trial", "missing-study"],
)
def test_a_missing_trial_or_study_is_one_line(extra: list[str], message: str, tmp_path: Path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    url = f"sqlite:///{tmp_path / 'optuna.db'}"
    _study_with_trials(url)
    err = fails_with(["train", *TINY, "-n", "10", "--storage", url, *extra], capsys)
    assert message in err


def test_the_storage_password_is_not_written(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    url = "postgresql://user:hunter2@db.example/optuna"
    argv = ["train", *TINY, "-n", "10", "--eval-freq", "-1", "--storage", url, "--study-name", "s"]
    monkeypatch.setattr(sys, "orig_argv", [sys.executable, "-m", "sb3_maddpg", *argv])
    assert main(argv) == 0
    params = tmp_path / "logs" / "maddpg" / f"{ENV}_1" / ENV
    for name in ("args.yml", "command.txt"):
        text = (params / name).read_text()
        assert "hunter2" not in text and "user:***@db.example" in text, name
    assert storage.mask_password(f"--storage {url} --x") == "--storage postgresql://user:***@db.example/optuna --x"


def test_the_pickled_study_storage_has_no_password(tmp_path: Path) -> None:
    # RL Zoo pickles the study, with its storage, into report_*.pkl
    shared = exp_manager.ZooRDBStorage(f"sqlite:///{tmp_path / 'optuna.db'}")
    shared.url = "postgresql://user:hunter2@db.example/optuna"  # as on a database server
    assert b"hunter2" not in pickle.dumps(shared)


def test_a_trials_parameters_are_read_as_data(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys) -> None:
    from sb3_maddpg.zoo.run_files import read_as_data

    monkeypatch.chdir(tmp_path)
    marker = tmp_path / "ran"
    url = f"sqlite:///{tmp_path / 'optuna.db'}"
    study = optuna.create_study(storage=url, study_name="shared", direction="maximize")
    # a study from someone else: a string parameter that RL Zoo would evaluate as policy_kwargs
    code = f"open({str(marker)!r}, 'w').close() or dict()"
    distributions = {"one_minus_gamma": optuna.distributions.FloatDistribution(0.01, 0.3)}
    distributions["policy_kwargs"] = optuna.distributions.CategoricalDistribution([code])
    trial = optuna.trial.create_trial(
        params={"one_minus_gamma": 0.1, "policy_kwargs": code}, distributions=distributions, value=1.0
    )
    study.add_trial(trial)
    err = fails_with(["train", *TINY, "-n", "10", "--storage", url, "--study-name", "shared", "--trial-id", "0"], capsys)
    assert "policy_kwargs: " in err and "in trial 0 of the study 'shared'" in err and "only values are accepted" in err
    assert not marker.exists()
    # what RL Zoo's entries hold is read as the data it stands for
    read = read_as_data({"policy_kwargs": "dict(net_arch=[64, -1], activation_fn=nn.ReLU, n={'a': (1.5, None)})"}, "x")
    assert read["policy_kwargs"] == {"net_arch": [64, -1], "activation_fn": torch.nn.ReLU, "n": {"a": (1.5, None)}}


def test_sigterm_during_the_first_trial_ends_with_the_report(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys) -> None:
    import os
    import signal

    from rl_zoo3.exp_manager import ExperimentManager

    monkeypatch.chdir(tmp_path)

    def terminated(self, trial):
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(5)  # the handler interrupts this
        raise AssertionError("SIGTERM was not handled")

    monkeypatch.setattr(ExperimentManager, "objective", terminated)
    url = f"sqlite:///{tmp_path / 'optuna.db'}"
    argv = ["optimize", *TINY, "-n", "10", "--n-trials", "2", "--storage", url, "--study-name", "stopped"]
    assert main(argv) == 143
    out, err = capsys.readouterr()
    assert "No trial of the study 'stopped' has completed yet" in out and "trial 0: FAIL" in out, out
    assert "stopped by SIGTERM" in err and "Traceback" not in err


def _dead_pid() -> int:
    """The process id of a process that has ended."""
    import subprocess

    process = subprocess.Popen([sys.executable, "-c", "pass"])
    process.wait()
    return process.pid


def _journal_study(path: Path, name: str = "shared") -> optuna.Study:
    journal = optuna.storages.JournalStorage(optuna.storages.journal.JournalFileBackend(str(path)))
    return optuna.create_study(storage=journal, study_name=name, direction="maximize", load_if_exists=True)


def test_on_a_journal_file_only_the_trials_of_dead_workers_of_this_machine_are_failed(tmp_path: Path) -> None:
    import socket

    study = _journal_study(tmp_path / "optuna.log")
    host = socket.gethostname()
    workers = [f"{host}:{_dead_pid()}", f"{host}:{__import__('os').getpid()}", "another-machine:1", "no worker"]
    for worker in workers:
        trial = study.ask({"x": optuna.distributions.FloatDistribution(0.0, 1.0)})
        trial.set_user_attr("worker", worker)
    assert storage.fail_dead_workers_trials(study) == [0]
    states = [trial.state for trial in study.get_trials(deepcopy=False)]
    running, failed, waiting = (optuna.trial.TrialState.RUNNING, optuna.trial.TrialState.FAIL, optuna.trial.TrialState.WAITING)
    assert states == [failed, running, running, running, waiting]
    retry = study.get_trials(deepcopy=False)[-1]
    assert retry.user_attrs["failed_trial"] == 0 and retry.system_attrs["fixed_params"] == study.trials[0].params
    assert storage.fail_dead_workers_trials(study) == []  # nothing more to fail


def test_a_dead_workers_trial_on_a_journal_file_does_not_count(tmp_path: Path, monkeypatch, capsys) -> None:
    """--max-total-trials 1 with a killed worker's trial left RUNNING: this worker still runs its trial."""
    import socket

    monkeypatch.chdir(tmp_path)
    study = _journal_study(tmp_path / "optuna.log")
    trial = study.ask()
    trial.set_user_attr("worker", f"{socket.gethostname()}:{_dead_pid()}")
    argv = ["optimize", *TINY, "-n", "40", "--storage", str(tmp_path / "optuna.log"), "--study-name", "shared"]
    assert main([*argv, "--max-total-trials", "1", "--eval-episodes", "1", "--n-evaluations", "1"]) == 0
    states = [trial.state for trial in _journal_study(tmp_path / "optuna.log").get_trials(deepcopy=False)]
    assert states[0] == optuna.trial.TrialState.FAIL and optuna.trial.TrialState.COMPLETE in states, states
