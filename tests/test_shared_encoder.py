"""share_features_extractor: the actors read the critics' encoders, trained by the critics' loss only.

What is checked: the actors own no encoder (parameters, state dict, soft update), the actors' outputs are the MLPs on
the critics' encodings, the critics' target is the target critics' encoding of o' fed to the target actors and the
target critics, no actor gradient reaches an encoder, and saving and loading keep the sharing and the actions.
"""

import numpy as np
import pytest
import torch as th
from maddpg_test_envs import CountingImageEnv
from test_matd3 import hand_batch

from sb3_maddpg import MADDPG, MATD3, make_multiagent_vec_env
from sb3_maddpg.common.distributional import quantile_huber_loss


def make_model(algorithm=MADDPG, share: bool = True, **policy_kwargs) -> MADDPG:
    venv = make_multiagent_vec_env(CountingImageEnv, n_envs=1, seed=0, env_kwargs=dict(n_agents=3))
    kwargs = dict(n_quantiles=5, net_arch=[16, 16], share_features_extractor=share, **policy_kwargs)
    return algorithm(
        "CnnPolicy",
        venv,
        buffer_size=200,
        learning_starts=0,
        batch_size=8,
        target_policy_noise=0.0,
        policy_kwargs=kwargs,
        seed=0,
        device="cpu",
    )


def test_actors_own_no_encoder_and_read_the_critics():
    model = make_model()
    assert model.actor.features is model.critic.features
    assert model.actor_target.features is model.critic_target.features
    encoder = {id(p) for p in model.critic.features.parameters()}
    assert encoder and not encoder & {id(p) for p in model.actor.parameters()}
    assert not any(key.startswith("features.") for key in model.actor.state_dict())
    # every tensor once in the fused soft update: no encoder weight updated twice
    assert len({id(p) for p in model._online_parameters}) == len(model._online_parameters)
    # the actors' MLPs take the critic's encoding (F features per agent) as input
    assert model.actor.mu.first_layer.in_features == model.critic.features.features_dim
    # without the flag each actor has its own encoder, as before
    unshared = make_model(share=False)
    assert unshared.actor.features is not unshared.critic.features
    assert any(key.startswith("features.") for key in unshared.actor.state_dict())


def test_actions_are_the_mlps_on_the_critics_encodings():
    model = make_model()
    model.policy.set_training_mode(False)
    batch = hand_batch(model)
    with th.no_grad():
        expected = th.tanh(model.actor.mu(model.critic.encode(batch.observations)))
        assert th.equal(model.actor(batch.observations), expected)
        # predict's row layout: row = copy * N + agent
        rows = batch.observations.flatten(0, 1)
        assert th.equal(model.policy._predict(rows), expected.flatten(0, 1))


@pytest.mark.parametrize("algorithm", [MADDPG, MATD3])
def test_critic_target_uses_one_target_encoding_of_the_next_observations(algorithm):
    model = make_model(algorithm)
    batch = hand_batch(model)
    loss, _, _ = model.critic_loss(batch)
    with th.no_grad():
        next_features = model.critic_target.encode(batch.next_observations)
        next_actions = th.tanh(model.actor_target.mu(next_features))
        next_quantiles = model.critic_target.all_quantiles_from_features(next_features, next_actions).min(dim=0).values
        target = batch.rewards.unsqueeze(-1) + (1 - batch.dones.unsqueeze(-1)) * model.gamma * next_quantiles
        all_quantiles = model.critic.all_quantiles(batch.observations, batch.actions)
        expected = sum(quantile_huber_loss(q, target).mean(dim=0) for q in all_quantiles)
    th.testing.assert_close(loss, expected)


def test_only_the_critics_loss_trains_the_encoders():
    model = make_model()
    batch = hand_batch(model)
    _, _, features = model.critic_loss(batch)
    encoder_before = [p.detach().clone() for p in model.critic.features.parameters()]
    actor_before = [p.detach().clone() for p in model.actor.parameters()]
    model.critic.optimizer.zero_grad(set_to_none=True)
    model.actor.optimizer.zero_grad(set_to_none=True)
    model.actor_loss(batch, features.detach(), model.actor.preactivations(batch.observations)).sum().backward()
    assert all(p.grad is None for p in model.critic.features.parameters())
    assert any(p.grad is not None and p.grad.abs().sum() > 0 for p in model.actor.parameters())
    # a whole gradient step moves both: the encoders through the critics' loss, the actors through theirs
    model._gradient_step(batch, update_actor=True, update_targets=False)
    assert any(not th.equal(a, b) for a, b in zip(encoder_before, model.critic.features.parameters(), strict=True))
    assert any(not th.equal(a, b) for a, b in zip(actor_before, model.actor.parameters(), strict=True))


def test_save_and_load_keep_the_sharing_and_the_actions(tmp_path):
    model = make_model()
    model.learn(40)
    model.save(tmp_path / "model.zip")
    loaded = MADDPG.load(tmp_path / "model.zip", env=model.get_env(), device="cpu")
    assert loaded.policy.share_features_extractor is True
    assert loaded.actor.features is loaded.critic.features
    assert loaded.actor_target.features is loaded.critic_target.features
    obs = model.get_env().reset()
    np.testing.assert_array_equal(model.predict(obs, deterministic=True)[0], loaded.predict(obs, deterministic=True)[0])


def test_share_features_extractor_must_be_a_bool():
    with pytest.raises(TypeError, match="share_features_extractor must be True or False, got 'yes'"):
        make_model(share="yes")
