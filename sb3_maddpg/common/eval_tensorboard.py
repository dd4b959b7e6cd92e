"""
What an evaluation adds to TensorBoard beside SB3's ``eval/mean_reward``: the episode-end metrics of the evaluation's
episodes, and, on a task that can draw itself (whose env's task tools ``can_draw``: on the UAV coverage envs the
coverage heat map with the team's positions and links), a picture of one evaluation episode's end and, on request, a
short video of it.

Everything here runs after an evaluation only (``EvalCallback(callback_after_eval=...)``), never on a training step.
The drawn episode is played on an env of its own, from the same seed at every evaluation (the pictures of successive
evaluations compare), and Python's, NumPy's and PyTorch's global random states are put back afterwards, so that a run
draws the same random numbers with pictures as without.
"""

import contextlib
import importlib
import io
import math
import random
import time
import warnings
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import torch as th
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import Image, Video
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper, VecFrameStack, VecNormalize, VecTransposeImage

from sb3_maddpg.common.callbacks import declared_episode_metrics
from sb3_maddpg.common.hparams import tensorboard_formats, write_to_tensorboard
from sb3_maddpg.common.validation import check_int
from sb3_maddpg.evaluation.task_tools import TaskTools, episode_limit, task_tools

# The picture's tag is eval/<the task's map_name> (image_tag); the video's is the same for every task
IMAGE_SECTION = "eval"
VIDEO_TAG = "eval/episode"
# The picture's size in pixels (width, height): small enough that each evaluation adds tens of kilobytes
MAP_SIZE_PX = (416, 360)


def image_tag(tools: TaskTools) -> str:
    """
    :param tools: a task's tools (:func:`~sb3_maddpg.evaluation.task_tools.task_tools` of its env)
    :return: the TensorBoard tag of the task's picture after an evaluation: ``eval/<map_name>`` (on the UAV envs
        ``eval/coverage_map``; ``eval/state_image`` for tools that name none)
    """
    return f"{IMAGE_SECTION}/{tools.map_name}"


@contextlib.contextmanager
def kept_random_states() -> Iterator[None]:
    """Put back Python's, NumPy's and PyTorch's global random states (CUDA's too) when the block ends."""
    python_state, numpy_state, torch_state = random.getstate(), np.random.get_state(), th.get_rng_state()
    cuda_states = th.cuda.get_rng_state_all() if th.cuda.is_available() and th.cuda.is_initialized() else None
    try:
        yield
    finally:
        random.setstate(python_state)
        np.random.set_state(numpy_state)
        th.set_rng_state(torch_state)
        if cuda_states is not None:
            th.cuda.set_rng_state_all(cuda_states)


def video_encoder() -> str:
    """
    How a video reaches TensorBoard here: ``"moviepy"`` (SB3's ``Video``, which PyTorch's writer encodes with
    ``moviepy.editor``, gone from moviepy 2) or ``"pillow"`` (the same animated GIF image summary, encoded with Pillow).
    """
    try:
        importlib.import_module("moviepy.editor")
    except ImportError:
        return "pillow"
    return "moviepy"


def write_gif_summary(logger: Any, tag: str, frames: np.ndarray, fps: float, step: int) -> None:
    """
    Write frames as the animated GIF image summary PyTorch's ``add_video`` writes, encoded with Pillow, to the logger's
    TensorBoard outputs (TensorBoard plays it in its Images tab).

    :param logger: SB3's logger
    :param tag: the summary's tag
    :param frames: (T, H, W, 3) uint8 frames
    :param fps: frames per second
    :param step: the timestep
    """
    from PIL import Image as PILImage
    from tensorboard.compat.proto.summary_pb2 import Summary

    # Pillow's default palette for GIF (median cut) costs about ten times more than the fast octree, which the
    # rendered map's few flat colours do not need
    images = [PILImage.fromarray(frame).quantize(colors=128, method=PILImage.Quantize.FASTOCTREE) for frame in frames]
    buffer = io.BytesIO()
    images[0].save(buffer, format="GIF", save_all=True, append_images=images[1:], duration=max(1, round(1000 / fps)), loop=0)
    height, width = frames.shape[1:3]
    image = Summary.Image(height=height, width=width, colorspace=3, encoded_image_string=buffer.getvalue())
    for output in tensorboard_formats(logger):
        output.writer.file_writer.add_summary(Summary(value=[Summary.Value(tag=tag, image=image)]), step)
        output.writer.flush()


def _observation_changing_wrapper(env: VecEnv) -> str | None:
    """The name of a wrapper of the evaluation env that changes what the model sees, which a raw env would not do."""
    while isinstance(env, VecEnvWrapper):
        if isinstance(env, VecFrameStack | VecTransposeImage) or (isinstance(env, VecNormalize) and env.norm_obs):
            return type(env).__name__
        env = env.venv
    return None


def _episode_rows(env: Any) -> list[dict[str, Any]] | None:
    """The joint episodes the evaluation env's ``JointEpisodeMonitor`` kept (its ``episodes`` rows), if it has one."""
    while env is not None:
        episodes = getattr(env, "episodes", None)
        if isinstance(episodes, list):
            return episodes
        env = getattr(env, "venv", None)
    return None


class EvalTensorBoardCallback(BaseCallback):
    """
    Called after each evaluation (``EvalCallback(callback_after_eval=...)``), it writes to TensorBoard, at the
    evaluation's timestep:

    - ``eval/<metric>``: the mean of each episode metric the env declares (``declared_episode_metrics``: on the UAV
      envs coverage, fairness, energy, ...) over the evaluation's episodes, read from the ``JointEpisodeMonitor`` of
      the evaluation env, where the env reports them;
    - ``eval/<map_name>`` (with ``images``, :func:`image_tag`): the task's picture (``TaskTools.draw_map``) at the end
      of one deterministic episode, on a task that can draw itself (on the UAV coverage envs ``eval/coverage_map``,
      the coverage heat map with the team's positions and links);
    - ``eval/episode`` (with ``video``): that episode as an animated GIF (SB3's ``Video`` where moviepy can encode it,
      else the same GIF encoded with Pillow).

    A run without TensorBoard (no ``tensorboard_log``) draws nothing. Other envs (e.g. MPE's) get no pictures, and no
    error. ``drawing_seconds`` adds up the time spent playing and drawing the pictured episodes.

    :param make_env: builds the PettingZoo ParallelEnv the pictured episode is played on (the evaluation env's id
        and arguments), or None for no pictures
    :param images: draw the task's picture (on the UAV envs the coverage heat map)
    :param video: record the episode as a video
    :param seed: the pictured episode's seed, the same at every evaluation
    :param video_fps: frames per second of the video
    :param video_frames: the most frames the video keeps (every k-th step, and the last)
    :param video_size: side in pixels of the video's map
    :param verbose: 0: silent, 1: a warning when pictures cannot be drawn, 2: the drawing time of each evaluation
    """

    def __init__(
        self,
        make_env: Callable[[], Any] | None = None,
        images: bool = True,
        video: bool = False,
        seed: int = 0,
        video_fps: int = 10,
        video_frames: int = 40,
        video_size: int = 256,
        verbose: int = 1,
    ) -> None:
        super().__init__(verbose)
        if make_env is not None and not callable(make_env):
            raise TypeError(f"make_env must be a function that builds the env, or None; got {type(make_env).__name__}")
        for name, flag in (("images", images), ("video", video)):
            if not isinstance(flag, bool):
                raise TypeError(f"{name} must be True or False, got {flag!r}")
        self.make_env = make_env
        self.images = images
        self.video = video
        self.seed = check_int("seed", seed, low=0)
        self.video_fps = check_int("video_fps", video_fps, low=1)
        self.video_frames = check_int("video_frames", video_frames, low=2)
        self.video_size = check_int("video_size", video_size, low=32)
        self.drawing_seconds = 0.0
        self._env: Any = None
        self._seen_episodes = 0

    def _init_callback(self) -> None:
        self._env = None
        if self.make_env is None or not (self.images or self.video) or not tensorboard_formats(self.logger):
            return
        eval_env = getattr(self.parent, "eval_env", None)
        wrapper = None if eval_env is None else _observation_changing_wrapper(eval_env)
        if wrapper is not None:
            if self.verbose:
                warnings.warn(
                    f"no evaluation pictures: the evaluation env is wrapped in {wrapper}, so the model does not act on "
                    "the env's own observations",
                    stacklevel=2,
                )
            return
        with kept_random_states():
            env = self.make_env()
        if not task_tools(env).can_draw:
            # A task that cannot draw itself (e.g. MPE): metrics and hyperparameters only
            env.close()
            return
        self._env = env

    def _on_step(self) -> bool:
        values: dict[str, Any] = self._eval_metrics()
        if self._env is not None:
            start = time.perf_counter()
            with kept_random_states():
                values.update(self._pictures())
            self.drawing_seconds += time.perf_counter() - start
            if self.verbose >= 2:
                print(f"Evaluation pictures: {time.perf_counter() - start:.2f} s ({self.drawing_seconds:.1f} s in all)")
        frames = values.pop(VIDEO_TAG, None)
        if values:
            write_to_tensorboard(self.logger, values, self.num_timesteps)
        if frames is not None:
            start = time.perf_counter()
            if video_encoder() == "moviepy":
                # (1, T, C, H, W), as SB3's Video expects
                video = Video(th.from_numpy(np.ascontiguousarray(frames.transpose(0, 3, 1, 2)))[None], fps=self.video_fps)
                write_to_tensorboard(self.logger, {VIDEO_TAG: video}, self.num_timesteps)
            else:
                write_gif_summary(self.logger, VIDEO_TAG, frames, self.video_fps, self.num_timesteps)
            self.drawing_seconds += time.perf_counter() - start
        return True

    def _eval_metrics(self) -> dict[str, float]:
        """The mean episode-end metrics of the episodes the evaluation env ended since the previous evaluation."""
        eval_env = getattr(self.parent, "eval_env", None)
        rows = _episode_rows(eval_env)
        if rows is None:
            return {}
        new, self._seen_episodes = rows[self._seen_episodes :], len(rows)
        means = {}
        keys, _ = declared_episode_metrics(eval_env)
        for key in keys:
            values = [float(row[key]) for row in new if row.get(key, "") != ""]
            if values:
                means[f"eval/{key}"] = float(np.mean(values))
        return means

    def _pictures(self) -> dict[str, Any]:
        """Play one deterministic episode on the callback's env and draw it."""
        from sb3_maddpg.evaluation.baselines import ModelController

        env = self._env
        tools = task_tools(env)
        controller = ModelController(self.model, deterministic=bool(getattr(self.parent, "deterministic", True)))
        # every k-th step, so that the video keeps at most video_frames frames (every step where the env does not say
        # how long an episode lasts)
        every = max(1, math.ceil(int(episode_limit(env) or 1) / (self.video_frames - 1)))
        frames: list[np.ndarray] = []
        observations, _ = env.reset(seed=self.seed)
        step = 0
        if self.video:
            frames.append(tools.draw_frame(env, self.video_size))
        while env.agents:
            live = {agent: observation for agent, observation in observations.items() if agent in env.agents}
            observations, *_ = env.step(controller.act(live, env))
            step += 1
            if self.video and (step % every == 0 or not env.agents):
                frames.append(tools.draw_frame(env, self.video_size))
        pictures: dict[str, Any] = {}
        if self.images:
            pictures[image_tag(tools)] = Image(tools.draw_map(env, MAP_SIZE_PX), "HWC")
        if self.video:
            pictures[VIDEO_TAG] = np.stack(frames)
        return pictures
