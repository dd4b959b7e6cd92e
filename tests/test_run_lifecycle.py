"""A training run's folder, its end at a scheduler's time limit, its checkpoints and its resumption."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from sb3_maddpg.__main__ import main

ROOT = Path(__file__).resolve().parent.parent
CONFIG = str(ROOT / "zoo_configs" / "maddpg.yml")
ENV = "uav_coverage_fast_v0"
TINY = [
    "--env",
    ENV,
    "-conf",
    CONFIG,
    "--env-kwargs",
    "obs_size:16",
    "max_cycles:10",
    "n_uavs:2",
    "-params",
    "learning_starts:20",
    "train_freq:10",
    "policy_kwargs:dict(n_quantiles=4, net_arch=[16])",
    "--seed",
    "0",
    "--eval-freq",
    "-1",
]


def test_runs_started_together_on_one_log_folder_get_one_folder_each(tmp_path: Path, monkeypatch) -> None:
    import rl_zoo3.exp_manager

    monkeypatch.chdir(tmp_path)
    # As for runs started at the same moment: each finds no run yet and numbers its folder 1
    monkeypatch.setattr(rl_zoo3.exp_manager, "get_latest_run_id", lambda *args: 0)
    for _ in range(3):
        assert main(["train", *TINY, "-n", "10"]) == 0
    runs = sorted(path.name for path in (tmp_path / "logs" / "maddpg").iterdir())
    assert runs == [f"{ENV}_1", f"{ENV}_2", f"{ENV}_3"]
    assert all((tmp_path / "logs" / "maddpg" / run / f"{ENV}.zip").is_file() for run in runs)


def test_three_processes_started_together_make_three_run_folders(tmp_path: Path) -> None:
    command = [sys.executable, "-m", "sb3_maddpg", "train", *TINY, "-n", "20"]
    pipes = {"stdout": subprocess.PIPE, "stderr": subprocess.STDOUT, "text": True}
    runs = [subprocess.Popen(command, cwd=tmp_path, **pipes) for _ in range(3)]
    outputs = [run.communicate(timeout=300)[0] for run in runs]
    assert [run.returncode for run in runs] == [0, 0, 0], outputs
    folders = sorted((tmp_path / "logs" / "maddpg").glob(f"{ENV}_*"))
    assert len(folders) == 3 and all((folder / f"{ENV}.zip").is_file() for folder in folders), outputs
    for folder in folders:
        lines = (folder / "monitor.csv").read_text().splitlines()
        assert len(lines) == 2 + 2  # header lines, then this run's own two 10-step episodes


def test_sigterm_saves_the_model_and_replay_buffer_as_ctrl_c_does(tmp_path: Path) -> None:
    command = [sys.executable, "-m", "sb3_maddpg", "train", *TINY, "-n", "1000000", "--save-replay-buffer"]
    process = subprocess.Popen(command, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    run = tmp_path / "logs" / "maddpg" / f"{ENV}_1"
    deadline = time.monotonic() + 120
    while not (run / "monitor.csv").is_file() or len((run / "monitor.csv").read_text().splitlines()) < 4:
        assert process.poll() is None and time.monotonic() < deadline, process.communicate()[0]
        time.sleep(0.2)
    process.send_signal(signal.SIGTERM)
    output, _ = process.communicate(timeout=120)
    # saved, and told apart from a finished run
    assert process.returncode == 143 and "stopped by SIGTERM before the end of the run" in output, output
    assert (run / f"{ENV}.zip").is_file() and (run / "replay_buffer.pkl").is_file(), output


def test_checkpoints_carry_the_replay_buffer_and_resume_with_their_own(tmp_path: Path, monkeypatch, capsys) -> None:
    from sb3_maddpg import MADDPG

    monkeypatch.chdir(tmp_path)
    assert main(["train", *TINY, "-n", "60", "--save-freq", "30", "--save-replay-buffer"]) == 0
    run = tmp_path / "logs" / "maddpg" / f"{ENV}_1"
    assert (run / "rl_model_replay_buffer_30_steps.pkl").is_file()
    assert (run / "replay_buffer.pkl").is_file()
    capsys.readouterr()
    # the checkpoint at 30 timesteps resumes with its own 30 transitions, not the final buffer's 60
    loaded = []
    monkeypatch.setattr(MADDPG, "load_replay_buffer", lambda self, path, **kwargs: loaded.append(os.path.basename(path)))
    assert main(["train", *TINY, "-n", "10", "-i", str(run / "rl_model_30_steps.zip")]) == 0
    assert loaded == ["rl_model_replay_buffer_30_steps.pkl"]
    # a model saved without its own buffer does not get the final one
    (run / "rl_model_replay_buffer_60_steps.pkl").unlink()
    assert main(["train", *TINY, "-n", "10", "-i", str(run / "rl_model_60_steps.zip")]) == 0
    assert loaded == ["rl_model_replay_buffer_30_steps.pkl"]
    assert "Not loading" in capsys.readouterr().out


def test_resuming_with_another_buffer_size_uses_it(tmp_path: Path) -> None:
    from sb3_maddpg import MADDPG, make_multiagent_vec_env
    from sb3_maddpg_envs import uav_coverage_v0

    def env():
        return make_multiagent_vec_env(uav_coverage_v0.parallel_env, n_envs=1, env_kwargs=dict(obs_size=16, n_uavs=2))

    model = MADDPG("CnnPolicy", env(), buffer_size=200, learning_starts=10, batch_size=4, device="cpu", seed=0)
    model.learn(40)
    model.save(tmp_path / "model.zip")
    model.save_replay_buffer(tmp_path / "buffer.pkl")
    resumed = MADDPG.load(tmp_path / "model.zip", env=env(), buffer_size=20)
    resumed.load_replay_buffer(tmp_path / "buffer.pkl")
    assert resumed.replay_buffer.buffer_size == 20 and resumed.replay_buffer.pos == 0 and resumed.replay_buffer.full


def test_a_killed_env_worker_ends_training_with_a_final_save(tmp_path: Path, monkeypatch, capsys) -> None:
    from sb3_maddpg.common.off_policy_algorithm import MultiAgentOffPolicyAlgorithm

    monkeypatch.chdir(tmp_path)
    original = MultiAgentOffPolicyAlgorithm.collect_rollouts

    def collect_then_lose_the_worker(self, *args, **kwargs):
        if self.num_timesteps >= 20:
            raise ConnectionResetError(104, "Connection reset by peer")
        return original(self, *args, **kwargs)

    monkeypatch.setattr(MultiAgentOffPolicyAlgorithm, "collect_rollouts", collect_then_lose_the_worker)
    assert main(["train", *TINY, "-n", "100"]) == 3  # saved, and told apart from a finished run
    assert "An env worker process ended (ConnectionResetError" in capsys.readouterr().out
    assert (tmp_path / "logs" / "maddpg" / f"{ENV}_1" / f"{ENV}.zip").is_file()
