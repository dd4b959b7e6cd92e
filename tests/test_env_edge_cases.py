"""PoI images at full depth and with alpha marks; parameter bounds so that every accepted configuration runs."""

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from sb3_maddpg_envs.uav_coverage.core import UAVCoverageCore, load_poi_image


def _marks(dtype, background, mark) -> np.ndarray:
    """32 x 32 pixels; every 4th pixel of every 4th row marked: on a 16 x 16 map, 8 x 8 = 64 cells hold a mark."""
    image = np.full((32, 32), background, dtype=dtype)
    image[::4, ::4] = mark
    return image


def test_16_bit_png_is_read_at_full_depth(tmp_path: Path) -> None:
    path = tmp_path / "pois16.png"
    Image.fromarray(_marks(np.uint16, 3000, 60000)).save(path)
    with Image.open(path) as image:
        assert image.mode.startswith("I;16")
    assert load_poi_image(path).max() == 60000
    # 3000 / 60000 = 0.05 of the maximum: background, below poi_threshold=0.1 (8 bits saturated it to 255 = PoIs)
    assert UAVCoverageCore(pois=str(path), obs_size=16).n_pois_total == 64


def test_rgba_image_with_pois_marked_only_by_alpha_uses_alpha(tmp_path: Path) -> None:
    rgba = np.zeros((32, 32, 4), dtype=np.uint8)
    rgba[..., :3] = 40  # the same colour everywhere
    rgba[..., 3] = _marks(np.uint8, 0, 255)
    path = tmp_path / "pois_alpha.png"
    Image.fromarray(rgba).save(path)
    assert UAVCoverageCore(pois=str(path), obs_size=16).n_pois_total == 64


def test_8_bit_and_coloured_images_are_read_as_before(tmp_path: Path) -> None:
    gray = tmp_path / "gray.png"
    Image.fromarray(_marks(np.uint8, 10, 200)).save(gray)
    np.testing.assert_array_equal(load_poi_image(gray), _marks(np.uint8, 10, 200).astype(np.float64))
    # an RGBA image whose colour carries the marks: its luminance, alpha ignored
    rgba = np.zeros((32, 32, 4), dtype=np.uint8)
    rgba[..., 0] = _marks(np.uint8, 0, 255)
    rgba[..., 3] = 255
    Image.fromarray(rgba).save(tmp_path / "red.png")
    assert UAVCoverageCore(pois=str(tmp_path / "red.png"), obs_size=16).n_pois_total == 64


def test_a_directory_given_as_pois_says_it_is_a_directory(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=r"pois: .* is a directory, not an image file"):
        UAVCoverageCore(pois=str(tmp_path))


EDGE_VALUES = [
    (dict(coverage_range=1e200, comm_range=1e200), "coverage_range must lie in"),  # was OverflowError
    (dict(move_energy=1e-200, max_distance=1e-200), "max_distance must lie in"),  # was ZeroDivisionError
    (dict(move_energy=1e-200), "move_energy must lie in"),
    (dict(reward_scale=1e308), "reward_scale must lie in"),  # was infinite rewards
    (dict(eps=1e-300), r"eps must lie in \[1e-12, 1\)"),
    (dict(wall_penalty=1e300), r"wall_penalty must lie in \[0, 1e\+12\]"),
    (dict(max_energy=1e-300), "max_energy must lie in"),
]


@pytest.mark.parametrize(("kwargs", "message"), EDGE_VALUES, ids=[str(k) for k, _ in EDGE_VALUES])
def test_edge_values_that_would_crash_inside_are_refused(kwargs, message) -> None:
    with pytest.raises(ValueError, match=message):
        UAVCoverageCore(**kwargs)


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(coverage_range=1e12, comm_range=1e12, reward_scale=1e12, wall_penalty=1e12, entropy_coef=1e12),
        dict(move_energy=1e-12, max_distance=1e-12, hover_energy=1e-12, eps=1e-12, max_energy=1e12),
        dict(max_energy=1e-12, move_energy=1e12, max_distance=1e12, hover_energy=1e12, eps=1e-12, reward_scale=1e12),
    ],
    ids=["largest", "smallest", "mixed"],
)
def test_the_bounds_themselves_run(kwargs) -> None:
    core = UAVCoverageCore(obs_size=16, max_cycles=6, **kwargs)
    core.reset(seed=0)
    rng = np.random.default_rng(0)
    for _ in range(6):
        _, rewards, terminated, truncated = core.step(rng.random((core.n_uavs, 2)))
        assert np.isfinite(rewards).all() and np.isfinite(rewards.astype(np.float32)).all()
        assert all(np.isfinite(value) for value in core.metrics().values())
        if terminated or truncated:
            break
