"""rgb_array rendering and the plot helpers."""

import numpy as np
import pytest
from PIL import Image

from sb3_maddpg_envs import uav_coverage_v0
from sb3_maddpg_envs.uav_coverage.plotting import save_coverage_heatmap, save_gif, save_state_image


def test_render_rgb_array_changes_when_a_uav_moves():
    env = uav_coverage_v0.parallel_env(n_uavs=2, obs_size=16, render_mode="rgb_array")
    env.reset(seed=0)
    first = env.render()
    assert first.ndim == 3 and first.shape[2] == 3 and first.dtype == np.uint8
    env.step({"uav_0": np.array([0.0, 1.0]), "uav_1": np.array([0.5, 1.0])})
    second = env.render()
    assert second.shape == first.shape
    assert (second != first).any()


def test_render_without_mode_returns_none():
    env = uav_coverage_v0.parallel_env(n_uavs=2, obs_size=16)
    env.reset(seed=0)
    with pytest.warns(UserWarning, match="render_mode"):
        assert env.render() is None


def test_plot_helpers_write_png_and_gif(tmp_path):
    env = uav_coverage_v0.parallel_env(n_uavs=3, obs_size=16, render_mode="rgb_array")
    env.reset(seed=1)
    frames = [env.render()]
    for _ in range(3):
        env.step({agent: np.array([0.2, 0.8]) for agent in env.agents})
        frames.append(env.render())
    save_gif(frames, tmp_path / "episode.gif", fps=5)
    save_coverage_heatmap(env.core, tmp_path / "heat.png")
    save_state_image(env, tmp_path / "state.png")
    aec = uav_coverage_v0.env(n_uavs=2, obs_size=16)
    aec.reset(seed=0)
    save_state_image(aec, tmp_path / "state_aec.png")
    with Image.open(tmp_path / "episode.gif") as gif:
        assert gif.format == "GIF" and gif.n_frames == 4
    for name in ("heat.png", "state.png", "state_aec.png"):
        with Image.open(tmp_path / name) as image:
            assert image.format == "PNG" and image.size[0] > 0
    with pytest.raises(ValueError, match="empty"):
        save_gif([], tmp_path / "none.gif")
