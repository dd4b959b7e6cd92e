"""The command end to end with tiny budgets (train -> enjoy -> evaluate -> plot, optimize) and its errors."""

import glob
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from PIL import Image

from sb3_maddpg.__main__ import main

CONFIG = str(Path(__file__).resolve().parent.parent / "zoo_configs" / "maddpg.yml")
ENV = "uav_coverage_fast_v0"
TINY_ENV = ["--env-kwargs", "obs_size:16", "max_cycles:20", "n_uavs:3"]
TINY_TRAIN = ["--env", ENV, "-conf", CONFIG, *TINY_ENV, "-params", "learning_starts:60", "train_freq:10", "--seed", "0"]


@pytest.fixture(scope="module")
def trained_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One tiny training run (200 timesteps, 10 episodes), shared by the tests that use its outputs."""
    root = tmp_path_factory.mktemp("cli")
    cwd = os.getcwd()
    os.chdir(root)
    try:
        status = main(
            [
                "train",
                *TINY_TRAIN,
                "-n",
                "200",
                "-tb",
                "tb",
                "--eval-freq",
                "100",
                "--eval-episodes",
                "1",
                "--save-freq",
                "100",
            ]
        )
    finally:
        os.chdir(cwd)
    assert status == 0
    return root


def run_dir(root: Path) -> Path:
    return root / "logs" / "maddpg" / f"{ENV}_1"


def test_train_leaves_model_checkpoints_config_and_monitor(trained_run: Path) -> None:
    run = run_dir(trained_run)
    assert (run / f"{ENV}.zip").is_file()
    assert (run / "best_model.zip").is_file()
    assert (run / "rl_model_100_steps.zip").is_file() and (run / "rl_model_200_steps.zip").is_file()
    assert (run / ENV / "config.yml").is_file() and (run / ENV / "args.yml").is_file()
    lines = (run / "monitor.csv").read_text().splitlines()
    assert lines[1].startswith("r,l,t,r_uav_0,r_uav_1,r_uav_2,coverage,fairness")
    # one line per joint episode: 200 timesteps of 20-step episodes
    assert len(lines) - 2 == 10
    # each line is a whole joint episode: length 20 joint steps
    assert all(line.split(",")[1] == "20" for line in lines[2:])


def test_train_writes_coverage_and_fairness_to_tensorboard(trained_run: Path) -> None:
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    events = glob.glob(str(trained_run / "tb" / ENV / "**" / "events.out.tfevents.*"), recursive=True)
    assert events
    accumulator = EventAccumulator(events[0])
    accumulator.Reload()
    tags = accumulator.Tags()["scalars"]
    for tag in ("rollout/coverage", "rollout/fairness", "rollout/energy_efficiency", "rollout/ep_rew_mean"):
        assert tag in tags
    assert all(0.0 < event.value <= 1.0 for event in accumulator.Scalars("rollout/coverage"))


def test_enjoy(trained_run: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture) -> None:
    monkeypatch.chdir(trained_run)
    assert main(["enjoy", "--env", ENV, "-n", "45", "--no-render", "--seed", "0"]) == 0
    out = capsys.readouterr().out
    assert "Episode Length 20" in out
    assert "2 Episodes" in out


def test_evaluate_model(trained_run: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture) -> None:
    monkeypatch.chdir(trained_run)
    model = str(run_dir(trained_run) / f"{ENV}.zip")
    assert main(["evaluate", "--model", model, "--episodes", "2", "--out", "evaluation"]) == 0
    out = capsys.readouterr().out
    assert "| maddpg | 2 |" in out and "| greedy_static | 2 |" in out
    payload = json.loads((trained_run / "evaluation" / "results.json").read_text())
    # the model's training env kwargs, with random starts
    assert payload["metadata"]["env_kwargs"] == {"obs_size": 16, "max_cycles": 20, "n_uavs": 3, "start": "random"}
    assert [row["method"] for row in payload["summary"]] == ["maddpg", "random", "greedy_static"]
    figures = trained_run / "evaluation" / "figures"
    assert (figures / "fairness_vs_coverage.png").is_file()
    with Image.open(figures / "maddpg_episode.gif") as gif:
        assert gif.n_frames > 5


def test_evaluate_baselines_only(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "baselines"
    args = ["evaluate", "--baselines-only", "--episodes", "1", "--out", str(out), "--no-gif"]
    assert main([*args, "--env-kwargs", "n_uavs:2", "obs_size:16", "max_cycles:8"]) == 0
    assert (out / "results.csv").is_file() and (out / "episodes.csv").is_file()
    assert not (out / "figures" / "greedy_static_episode.gif").exists()
    assert "| random | 1 |" in capsys.readouterr().out


def test_plot(trained_run: Path, tmp_path: Path) -> None:
    assert main(["plot", "--log", str(run_dir(trained_run)), "--out", str(tmp_path / "figures")]) == 0
    for name in ("train_fairness_vs_coverage.png", "train_fairness_vs_energy_efficiency.png", "train_metrics_vs_episode.png"):
        with Image.open(tmp_path / "figures" / name) as image:
            assert image.format == "PNG"


def test_optimize_two_trials_on_sqlite(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture) -> None:
    monkeypatch.chdir(tmp_path)
    args = ["optimize", *TINY_TRAIN, "-n", "100", "--n-trials", "2", "--eval-episodes", "1", "--n-startup-trials", "2"]
    assert main(args) == 0
    assert "Number of finished trials:  2" in capsys.readouterr().out
    database = tmp_path / "logs" / "maddpg" / "optuna.db"
    assert database.is_file()

    import optuna

    study = optuna.load_study(study_name=f"maddpg_{ENV}", storage=f"sqlite:///{database}")
    assert len(study.trials) == 2
    assert {"one_minus_gamma", "cvar_alpha", "learning_rate"} <= set(study.trials[0].params)


# ---------------------------------------------------------------------------------------------------------------------
# Bad input: a clear one-line message on stderr and exit status 2
# ---------------------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["train", "--env", "no_such_env_v0"], "unknown env 'no_such_env_v0'"),
        (["train", "--env", "CartPole-v1"], "needs a multi-agent env"),
        (["train", "--algo", "matd3", "--env", "CartPole-v1"], "--algo matd3 needs a multi-agent env"),
        (["train", "--env", ENV, "--env-kwargs", "obs_size:17"], "obs_size must be a positive multiple"),
        (["train", "--env", ENV, "--env-kwargs", "no_such_kwarg:1"], "no_such_kwarg"),
        (["train", "--env", ENV, "--env-kwargs", "obs_size:sixteen"], "cannot read the value of 'obs_size'"),
        (["train", "--env", ENV, "--env-kwargs", "obs_size"], "expected key:value"),
        (["train", "--env", ENV, "-conf", "no_such_file.yml"], "config file no_such_file.yml not found"),
        (
            ["train", "--env", ENV, "-conf", CONFIG, "-params", "no_such_key:1", "-n", "10"],
            "unknown hyperparameter(s) 'no_such_key'",
        ),
        (["train", "--env", ENV, "-conf", CONFIG, "-i", "no_such_model.zip"], "not an existing .zip model file"),
        (["enjoy", "--env", ENV, "-f", "no_such_folder"], "no trained model to load"),
        (["evaluate", "--model", "no_such_model.zip"], "model file no_such_model.zip not found"),
        (["evaluate", "--baselines-only", "--env", "no_such_env_v0"], "unknown env 'no_such_env_v0'"),
        (["evaluate", "--baselines-only", "--env-kwargs", "n_uavs:0"], "n_uavs must be an integer in [1, 1024]"),
        (["plot", "--log", "no_such_folder"], "no_such_folder not found"),
    ],
)
def test_bad_input_exits_with_a_message(
    argv: list[str], message: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert f"sb3_maddpg {argv[0]}: error:" in err
    assert message in err
    assert "Traceback" not in err


def test_unknown_yaml_key_from_the_command_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    monkeypatch.chdir(tmp_path)
    config = tmp_path / "bad.yml"
    config.write_text(f"{ENV}:\n  n_timesteps: 10\n  policy: 'CnnPolicy'\n  learning_rat: 0.001\n")
    with pytest.raises(SystemExit) as exit_info:
        main(["train", "--env", ENV, "-conf", str(config)])
    assert exit_info.value.code == 2
    assert "unknown hyperparameter(s) 'learning_rat'" in capsys.readouterr().err


def test_console_error_has_no_traceback(tmp_path: Path) -> None:
    result = subprocess.run(
        [sys.executable, "-m", "sb3_maddpg", "evaluate", "--model", "missing.zip"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 2
    assert result.stderr.strip() == "sb3_maddpg evaluate: error: --model: model file missing.zip not found"


def test_help_lists_the_commands(capsys: pytest.CaptureFixture) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["--help"])
    assert exit_info.value.code == 0
    out = capsys.readouterr().out
    for command in ("train", "optimize", "enjoy", "evaluate", "plot"):
        assert command in out


def test_bad_hyperparameter_value_exits_with_the_algorithms_message(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exit_info:
        main(["train", *TINY_TRAIN, "-n", "10", "-params", "cvar_alpha:2.0"])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert "cvar_alpha must be a number in (0, 1]" in err and "Traceback" not in err


def test_evaluate_refuses_a_model_trained_for_another_team_size(
    trained_run: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    monkeypatch.chdir(trained_run)
    model = str(run_dir(trained_run) / f"{ENV}.zip")
    # the run used 3 UAVs; 6 would be read as two copies of the team and give plausible but wrong numbers
    with pytest.raises(SystemExit) as exit_info:
        main(["evaluate", "--model", model, "--episodes", "1", "--out", "bad", "--env-kwargs", "n_uavs:6"])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert "trained with 3 agents" in err and "has 6 agents" in err and "Traceback" not in err


def test_evaluate_refuses_a_zip_that_is_not_a_model(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    import zipfile

    monkeypatch.chdir(tmp_path)
    with zipfile.ZipFile(tmp_path / "not_a_model.zip", "w") as archive:
        archive.writestr("hello.txt", "hello")
    with pytest.raises(SystemExit) as exit_info:
        main(["evaluate", "--model", "not_a_model.zip", "--episodes", "1", "--out", "bad"])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert "not a MADDPG model" in err and "Traceback" not in err


def test_evaluation_env_gets_the_entrys_env_kwargs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """RL Zoo would build the evaluation env with the env defaults when only the YAML sets env_kwargs."""
    import rl_zoo3.train

    from sb3_maddpg.zoo import exp_manager, integration

    integration.register_with_rl_zoo()
    seen: list[tuple[bool, dict]] = []
    create_envs = exp_manager.MultiAgentExperimentManager.create_envs

    def spy(self, n_envs, eval_env=False, no_log=False):
        seen.append((eval_env, dict(self.eval_env_kwargs if eval_env else self.env_kwargs)))
        return create_envs(self, n_envs, eval_env=eval_env, no_log=no_log)

    monkeypatch.setattr(exp_manager.MultiAgentExperimentManager, "create_envs", spy)
    monkeypatch.chdir(tmp_path)
    config = tmp_path / "tiny.yml"
    config.write_text(
        f"{ENV}:\n  n_timesteps: 20\n  policy: 'CnnPolicy'\n  learning_starts: 10\n  buffer_size: 50\n"
        '  batch_size: 4\n  policy_kwargs: "dict(n_quantiles=2, net_arch=[8])"\n'
        "  env_kwargs:\n    obs_size: 16\n    max_cycles: 5\n    n_uavs: 2\n"
    )
    assert rl_zoo3.train.ExperimentManager is exp_manager.MultiAgentExperimentManager
    assert main(["train", "--env", ENV, "-conf", str(config), "--eval-freq", "10", "--eval-episodes", "1"]) == 0
    expected = {"obs_size": 16, "max_cycles": 5, "n_uavs": 2}
    assert (False, expected) in seen and (True, expected) in seen
