"""Random valid configurations and random (also out-of-range) actions keep every quantity in range."""

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sb3_maddpg_envs.uav_coverage.core import UAVCoverageCore


@st.composite
def configs(draw):
    map_size = draw(st.integers(1, 6))
    comm_range = draw(st.floats(0.1, 10.0))
    return dict(
        map_size=map_size,
        n_uavs=draw(st.integers(1, 4)),
        pois=draw(st.sampled_from(["grid", "uniform"])),
        max_energy=draw(st.floats(0.01, 50.0)),
        max_distance=draw(st.floats(0.01, 5.0)),
        move_energy=draw(st.floats(0.01, 3.0)),
        hover_energy=draw(st.floats(0.01, 3.0)),
        coverage_range=draw(st.floats(0.01, 1.0)) * comm_range,
        comm_range=comm_range,
        wall_penalty=draw(st.floats(0.0, 20.0)),
        comm_penalty=draw(st.floats(0.0, 5.0)),
        entropy_coef=draw(st.floats(0.0, 1.0)),
        max_cycles=draw(st.integers(1, 12)),
        obs_size=map_size * draw(st.integers(1, 3)),
        start=draw(st.sampled_from(["fixed", "random"])),
        reward_clip=draw(st.sampled_from([None, 5.0])),
    )


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(config=configs(), seed=st.integers(0, 2**31 - 1))
def test_random_episodes_stay_in_range(config, seed):
    core = UAVCoverageCore(**config)
    rng = np.random.default_rng(seed)
    obs = core.reset(seed=seed)
    assert obs.dtype == np.uint8
    done = False
    while not done:
        actions = rng.uniform(-1.0, 2.0, size=(core.n_uavs, 2))  # out-of-range values are clipped
        obs, rewards, terminated, truncated = core.step(actions)
        done = terminated or truncated
        assert np.isfinite(rewards).all()
        assert (core.energy >= 0).all()
        assert ((core.positions >= 0) & (core.positions < core.map_size)).all()
        assert ((core.coverage_scores >= 0) & (core.coverage_scores <= 1)).all()
        for value in (core.coverage, core.fairness):
            assert 0.0 <= value <= 1.0
        assert np.isfinite([core.energy_ratio, core.energy_efficiency]).all() and core.energy_ratio >= 0
        if config["reward_clip"] is not None:
            assert (np.abs(rewards) <= 5.0).all()
        assert obs.shape == (core.n_uavs, 3, core.obs_size, core.obs_size)
    assert core.t <= config["max_cycles"]
