"""The command checks its input before any work is done, and says what to do in one line."""

import configparser
import sys
from pathlib import Path

import pytest

from sb3_maddpg.__main__ import main

ROOT = Path(__file__).resolve().parent.parent
CONFIG = str(ROOT / "zoo_configs" / "maddpg.yml")
ENV = "uav_coverage_fast_v0"
TINY = ["--env", ENV, "-conf", CONFIG, "--env-kwargs", "obs_size:16", "max_cycles:5", "n_uavs:2"]


def _fails_with(argv: list[str], capsys: pytest.CaptureFixture) -> str:
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith(f"sb3_maddpg {argv[0]}: error:") and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1, err
    return err


@pytest.fixture
def not_a_folder(tmp_path: Path) -> Path:
    """A path no one can create a folder at, whoever runs the tests (root included): its parent is a file."""
    (tmp_path / "file").write_text("x")
    return tmp_path / "file" / "out"


@pytest.mark.parametrize(
    "argv",
    [
        ["train", *TINY, "-f", "{bad}"],
        ["train", *TINY, "-tb", "{bad}"],
        ["optimize", *TINY, "-f", "{bad}"],
        ["plot", "--log", "{run}", "--out", "{bad}"],
        ["evaluate", "--baselines-only", "--episodes", "1", "--out", "{bad}", "--env-kwargs", "n_uavs:2", "obs_size:16"],
    ],
    ids=["train-f", "train-tb", "optimize-f", "plot-out", "evaluate-out"],
)
def test_unwritable_output_folder_is_one_line_before_any_work(
    argv: list[str], not_a_folder: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    import sb3_maddpg.evaluation.evaluate as evaluate_module

    monkeypatch.chdir(tmp_path)
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "monitor.csv").write_text('#{"t_start": 0}\nr,l,t\n1.0,5,0.1\n')
    # evaluate must not run a single episode before refusing the folder
    monkeypatch.setattr(evaluate_module, "run_episode", lambda *args, **kwargs: pytest.fail("an episode was run"))
    argv = [arg.format(bad=not_a_folder, run=tmp_path / "run") for arg in argv]
    err = _fails_with(argv, capsys)
    assert str(not_a_folder) in err and "is not a folder" in err
    assert not (tmp_path / "logs").exists()


def test_without_rl_zoo_the_zoo_commands_say_which_extra_to_install(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    monkeypatch.setitem(sys.modules, "rl_zoo3", None)  # import rl_zoo3 now raises ModuleNotFoundError
    for command in ("train", "enjoy", "optimize"):
        err = _fails_with([command, "--env", ENV], capsys)
        assert 'pip install "sb3_maddpg[zoo]"' in err


@pytest.mark.parametrize("budget", ["-5", "0"])
def test_non_positive_budget_is_refused(budget: str, tmp_path: Path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    err = _fails_with(["train", *TINY, "-n", budget], capsys)
    assert f"-n/--n-timesteps must be a positive number of timesteps, got {budget}" in err
    assert not (tmp_path / "logs").exists()


def test_a_value_the_algorithm_refuses_leaves_no_run_folder(tmp_path: Path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    err = _fails_with(["train", *TINY, "-n", "10", "-params", "gamma:1.5"], capsys)
    assert "gamma must be a number in [0, 1], got 1.5" in err
    assert list((tmp_path / "logs" / "maddpg").iterdir()) == []


def test_optimize_refuses_parallel_jobs_in_one_process(tmp_path: Path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    err = _fails_with(["optimize", *TINY, "-n", "10", "--n-trials", "2", "--n-jobs", "2"], capsys)
    assert "--n-jobs 2" in err and "run several processes" in err and "--storage" in err


def test_rl_zoo_is_bounded_to_the_tested_releases() -> None:
    from importlib.metadata import version

    from packaging.requirements import Requirement

    setup = configparser.ConfigParser()
    setup.read(ROOT / "setup.cfg")
    requirements = [Requirement(line) for line in setup["options.extras_require"]["zoo"].split("\n") if line.strip()]
    rl_zoo = next(requirement for requirement in requirements if requirement.name == "rl_zoo3")
    assert any(spec.operator in ("<", "<=", "~=", "==") for spec in rl_zoo.specifier), "no upper bound"
    assert version("rl_zoo3") in rl_zoo.specifier
    usage = (ROOT / "docs" / "usage.md").read_text()
    for internal in ("ExperimentManager", "create_test_env", "_load_pretrained_agent", "ALGOS"):
        assert internal in usage


DATA = Path(__file__).resolve().parent / "data"
# A binary file named monitor.csv (a PNG's first bytes): not text
BINARY_MONITOR = DATA / "binary_monitor.csv"


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["plot", "--log", "model.zip"], "--log: model.zip is not a monitor.csv (a text CSV file written during training)"),
        (["plot", "--log", str(BINARY_MONITOR)], "binary_monitor.csv is not a monitor.csv"),
        (["plot", "--log", "run"], "run/monitor.csv is not a monitor.csv"),
        (["plot", "--log", "run", "--env", "no_such_env_v0"], "--env: unknown env 'no_such_env_v0'; registered multi-agent"),
        (["record-video", "--env", ENV, "-o", "model.zip"], "-o/--output-folder: model.zip exists and is not a folder"),
        (["record-video", "--env", ENV, "-n", "0"], "-n/--n-timesteps must be a positive number of timesteps to play, got 0"),
        (["enjoy", "--env", ENV, "-n", "-3"], "-n/--n-timesteps must be a positive number of timesteps to play, got -3"),
        (
            ["evaluate", "--baselines-only", "--env", ENV, "--state-steps", "-5"],
            "--state-steps: state steps must be steps of the episode, integers from 0 (after reset) to 300 (max_cycles); "
            "got [-5]",
        ),
        (
            ["evaluate", "--baselines-only", "--env", ENV, "--env-kwargs", "max_cycles:20", "--state-steps", "0", "21"],
            "to 20 (max_cycles); got [21]",
        ),
    ],
)
def test_a_file_or_number_that_cannot_work_is_one_line(argv, message, tmp_path: Path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "model.zip").write_bytes(b"PK\x03\x04\x14\x00\x00\x00\x08\x00\xff\xfe\x80\x81 not a monitor file")
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "monitor.csv").write_bytes(BINARY_MONITOR.read_bytes())
    assert message in _fails_with(argv, capsys)
    assert not (tmp_path / "logs").exists() and not (tmp_path / "results").exists()


def test_an_env_wrapper_on_a_multiagent_env_is_refused(tmp_path: Path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "wrapped.yml").write_text(f"{ENV}:\n  n_timesteps: 10\n  env_wrapper: gymnasium.wrappers.TimeLimit\n")
    argv = ["train", "--env", ENV, "-conf", str(tmp_path / "wrapped.yml"), "--env-kwargs", "obs_size:16", "n_uavs:2"]
    err = _fails_with(argv, capsys)
    assert f"env_wrapper wraps a single-agent Gymnasium env and would have no effect on the multi-agent env {ENV}" in err
    assert not (tmp_path / "logs" / "maddpg" / f"{ENV}_1").exists()
