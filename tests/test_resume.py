"""Resuming a run: exact continuation, the command's -i, and replay buffers from another configuration."""

import os
from pathlib import Path

import numpy as np
import pytest
import torch as th

from sb3_maddpg import MADDPG, make_multiagent_vec_env
from sb3_maddpg.common.buffers import MultiAgentReplayBuffer
from sb3_maddpg.common.noise import current_noise_std
from sb3_maddpg_envs import uav_coverage_v0

ENV_KWARGS = dict(obs_size=16, max_cycles=20, n_uavs=2)


def tiny_env(n_envs: int = 1, seed: int = 0, **kwargs) -> object:
    return make_multiagent_vec_env(uav_coverage_v0.parallel_env, n_envs=n_envs, seed=seed, env_kwargs={**ENV_KWARGS, **kwargs})


def tiny_model(env, **kwargs) -> MADDPG:
    return MADDPG(
        "CnnPolicy",
        env,
        buffer_size=1000,
        learning_starts=50,
        batch_size=16,
        seed=0,
        device="cpu",
        policy_kwargs=dict(n_quantiles=4, net_arch=[16]),
        **kwargs,
    )


def parameters(model: MADDPG) -> th.Tensor:
    return th.nn.utils.parameters_to_vector(model.policy.parameters()).detach()


@pytest.mark.parametrize(("start", "half"), [("fixed", 400), ("random", 100)])
def test_save_load_continue_at_an_episode_boundary_equals_the_uninterrupted_run(start: str, half: int, tmp_path: Path) -> None:
    # `half` timesteps are whole episodes of 20 steps: the resumed run starts where the uninterrupted one did (a reset)
    uninterrupted = tiny_model(tiny_env(start=start), train_freq=4)
    uninterrupted.learn(2 * half)

    first = tiny_model(tiny_env(start=start), train_freq=4)
    first.learn(half)
    first.save(tmp_path / "model.zip")
    first.save_replay_buffer(tmp_path / "buffer.pkl")
    del first
    # a fresh process would do the same: new env (another seed: the saved states win), load, continue the counter
    resumed = MADDPG.load(tmp_path / "model.zip", env=tiny_env(seed=123, start=start), device="cpu")
    resumed.load_replay_buffer(tmp_path / "buffer.pkl")
    resumed.learn(half, reset_num_timesteps=False)

    assert resumed.num_timesteps == uninterrupted.num_timesteps == 2 * half
    assert resumed._n_updates == uninterrupted._n_updates > 0
    assert th.equal(parameters(resumed), parameters(uninterrupted))
    noise_std = current_noise_std(resumed.action_noise)
    assert noise_std == current_noise_std(uninterrupted.action_noise) and noise_std is not None and noise_std < 1.0


def test_without_the_saved_random_states_the_resumed_run_differs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The exactness above comes from the saved states: reseeding from the saved seed (SB3's load) is not enough."""
    import sb3_maddpg.common.saving as saving_module

    uninterrupted = tiny_model(tiny_env(), train_freq=4)
    uninterrupted.learn(200)
    first = tiny_model(tiny_env(), train_freq=4)
    first.learn(100)
    first.save(tmp_path / "model.zip")
    first.save_replay_buffer(tmp_path / "buffer.pkl")
    monkeypatch.setattr(saving_module, "restore_random_states", lambda model, states: None)
    resumed = MADDPG.load(tmp_path / "model.zip", env=tiny_env(), device="cpu")
    resumed.load_replay_buffer(tmp_path / "buffer.pkl")
    resumed.learn(100, reset_num_timesteps=False)
    assert not th.equal(parameters(resumed), parameters(uninterrupted))


def test_load_restores_the_random_states_saved_with_the_model(tmp_path: Path) -> None:
    model = tiny_model(tiny_env())
    model.learn(30)
    model.save(tmp_path / "model.zip")
    expected = (np.random.random(), th.rand(1).item(), model.action_space.sample())
    np.random.seed(99)
    MADDPG.load(tmp_path / "model.zip", device="cpu")
    loaded = MADDPG.load(tmp_path / "model.zip", device="cpu")
    assert (np.random.random(), th.rand(1).item()) == expected[:2]
    np.testing.assert_array_equal(loaded.action_space.sample(), expected[2])
    assert "_saved_random_states" not in loaded.__dict__ and "_saved_random_states" not in model.__dict__


# ---------------------------------------------------------------------------------------------------------------------
# The command: train --save-replay-buffer, then train -i model.zip continues
# ---------------------------------------------------------------------------------------------------------------------
def test_command_resume_continues_counter_noise_and_tensorboard(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    from sb3_maddpg.__main__ import main

    monkeypatch.chdir(tmp_path)
    config = Path(__file__).resolve().parent.parent / "zoo_configs" / "maddpg.yml"
    common = [
        "train",
        "--env",
        "uav_coverage_fast_v0",
        "-conf",
        str(config),
        "--env-kwargs",
        "obs_size:16",
        "max_cycles:20",
        "n_uavs:2",
        "-params",
        "learning_starts:60",
        "train_freq:10",
        "policy_kwargs:dict(n_quantiles=4, net_arch=[16])",
        "--seed",
        "0",
        "-n",
        "100",
        "-tb",
        "tb",
        "--eval-freq",
        "-1",
    ]
    assert main([*common, "--save-replay-buffer"]) == 0
    first = tmp_path / "logs" / "maddpg" / "uav_coverage_fast_v0_1"
    assert main([*common, "-i", str(first / "uav_coverage_fast_v0.zip")]) == 0
    resumed = MADDPG.load(tmp_path / "logs" / "maddpg" / "uav_coverage_fast_v0_2" / "uav_coverage_fast_v0.zip")
    assert resumed.num_timesteps == 200
    # the noise schedule went on from the saved run instead of starting again from the YAML's noise_std
    after_first = current_noise_std(MADDPG.load(first / "uav_coverage_fast_v0.zip").action_noise)
    assert after_first is not None and current_noise_std(resumed.action_noise) < after_first < 1.0
    # one TensorBoard run whose x-axis goes on past the first run's end
    runs = sorted(os.listdir(tmp_path / "tb" / "uav_coverage_fast_v0"))
    assert runs == ["MADDPG_1"]
    steps = set()
    for events in (tmp_path / "tb" / "uav_coverage_fast_v0" / "MADDPG_1").iterdir():
        accumulator = EventAccumulator(str(events))
        accumulator.Reload()
        steps |= {event.step for event in accumulator.Scalars("time/fps")}
    assert max(steps) > 100


# ---------------------------------------------------------------------------------------------------------------------
# Replay buffers from another configuration
# ---------------------------------------------------------------------------------------------------------------------
def _filled_buffer(n_copies: int, n_agents: int = 2, steps: int = 13, episode: int = 4, capacity: int = 1000):
    """A buffer whose observations encode (copy, step) so that every transition can be recognised."""
    from gymnasium import spaces

    obs_space = spaces.Box(0, 255, (3,), np.float32)
    act_space = spaces.Box(-1, 1, (2,), np.float32)
    buffer = MultiAgentReplayBuffer(
        capacity, obs_space, act_space, device="cpu", n_envs=n_copies * n_agents, n_agents=n_agents
    )
    transitions = {}
    for step in range(steps):
        obs = np.array([[copy, step, agent] for copy in range(n_copies) for agent in range(n_agents)], np.float32)
        done_now = (step + 1) % episode == 0
        next_obs = obs + np.array([0, 1, 0], np.float32)
        if done_now:
            next_obs[:, 0] += 100  # the terminal observation differs from the next episode's first one
        action = np.tile(np.array([[step / 20, -step / 20]], np.float32), (n_copies * n_agents, 1))
        reward = np.full(n_copies * n_agents, float(step), np.float32)
        done = np.full(n_copies * n_agents, done_now)
        infos = [{"TimeLimit.truncated": done_now} for _ in range(n_copies * n_agents)]
        buffer.add(obs, next_obs, action, reward, done, infos)
        for copy in range(n_copies):
            rows = slice(copy * n_agents, (copy + 1) * n_agents)
            transitions[(copy, step)] = (next_obs[rows], float(step), done_now)
    return buffer, transitions


def _all_samples(buffer: MultiAgentReplayBuffer) -> list:
    slots, copies = buffer.stored_transitions()
    data = buffer._get_samples(slots, copy_inds=copies)
    return list(zip(data.observations.numpy(), data.next_observations.numpy(), data.rewards.numpy(), strict=True))


@pytest.mark.parametrize(("old_copies", "new_copies"), [(2, 1), (1, 3), (2, 4), (3, 2)])
def test_replay_buffer_laid_out_for_another_number_of_copies_keeps_every_transition(old_copies, new_copies) -> None:
    buffer, transitions = _filled_buffer(old_copies)
    relaid = buffer.with_copies(new_copies)
    samples = _all_samples(relaid)
    total = len(transitions)
    assert len(samples) == total - total % new_copies
    seen = set()
    for obs, next_obs, reward in samples:
        copy, step = int(obs[0, 0]), int(obs[0, 1])
        expected_next, expected_reward, _ = transitions[(copy, step)]
        np.testing.assert_array_equal(next_obs, expected_next)
        assert reward[0] == expected_reward
        seen.add((copy, step))
    assert len(seen) == len(samples)
    # the newest transitions are kept
    assert {(c, 12) for c in range(old_copies)} <= seen


def _model_with_buffer(env, tmp_path: Path, name: str) -> Path:
    model = tiny_model(env)
    model.learn(60)
    path = tmp_path / f"{name}.pkl"
    model.save_replay_buffer(path)
    return path


def test_replay_buffer_of_another_team_or_observation_is_refused_naming_both_shapes(tmp_path: Path) -> None:
    three_uavs = _model_with_buffer(tiny_env(n_uavs=3), tmp_path, "three")
    model = tiny_model(tiny_env())
    with pytest.raises(ValueError, match=r"3 agents with observations \(3, 16, 16\).*model has 2 agents"):
        model.load_replay_buffer(three_uavs)
    bigger = _model_with_buffer(tiny_env(obs_size=32), tmp_path, "bigger")
    with pytest.raises(ValueError, match=r"observations \(3, 32, 32\).*observations \(3, 16, 16\)"):
        model.load_replay_buffer(bigger)
    assert model.replay_buffer is not None and model.replay_buffer.obs_shape == (3, 16, 16)  # the model's kept


def test_replay_buffer_from_another_number_of_copies_is_laid_out_and_training_goes_on(tmp_path: Path) -> None:
    two_copies = _model_with_buffer(tiny_env(n_envs=2), tmp_path, "two")
    model = tiny_model(tiny_env(n_envs=1))
    model.load_replay_buffer(two_copies)
    assert model.replay_buffer is not None and model.replay_buffer.n_copies == 1
    assert model.replay_buffer.pos == 60  # 60 timesteps = 30 VecEnv steps of 2 copies: 60 joint transitions
    model.learn(40, reset_num_timesteps=False)  # was: cannot reshape array of size ... into shape (1, ...)


def test_a_file_that_is_not_a_replay_buffer_is_refused(tmp_path: Path) -> None:
    import pickle

    model = tiny_model(tiny_env())
    (tmp_path / "list.pkl").write_bytes(pickle.dumps([1, 2, 3]))
    with pytest.raises(TypeError, match="holds a list, not a MultiAgentReplayBuffer"):
        model.load_replay_buffer(tmp_path / "list.pkl")
    (tmp_path / "broken.pkl").write_bytes(b"\x80\x05garbage")
    with pytest.raises(ValueError, match="broken.pkl is not a replay buffer that can be read here, or is damaged"):
        model.load_replay_buffer(tmp_path / "broken.pkl")


@pytest.mark.parametrize(
    ("damage", "message"),
    [
        (
            lambda buffer: setattr(buffer, "pos", buffer.buffer_size + 5),
            r"is damaged: its position pos=1005 is outside its 1000 slots",
        ),
        (
            lambda buffer: setattr(buffer, "rewards", buffer.rewards[:-1]),
            r"is damaged: its rewards has shape \(999, 1, 2\), but 1000 slots",
        ),
        (lambda buffer: setattr(buffer, "dones", buffer.dones[:, :0]), r"is damaged: its dones has shape \(1000, 0\)"),
        (lambda buffer: buffer.rewards.__setitem__((3, 0, 1), np.nan), r"NaN or infinite rewards \(the first at slot 3\)"),
        (lambda buffer: buffer.actions.__setitem__((4, 0, 0, 1), np.inf), r"NaN or infinite actions \(the first at slot 4\)"),
        (lambda buffer: buffer._next_obs_index_host.__setitem__((2, 0), 10**6), "index points outside its"),
    ],
    ids=["pos", "rewards_length", "dones_copies", "nan_reward", "inf_action", "next_obs_index"],
)
def test_a_damaged_replay_buffer_is_refused_at_load(damage, message, tmp_path: Path) -> None:
    import pickle

    saved = _model_with_buffer(tiny_env(), tmp_path, "saved")
    buffer = pickle.loads(saved.read_bytes())
    damage(buffer)
    (tmp_path / "damaged.pkl").write_bytes(pickle.dumps(buffer))
    model = tiny_model(tiny_env())
    with pytest.raises(ValueError, match=f"the replay buffer .*damaged.pkl .*{message}"):
        model.load_replay_buffer(tmp_path / "damaged.pkl")
    model.load_replay_buffer(saved)  # the undamaged buffer loads
    assert model.replay_buffer is not None and model.replay_buffer.pos == 60
