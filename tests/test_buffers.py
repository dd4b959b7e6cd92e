"""The joint replay buffer: layout, derived next observations, terminations vs truncations, uint8, pickling."""

import numpy as np
import pytest
import torch as th
from gymnasium import spaces
from stable_baselines3.common.save_util import load_from_pkl, save_to_pkl

from sb3_maddpg.common.buffers import MultiAgentReplayBuffer

N_COPIES, N_AGENTS, SIZE = 3, 2, 16
OBS_SPACE = spaces.Box(0, 255, (3, SIZE, SIZE), np.uint8)
ACT_SPACE = spaces.Box(0.0, 1.0, (2,), np.float32)


def encode_obs(step: int, copy: int, agent: int, terminal: bool) -> np.ndarray:
    """An observation that spells out (global step, copy, agent, terminal) in a few pixels."""
    obs = np.zeros((3, SIZE, SIZE), np.uint8)
    obs[0, 0, 0], obs[0, 0, 1] = step % 256, step // 256
    obs[1, 0, 0], obs[2, 0, 0], obs[0, 1, 0] = copy, agent, int(terminal)
    return obs


def decode_obs(obs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(..., 3, S, S) -> step, copy, agent, terminal arrays of shape (...)."""
    step = obs[..., 0, 0, 0].astype(int) + 256 * obs[..., 0, 0, 1].astype(int)
    return step, obs[..., 1, 0, 0].astype(int), obs[..., 2, 0, 0].astype(int), obs[..., 0, 1, 0].astype(int)


def fill(buffer: MultiAgentReplayBuffer, n_steps: int, episode_lengths=(3, 4, 5), truncate_copy: int = 1):
    """
    Feed the buffer as SB3's `_store_transition` does: rows in (copy, agent) order, next_obs rows holding the
    terminal observation where an episode ended. Copy c's episodes last episode_lengths[c] steps; those of copy
    `truncate_copy` end by truncation, the others by termination.
    """
    ep_step = np.zeros(N_COPIES, int)
    for t in range(n_steps):
        obs = np.stack([encode_obs(t, c, i, False) for c in range(N_COPIES) for i in range(N_AGENTS)])
        ep_step += 1
        done_copy = ep_step >= np.array(episode_lengths)
        next_obs = np.stack([encode_obs(t + 1, c, i, bool(done_copy[c])) for c in range(N_COPIES) for i in range(N_AGENTS)])
        actions = np.array([[t, 10 * c + i] for c in range(N_COPIES) for i in range(N_AGENTS)], np.float32)
        rewards = np.array([1000 * t + 10 * c + i for c in range(N_COPIES) for i in range(N_AGENTS)], np.float32)
        dones = np.repeat(done_copy, N_AGENTS)
        infos = [
            {"TimeLimit.truncated": bool(done_copy[c] and c == truncate_copy)}
            for c in range(N_COPIES)
            for _ in range(N_AGENTS)
        ]
        buffer.add(obs, next_obs, actions, rewards, dones, infos)
        ep_step[done_copy] = 0


def make_buffer(buffer_size: int = 30) -> MultiAgentReplayBuffer:
    return MultiAgentReplayBuffer(
        buffer_size, OBS_SPACE, ACT_SPACE, device="cpu", n_envs=N_COPIES * N_AGENTS, n_agents=N_AGENTS
    )


def check_samples(buffer: MultiAgentReplayBuffer, n_steps: int, episode_lengths=(3, 4, 5), truncate_copy: int = 1):
    data = buffer.sample(2000)
    obs, next_obs = data.observations.numpy(), data.next_observations.numpy()
    assert data.observations.dtype == th.uint8 and data.next_observations.dtype == th.uint8
    assert obs.shape == (2000, N_AGENTS, 3, SIZE, SIZE)
    assert data.actions.shape == (2000, N_AGENTS, 2) and data.rewards.shape == (2000, N_AGENTS)
    assert data.dones.shape == (2000, 1)
    step, copy, agent, terminal = decode_obs(obs)
    # every sampled joint transition holds all agents, in order, of one (step, copy)
    assert (agent == np.arange(N_AGENTS)).all()
    assert (step == step[:, :1]).all() and (copy == copy[:, :1]).all() and not terminal.any()
    t, c = step[:, 0], copy[:, 0]
    assert (t >= n_steps - buffer.buffer_size).all() and (t < n_steps).all()
    np.testing.assert_array_equal(data.actions.numpy()[..., 0], np.repeat(t[:, None], N_AGENTS, 1))
    np.testing.assert_array_equal(data.actions.numpy()[..., 1], 10 * c[:, None] + np.arange(N_AGENTS))
    np.testing.assert_array_equal(data.rewards.numpy(), 1000 * t[:, None] + 10 * c[:, None] + np.arange(N_AGENTS))
    # the next observation is the true successor: step t + 1 of the same copy, the terminal one at episode ends
    n_step, n_copy, n_agent, n_terminal = decode_obs(next_obs)
    assert (n_step == t[:, None] + 1).all() and (n_copy == c[:, None]).all() and (n_agent == np.arange(N_AGENTS)).all()
    lengths = np.array(episode_lengths)
    episode_end = (t + 1) % lengths[c] == 0
    np.testing.assert_array_equal(n_terminal[:, 0], episode_end.astype(int))
    # dones are terminations only: episode ends of the truncating copy are not terminal
    np.testing.assert_array_equal(data.dones.numpy()[:, 0], (episode_end & (c != truncate_copy)).astype(np.float32))
    # the newest step and wrapped-around slots were sampled too
    assert (t == n_steps - 1).any() and episode_end.any()
    return data


def test_layout_and_sampled_transitions_before_wrap():
    buffer = make_buffer(buffer_size=30)  # 10 slots of 3 copies
    assert buffer.buffer_size == 10
    assert buffer.observations.shape == (10, N_COPIES, N_AGENTS, 3, SIZE, SIZE)
    assert buffer.observations.dtype == np.uint8
    assert buffer.actions.shape == (10, N_COPIES, N_AGENTS, 2)
    assert buffer.rewards.shape == (10, N_COPIES, N_AGENTS)
    assert buffer.dones.shape == buffer.timeouts.shape == (10, N_COPIES)
    assert not hasattr(buffer, "next_observations")
    fill(buffer, 7)
    check_samples(buffer, 7)


def test_sampled_transitions_after_wrap_around():
    buffer = make_buffer(buffer_size=30)
    fill(buffer, 37)
    assert buffer.full
    check_samples(buffer, 37)
    # explicit next observations are kept only for the episode ends currently in the buffer
    live = (buffer.next_obs_index >= 0).sum()
    assert live == (buffer.dones > 0).sum()
    assert len(buffer.extra_next_observations) <= 2 * live + 8


def test_successor_kept_when_the_env_is_reset_without_an_episode_end():
    buffer = make_buffer(buffer_size=30)
    fill(buffer, 5)
    pending = buffer.pending_next_observations.copy()
    # The next add starts from a fresh reset (e.g. a new learn() call): its obs is not the previous next obs
    obs = np.stack([encode_obs(500, c, i, False) for c in range(N_COPIES) for i in range(N_AGENTS)])
    infos = [{} for _ in range(N_COPIES * N_AGENTS)]
    buffer.add(obs, obs, np.zeros((6, 2), np.float32), np.zeros(6, np.float32), np.zeros(6), infos)
    next_of_prev = buffer.next_observations_of(np.full(N_COPIES, 4), np.arange(N_COPIES))
    np.testing.assert_array_equal(next_of_prev, pending)


def test_timeouts_kept_apart_without_handle_timeout_termination():
    buffer = MultiAgentReplayBuffer(
        30, OBS_SPACE, ACT_SPACE, "cpu", n_envs=6, n_agents=N_AGENTS, handle_timeout_termination=False
    )
    fill(buffer, 12)
    data = buffer.sample(500)
    step, copy, *_ = decode_obs(data.observations.numpy()[:, 0])
    episode_end = (step + 1) % np.array([3, 4, 5])[copy] == 0
    np.testing.assert_array_equal(data.dones.numpy()[:, 0], episode_end.astype(np.float32))


def test_save_and_load_gives_the_same_samples(tmp_path):
    buffer = make_buffer(buffer_size=30)
    fill(buffer, 23)
    save_to_pkl(tmp_path / "buffer.pkl", buffer)
    loaded = load_from_pkl(tmp_path / "buffer.pkl")
    np.random.seed(3)
    a = buffer.sample(64)
    np.random.seed(3)
    b = loaded.sample(64)
    for x, y in zip(a, b, strict=True):
        assert th.equal(x, y)
    # and it keeps working after loading
    fill(loaded, 40)
    check_samples(loaded, 40)


def test_bytes_per_joint_transition_at_the_report_configuration():
    obs_space = spaces.Box(0, 255, (3, 80, 80), np.uint8)
    buffer = MultiAgentReplayBuffer(100, obs_space, ACT_SPACE, "cpu", n_envs=6, n_agents=6)
    per_transition = buffer.bytes_per_joint_transition()
    print(f"\nbytes per stored joint transition (6 agents, 3x80x80 uint8): {per_transition:.0f}")
    # 6 * 3 * 80 * 80 bytes of observations + actions, rewards and flags
    assert 6 * 3 * 80 * 80 <= per_transition <= 120_000


def test_rejects_rows_that_are_not_whole_joint_steps():
    with pytest.raises(ValueError, match="multiple of n_agents"):
        MultiAgentReplayBuffer(30, OBS_SPACE, ACT_SPACE, "cpu", n_envs=5, n_agents=2)
    with pytest.raises(TypeError, match="Box"):
        MultiAgentReplayBuffer(30, spaces.Discrete(3), ACT_SPACE, "cpu", n_envs=2, n_agents=2)
    # the action spaces are the algorithms' (sb3_maddpg.common.actions.check_action_space)
    with pytest.raises(TypeError, match=r"MultiAgentReplayBuffer accepts Box \(continuous\) and Discrete action spaces"):
        MultiAgentReplayBuffer(30, OBS_SPACE, spaces.MultiBinary(3), "cpu", n_envs=2, n_agents=2)


def test_like_from_buffer_and_to_numpy_buffer_build_independent_buffers():
    buffer = make_buffer(buffer_size=30)
    fill(buffer, 17)
    empty = MultiAgentReplayBuffer.like(buffer, n_copies=1, buffer_size=8)
    assert (type(empty), empty.n_copies, empty.buffer_size, empty.size()) == (MultiAgentReplayBuffer, 1, 8, 0)
    assert (empty.n_agents, empty.observation_space, empty.device) == (N_AGENTS, OBS_SPACE, buffer.device)
    for copy in (buffer.to_numpy_buffer(), MultiAgentReplayBuffer.from_buffer(buffer)):
        assert copy.observations is not buffer.observations and copy._free_extra == buffer._free_extra
        samples = []
        for source in (buffer, copy):
            np.random.seed(1)
            samples.append(source.sample(64))
        assert all(th.equal(x, y) for x, y in zip(*samples, strict=True))
        fill(copy, 40)  # the copy goes on alone
        check_samples(copy, 40)
    check_samples(buffer, 17)
