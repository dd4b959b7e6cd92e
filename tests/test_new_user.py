"""What a new user meets: packaged configs, the progress bar, videos, start-up cost, the CPU default, the PoI key."""

import os
import subprocess
import sys
from pathlib import Path

import pytest
from stable_baselines3.common.callbacks import ProgressBarCallback

from sb3_maddpg import MADDPG, make_multiagent_vec_env
from sb3_maddpg.__main__ import main
from sb3_maddpg.common.callbacks import JointStepProgressBarCallback
from sb3_maddpg.zoo.command_line import packaged_config
from sb3_maddpg.zoo.registry import DEFAULT_ENV_ID as DEFAULT_ENV
from sb3_maddpg_envs import uav_coverage_v1

ROOT = Path(__file__).resolve().parent.parent
TINY = ["--env-kwargs", "obs_size:16", "max_cycles:20", "n_uavs:2", "-params", "learning_starts:40", "buffer_size:500"]


def tiny_venv(n_envs: int = 1):
    return make_multiagent_vec_env(
        uav_coverage_v1.parallel_env, n_envs=n_envs, seed=0, env_kwargs=dict(obs_size=16, n_uavs=3, max_cycles=10)
    )


def test_the_package_ships_its_configs_and_train_reads_them_from_anywhere(tmp_path, monkeypatch) -> None:
    for algo in ("maddpg", "matd3"):
        config = packaged_config(algo)
        assert config is not None and config.read_text() == (ROOT / "zoo_configs" / f"{algo}.yml").read_text()
    monkeypatch.chdir(tmp_path)  # no zoo_configs/ here
    assert main(["train", "-n", "40", "-f", "logs", "--seed", "0", *TINY]) == 0
    run = tmp_path / "logs" / "maddpg" / f"{DEFAULT_ENV}_1"
    assert (run / f"{DEFAULT_ENV}.zip").is_file()
    assert "zoo_configs" in (run / DEFAULT_ENV / "args.yml").read_text()


@pytest.mark.parametrize("n_envs", [1, 2])
def test_sb3_progress_bar_counts_timesteps_not_agent_rows(n_envs: int) -> None:
    model = MADDPG("CnnPolicy", tiny_venv(n_envs), buffer_size=200, learning_starts=10, batch_size=8)
    callbacks = [ProgressBarCallback()]  # what RL Zoo's -P adds; RL Zoo closes callbacks[0] after learn
    plain = callbacks[0]
    model.learn(40, callback=callbacks)
    assert model.num_timesteps == 40
    assert not hasattr(plain, "pbar")  # replaced by the joint-step bar, never started
    assert isinstance(callbacks[0], JointStepProgressBarCallback) and callbacks[0].pbar.n == 40
    callbacks[0].on_training_end()
    joint = JointStepProgressBarCallback()
    model.learn(40, callback=joint, progress_bar=True)
    assert joint.pbar.n == joint.pbar.total == 40


def test_the_quick_start_shows_a_progress_bar() -> None:
    script = (ROOT / "scripts" / "quickstart.sh").read_text()
    train_line = script[script.index("sb3_maddpg train") : script.index("run=")]
    assert " -P" in train_line


def test_record_video_writes_an_mp4_and_enjoy_warns_that_nothing_is_shown(tmp_path, monkeypatch) -> None:
    pytest.importorskip("moviepy")
    monkeypatch.chdir(tmp_path)
    assert main(["train", "-n", "40", "-f", "logs", "--seed", "0", *TINY]) == 0
    assert main(["record-video", "-f", "logs", "-n", "25", "-o", "videos", "--env-kwargs", "max_cycles:20"]) == 0
    videos = list((tmp_path / "videos").glob("*.mp4"))
    assert len(videos) == 1 and videos[0].stat().st_size > 1000
    with pytest.warns(UserWarning, match="cannot be shown on screen.*record-video"):
        assert main(["enjoy", "-f", "logs", "-n", "25"]) == 0


def test_help_and_version_do_not_import_torch_and_say_the_defaults() -> None:
    code = (
        "import sys\n"
        "from sb3_maddpg.__main__ import main\n"
        "try:\n    main(['--version'])\nexcept SystemExit:\n    pass\n"
        "print('torch' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT).stdout
    assert out.split() == ["sb3_maddpg", "0.1.0", "False"]
    help_text = subprocess.run(
        [sys.executable, "-m", "sb3_maddpg", "--help"], capture_output=True, text=True, check=True, cwd=ROOT
    ).stdout
    assert "--env uav_coverage_cpu_v1" in " ".join(help_text.split()) and "record-video" in help_text
    assert DEFAULT_ENV == "uav_coverage_cpu_v1"


def test_from_sb3_maddpg_import_works_as_before() -> None:
    import sb3_maddpg

    assert sb3_maddpg.MADDPG is MADDPG and "MATD3" in dir(sb3_maddpg)
    with pytest.raises(AttributeError):
        sb3_maddpg.NotAThing  # noqa: B018


def test_frames_carry_a_key_of_the_poi_colours() -> None:
    env = uav_coverage_v1.parallel_env(render_mode="rgb_array", n_uavs=2)
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (512 + 44, 512, 3)
    key = frame[512 + 44 - 10, 150:270].astype(int)  # the bar: red at 0, green at 1
    assert key[0, 0] > 200 and key[0, 1] < 20 and key[-1, 1] > 200 and key[-1, 0] < 20


def test_the_install_hint_works_outside_a_clone() -> None:
    from sb3_maddpg.zoo.registry import MultiAgentEnvSpec

    with pytest.raises(ImportError, match=r'pip install "sb3_maddpg\[zoo\]"'):
        MultiAgentEnvSpec("x_v0", "not_a_module_anywhere:parallel_env").constructor()


def test_usage_docs_quote_no_stale_timing() -> None:
    assert "2 min 40 s" not in (ROOT / "docs" / "usage.md").read_text()
    assert "about three minutes" not in (ROOT / "zoo_configs" / "maddpg.yml").read_text()
    assert os.path.isfile(ROOT / ".ci" / "wheel_check.sh")
