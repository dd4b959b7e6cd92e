"""``train -tb``: the evaluations' pictures (--eval-video, --no-eval-images) and the run's HParams in the event file;
an MPE task writes its HParams and no picture."""

import glob
import os
from pathlib import Path

import pytest
from tensorboard_testing import read_hparams

from sb3_maddpg.__main__ import main
from sb3_maddpg.common.eval_tensorboard import MAP_SIZE_PX, VIDEO_TAG

CONFIG = str(Path(__file__).resolve().parent.parent / "zoo_configs" / "maddpg.yml")
UAV = ["--env", "uav_coverage_fast_v0", "--env-kwargs", "obs_size:16", "max_cycles:10", "n_uavs:2"]
COMMON = ["-conf", CONFIG, "-params", "learning_starts:20", "train_freq:10", "--seed", "4", "-n", "40"]
EVALUATIONS = ["--eval-freq", "20", "--eval-episodes", "1"]


def train(root: Path, *argv: str) -> Path:
    """Run ``train`` in ``root``; return its TensorBoard folder."""
    cwd = os.getcwd()
    os.chdir(root)
    try:
        assert main(["train", *argv, *COMMON, "-tb", "tb", "--verbose", "0"]) == 0
    finally:
        os.chdir(cwd)
    return root / "tb"


def accumulator(folder: Path):
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    (events,) = glob.glob(str(folder / "**" / "events.out.tfevents.*"), recursive=True)
    loaded = EventAccumulator(events, size_guidance={"images": 0})
    loaded.Reload()
    return loaded


def test_uav_run_with_the_video(tmp_path: Path) -> None:
    folder = train(tmp_path, *UAV, *EVALUATIONS, "--eval-video")
    events = accumulator(folder)
    maps, videos = events.Images("eval/coverage_map"), events.Images(VIDEO_TAG)
    assert [image.step for image in maps] == [20, 40] == [video.step for video in videos]
    assert {(image.width, image.height) for image in maps} == {MAP_SIZE_PX}
    assert all(video.encoded_image_string.startswith(b"GIF8") for video in videos)
    assert {"eval/coverage", "eval/fairness", "eval/energy_efficiency"} <= set(events.Tags()["scalars"])
    hparams, metrics = read_hparams(folder)
    # The YAML entry as trained (-params over it), the env's arguments, the seed and the timesteps
    assert hparams["algo"] == "maddpg" and hparams["env"] == "uav_coverage_fast_v0"
    assert hparams["learning_starts"] == 20.0 and hparams["seed"] == 4.0 and hparams["n_timesteps"] == 40.0
    assert hparams["env_kwargs/n_uavs"] == 2.0 and hparams["env_kwargs/max_cycles"] == 10.0
    assert {"eval/mean_reward", "eval/coverage"} <= set(metrics)


def test_uav_run_without_images(tmp_path: Path) -> None:
    events = accumulator(train(tmp_path, *UAV, *EVALUATIONS, "--no-eval-images"))
    assert events.Tags()["images"] == []
    # The metrics stay, and the hyperparameters
    assert "eval/coverage" in events.Tags()["scalars"]
    assert read_hparams(tmp_path / "tb")[0]["env"] == "uav_coverage_fast_v0"


def test_mpe_run_logs_its_hyperparameters_only(tmp_path: Path) -> None:
    folder = train(tmp_path, "--env", "simple_spread_v3", "--env-kwargs", "max_cycles:10", "N:2", *EVALUATIONS)
    events = accumulator(folder)
    assert events.Tags()["images"] == []
    assert "eval/mean_reward" in events.Tags()["scalars"]
    assert read_hparams(folder)[0]["env"] == "simple_spread_v3"


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["train", *UAV, "--eval-video"], "--eval-video writes the video into TensorBoard: give -tb"),
        (["enjoy", "--eval-video"], "--eval-video is a train flag"),
    ],
)
def test_picture_flags_refused_where_they_cannot_work(argv: list[str], message: str, capsys: pytest.CaptureFixture) -> None:
    with pytest.raises(SystemExit) as stopped:
        main(argv)
    assert stopped.value.code == 2
    assert message in capsys.readouterr().err
