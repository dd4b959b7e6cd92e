"""``mean_loss="squared"``: the critics fit the mean of their targets with TD3's squared error (hand-checked loss
values are in test_distributional.py); here, that a model uses it in its updates and keeps it through save/load."""

import pytest
import torch as th
from maddpg_test_envs import TargetReachEnv

from sb3_maddpg import MADDPG, make_multiagent_vec_env


@pytest.mark.parametrize("kwargs", [dict(policy_kwargs=dict(n_quantiles=1)), dict(mean_anchored_quantiles=True)])
def test_the_models_critic_loss_takes_the_squared_mean(kwargs):
    model = MADDPG(
        "MlpPolicy", make_multiagent_vec_env(TargetReachEnv), learning_starts=0, mean_loss="squared", seed=0, **kwargs
    )
    model.learn(64)
    batch = model.replay_buffer.sample(16)
    # Rewards raised by 10: every TD error is beyond the Huber threshold, where the squared loss is the larger
    batch = batch._replace(rewards=batch.rewards + 10.0)
    with th.no_grad():
        losses, quantiles, _ = model.critic_loss(batch)
    huber = MADDPG("MlpPolicy", make_multiagent_vec_env(TargetReachEnv), learning_starts=0, seed=0, **kwargs)
    huber.set_parameters(model.get_parameters())
    with th.no_grad():
        huber_losses, huber_quantiles, _ = huber.critic_loss(batch)
    assert th.equal(quantiles, huber_quantiles)
    # TD errors e of about 10: n e^2 / 4 (about 25 n) against the Huber term's n (|e| - 1/2) / 2 (about 5 n)
    assert (losses > 3 * huber_losses).all()


def test_mean_loss_survives_save_and_load(tmp_path):
    model = MADDPG(
        "MlpPolicy", make_multiagent_vec_env(TargetReachEnv), mean_loss="squared", policy_kwargs=dict(n_quantiles=1)
    )
    model.save(tmp_path / "model.zip")
    assert MADDPG.load(tmp_path / "model.zip").mean_loss == "squared"
