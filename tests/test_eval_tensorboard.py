"""What an evaluation writes to TensorBoard: the coverage map (read back from the event file), the video, the metrics,
with the run's random numbers unchanged; an MPE task gets no pictures and no error."""

import functools
import glob
import io
from pathlib import Path

import numpy as np
import pytest
import torch as th
from PIL import Image
from stable_baselines3.common.callbacks import EvalCallback
from stable_baselines3.common.logger import configure

from sb3_maddpg import MADDPG, make_multiagent_vec_env
from sb3_maddpg.common.eval_tensorboard import (
    MAP_SIZE_PX,
    VIDEO_TAG,
    EvalTensorBoardCallback,
    image_tag,
    kept_random_states,
)
from sb3_maddpg.evaluation.baselines import ModelController
from sb3_maddpg.zoo.monitor import JointEpisodeMonitor
from sb3_maddpg_envs import uav_coverage_v1
from sb3_maddpg_envs.uav_coverage.plotting import coverage_map

KWARGS = dict(obs_size=16, n_uavs=3, max_cycles=10)
SEED = 3
# The UAV task's picture (its tools' map_name)
IMAGE_TAG = "eval/coverage_map"


def event_accumulator(folder: Path):
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    files = glob.glob(str(folder / "**" / "events.out.tfevents.*"), recursive=True)
    assert len(files) == 1, files
    accumulator = EventAccumulator(files[0], size_guidance={"images": 0, "scalars": 0})
    accumulator.Reload()
    return accumulator


def train(folder: Path | None, after_eval: EvalTensorBoardCallback | None, learning_starts: int) -> MADDPG:
    """A tiny run evaluated every 10 steps (one 10-step episode), with TensorBoard in ``folder``."""
    env = make_multiagent_vec_env(uav_coverage_v1.parallel_env, n_envs=1, seed=0, env_kwargs=KWARGS)
    eval_env = JointEpisodeMonitor(make_multiagent_vec_env(uav_coverage_v1.parallel_env, seed=100, env_kwargs=KWARGS))
    model = MADDPG(
        "CnnPolicy", JointEpisodeMonitor(env), buffer_size=200, learning_starts=learning_starts, batch_size=8, seed=0
    )
    model.set_logger(configure(None if folder is None else str(folder), ["tensorboard"] if folder else []))
    evaluation = EvalCallback(eval_env, callback_after_eval=after_eval, n_eval_episodes=1, eval_freq=10, warn=False)
    model.learn(30, callback=evaluation)
    return model


def replayed_map(model: MADDPG) -> np.ndarray:
    """The map drawn from the end of a deterministic episode from SEED, played here."""
    env = uav_coverage_v1.parallel_env(**KWARGS)
    controller = ModelController(model)
    observations, _ = env.reset(seed=SEED)
    while env.agents:
        observations, *_ = env.step(controller.act(observations, env))
    return coverage_map(env.core)


def test_the_coverage_map_read_back_from_the_event_file(tmp_path: Path) -> None:
    # learning_starts beyond the run: the model is the same at each evaluation and after, so the map can be replayed
    after_eval = EvalTensorBoardCallback(functools.partial(uav_coverage_v1.parallel_env, **KWARGS), seed=SEED)
    model = train(tmp_path, after_eval, learning_starts=1000)
    accumulator = event_accumulator(tmp_path)
    assert image_tag(uav_coverage_v1.parallel_env(**KWARGS).task_tools) == IMAGE_TAG
    images = accumulator.Images(IMAGE_TAG)
    assert [image.step for image in images] == [10, 20, 30]
    assert VIDEO_TAG not in accumulator.Tags()["images"]  # the video is opt-in
    expected = replayed_map(model)
    assert expected.shape == (MAP_SIZE_PX[1], MAP_SIZE_PX[0], 3)
    for image in images:
        logged = np.asarray(Image.open(io.BytesIO(image.encoded_image_string)).convert("RGB"))
        assert (image.height, image.width) == expected.shape[:2]
        np.testing.assert_array_equal(logged, expected)
    # Each evaluation's mean episode-end metrics beside eval/mean_reward, at the same timesteps
    coverage = accumulator.Scalars("eval/coverage")
    assert [event.step for event in coverage] == [event.step for event in accumulator.Scalars("eval/mean_reward")]
    assert all(0.0 <= event.value <= 1.0 for event in coverage)
    assert after_eval.drawing_seconds > 0.0


def test_the_map_shows_the_links_and_the_positions() -> None:
    env = uav_coverage_v1.parallel_env(**KWARGS)
    env.reset(seed=0)
    core = env.core
    core.positions[:] = [[2.0, 2.0], [4.0, 2.0], [12.0, 12.0]]
    assert [list(pair) for pair in core.links()] == [[0, 1]]
    linked = coverage_map(core)
    core.links = lambda: np.empty((0, 2), dtype=np.int64)  # the same scene without its link
    unlinked = coverage_map(core)
    assert not np.array_equal(linked, unlinked)
    # The markers are red: there are red pixels, and moving a UAV moves them
    red = (linked[..., 0] > 200) & (linked[..., 1] < 60) & (linked[..., 2] < 60)
    assert red.sum() > 20
    core.positions[2] = [6.0, 12.0]
    moved = coverage_map(core)
    assert not np.array_equal((moved[..., 0] > 200) & (moved[..., 1] < 60) & (moved[..., 2] < 60), red)


def test_a_video_of_one_episode_when_asked(tmp_path: Path) -> None:
    after_eval = EvalTensorBoardCallback(
        functools.partial(uav_coverage_v1.parallel_env, **KWARGS), images=False, video=True, video_frames=4, video_size=64
    )
    train(tmp_path, after_eval, learning_starts=1000)
    accumulator = event_accumulator(tmp_path)
    assert IMAGE_TAG not in accumulator.Tags()["images"]
    videos = accumulator.Images(VIDEO_TAG)
    assert [video.step for video in videos] == [10, 20, 30]
    gif = Image.open(io.BytesIO(videos[0].encoded_image_string))
    assert gif.format == "GIF"
    # at most video_frames frames: steps 0, 4 and 8 (every ceil(10 / 3) steps) and the last, 10
    assert gif.n_frames == 4
    assert gif.size == (64, 64 + 44)  # the map and render_frame's text panel


def test_pictures_leave_the_run_unchanged(tmp_path: Path) -> None:
    # Training from the first evaluation on: the run's parameters are the same with the pictures as without
    with_pictures = EvalTensorBoardCallback(functools.partial(uav_coverage_v1.parallel_env, **KWARGS), video=True)
    pictured = train(tmp_path, with_pictures, learning_starts=10)
    plain = train(None, None, learning_starts=10)
    assert with_pictures.drawing_seconds > 0.0
    for (name, value), (_, other) in zip(pictured.policy.state_dict().items(), plain.policy.state_dict().items(), strict=True):
        assert th.equal(value, other), name


def test_kept_random_states_puts_the_global_generators_back() -> None:
    np.random.seed(0)
    th.manual_seed(0)
    with kept_random_states():
        np.random.random(5)
        th.rand(5)
    after = (np.random.random(), th.rand(1).item())
    np.random.seed(0)
    th.manual_seed(0)
    assert after == (np.random.random(), th.rand(1).item())


def test_no_pictures_and_no_error_on_a_task_that_cannot_draw_itself(tmp_path: Path) -> None:
    from mpe2 import simple_spread_v3

    kwargs = dict(continuous_actions=True, max_cycles=10, N=2)
    env = make_multiagent_vec_env(simple_spread_v3.parallel_env, seed=0, env_kwargs=kwargs)
    eval_env = JointEpisodeMonitor(make_multiagent_vec_env(simple_spread_v3.parallel_env, seed=1, env_kwargs=kwargs))
    model = MADDPG("MlpPolicy", JointEpisodeMonitor(env), buffer_size=100, learning_starts=100, batch_size=8, seed=0)
    model.set_logger(configure(str(tmp_path), ["tensorboard"]))
    after_eval = EvalTensorBoardCallback(functools.partial(simple_spread_v3.parallel_env, **kwargs), video=True)
    model.learn(20, callback=EvalCallback(eval_env, callback_after_eval=after_eval, eval_freq=10, warn=False))
    accumulator = event_accumulator(tmp_path)
    assert accumulator.Tags()["images"] == []
    assert "eval/mean_reward" in accumulator.Tags()["scalars"]
    assert after_eval.drawing_seconds == 0.0


@pytest.mark.parametrize(
    ("kwargs", "error"),
    [
        ({"make_env": "uav_coverage_v1"}, TypeError),
        ({"video": "yes"}, TypeError),
        ({"seed": -1}, ValueError),
        ({"video_frames": 1}, ValueError),
        ({"video_fps": 0}, ValueError),
    ],
)
def test_bad_arguments_name_what_is_accepted(kwargs: dict, error: type) -> None:
    with pytest.raises(error, match="must be"):
        EvalTensorBoardCallback(**kwargs)
