"""What SB3 users rely on: learn with callbacks and progress bar, timestep counters, predict, save/load, seeding."""

import numpy as np
import pytest
import torch as th
from maddpg_test_envs import CountingImageEnv, TargetReachEnv
from stable_baselines3.common.callbacks import CheckpointCallback, EvalCallback
from stable_baselines3.common.evaluation import evaluate_policy
from stable_baselines3.common.logger import KVWriter, Logger

from sb3_maddpg import MADDPG, make_multiagent_vec_env
from sb3_maddpg.common.callbacks import JointStepProgressBarCallback

SMALL = dict(buffer_size=250, learning_starts=100, batch_size=16, policy_kwargs=dict(n_quantiles=5, net_arch=[16, 16]))


def vector_env(n_envs: int = 2, n_agents: int = 3, seed: int = 0):
    return make_multiagent_vec_env(TargetReachEnv, n_envs=n_envs, seed=seed, env_kwargs=dict(n_agents=n_agents))


def image_env(n_envs: int = 2, n_agents: int = 2, seed: int = 0):
    return make_multiagent_vec_env(CountingImageEnv, n_envs=n_envs, seed=seed, env_kwargs=dict(n_agents=n_agents))


class StepRecorder(KVWriter):
    def __init__(self):
        self.records = []

    def write(self, key_values, key_excluded, step=0):
        self.records.append((step, dict(key_values)))

    def close(self):
        pass


@pytest.mark.parametrize("n_envs", [1, 3])
def test_timestep_counters_agree(n_envs, monkeypatch):
    """num_timesteps, learning_starts, the progress bar and the logger's x-axis all count joint steps of one copy."""
    counted = {}

    def record_bar(self):
        counted["bar_n"], counted["bar_total"] = self.pbar.n, self.pbar.total
        self.pbar.close()

    monkeypatch.setattr(JointStepProgressBarCallback, "_on_training_end", record_bar)
    venv = vector_env(n_envs=n_envs, n_agents=2)
    model = MADDPG("MlpPolicy", venv, seed=0, **SMALL)
    recorder = StepRecorder()
    model.set_logger(Logger(folder=None, output_formats=[recorder]))
    model.learn(total_timesteps=200, progress_bar=True, log_interval=1)
    # learn(T) steps until num_timesteps >= T; each VecEnv step adds n_copies
    expected = -(-200 // n_envs) * n_envs
    assert model.num_timesteps == expected
    assert counted == {"bar_n": expected, "bar_total": 200}
    # updates start once num_timesteps > learning_starts: one per VecEnv step after that
    assert model._n_updates == expected // n_envs - 100 // n_envs
    # TensorBoard's x-axis is num_timesteps; episodes are joint episodes of 5 steps
    steps = [step for step, _ in recorder.records]
    assert steps and all(step % n_envs == 0 and 0 < step <= expected for step in steps)
    assert model._episode_num == (expected // n_envs // 5) * n_envs
    assert recorder.records[-1][1]["rollout/ep_len_mean"] == 5
    logged = set().union(*(values for _, values in recorder.records))
    for key in ("critic_loss_agent_0", "actor_loss_agent_1", "q_mean_agent_0", "cvar_agent_1", "noise_std"):
        assert f"train/{key}" in logged


def test_learn_with_eval_and_checkpoint_callbacks(tmp_path):
    venv, eval_env = image_env(n_envs=2), image_env(n_envs=1, seed=5)
    model = MADDPG("CnnPolicy", venv, seed=0, **SMALL)
    eval_cb = EvalCallback(eval_env, n_eval_episodes=2, eval_freq=50, log_path=str(tmp_path / "eval"), verbose=0)
    ckpt_cb = CheckpointCallback(save_freq=50, save_path=str(tmp_path / "ckpt"), save_replay_buffer=True)
    model.learn(200, callback=[eval_cb, ckpt_cb], progress_bar=True)
    # callbacks count VecEnv steps (as in SB3); each is n_copies = 2 timesteps
    evaluations = np.load(tmp_path / "eval" / "evaluations.npz")
    np.testing.assert_array_equal(evaluations["timesteps"], [100, 200])
    saved = sorted(p.name for p in (tmp_path / "ckpt").iterdir())
    assert "rl_model_100_steps.zip" in saved and "rl_model_200_steps.zip" in saved
    assert "rl_model_replay_buffer_200_steps.pkl" in saved
    mean, _ = evaluate_policy(model, eval_env, n_eval_episodes=2)
    assert np.isfinite(mean)


@pytest.mark.parametrize("share_actor", [False, True])
def test_predict_maps_rows_to_agents(share_actor):
    venv = vector_env(n_envs=2, n_agents=3)
    model = MADDPG("MlpPolicy", venv, seed=0, share_actor=share_actor, **SMALL)
    same = np.tile(np.array([0.2, -0.1, 0.5, 0.3], np.float32), (6, 1))
    actions, _ = model.predict(same, deterministic=True)
    assert actions.shape == (6, 2)
    assert venv.action_space.contains(actions[0])
    with th.no_grad():
        per_agent = model.actor(th.as_tensor(same[:3]).unsqueeze(0))[0].numpy()
    expected = model.policy.unscale_action(per_agent)
    for row in range(6):
        np.testing.assert_allclose(actions[row], expected[row % 3], atol=1e-6)
    if share_actor:
        np.testing.assert_allclose(actions[0], actions[1], atol=1e-6)
    else:
        assert not np.allclose(actions[0], actions[1])
    # actions lie in the action space, here [-1, 1]^2; a non-symmetric box is rescaled
    box_env = make_multiagent_vec_env(TargetReachEnv, n_envs=1, env_kwargs=dict(n_agents=3, action_low=0.0))
    box_model = MADDPG("MlpPolicy", box_env, seed=0, **SMALL)
    box_actions, _ = box_model.predict(box_env.reset(), deterministic=True)
    assert (box_actions >= 0).all() and (box_actions <= 1).all()


def test_save_load_identical_actions_and_no_buffer_without_env(tmp_path):
    venv = image_env(n_envs=2)
    model = MADDPG("CnnPolicy", venv, seed=0, **SMALL)
    model.learn(150)
    obs = venv.reset()
    before, _ = model.predict(obs, deterministic=True)
    model.save(tmp_path / "model.zip")

    loaded = MADDPG.load(tmp_path / "model.zip")
    # acting only: no replay buffer is allocated
    assert loaded.replay_buffer is None
    after, _ = loaded.predict(obs, deterministic=True)
    np.testing.assert_array_equal(before, after)
    assert loaded.n_agents == 2 and loaded.agent_names == ["agent_0", "agent_1"]
    for key, value in model.policy.state_dict().items():
        assert th.equal(value, loaded.policy.state_dict()[key]), key

    # with an env it trains on; the buffer is allocated then
    loaded = MADDPG.load(tmp_path / "model.zip", env=venv)
    loaded.learn(20, reset_num_timesteps=False)
    assert loaded.replay_buffer is not None and loaded.num_timesteps == 170
    # also with another number of copies
    loaded = MADDPG.load(tmp_path / "model.zip", env=image_env(n_envs=3))
    loaded.learn(30)
    assert loaded.n_copies == 3 and loaded.num_timesteps == 30
    # set_env after an env-less load works too
    acting = MADDPG.load(tmp_path / "model.zip")
    acting.set_env(venv)
    acting.learn(10)
    assert acting.replay_buffer is not None and acting.replay_buffer.pos > 0


def test_save_and_load_replay_buffer_then_continue(tmp_path):
    venv = vector_env(n_envs=2, n_agents=2)
    model = MADDPG("MlpPolicy", venv, seed=0, **SMALL)
    model.learn(180)
    model.save(tmp_path / "model.zip")
    model.save_replay_buffer(tmp_path / "buffer.pkl")
    pos = model.replay_buffer.pos

    resumed = MADDPG.load(tmp_path / "model.zip", env=vector_env(n_envs=2, n_agents=2, seed=1))
    resumed.load_replay_buffer(tmp_path / "buffer.pkl")
    assert resumed.replay_buffer.pos == pos
    np.testing.assert_array_equal(resumed.replay_buffer.observations, model.replay_buffer.observations)
    updates = resumed._n_updates
    resumed.learn(40, reset_num_timesteps=False)
    assert resumed._n_updates == updates + 20
    assert resumed.replay_buffer.pos == (pos + 20) % resumed.replay_buffer.buffer_size


@pytest.mark.parametrize("policy", ["MlpPolicy", "CnnPolicy"])
def test_same_seed_gives_identical_parameters(policy):
    def run():
        venv = vector_env(n_envs=2, n_agents=2) if policy == "MlpPolicy" else image_env(n_envs=2)
        model = MADDPG(policy, venv, seed=3, **SMALL)
        model.learn(160)
        return model.policy.state_dict()

    a, b = run(), run()
    for key in a:
        assert th.equal(a[key], b[key]), key


@pytest.mark.skipif(not th.cuda.is_available(), reason="needs a CUDA device")
def test_cuda_learn_and_predict():
    model = MADDPG("CnnPolicy", image_env(n_envs=2), device="cuda", seed=0, **SMALL)
    model.learn(150)
    assert next(model.policy.parameters()).is_cuda
    actions, _ = model.predict(model.env.reset(), deterministic=True)
    assert actions.shape == (4, 2)
