"""The annealed risk level (cvar_alpha_anneal_steps): values by hand, the actor loss that uses it, saving and resuming."""

from pathlib import Path

import pytest
import torch as th
from maddpg_test_envs import TargetReachEnv
from stable_baselines3.common.logger import configure

from sb3_maddpg import MADDPG, MATD3, make_multiagent_vec_env
from sb3_maddpg.common.distributional import cvar


def small_model(algorithm=MADDPG, **kwargs):
    venv = make_multiagent_vec_env(TargetReachEnv, n_envs=1, seed=0)
    settings = dict(buffer_size=500, learning_starts=20, batch_size=8, seed=0, policy_kwargs=dict(n_quantiles=8))
    settings.update(kwargs)
    return algorithm("MlpPolicy", venv, **settings)


@pytest.mark.parametrize("algorithm", [MADDPG, MATD3])
def test_the_risk_level_by_hand(algorithm):
    model = small_model(algorithm, cvar_alpha=0.25, cvar_alpha_anneal_steps=1000)
    # alpha(t) = 1 + (0.25 - 1) t / 1000 until t = 1000, then 0.25
    for timesteps, alpha in [(0, 1.0), (200, 0.85), (500, 0.625), (999, 0.25075), (1000, 0.25), (5000, 0.25)]:
        model.num_timesteps = timesteps
        assert model.current_cvar_alpha() == pytest.approx(alpha)
    fixed = small_model(algorithm, cvar_alpha=0.25)
    fixed.num_timesteps = 0
    assert fixed.current_cvar_alpha() == 0.25


def test_the_actor_loss_reads_the_current_level():
    annealed = small_model(cvar_alpha=0.25, cvar_alpha_anneal_steps=1000)
    annealed.learn(60)
    batch = annealed.replay_buffer.sample(16)
    features = annealed.critic.encode(batch.observations).detach()
    policy_actions = annealed.actor(batch.observations)
    quantiles = annealed.critic.quantiles_with_own_actions(features, batch.actions, policy_actions)
    annealed.num_timesteps = 500  # alpha 0.625: the lowest ceil(0.625 * 8) = 5 of the 8 quantiles
    lowest_five = quantiles.sort(dim=-1).values[..., :5].mean(dim=-1).mean(dim=0)
    assert th.allclose(annealed.actor_loss(batch, features), -lowest_five, atol=1e-6)
    assert th.allclose(lowest_five, cvar(quantiles, 0.625).mean(dim=0))


def test_logged_saved_and_resumed_exactly(tmp_path: Path):
    from test_resume import tiny_env

    def model(env):
        settings = dict(buffer_size=1000, learning_starts=50, batch_size=16, seed=0, train_freq=4)
        policy_kwargs = dict(n_quantiles=4, net_arch=[16])
        return MADDPG("CnnPolicy", env, **settings, policy_kwargs=policy_kwargs, cvar_alpha=0.25, cvar_alpha_anneal_steps=150)

    uninterrupted = model(tiny_env(start="random"))
    uninterrupted.set_logger(configure(str(tmp_path / "log"), ["csv"]))
    uninterrupted.learn(200)
    first = model(tiny_env(start="random"))
    first.learn(100)  # saved halfway through the annealing (alpha 0.5)
    first.save(tmp_path / "model")
    first.save_replay_buffer(tmp_path / "buffer")
    resumed = MADDPG.load(tmp_path / "model", env=tiny_env(seed=123, start="random"))
    assert resumed.cvar_alpha_anneal_steps == 150 and resumed.current_cvar_alpha() == pytest.approx(0.5)
    resumed.load_replay_buffer(tmp_path / "buffer")
    resumed.learn(100, reset_num_timesteps=False)
    vector = th.nn.utils.parameters_to_vector
    assert th.equal(vector(resumed.policy.parameters()), vector(uninterrupted.policy.parameters()))
    logged = (tmp_path / "log" / "progress.csv").read_text().splitlines()
    column = logged[0].split(",").index("train/cvar_alpha")
    values = [float(row.split(",")[column]) for row in logged[1:] if row.split(",")[column]]
    assert values == sorted(values, reverse=True) and values[0] < 1.0 and values[-1] == 0.25


def test_bad_annealing_is_refused():
    with pytest.raises(ValueError, match="cvar_alpha_anneal_steps .* must be an integer >= 0, got -1"):
        small_model(cvar_alpha_anneal_steps=-1)
    with pytest.raises(ValueError, match="must be an integer >= 0, got 1.5"):
        small_model(cvar_alpha_anneal_steps=1.5)
    with pytest.raises(ValueError, match="a CUDA graph cannot follow"):
        small_model(cvar_alpha_anneal_steps=100, cuda_graph=True)
