"""PoIs and start positions (docs/environment.md, "Parameters")."""

import numpy as np
import pytest
from PIL import Image

from sb3_maddpg_envs.uav_coverage.core import UAVCoverageCore


def test_grid_is_the_integer_lattice():
    core = UAVCoverageCore(map_size=3, n_uavs=1, obs_size=3)
    assert core.pois.shape == (9, 2)
    assert {tuple(p) for p in core.pois.tolist()} == {(x, y) for x in range(3) for y in range(3)}
    assert UAVCoverageCore().pois.shape == (256, 2)  # default K = 16 * 16


def test_uniform_pois_come_from_the_seed():
    a = UAVCoverageCore(map_size=4, n_uavs=2, pois="uniform", n_pois=7, obs_size=4)
    b = UAVCoverageCore(map_size=4, n_uavs=2, pois="uniform", n_pois=7, obs_size=4)
    a.reset(seed=3)
    b.reset(seed=3)
    assert a.pois.shape == (7, 2)
    assert ((a.pois >= 0) & (a.pois < 4)).all()
    np.testing.assert_array_equal(a.pois, b.pois)
    first = a.pois.copy()
    a.reset(seed=4)  # drawn once, kept for the run
    np.testing.assert_array_equal(a.pois, first)
    assert UAVCoverageCore(map_size=4, n_uavs=1, pois="uniform", obs_size=4).n_pois == 16  # default L^2


def test_image_png_to_pois(tmp_path):
    # 8 x 8 image for L = 4 (2 x 2 pixels per cell). Bright top-left block -> cell row 0 (top), column 0
    # -> PoI at (0.5, 3.5). 128 on rows 4-5, cols 6-7 -> cell row 2, column 3 -> y cell 4 - 1 - 2 = 1 -> (3.5, 1.5).
    # 20 on the bottom-right block: 20 < 0.1 * 255 = 25.5, no PoI.
    pixels = np.zeros((8, 8), dtype=np.uint8)
    pixels[0:2, 0:2] = 255
    pixels[4:6, 6:8] = 128
    pixels[6:8, 6:8] = 20
    path = tmp_path / "map.png"
    Image.fromarray(pixels).save(path)
    core = UAVCoverageCore(map_size=4, n_uavs=1, pois=path, obs_size=4)
    assert sorted(core.pois.tolist()) == [[0.5, 3.5], [3.5, 1.5]]
    same = UAVCoverageCore(map_size=4, n_uavs=1, pois=str(path), obs_size=4)
    np.testing.assert_array_equal(np.sort(same.pois, axis=0), np.sort(core.pois, axis=0))
    # The observation's channel 0 puts the top-left PoI in the top-left pixel.
    obs = core.reset(seed=0)
    assert obs[0, 0, 0, 0] == 255 and obs[0, 0, 3, 0] == 0


def test_image_area_averaging_with_uneven_size():
    # 6 x 6 image -> 4 x 4 cells: input pixel j spans [2j/3, 2(j+1)/3). Cell column 3 = [3, 4) overlaps pixel 4 by
    # 1/3 and pixel 5 by 2/3: mean = (1/3 * 0 + 2/3 * 90) = 60; the other cell columns are 0.
    image = np.array([[0, 0, 0, 0, 0, 90]] * 6, dtype=float)
    core = UAVCoverageCore(map_size=4, n_uavs=1, pois=image, obs_size=4)  # 60 > 0.1 * 90
    assert sorted(core.pois.tolist()) == [[3.5, 0.5], [3.5, 1.5], [3.5, 2.5], [3.5, 3.5]]
    with pytest.raises(ValueError, match="no cell"):
        UAVCoverageCore(map_size=4, n_uavs=1, pois=image, poi_threshold=0.7, obs_size=4)  # 60 < 0.7 * 90 = 63


@pytest.mark.parametrize("shape", [(5, 3), (3, 5), (2, 3), (3, 3)])
def test_an_ambiguous_array_is_refused_not_guessed(shape):
    # (5, 3) could be five (x, y, weight) PoIs; a 3-pixel-wide "image" would be read as a few cells of a table
    with pytest.raises(ValueError, match=rf"got shape \({shape[0]}, {shape[1]}\); weighted PoIs"):
        UAVCoverageCore(map_size=16, n_uavs=1, pois=np.ones(shape), obs_size=16)


def test_two_columns_are_coordinates_and_a_4_by_4_array_is_an_image():
    assert UAVCoverageCore(map_size=4, n_uavs=1, pois=np.ones((2, 2)), obs_size=4).pois.tolist() == [[1, 1], [1, 1]]
    assert len(UAVCoverageCore(map_size=4, n_uavs=1, pois=np.ones((4, 4)), obs_size=4).pois) == 16


def test_image_errors(tmp_path):
    with pytest.raises(ValueError, match="missing.png"):
        UAVCoverageCore(map_size=4, n_uavs=1, pois=tmp_path / "missing.png", obs_size=4)
    text = tmp_path / "notes.png"
    text.write_text("not an image")
    with pytest.raises(ValueError, match="notes.png.*not an image"):
        UAVCoverageCore(map_size=4, n_uavs=1, pois=text, obs_size=4)
    dark = tmp_path / "dark.png"
    Image.fromarray(np.zeros((8, 8), dtype=np.uint8)).save(dark)
    with pytest.raises(ValueError, match="dark.png.*no cell"):
        UAVCoverageCore(map_size=4, n_uavs=1, pois=dark, obs_size=4)
    with pytest.raises(ValueError, match="shape"):
        UAVCoverageCore(map_size=4, n_uavs=1, pois=np.ones((2, 3, 4)), obs_size=4)
    with pytest.raises(ValueError, match="shape"):
        UAVCoverageCore(map_size=4, n_uavs=1, pois=np.ones(5), obs_size=4)


def test_start_modes():
    fixed = UAVCoverageCore(map_size=8, n_uavs=3, obs_size=8, start="fixed")
    fixed.reset(seed=1)
    first = fixed.positions.copy()
    fixed.step(np.full((3, 2), 0.5))
    fixed.reset()
    np.testing.assert_array_equal(fixed.positions, first)
    fixed.reset(seed=2)  # drawn once from the first seed, then reused
    np.testing.assert_array_equal(fixed.positions, first)

    rand = UAVCoverageCore(map_size=8, n_uavs=3, obs_size=8, start="random")
    rand.reset(seed=1)
    a = rand.positions.copy()
    rand.reset()
    assert not np.array_equal(rand.positions, a)
    rand.reset(seed=1)
    np.testing.assert_array_equal(rand.positions, a)
    assert ((a >= 0) & (a < 8)).all()

    given = UAVCoverageCore(map_size=8, n_uavs=2, obs_size=8, start=[[1.0, 2.0], [7.5, 0.0]])
    given.reset(seed=5)
    np.testing.assert_array_equal(given.positions, [[1.0, 2.0], [7.5, 0.0]])
