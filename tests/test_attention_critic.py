"""The attention critic (``critic="attention"``) and the own-action diagnostic: by hand, invariances, and in training."""

import math
from pathlib import Path

import numpy as np
import pytest
import torch as th
from gymnasium import spaces
from maddpg_test_envs import CountingImageEnv, MixedSpacesEnv, TargetReachEnv
from stable_baselines3.common.logger import configure
from stable_baselines3.common.torch_layers import FlattenExtractor
from torch import nn

from sb3_maddpg import MADDPG, MATD3, make_multiagent_vec_env
from sb3_maddpg.common.diagnostics import N_RANDOM_CANDIDATES, own_action_candidates, own_action_value_range
from sb3_maddpg.maddpg import maddpg as maddpg_module
from sb3_maddpg.maddpg.critics import AttentionQuantileCritic, MultiAgentQuantileCritic


def vector_critic(n_agents: int, obs_dim: int = 1, action_dim: int = 1, critic_class=AttentionQuantileCritic, **kwargs):
    settings = dict(
        observation_space=spaces.Box(-10, 10, (obs_dim,)),
        action_space=spaces.Box(-1, 1, (action_dim,)),
        n_agents=n_agents,
        n_quantiles=3,
        net_arch=[8],
        activation_fn=nn.ReLU,
        features_extractor_class=FlattenExtractor,
        features_extractor_kwargs={},
        normalize_images=False,
    )
    settings.update(kwargs)
    return critic_class(**settings)


def set_weight(layer, model: int, weight: list[list[float]]) -> None:
    """Model ``model``'s weight (in, out) of a BatchedLinear, and a zero bias."""
    with th.no_grad():
        layer.weight[model] = th.tensor(weight)
        layer.bias.zero_()


def test_two_agents_by_hand():
    """
    Linear activations, E = 2, one head, one quantile, no hidden layer, F = A = 1. With two agents each critic's only
    teammate gets attention weight 1, so critic 0 is, by the weights below,
    Q_0 = [h, ctx] . (1, 1, 3, 0) with h = (f_0, 2 a_0) and ctx = e_1 = (f_1, a_1): Q_0 = f_0 + 2 a_0 + 3 f_1.
    """
    critic = vector_critic(2, n_quantiles=1, net_arch=[], activation_fn=nn.Identity, embed_dim=2, n_heads=1)
    for agent in (0, 1):
        set_weight(critic.own_path, agent, [[1, 0], [0, 2]])  # h = (f_i, 2 a_i)
        set_weight(critic.quantile_nets.first_layer, agent, [[1], [1], [3], [0]])
    set_weight(critic.teammate_embedding, 0, [[1, 0], [0, 1]])  # e_j = (f_j, a_j)
    set_weight(critic.value, 0, [[1, 0], [0, 1]])  # v_j = e_j
    features = th.tensor([[[0.5], [-1.0]]])  # (B=1, N=2, F=1)
    actions = th.tensor([[[0.2], [0.4]]])
    quantiles = critic.quantiles_from_features(features, actions)  # (1, 2, 1)
    assert quantiles[0, 0, 0].item() == pytest.approx(0.5 + 2 * 0.2 + 3 * -1.0)  # -2.1
    assert quantiles[0, 1, 0].item() == pytest.approx(-1.0 + 2 * 0.4 + 3 * 0.5)  # 1.3
    # agent 0's own action reaches its critic through its own path only: slope 2
    own = critic.quantiles_with_own_actions(features, actions, th.tensor([[[0.7], [0.4]]]))
    assert own[0, 0, 0].item() == pytest.approx(-2.1 + 2 * (0.7 - 0.2))
    assert own[0, 1, 0].item() == pytest.approx(1.3)  # agent 1's own action unchanged, agent 0's is not its input


def test_three_agents_attention_weights_by_hand():
    """
    Query W_q f_i = (f_i, 0), keys W_k e_j = (f_j, 0), values e_j = (f_j, a_j): critic i reads
    ctx_i = sum_{j != i} softmax_j(f_i f_j / sqrt 2) (f_j, a_j); with Q_i = ctx_i[1] (the weights on h are 0).
    """
    critic = vector_critic(3, n_quantiles=1, net_arch=[], activation_fn=nn.Identity, embed_dim=2, n_heads=1)
    for agent in range(3):
        set_weight(critic.own_path, agent, [[1, 0], [0, 1]])
        set_weight(critic.quantile_nets.first_layer, agent, [[0], [0], [0], [1]])
    set_weight(critic.teammate_embedding, 0, [[1, 0], [0, 1]])
    set_weight(critic.value, 0, [[1, 0], [0, 1]])
    set_weight(critic.query, 0, [[1, 0]])
    set_weight(critic.key, 0, [[1, 0], [0, 0]])
    f, a = [1.0, 2.0, -1.0], [0.3, -0.6, 0.9]
    quantiles = critic.quantiles_from_features(th.tensor([f]).unsqueeze(-1), th.tensor([a]).unsqueeze(-1))
    for i in range(3):
        others = [j for j in range(3) if j != i]
        scores = [f[i] * f[j] / math.sqrt(2) for j in others]
        weights = [math.exp(s) / sum(math.exp(t) for t in scores) for s in scores]
        expected = sum(w * a[j] for w, j in zip(weights, others, strict=True))
        assert quantiles[0, i, 0].item() == pytest.approx(expected, rel=1e-5)


@pytest.mark.parametrize(("n_critics", "mean_head"), [(1, False), (2, False), (2, True)])
def test_shapes_and_the_fast_own_action_form(n_critics, mean_head):
    th.manual_seed(0)
    critic = vector_critic(4, obs_dim=3, action_dim=2, n_critics=n_critics, mean_head=mean_head, embed_dim=8, n_heads=2)
    features, actions, own = th.randn(5, 4, 3), th.rand(5, 4, 2) * 2 - 1, th.rand(5, 4, 2) * 2 - 1
    assert critic.all_quantiles_from_features(features, actions).shape == (n_critics, 5, 4, 3)
    first = critic.quantiles_from_features(features, actions)
    assert first.shape == (5, 4, 3)
    assert th.allclose(first, critic.all_quantiles_from_features(features, actions)[0], atol=1e-6)
    # critic i on the joint action with agent i's action replaced, built explicitly: (B, N_critics, N, A)
    mixed = actions.unsqueeze(1).repeat(1, 4, 1, 1)
    for i in range(4):
        mixed[:, i, i] = own[:, i]
    fast = critic.quantiles_with_own_actions(features, actions, own)
    assert th.allclose(fast, critic.quantiles_from_features(features, mixed), atol=1e-6)


def test_exchanging_two_teammates_leaves_a_critic_unchanged():
    th.manual_seed(1)
    critic = vector_critic(5, obs_dim=3, action_dim=2, embed_dim=8, n_heads=2)
    features, actions = th.randn(6, 5, 3), th.rand(6, 5, 2) * 2 - 1
    swapped = [0, 3, 2, 1, 4]  # teammates 1 and 3 of agent 0 (and of agents 2 and 4) exchange places
    before = critic.quantiles_from_features(features, actions)
    after = critic.quantiles_from_features(features[:, swapped], actions[:, swapped])
    for agent in (0, 2, 4):
        assert th.allclose(before[:, agent], after[:, agent], atol=1e-6)
    assert not th.allclose(before[:, 1], after[:, 1], atol=1e-3)  # agent 1's critic now reads agent 3 as its own


def critic_parameters(critic) -> int:
    return sum(p.numel() for name, p in critic.named_parameters() if not name.startswith("features."))


def test_a_critics_size_does_not_grow_with_the_team():
    """Attention: parameters a N + b with the same a and b from N 2 to 8 (one critic: a + b). Joint: its input grows."""
    sizes = {n: critic_parameters(vector_critic(n, obs_dim=6, action_dim=2)) for n in (2, 3, 8)}
    per_agent = sizes[3] - sizes[2]
    assert sizes[8] - sizes[3] == 5 * per_agent and sizes[2] - 2 * per_agent == sizes[3] - 3 * per_agent > 0
    joint = {
        n: critic_parameters(vector_critic(n, obs_dim=6, action_dim=2, critic_class=MultiAgentQuantileCritic))
        for n in (2, 3, 8)
    }
    assert joint[8] - joint[3] > 5 * (joint[3] - joint[2])  # quadratic in N


def test_a_team_of_one_reads_no_teammates():
    critic = vector_critic(1, obs_dim=2, action_dim=2)
    quantiles = critic.quantiles_from_features(th.randn(4, 1, 2), th.zeros(4, 1, 2))
    assert quantiles.shape == (4, 1, 3) and th.isfinite(quantiles).all()


def small_model(algorithm=MADDPG, env_cls=TargetReachEnv, policy="MlpPolicy", env_kwargs=None, **kwargs):
    venv = make_multiagent_vec_env(env_cls, n_envs=1, seed=0, env_kwargs=env_kwargs or {})
    policy_kwargs = dict(n_quantiles=3, net_arch=[16], critic="attention", critic_kwargs=dict(embed_dim=8, n_heads=2))
    policy_kwargs.update(kwargs.pop("policy_kwargs", {}))
    settings = dict(buffer_size=500, learning_starts=20, batch_size=8, seed=0, policy_kwargs=policy_kwargs)
    settings.update(kwargs)
    return algorithm(policy, venv, **settings)


@pytest.mark.parametrize(
    ("algorithm", "env_cls", "policy", "kwargs"),
    [
        (MADDPG, TargetReachEnv, "MlpPolicy", {}),
        (MATD3, TargetReachEnv, "MlpPolicy", {}),
        (MADDPG, CountingImageEnv, "CnnPolicy", {}),  # images
        (MATD3, MixedSpacesEnv, "MlpPolicy", {}),  # padded spaces
        (MADDPG, TargetReachEnv, "MlpPolicy", dict(groups=[["agent_0", "agent_1"]])),
        (MADDPG, TargetReachEnv, "MlpPolicy", dict(policy_kwargs=dict(share_features_extractor=True))),
    ],
)
def test_trains_saves_and_loads_with_every_kind_of_team(algorithm, env_cls, policy, kwargs, tmp_path: Path):
    model = small_model(algorithm, env_cls, policy, **kwargs)
    assert isinstance(model.critic, AttentionQuantileCritic) and isinstance(model.critic_target, AttentionQuantileCritic)
    before = [p.detach().clone() for p in model.critic.parameters()]
    model.learn(80)
    assert any(not th.equal(a, b) for a, b in zip(before, model.critic.parameters(), strict=True))
    assert all(th.isfinite(p).all() for p in model.policy.parameters())
    model.save(tmp_path / "model")
    loaded = algorithm.load(tmp_path / "model", env=model.get_env())
    assert loaded.policy.critic_name == "attention" and loaded.policy.critic_design_kwargs == dict(embed_dim=8, n_heads=2)
    batch = model.replay_buffer.sample(8)
    loaded.policy.set_training_mode(False)
    model.policy.set_training_mode(False)
    assert th.equal(
        loaded.critic.all_quantiles(batch.observations, batch.actions),
        model.critic.all_quantiles(batch.observations, batch.actions),
    )
    obs = model.get_env().reset()
    assert np.array_equal(loaded.predict(obs, deterministic=True)[0], model.predict(obs, deterministic=True)[0])


def test_departing_agents_train_with_the_attention_critic():
    from test_departures import LeavingAgentEnv

    venv = make_multiagent_vec_env(LeavingAgentEnv, n_envs=1, seed=0, black_death=True)
    model = MADDPG("MlpPolicy", venv, buffer_size=300, learning_starts=20, batch_size=8, seed=0,
                   policy_kwargs=dict(n_quantiles=3, net_arch=[16], critic="attention"))  # fmt: skip
    model.learn(60)
    assert all(th.isfinite(p).all() for p in model.policy.parameters())


def test_an_exact_resume(tmp_path: Path):
    """Saved at an episode boundary of the UAV task (its random states travel with the model) and resumed."""
    from test_resume import ENV_KWARGS, tiny_env

    def model(env):
        return MADDPG("CnnPolicy", env, buffer_size=1000, learning_starts=50, batch_size=16, seed=0, train_freq=4,
                      policy_kwargs=dict(n_quantiles=4, net_arch=[16], critic="attention"))  # fmt: skip

    uninterrupted = model(tiny_env(start="random"))
    uninterrupted.learn(200)
    first = model(tiny_env(start="random"))
    first.learn(100)
    first.save(tmp_path / "model")
    first.save_replay_buffer(tmp_path / "buffer")
    resumed = MADDPG.load(tmp_path / "model", env=tiny_env(seed=123, start="random"))
    resumed.load_replay_buffer(tmp_path / "buffer")
    resumed.learn(100, reset_num_timesteps=False)
    assert ENV_KWARGS["max_cycles"] == 20 and resumed._n_updates == uninterrupted._n_updates > 0
    vector = th.nn.utils.parameters_to_vector
    assert th.equal(vector(resumed.policy.parameters()), vector(uninterrupted.policy.parameters()))


def test_bad_critic_choices_are_refused_where_the_policy_takes_them():
    venv = make_multiagent_vec_env(TargetReachEnv, seed=0)
    with pytest.raises(ValueError, match=r"critic must be one of \['attention', 'joint'\], got 'mixer'"):
        MADDPG("MlpPolicy", venv, policy_kwargs=dict(critic="mixer"))
    with pytest.raises(ValueError, match="critic='joint' takes the critic_kwargs \\[\\], got unknown keys \\['embed_dim'\\]"):
        MADDPG("MlpPolicy", venv, policy_kwargs=dict(critic_kwargs=dict(embed_dim=8)))
    with pytest.raises(ValueError, match="unknown keys \\['heads'\\]"):
        MADDPG("MlpPolicy", venv, policy_kwargs=dict(critic="attention", critic_kwargs=dict(heads=2)))
    with pytest.raises(ValueError, match=r"embed_dim \(10\) must be a multiple of n_heads \(4\)"):
        MADDPG("MlpPolicy", venv, policy_kwargs=dict(critic="attention", critic_kwargs=dict(embed_dim=10)))
    with pytest.raises(ValueError, match="n_heads"):
        MADDPG("MlpPolicy", venv, policy_kwargs=dict(critic="attention", critic_kwargs=dict(n_heads=0)))
    with pytest.raises(TypeError, match="critic_kwargs must be a dict or None, got list"):
        MADDPG("MlpPolicy", venv, policy_kwargs=dict(critic="attention", critic_kwargs=[8]))


class LinearOwnActionCritic:
    """A hand-made critic whose value is w_i * (agent i's first action entry), whatever the rest."""

    def __init__(self, weights: list[float]):
        self.weights = th.tensor(weights)

    def quantiles_with_own_actions(self, features, actions, own_actions):
        return (own_actions[..., 0] * self.weights).unsqueeze(-1).expand(-1, -1, 4)


def test_own_action_value_range_by_hand():
    critic = LinearOwnActionCritic([3.0, 0.0, -0.5])
    candidates = th.tensor([[-1.0, 5.0], [0.0, 5.0], [1.0, -5.0]])
    actions = th.rand(6, 3, 2)
    ranges = own_action_value_range(critic, th.zeros(6, 3, 1), actions, candidates)
    assert ranges.tolist() == pytest.approx([6.0, 0.0, 1.0])
    present = th.ones(6, 3)
    present[:, 2] = 0.0  # agent 2 has left in every row: nothing to average
    assert own_action_value_range(critic, th.zeros(6, 3, 1), actions, candidates, present).tolist() == pytest.approx([6, 0, 0])


def test_own_action_candidates_are_fixed_and_leave_the_random_state_alone():
    state = th.random.get_rng_state()
    box = own_action_candidates(2, discrete=False)
    assert th.equal(th.random.get_rng_state(), state)
    assert box.shape == (N_RANDOM_CANDIDATES + 1, 2) and th.equal(box[0], th.zeros(2)) and box.abs().max() <= 1.0
    assert th.equal(box, own_action_candidates(2, discrete=False))
    assert th.equal(own_action_candidates(3, discrete=True), th.eye(3))


@pytest.mark.parametrize("critic", ["joint", "attention"])
def test_the_own_action_range_is_logged_and_changes_no_weight(critic, tmp_path: Path, monkeypatch):
    def trained(interval: int):
        monkeypatch.setattr(maddpg_module, "OWN_ACTION_RANGE_INTERVAL", interval)
        model = small_model(policy_kwargs=dict(critic=critic, critic_kwargs=None))
        model.set_logger(configure(str(tmp_path / f"log_{interval}"), ["csv"]))
        model.learn(100)
        return model

    measured, unmeasured = trained(10), trained(10**9)
    vector = th.nn.utils.parameters_to_vector
    assert th.equal(vector(measured.policy.parameters()), vector(unmeasured.policy.parameters()))
    header = (tmp_path / "log_10" / "progress.csv").read_text().splitlines()[0].split(",")
    assert {"train/own_action_range_agent_0", "train/own_action_range_agent_1", "train/own_action_range"} <= set(header)
    assert "train/own_action_range" not in (tmp_path / f"log_{10**9}" / "progress.csv").read_text()
    batch = measured.replay_buffer.sample(16)
    ranges = measured.own_action_range(batch)
    assert ranges.shape == (2,) and bool((ranges > 0).all())
