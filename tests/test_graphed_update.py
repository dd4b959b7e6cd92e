"""The update recorded as CUDA graphs (``cuda_graph=True``) computes the eager update; bf16 autocast; argument checks."""

import numpy as np
import pytest
import torch as th
from maddpg_test_envs import CountingImageEnv, DiscreteTargetReachEnv, TargetReachEnv

from sb3_maddpg import MADDPG, make_multiagent_vec_env
from sb3_maddpg.common.graphed_update import GraphedUpdate, make_capturable

needs_cuda = pytest.mark.skipif(not th.cuda.is_available(), reason="needs a CUDA device")

# Every kind of step: critic-only warm-up, critic + targets between delayed actor updates, full steps; target
# smoothing noise (random numbers inside the step) and gradient clipping
STEP_KINDS = dict(critic_warmup_steps=4, policy_delay=2, target_policy_noise=0.2, max_grad_norm=5.0, actor_reg=1e-3)


def make_model(policy: str, device: str = "cpu", discrete: bool = False, **kwargs) -> MADDPG:
    env_cls = (DiscreteTargetReachEnv if discrete else TargetReachEnv) if policy == "MlpPolicy" else CountingImageEnv
    venv = make_multiagent_vec_env(env_cls, n_envs=2, seed=0, env_kwargs=dict(n_agents=3))
    model = MADDPG(
        policy,
        venv,
        buffer_size=200,
        learning_starts=0,
        batch_size=16,
        seed=0,
        device=device,
        policy_kwargs=dict(n_quantiles=5, net_arch=[16, 16]),
        **STEP_KINDS,
        **kwargs,
    )
    model.learn(60)  # fills the buffer (and takes some eager updates) identically for every model built this way
    return model


def train_seeded(model: MADDPG, steps: int, seed: int = 1) -> None:
    """Updates with the same batches and the same random numbers for every model."""
    np.random.seed(seed)
    th.manual_seed(seed)
    model.train(gradient_steps=steps, batch_size=16)


def graphed_code_path(model: MADDPG) -> GraphedUpdate:
    """The graph's code path run without recording: static batch tensors, capturable optimizers."""
    return GraphedUpdate(model._gradient_step, [model.critic.optimizer, model.actor.optimizer], capture=False)


def assert_same_networks(a: MADDPG, b: MADDPG, atol: float) -> None:
    state_a, state_b = a.policy.state_dict(), b.policy.state_dict()
    assert state_a.keys() == state_b.keys()
    for key in state_a:
        assert th.allclose(state_a[key].float().cpu(), state_b[key].float().cpu(), atol=atol, rtol=1e-5), key


@pytest.mark.parametrize(("policy", "discrete"), [("MlpPolicy", False), ("CnnPolicy", False), ("MlpPolicy", True)])
def test_graph_code_path_computes_the_eager_update_on_cpu(policy, discrete):
    # discrete: Gumbel-softmax actors, whose Gumbel noise is drawn inside the step
    eager, graphed = make_model(policy, discrete=discrete), make_model(policy, discrete=discrete)
    assert_same_networks(eager, graphed, atol=0.0)
    # The graph's code path, run without recording: static batch tensors, capturable optimizers, tensor learning
    # rates. The eager model gets the same capturable optimizers, so any difference would come from the code path.
    graphed._graphed_update = graphed_code_path(graphed)
    make_capturable(eager.critic.optimizer)
    make_capturable(eager.actor.optimizer)
    assert isinstance(graphed.critic.optimizer.param_groups[0]["lr"], th.Tensor)
    train_seeded(eager, 12)
    train_seeded(graphed, 12)
    assert_same_networks(eager, graphed, atol=0.0)
    for key in ("train/critic_loss", "train/actor_loss", "train/actor_saturation", "train/q_mean_agent_0"):
        assert graphed.logger.name_to_value[key] == eager.logger.name_to_value[key]


def test_capturable_optimizers_take_the_default_optimizers_steps():
    default, capturable = make_model("MlpPolicy"), make_model("MlpPolicy")
    make_capturable(capturable.critic.optimizer)
    make_capturable(capturable.actor.optimizer)
    train_seeded(default, 12)
    train_seeded(capturable, 12)
    # Equal to rounding. (With CnnPolicy they drift apart where a gradient is pure rounding noise, the bias of a
    # convolution before BatchNorm, which Adam scales to a full step either way: that is why the code-path test
    # above compares with the same optimizers.)
    assert_same_networks(default, capturable, atol=1e-6)


def test_graph_code_path_follows_a_learning_rate_schedule():
    eager = make_model("MlpPolicy", learning_rate=lambda progress: 1e-3 * progress)
    graphed = make_model("MlpPolicy", learning_rate=lambda progress: 1e-3 * progress)
    graphed._graphed_update = graphed_code_path(graphed)
    lr_tensor = graphed.critic.optimizer.param_groups[0]["lr"]
    for progress in (0.8, 0.3):
        eager._current_progress_remaining = graphed._current_progress_remaining = progress
        train_seeded(eager, 4)
        train_seeded(graphed, 4)
        # the same tensor, written in place (a recorded step reads it), holding the schedule's value
        assert graphed.critic.optimizer.param_groups[0]["lr"] is lr_tensor
        assert lr_tensor.item() == pytest.approx(1e-3 * progress)
    assert_same_networks(eager, graphed, atol=1e-6)


def test_make_capturable_keeps_the_optimizer_state():
    model = make_model("MlpPolicy")
    optimizer = model.critic.optimizer
    steps = [state["step"].clone() for state in optimizer.state.values()]
    make_capturable(optimizer)
    group = optimizer.param_groups[0]
    assert group["capturable"] is True and isinstance(group["lr"], th.Tensor)
    assert [state["step"] for state in optimizer.state.values()] == steps


def test_cuda_graph_needs_cuda():
    venv = make_multiagent_vec_env(TargetReachEnv, n_envs=1, seed=0, env_kwargs=dict(n_agents=2))
    with pytest.raises(ValueError, match="needs device='cuda'"):
        MADDPG("MlpPolicy", venv, cuda_graph=True, device="cpu")
    with pytest.raises(TypeError, match="cuda_graph must be True or False"):
        MADDPG("MlpPolicy", venv, cuda_graph="yes", device="cpu")
    with pytest.raises(TypeError, match="bf16_autocast must be True or False"):
        MADDPG("MlpPolicy", venv, bf16_autocast=1, device="cpu")
    if not th.cuda.is_available():
        model = MADDPG("MlpPolicy", venv, device="cpu")
        with pytest.raises(ValueError, match="CUDA graphs need CUDA"):
            GraphedUpdate(model._gradient_step, [model.critic.optimizer], capture=True)


def test_bf16_autocast_trains_close_to_float32():
    full, mixed = make_model("CnnPolicy"), make_model("CnnPolicy")
    mixed.bf16_autocast = True  # from the same networks on
    mixed._n_updates = full._n_updates = 2 * STEP_KINDS["critic_warmup_steps"] + 1  # next: a full step
    train_seeded(full, 1)
    train_seeded(mixed, 1)
    # bfloat16 keeps 8 bits of mantissa: the same step's losses agree to about 1 %
    for key in ("train/critic_loss", "train/actor_loss"):
        assert mixed.logger.name_to_value[key] == pytest.approx(full.logger.name_to_value[key], rel=0.03, abs=1e-3)
    train_seeded(mixed, 10)
    for param in mixed.policy.parameters():
        assert param.dtype == th.float32 and th.isfinite(param).all()


@needs_cuda
@pytest.mark.parametrize("policy", ["MlpPolicy", "CnnPolicy"])
def test_cuda_graph_equals_eager_on_the_gpu(policy):
    eager = make_model(policy, device="cuda")
    graphed = make_model(policy, device="cuda", cuda_graph=True)
    assert graphed._graphed_update is not None
    # The graph model's optimizers were made capturable at construction, so its first 60 timesteps of updates ran
    # through the graphs too; compare from a common state: copy the eager networks and optimizer state into it
    graphed.policy.load_state_dict(eager.policy.state_dict())
    graphed.critic.optimizer.load_state_dict(eager.critic.optimizer.state_dict())
    graphed.actor.optimizer.load_state_dict(eager.actor.optimizer.state_dict())
    make_capturable(graphed.critic.optimizer)
    make_capturable(graphed.actor.optimizer)
    graphed._n_updates = eager._n_updates
    train_seeded(eager, 20)
    train_seeded(graphed, 20)
    assert graphed._graphed_update.n_graphs >= 2
    assert_same_networks(eager, graphed, atol=1e-5)
