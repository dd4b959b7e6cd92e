"""Parameter sharing inside groups of agents: shared weights, an agent's own first-layer bias, and the groups argument."""

import numpy as np
import pytest
import torch as th
from maddpg_test_envs import MixedSpacesEnv, TargetReachEnv

from sb3_maddpg import MADDPG, MATD3, make_multiagent_vec_env
from sb3_maddpg.common.groups import agent_groups
from sb3_maddpg.common.torch_layers import BatchedLinear, BatchedMlp


def test_shared_weights_by_hand():
    th.manual_seed(0)
    layer = BatchedLinear(3, 2, 2, shared_by=(0, 0, 1), own_bias=True)
    assert layer.weight.shape == (2, 2, 2) and layer.bias.shape == (3, 2)
    x = th.tensor([[[1.0, 2.0], [1.0, 2.0], [1.0, 2.0]]])  # (B=1, 3 models, 2)
    out = layer(x)
    with th.no_grad():
        for model, weight in enumerate((0, 0, 1)):
            expected = x[0, model] @ layer.weight[weight] + layer.bias[model]
            assert th.allclose(out[0, model], expected)
    # models 0 and 1 share the weight: their outputs differ by their biases only
    assert th.allclose(out[0, 0] - out[0, 1], (layer.bias[0] - layer.bias[1]).detach())
    # the shared weight's gradient is the sum of its models'
    out[0, 0].sum().backward(retain_graph=True)
    first = layer.weight.grad[0].clone()
    layer.weight.grad = None
    out[0, :2].sum().backward()
    assert th.allclose(layer.weight.grad[0], 2 * first) and th.all(layer.weight.grad[1] == 0)
    shared_bias = BatchedLinear(3, 2, 2, shared_by=(0, 0, 1), own_bias=False)
    assert shared_bias.bias.shape == (2, 2)
    with pytest.raises(ValueError, match="weight index 0, 1"):
        BatchedLinear(3, 2, 2, shared_by=(0, 2, 2))


def test_mlp_shares_every_layer_but_the_first_bias():
    mlp = BatchedMlp(4, 3, 2, [5], shared_by=(0, 1, 0, 1))
    first, last = mlp.net[0], mlp.net[-1]
    assert first.weight.shape[0] == 2 and first.bias.shape[0] == 4
    assert last.weight.shape[0] == 2 and last.bias.shape[0] == 2


def test_groups_argument_resolves_to_indices():
    names = ["adversary_0", "adversary_1", "agent_0", "agent_1", "leader"]
    assert agent_groups("teams", names, None) == (0, 0, 1, 1, 2)
    assert agent_groups([["agent_1", "adversary_0"]], names, None) == (0, 1, 2, 0, 3)
    assert agent_groups(None, names, None) is None
    with pytest.raises(ValueError, match="'nobody' is not an agent of this env"):
        agent_groups([["nobody"]], names, None)
    with pytest.raises(ValueError, match="'agent_0' is in more than one group"):
        agent_groups([["agent_0"], ["agent_0"]], names, None)
    with pytest.raises(TypeError, match="groups must be None"):
        agent_groups("all", names, None)


@pytest.mark.parametrize("algo", [MADDPG, MATD3])
def test_a_group_trains_one_actor_and_one_critic(algo, tmp_path):
    venv = make_multiagent_vec_env(TargetReachEnv, seed=0, env_kwargs=dict(n_agents=3))
    model = algo(
        "MlpPolicy",
        venv,
        groups=[["agent_0", "agent_1"]],
        buffer_size=300,
        learning_starts=20,
        batch_size=8,
        seed=0,
        policy_kwargs=dict(n_quantiles=3, net_arch=[16]),
    )
    n_critics = model.policy.n_critics
    assert model.policy.agent_groups == (0, 0, 1)
    assert model.actor.mu.net[0].weight.shape[0] == 2 and model.critic.quantile_nets.net[0].weight.shape[0] == 2 * n_critics
    before = [p.detach().clone() for p in model.actor.parameters()]
    model.learn(100)
    assert any(not th.equal(a, b) for a, b in zip(before, model.actor.parameters(), strict=True))
    model.save(tmp_path / "groups")
    loaded = algo.load(tmp_path / "groups", env=venv)
    obs = venv.reset()
    assert loaded.policy.agent_groups == (0, 0, 1)
    assert np.array_equal(loaded.predict(obs)[0], model.predict(obs)[0])


def test_teams_on_an_mpe2_task_with_agents_of_two_kinds():
    simple_tag = pytest.importorskip("mpe2.simple_tag_v3")
    venv = make_multiagent_vec_env(simple_tag.parallel_env, seed=0, env_kwargs=dict(max_cycles=10))
    model = MADDPG("MlpPolicy", venv, groups="teams", buffer_size=200, learning_starts=15, batch_size=8, seed=0)
    assert model.policy.agent_groups == (0, 0, 0, 1)  # three adversaries, one good agent
    model.learn(30)


def test_bad_groups_are_refused_where_they_enter():
    venv = make_multiagent_vec_env(TargetReachEnv, seed=0)
    with pytest.raises(TypeError, match="groups must be None"):
        MADDPG("MlpPolicy", venv, groups="everyone")
    with pytest.raises(ValueError, match="give groups or share_actor, not both"):
        MADDPG("MlpPolicy", venv, groups="teams", share_actor=True)
    with pytest.raises(ValueError, match="'agent_9' is not an agent"):
        MADDPG("MlpPolicy", venv, groups=[["agent_9"]])
    mixed = make_multiagent_vec_env(MixedSpacesEnv, seed=0)
    with pytest.raises(ValueError, match="share networks but not their spaces"):
        MADDPG("MlpPolicy", mixed, groups=[["mover", "slider"]])


def test_groups_from_the_command_line(tmp_path, monkeypatch):
    pytest.importorskip("mpe2")
    from sb3_maddpg.__main__ import main

    monkeypatch.chdir(tmp_path)
    args = ["train", "--algo", "maddpg", "--env", "simple_tag_discrete_v3", "-n", "60", "--seed", "0", "--eval-freq", "-1"]
    assert (
        main([*args, "--env-kwargs", "max_cycles:10", "-params", "learning_starts:30", "batch_size:8", "groups:'teams'"]) == 0
    )
    model = MADDPG.load(tmp_path / "logs" / "maddpg" / "simple_tag_discrete_v3_1" / "simple_tag_discrete_v3.zip")
    assert model.groups == "teams" and model.policy.agent_groups == (0, 0, 0, 1)
