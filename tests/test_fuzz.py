"""
Fuzz tests (Hypothesis): the env under random valid configurations and random actions, and the replay buffer under
random sequences of add / sample / save-load / re-layout, keep their invariants.
"""

import io
import pickle

import numpy as np
import pytest
from gymnasium import spaces
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sb3_maddpg.common.buffers import MultiAgentReplayBuffer
from sb3_maddpg_envs.uav_coverage.core import UAVCoverageCore

FUZZ_ENV = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
# Buffer sequences are cheap; a bug in a rare path (a re-layout joining two copies' histories) needs ~100 examples
FUZZ_BUFFER = settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def log_uniform(low: float, high: float) -> st.SearchStrategy[float]:
    """Numbers spread over every order of magnitude between low and high (the bounds included)."""
    return st.one_of(
        st.sampled_from([low, high]),
        st.floats(np.log10(low), np.log10(high)).map(lambda exponent: float(10.0**exponent)),
    ).map(lambda value: min(max(value, low), high))


@st.composite
def env_configs(draw: st.DrawFn) -> dict:
    map_size = draw(st.integers(1, 8))
    n_uavs = draw(st.integers(1, 4))
    coverage_range = draw(log_uniform(1e-12, 1e12))
    config = dict(
        map_size=map_size,
        n_uavs=n_uavs,
        obs_size=map_size * draw(st.integers(1, 3)),
        max_cycles=draw(st.integers(1, 12)),
        max_energy=draw(log_uniform(1e-12, 1e12)),
        max_distance=draw(log_uniform(1e-12, 1e12)),
        move_energy=draw(log_uniform(1e-12, 1e12)),
        hover_energy=draw(log_uniform(1e-12, 1e12)),
        coverage_range=coverage_range,
        comm_range=min(1e12, coverage_range * draw(log_uniform(1.0, 1e6))),
        wall_penalty=draw(st.one_of(st.just(0.0), log_uniform(1e-12, 1e12))),
        comm_penalty=draw(st.one_of(st.just(0.0), log_uniform(1e-12, 1e12))),
        entropy_coef=draw(st.one_of(st.just(0.0), log_uniform(1e-12, 1e12))),
        eps=draw(log_uniform(1e-12, 0.5)),
        reward_scale=draw(log_uniform(1e-12, 1e12)),
        reward_clip=draw(st.one_of(st.none(), log_uniform(1e-12, 1e12))),
        start=draw(st.sampled_from(["fixed", "random"])),
    )
    pois = draw(st.sampled_from(["grid", "uniform", "array"]))
    if pois == "uniform":
        config.update(pois="uniform", n_pois=draw(st.integers(1, 40)))
    elif pois == "array":
        n_pois = draw(st.integers(1, 20))
        coordinates = draw(st.lists(st.floats(0.0, map_size, exclude_max=True), min_size=2 * n_pois, max_size=2 * n_pois))
        config["pois"] = np.array(coordinates).reshape(n_pois, 2)
    return config


@FUZZ_ENV
@given(config=env_configs(), seed=st.integers(0, 2**32 - 1), n_episodes=st.integers(1, 2))
def test_env_invariants_under_random_configurations_and_actions(config: dict, seed: int, n_episodes: int) -> None:
    core = UAVCoverageCore(**config)
    rng = np.random.default_rng(seed)
    n, size = core.n_uavs, core.obs_size
    for episode in range(n_episodes):
        observations = core.reset(seed=seed + episode)
        assert observations.shape == (n, 3, size, size) and observations.dtype == np.uint8
        previous_spent = 0.0
        for _ in range(core.max_cycles):
            # actions inside and outside the box (clipped by the env)
            observations, rewards, terminated, truncated = core.step(rng.uniform(-0.5, 1.5, size=(n, 2)))
            assert observations.shape == (n, 3, size, size) and observations.dtype == np.uint8
            assert rewards.shape == (n,) and np.isfinite(rewards).all()
            assert np.isfinite(rewards.astype(np.float32)).all()  # the VecEnv's dtype
            if config["reward_clip"] is not None:
                assert (np.abs(rewards) <= config["reward_clip"]).all()
            assert (core.energy >= 0.0).all() and (core.energy <= core.max_energy).all()
            assert core.total_energy_spent >= previous_spent
            previous_spent = core.total_energy_spent
            assert ((core.positions >= 0.0) & (core.positions < core.map_size)).all()
            metrics = core.metrics()
            assert 0.0 <= metrics["coverage"] <= 1.0 and 0.0 <= metrics["fairness"] <= 1.0
            assert np.isfinite(metrics["energy"]) and metrics["energy"] >= 0.0
            assert np.isfinite(metrics["energy_efficiency"]) and metrics["energy_efficiency"] >= 0.0
            assert ((core.coverage_scores >= 0.0) & (core.coverage_scores <= 1.0)).all()
            if terminated or truncated:
                assert not (terminated and truncated)
                break
        assert terminated or truncated


# ---------------------------------------------------------------------------------------------------------------------
# Replay buffer
# ---------------------------------------------------------------------------------------------------------------------
class BufferDriver:
    """
    Feeds a buffer with transitions whose observations carry a unique id, and remembers what was stored for each id,
    so that any transition read back can be checked against what was added.
    """

    def __init__(self, n_agents: int, n_copies: int, capacity: int, rng: np.random.Generator) -> None:
        self.n_agents, self.rng = n_agents, rng
        observation_space = spaces.Box(-np.inf, np.inf, (3,), np.float32)
        action_space = spaces.Box(-1.0, 1.0, (2,), np.float32)
        self.buffer = MultiAgentReplayBuffer(
            capacity, observation_space, action_space, device="cpu", n_envs=n_copies * n_agents, n_agents=n_agents
        )
        self.next_id = 0
        self.stored: dict[int, tuple] = {}  # id -> (next obs, action, reward, done, timeout)
        self.obs = self._fresh()

    def _fresh(self) -> np.ndarray:
        """New observations for every copy: agent a of a copy sees (id, a, copy)."""
        copies = self.buffer.n_copies
        ids = np.arange(self.next_id, self.next_id + copies)
        self.next_id += copies
        return np.array([[ids[c], a, c] for c in range(copies) for a in range(self.n_agents)], np.float32)

    def add(self, done: bool, truncated: bool) -> None:
        rows = self.buffer.n_copies * self.n_agents
        next_obs = self._fresh()
        action = self.rng.uniform(-1, 1, (rows, 2)).astype(np.float32)
        reward = self.rng.normal(size=rows).astype(np.float32)
        infos = [{"TimeLimit.truncated": done and truncated} for _ in range(rows)]
        self.buffer.add(self.obs, next_obs, action, reward, np.full(rows, done), infos)
        for copy in range(self.buffer.n_copies):
            block = slice(copy * self.n_agents, (copy + 1) * self.n_agents)
            self.stored[int(self.obs[block][0, 0])] = (next_obs[block], action[block], reward[block], done, done and truncated)
        # after an episode end the env resets: the next observation is a new one
        self.obs = self._fresh() if done else next_obs

    def env_reset_without_episode_end(self) -> None:
        """A new learn() call, or a resumed buffer: the next observation is not the pending successor."""
        self.obs = self._fresh()

    def check(self, slots: np.ndarray, copies: np.ndarray) -> None:
        data = self.buffer._get_samples(slots, copy_inds=copies)
        for obs, action, next_obs, done, reward in zip(*(tensor.numpy() for tensor in data), strict=True):
            uid = int(obs[0, 0])
            assert uid in self.stored, "sampled a transition that was never stored"
            np.testing.assert_array_equal(obs[:, 1], np.arange(self.n_agents))
            expected_next, expected_action, expected_reward, expected_done, expected_timeout = self.stored[uid]
            np.testing.assert_array_equal(next_obs, expected_next)
            np.testing.assert_allclose(action, expected_action)
            np.testing.assert_array_equal(reward, expected_reward)
            assert done[0] == float(expected_done and not expected_timeout)

    def check_everything_stored(self, n_added_per_copy: int) -> None:
        slots, copies = self.buffer.stored_transitions()
        assert len(slots) == min(n_added_per_copy, self.buffer.buffer_size) * self.buffer.n_copies
        if len(slots):
            self.check(slots, copies)


@FUZZ_BUFFER
@given(
    n_agents=st.integers(1, 3),
    n_copies=st.integers(1, 3),
    capacity=st.integers(1, 12),
    operations=st.lists(
        st.sampled_from(["step", "step", "step", "done", "truncated", "jump", "sample", "save_load", "relayout"]),
        max_size=40,
    ),
    seed=st.integers(0, 2**32 - 1),
)
def test_replay_buffer_returns_what_was_stored(n_agents, n_copies, capacity, operations, seed) -> None:
    rng = np.random.default_rng(seed)
    np.random.seed(seed % 2**32)  # the buffer samples with NumPy's global generator
    driver = BufferDriver(n_agents, n_copies, capacity * n_copies, rng)
    added = 0  # per copy, since the last re-layout
    for operation in operations:
        if operation in ("step", "done", "truncated"):
            driver.add(done=operation != "step", truncated=operation == "truncated")
            added += 1
        elif operation == "jump":
            driver.env_reset_without_episode_end()
        elif operation == "sample" and added > 0:
            batch = driver.buffer.sample(7)
            assert batch.observations.shape == (7, n_agents, 3)
            upper = driver.buffer.buffer_size if driver.buffer.full else driver.buffer.pos
            slots = rng.integers(0, upper, size=5)
            driver.check(slots, rng.integers(0, driver.buffer.n_copies, size=5))
        elif operation == "save_load":
            file = io.BytesIO()
            pickle.dump(driver.buffer, file, protocol=pickle.HIGHEST_PROTOCOL)
            driver.buffer = pickle.loads(file.getvalue())
        elif operation == "relayout":
            before = len(driver.buffer.stored_transitions()[0])
            new_copies = int(rng.integers(1, 4))
            driver.buffer = driver.buffer.with_copies(new_copies, int(rng.integers(1, 12)) * new_copies)
            added = len(driver.buffer.stored_transitions()[0]) // new_copies
            assert added * new_copies <= before
            driver.env_reset_without_episode_end()
        driver.check_everything_stored(added)


@pytest.mark.parametrize("n_copies", [1, 2])
def test_buffer_driver_detects_a_wrong_next_observation(n_copies: int) -> None:
    """The fuzz test above can fail: a corrupted stored observation is caught."""
    driver = BufferDriver(2, n_copies, 8, np.random.default_rng(0))
    for _ in range(3):
        driver.add(done=False, truncated=False)
    driver.buffer.observations[1, 0, 0, 0] += 1000.0  # the successor of slot 0 in copy 0
    with pytest.raises(AssertionError):
        driver.check_everything_stored(3)
