"""The replay buffer stored on a torch device: the same transitions as the numpy buffer, sampled on the device."""

import pickle
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch as th
from gymnasium import spaces
from stable_baselines3.common.save_util import load_from_pkl, save_to_pkl
from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize
from test_buffers import ACT_SPACE, N_AGENTS, N_COPIES, OBS_SPACE, check_samples, decode_obs, fill

from sb3_maddpg.common.buffers import MultiAgentReplayBuffer
from sb3_maddpg.common.device_buffer import DeviceReplayBuffer, _select_rows

CUDA = pytest.mark.skipif(not th.cuda.is_available(), reason="needs CUDA")
DEVICES = ["cpu", pytest.param("cuda", marks=CUDA)]
DATA = Path(__file__).parent / "data"
FIELDS = ("observations", "actions", "next_observations", "dones", "rewards")


def concrete(device: th.device) -> th.device:
    """The device of tensors put on ``device`` (``cuda`` -> ``cuda:0``), as SB3's ``buffer.device`` may be ``cuda``."""
    return th.empty(0, device=device).device


class TwinDriver:
    """
    Feeds a numpy buffer and a device buffer the same adds: observations carry a unique id, episodes end by
    termination or truncation at random, and the env is sometimes reset without an episode end.
    """

    def __init__(
        self,
        obs_space: spaces.Box,
        n_agents: int,
        n_copies: int,
        capacity: int,
        storage_device: str = "cpu",
        handle_timeout_termination: bool = True,
        seed: int = 0,
    ) -> None:
        self.obs_space, self.n_agents, self.n_copies = obs_space, n_agents, n_copies
        self.rng = np.random.default_rng(seed)
        action_space = spaces.Box(-1.0, 1.0, (2,), np.float32)
        common = dict(n_envs=n_copies * n_agents, n_agents=n_agents, handle_timeout_termination=handle_timeout_termination)
        self.numpy = MultiAgentReplayBuffer(capacity, obs_space, action_space, device="cpu", **common)
        self.device = DeviceReplayBuffer(
            capacity, obs_space, action_space, device=storage_device, storage_device=storage_device, **common
        )
        self.next_id = 1
        self.obs = self._fresh()

    def _fresh(self) -> np.ndarray:
        """New observations for every row: the first element of agent a of copy c is a unique id, then a, c."""
        rows = self.n_copies * self.n_agents
        obs = np.zeros((rows, *self.obs_space.shape), self.obs_space.dtype)
        flat = obs.reshape(rows, -1)
        flat[:, 0] = (self.next_id + np.arange(rows) // self.n_agents) % 250
        flat[:, 1] = np.tile(np.arange(self.n_agents), self.n_copies)
        flat[:, 2] = np.repeat(np.arange(self.n_copies), self.n_agents)
        self.next_id += self.n_copies
        return obs

    def step(self, p_end: float = 0.25) -> None:
        rows = self.n_copies * self.n_agents
        next_obs = self._fresh()
        ended = self.rng.random(self.n_copies) < p_end
        truncated = ended & (self.rng.random(self.n_copies) < 0.5)
        next_obs.reshape(rows, -1)[np.repeat(ended, self.n_agents), 3] = 1  # mark terminal observations
        action = self.rng.uniform(-1, 1, (rows, 2)).astype(np.float32)
        reward = self.rng.normal(size=rows).astype(np.float32)
        done = np.repeat(ended, self.n_agents)
        infos = [{"TimeLimit.truncated": bool(t)} for t in np.repeat(truncated, self.n_agents)]
        for buffer in (self.numpy, self.device):
            buffer.add(self.obs, next_obs, action, reward, done, infos)
        # after an episode end the env resets that copy: its next observation is a new one
        fresh = self._fresh()
        self.obs = np.where(done.reshape(-1, *[1] * len(self.obs_space.shape)), fresh, next_obs)

    def reset_without_episode_end(self) -> None:
        """A new learn() call: the next observation is not the pending successor."""
        self.obs = self._fresh()

    def run(self, operations: list[str]) -> None:
        for operation in operations:
            if operation == "step":
                self.step()
            elif operation == "reset":
                self.reset_without_episode_end()


def on_host(indices) -> np.ndarray:
    """Indices as a NumPy array, wherever they are (``np.asarray`` cannot read a CUDA tensor)."""
    return indices.cpu().numpy() if isinstance(indices, th.Tensor) else np.asarray(indices)


def assert_same_samples(numpy_buffer: MultiAgentReplayBuffer, device_buffer: DeviceReplayBuffer, slots, copies) -> None:
    expected = numpy_buffer._get_samples(on_host(slots), copy_inds=on_host(copies))
    got = device_buffer._get_samples(slots, copy_inds=copies)
    for name, x, y in zip(FIELDS, expected, got, strict=True):
        assert y.device == concrete(device_buffer.device), name
        assert x.dtype == y.dtype and x.shape == y.shape, name
        assert th.equal(x, y.cpu()), name


def assert_same_state(numpy_buffer: MultiAgentReplayBuffer, device_buffer: DeviceReplayBuffer) -> None:
    """Same stored arrays, same kept next observations (same rows: the free list is run in the same order)."""
    assert (numpy_buffer.pos, numpy_buffer.full, numpy_buffer.size()) == (
        device_buffer.pos,
        device_buffer.full,
        device_buffer.size(),
    )
    for name in ("observations", "actions", "rewards", "dones", "timeouts", "next_obs_index", "pending_next_observations"):
        np.testing.assert_array_equal(getattr(numpy_buffer, name), getattr(device_buffer, name).cpu().numpy(), err_msg=name)
    live = numpy_buffer.next_obs_index[numpy_buffer.next_obs_index >= 0]
    np.testing.assert_array_equal(
        numpy_buffer.extra_next_observations[live],
        device_buffer.extra_next_observations[th.as_tensor(live, device=device_buffer.storage_device)].cpu().numpy(),
    )
    np.testing.assert_array_equal(numpy_buffer.next_obs_index, device_buffer._next_obs_index_host)
    assert numpy_buffer._free_extra == device_buffer._free_extra


def assert_all_stored_samples_equal(driver: TwinDriver) -> None:
    slots, copies = driver.numpy.stored_transitions()
    np.testing.assert_array_equal(np.concatenate(driver.device.stored_transitions()), np.concatenate((slots, copies)))
    if len(slots):
        assert_same_samples(driver.numpy, driver.device, slots, copies)
        # torch indices too, in another order
        order = np.random.default_rng(1).permutation(len(slots))
        as_tensor = th.as_tensor(slots[order], device=driver.device.storage_device)
        assert_same_samples(driver.numpy, driver.device, as_tensor, th.as_tensor(copies[order]))


OBS_SPACES = {
    "image": spaces.Box(0, 255, (3, 4, 4), np.uint8),
    "vector": spaces.Box(-np.inf, np.inf, (5,), np.float32),
}


@pytest.mark.parametrize("storage_device", DEVICES)
@pytest.mark.parametrize("obs", ["image", "vector"])
@pytest.mark.parametrize("n_agents,n_copies,slots", [(2, 3, 5), (1, 1, 4), (3, 2, 1)])
@pytest.mark.parametrize("handle_timeout_termination", [True, False])
def test_get_samples_match_the_numpy_buffer(storage_device, obs, n_agents, n_copies, slots, handle_timeout_termination):
    driver = TwinDriver(
        OBS_SPACES[obs], n_agents, n_copies, slots * n_copies, storage_device, handle_timeout_termination, seed=slots
    )
    rng = np.random.default_rng(7)
    # Long enough to wrap around several times, with resets between adds and episode ends of both kinds
    for _ in range(4 * slots + 6):
        driver.run(list(rng.choice(["step", "step", "step", "reset"], size=2)))
        assert_same_state(driver.numpy, driver.device)
        assert_all_stored_samples_equal(driver)
    assert driver.device.full and driver.numpy.extra_next_observations.shape[0] > 0
    # the newest slot and kept next observations were among the compared transitions
    assert (driver.device.next_obs_index >= 0).any()


def test_the_device_buffer_passes_the_numpy_buffer_checks():
    """The sampled transitions of test_buffers: true successors, terminal observations, truncations, wrap-around."""
    buffer = DeviceReplayBuffer(
        30, OBS_SPACE, ACT_SPACE, "cpu", n_envs=N_COPIES * N_AGENTS, n_agents=N_AGENTS, storage_device="cpu"
    )
    fill(buffer, 7)
    check_samples(buffer, 7)
    fill(buffer, 37)  # wraps around (10 slots)
    assert buffer.full
    check_samples(buffer, 37)


@pytest.mark.parametrize("storage_device", DEVICES)
def test_sample_shapes_dtypes_devices_and_reproducibility(storage_device):
    driver = TwinDriver(OBS_SPACES["image"], 2, 3, 30, storage_device)
    for _ in range(4):
        driver.step()
    buffer = driver.device
    th.manual_seed(5)
    batch = buffer.sample(500)
    assert batch.observations.shape == batch.next_observations.shape == (500, 2, 3, 4, 4)
    assert batch.observations.dtype == batch.next_observations.dtype == th.uint8
    assert batch.actions.shape == (500, 2, 2) and batch.actions.dtype == th.float32
    assert batch.rewards.shape == (500, 2) and batch.rewards.dtype == th.float32
    assert batch.dones.shape == (500, 1) and batch.dones.dtype == th.float32
    assert all(x.device == concrete(buffer.device) for x in batch)
    # only the 4 stored slots of all 3 copies: the ids of the first observations of those steps
    stored_ids = set(buffer.observations[:4, :, 0].reshape(-1, 4 * 4 * 3)[:, 0].tolist())
    sampled_ids = set(batch.observations[:, 0].reshape(500, -1)[:, 0].tolist())
    assert sampled_ids == stored_ids and len(stored_ids) == 12
    th.manual_seed(5)
    again = buffer.sample(500)
    for x, y in zip(batch, again, strict=True):
        assert th.equal(x, y)


@pytest.mark.parametrize("storage_device", DEVICES)
def test_uint8_images_stay_uint8(storage_device):
    buffer = DeviceReplayBuffer(
        30, OBS_SPACE, ACT_SPACE, storage_device, n_envs=N_COPIES * N_AGENTS, n_agents=N_AGENTS, storage_device=storage_device
    )
    fill(buffer, 12)
    for tensor in (buffer.observations, buffer.extra_next_observations, buffer.pending_next_observations):
        assert tensor.dtype == th.uint8 and tensor.device == buffer.storage_device
    batch = buffer.sample(64)
    assert batch.observations.dtype == batch.next_observations.dtype == th.uint8
    step, *_ = decode_obs(batch.observations.cpu().numpy())
    assert (step < 12).all()
    # the storage is what the parent counts, per slot
    numpy_buffer = MultiAgentReplayBuffer(30, OBS_SPACE, ACT_SPACE, "cpu", n_envs=N_COPIES * N_AGENTS, n_agents=N_AGENTS)
    assert buffer.nbytes_per_slot() == numpy_buffer.nbytes_per_slot()
    assert buffer.bytes_per_joint_transition() == numpy_buffer.bytes_per_joint_transition()
    assert buffer.nbytes_per_slot() * buffer.buffer_size == sum(
        getattr(buffer, name).nbytes for name in ("observations", "actions", "rewards", "dones", "timeouts", "next_obs_index")
    )


@pytest.mark.parametrize("storage_device", DEVICES)
def test_pickle_round_trip_keeps_everything(tmp_path, storage_device):
    driver = TwinDriver(OBS_SPACES["image"], 2, 3, 15, storage_device)
    driver.run(["step"] * 7 + ["reset"] + ["step"] * 4)
    save_to_pkl(tmp_path / "buffer.pkl", driver.device)
    loaded = load_from_pkl(tmp_path / "buffer.pkl")
    assert isinstance(loaded, DeviceReplayBuffer) and loaded.storage_device == driver.device.storage_device
    assert_same_state(driver.numpy, loaded)
    th.manual_seed(3)
    a = driver.device.sample(64)
    th.manual_seed(3)
    b = loaded.sample(64)
    for x, y in zip(a, b, strict=True):
        assert th.equal(x, y)
    # and it keeps working after loading, as the numpy twin does
    driver.device = loaded
    driver.run(["step"] * 9 + ["reset", "step"])
    assert_same_state(driver.numpy, driver.device)
    assert_all_stored_samples_equal(driver)


@pytest.mark.skipif(th.cuda.is_available(), reason="checks loading a CUDA buffer on a machine without CUDA")
def test_a_cuda_buffer_loads_on_the_cpu_without_cuda():
    driver = TwinDriver(OBS_SPACES["vector"], 2, 2, 8)
    driver.run(["step"] * 5)
    state = pickle.loads(pickle.dumps(driver.device)).__getstate__()
    state["storage_device"] = state["device"] = th.device("cuda", 0)  # as pickled on a GPU machine
    loaded = DeviceReplayBuffer.__new__(DeviceReplayBuffer)
    with pytest.warns(UserWarning, match="loading it on the CPU"):
        loaded.__setstate__(state)
    assert loaded.storage_device == loaded.device == th.device("cpu")
    assert_same_state(driver.numpy, loaded)
    loaded.sample(4)


@pytest.mark.parametrize("kind", ["numpy", "device"])
def test_a_buffer_pickled_with_the_previous_layout_loads_and_samples_as_before(kind):
    """
    ``tests/data/old_layout_<kind>_buffer.pickle`` were pickled by the code before the two storages shared one
    host-side index (commit fb832a8, where the NumPy buffer kept ``pending_next_observations`` and
    ``extra_next_observations`` as two arrays), from this driver's buffers after the same operations.
    """
    with open(DATA / f"old_layout_{kind}_buffer.pickle", "rb") as file:
        loaded = pickle.load(file)
    driver = TwinDriver(OBS_SPACES["vector"], 2, 2, 8, seed=0)
    driver.run(["step"] * 9 + ["reset"] + ["step"] * 3)
    twin = getattr(driver, kind)
    assert type(loaded) is type(twin)
    assert_same_state(*((loaded, driver.device) if kind == "numpy" else (driver.numpy, loaded)))
    batches = []
    for buffer in (twin, loaded):
        np.random.seed(3)
        th.manual_seed(3)
        batches.append(buffer.sample(32))
    for x, y in zip(*batches, strict=True):
        assert th.equal(x, y)
    # and it keeps working as its twin does
    setattr(driver, kind, loaded)
    driver.run(["step"] * 6 + ["reset", "step"])
    assert_same_state(driver.numpy, driver.device)
    assert_all_stored_samples_equal(driver)


@pytest.mark.parametrize("storage_device", DEVICES)
@pytest.mark.parametrize("n_copies,buffer_size", [(1, None), (2, 6), (4, 40)])
def test_with_copies_matches_the_numpy_buffer(storage_device, n_copies, buffer_size):
    driver = TwinDriver(OBS_SPACES["vector"], 2, 3, 15, storage_device)
    driver.run(["step"] * 8 + ["reset"] + ["step"] * 3)
    expected = driver.numpy.with_copies(n_copies, buffer_size)
    got = driver.device.with_copies(n_copies, buffer_size)
    assert isinstance(got, DeviceReplayBuffer) and got.storage_device == driver.device.storage_device
    assert (got.n_copies, got.buffer_size, got.pos, got.full) == (
        expected.n_copies,
        expected.buffer_size,
        expected.pos,
        expected.full,
    )
    slots, copies = expected.stored_transitions()
    assert_same_samples(expected, got, slots, copies)
    # the original is unchanged, and the new one keeps working
    assert_all_stored_samples_equal(driver)
    rows = n_copies * 2
    step = (np.zeros((rows, 5)), np.ones((rows, 5)), np.zeros((rows, 2)), np.zeros(rows), np.zeros(rows), [{}] * rows)
    for buffer in (expected, got):
        buffer.add(*step)
    assert_same_state(expected, got)


def test_to_numpy_buffer_and_from_buffer_round_trip():
    driver = TwinDriver(OBS_SPACES["image"], 2, 3, 15)
    driver.run(["step"] * 9 + ["reset"] + ["step"] * 2)
    as_numpy = driver.device.to_numpy_buffer()
    assert type(as_numpy) is MultiAgentReplayBuffer
    assert_same_state(as_numpy, driver.device)
    back = DeviceReplayBuffer.from_buffer(driver.numpy, storage_device="cpu")
    assert_same_state(driver.numpy, back)
    driver.device = back
    driver.run(["step"] * 6)
    assert_same_state(driver.numpy, driver.device)
    assert_all_stored_samples_equal(driver)


def test_reset_empties_the_buffer():
    driver = TwinDriver(OBS_SPACES["vector"], 2, 2, 8)
    driver.run(["step"] * 12)
    for buffer in (driver.numpy, driver.device):
        buffer.reset()
    assert driver.device.size() == 0 and len(driver.device.extra_next_observations) == 0
    with pytest.raises(ValueError, match="empty"):
        driver.device.sample(4)
    driver.run(["step"] * 3)
    assert driver.device.size() == 3
    assert_all_stored_samples_equal(driver)


@pytest.mark.parametrize("bad", ["gpu", "cuda:x", 3, None])
def test_bad_storage_device(bad):
    with pytest.raises(ValueError, match="storage_device must be 'cuda', 'cuda:N', 'cpu', 'auto'"):
        DeviceReplayBuffer(8, OBS_SPACES["vector"], ACT_SPACE, "cpu", n_envs=2, n_agents=2, storage_device=bad)


@pytest.mark.skipif(th.cuda.is_available(), reason="checks the message without CUDA")
@pytest.mark.parametrize("storage_device", ["cuda", th.device("cuda", 1)])
def test_cuda_storage_without_cuda(storage_device):
    with pytest.raises(ValueError, match="CUDA is not available.*storage_device='cpu'.*MultiAgentReplayBuffer"):
        DeviceReplayBuffer(8, OBS_SPACES["vector"], ACT_SPACE, "cpu", n_envs=2, n_agents=2, storage_device=storage_device)


def test_vec_normalize_is_rejected():
    buffer = DeviceReplayBuffer(8, OBS_SPACES["vector"], ACT_SPACE, "cpu", n_envs=2, n_agents=2, storage_device="cpu")
    buffer.add(np.zeros((2, 5)), np.ones((2, 5)), np.zeros((2, 2)), np.zeros(2), np.zeros(2), [{}, {}])
    env = VecNormalize(DummyVecEnv([lambda: gym.make("Pendulum-v1")]))
    with pytest.raises(ValueError, match="VecNormalize"):
        buffer.sample(4, env=env)
    with pytest.raises(ValueError, match="VecNormalize"):
        buffer._get_samples(np.zeros(2, int), env=env)
    env.close()


@CUDA
def test_sampling_on_cuda_does_not_synchronise():
    driver = TwinDriver(OBS_SPACES["image"], 2, 3, 30, "cuda")
    driver.run(["step"] * 14 + ["reset", "step"])
    buffer = driver.device
    th.cuda.synchronize()
    th.cuda.set_sync_debug_mode("error")  # any synchronising call raises
    try:
        batch = buffer.sample(256)
    finally:
        th.cuda.set_sync_debug_mode("default")
    assert batch.observations.is_cuda
    assert_all_stored_samples_equal(driver)


@pytest.mark.parametrize("storage_device", DEVICES)
@pytest.mark.parametrize(
    "dtype,shape", [(th.uint8, (3,)), (th.uint8, (2, 8)), (th.float32, (5,)), (th.float64, (2, 3)), (th.int16, (1,))]
)
def test_select_rows_is_where_over_rows(storage_device, dtype, shape):
    """The byte-view selection used for next observations moves exactly the bits torch.where moves."""
    generator = th.Generator().manual_seed(0)
    a, b = (th.randn((7, *shape), generator=generator).mul(100).to(dtype).to(storage_device) for _ in range(2))
    a[0].view(-1)[0] = float("nan") if dtype.is_floating_point else 1  # bit-exact, NaN included
    condition = th.tensor([1, 0, 1, 1, 0, 0, 1], dtype=th.bool, device=storage_device)
    selected = _select_rows(condition, a, b)
    expected = th.where(condition.view(-1, *[1] * len(shape)), a, b)
    assert selected.dtype == dtype and selected.shape == a.shape
    assert th.equal(selected.view(th.uint8), expected.view(th.uint8))
    assert _select_rows(condition[:0], a[:0], b[:0]).shape == (0, *shape)


# --- MADDPG with replay_buffer_kwargs=dict(storage_device=...) ---------------------------------------------------


def _maddpg(tmp_path=None, **kwargs):
    from maddpg_test_envs import TargetReachEnv

    from sb3_maddpg import MADDPG, make_multiagent_vec_env

    venv = make_multiagent_vec_env(TargetReachEnv, n_envs=2, seed=0, env_kwargs=dict(n_agents=2))
    return MADDPG("MlpPolicy", venv, buffer_size=200, learning_starts=10, batch_size=8, seed=0, device="cpu", **kwargs)


def test_maddpg_picks_the_device_buffer_and_learns_with_it():
    model = _maddpg(replay_buffer_kwargs=dict(storage_device="cpu"))
    assert isinstance(model.replay_buffer, DeviceReplayBuffer)
    before = [p.detach().clone() for p in model.critic.parameters()]
    model.learn(60)
    assert model.replay_buffer.size() == 30  # 60 timesteps over 2 copies
    assert any(not th.equal(a, b) for a, b in zip(before, model.critic.parameters(), strict=True))


def test_maddpg_replay_buffer_files_move_between_the_two_storages(tmp_path):
    device_model = _maddpg(replay_buffer_kwargs=dict(storage_device="cpu"))
    device_model.learn(40)
    device_model.save_replay_buffer(tmp_path / "device.pkl")
    numpy_model = _maddpg()
    numpy_model.load_replay_buffer(tmp_path / "device.pkl")
    assert type(numpy_model.replay_buffer) is MultiAgentReplayBuffer
    assert numpy_model.replay_buffer.size() == device_model.replay_buffer.size()
    numpy_model.save_replay_buffer(tmp_path / "numpy.pkl")
    again = _maddpg(replay_buffer_kwargs=dict(storage_device="cpu"))
    again.load_replay_buffer(tmp_path / "numpy.pkl")
    assert isinstance(again.replay_buffer, DeviceReplayBuffer)
    slots, copies = device_model.replay_buffer.stored_transitions()
    expected = device_model.replay_buffer._get_samples(slots, copy_inds=copies)
    for a, b in zip(expected, again.replay_buffer._get_samples(slots, copy_inds=copies), strict=True):
        assert th.equal(a, b)
    again.learn(20, reset_num_timesteps=False)


def test_maddpg_refuses_a_storage_device_it_cannot_use():
    with pytest.raises(ValueError, match="needs the DeviceReplayBuffer"):
        _maddpg(replay_buffer_class=MultiAgentReplayBuffer, replay_buffer_kwargs=dict(storage_device="cpu"))
    with pytest.raises(ValueError, match="storage_device must be"):
        _maddpg(replay_buffer_kwargs=dict(storage_device="not a device"))
    if not th.cuda.is_available():
        with pytest.raises(ValueError, match="CUDA is not available"):
            _maddpg(replay_buffer_kwargs=dict(storage_device="cuda"))
    else:
        with pytest.raises(ValueError, match="must be the model's device"):
            _maddpg(replay_buffer_kwargs=dict(storage_device="cuda"))


def test_maddpg_device_buffer_refuses_vec_normalize():
    from maddpg_test_envs import TargetReachEnv
    from stable_baselines3.common.vec_env import VecNormalize

    from sb3_maddpg import MADDPG, make_multiagent_vec_env

    venv = VecNormalize(make_multiagent_vec_env(TargetReachEnv, n_envs=1, seed=0, env_kwargs=dict(n_agents=2)))
    venv.n_agents = 2
    model = MADDPG("MlpPolicy", venv, buffer_size=100, replay_buffer_kwargs=dict(storage_device="cpu"), device="cpu")
    with pytest.raises(ValueError, match="VecNormalize"):
        model.learn(10)
