"""The stabilisers that keep deterministic actors out of saturation while the critics learn, the saturation
statistics in the logs, the encoder options of ReportCNN and the noise schedule in timesteps."""

import numpy as np
import pytest
import torch as th
from gymnasium import spaces
from maddpg_test_envs import TargetReachEnv
from test_maddpg_update import hand_batch, make_model

from sb3_maddpg import MADDPG, make_multiagent_vec_env
from sb3_maddpg.common.noise import DecayingGaussianNoise
from sb3_maddpg.common.torch_layers import ReportCNN


def parameters_of(module: th.nn.Module) -> list[th.Tensor]:
    return [p.detach().clone() for p in module.parameters()]


def changed(before: list[th.Tensor], module: th.nn.Module) -> bool:
    return any(not th.equal(a, b) for a, b in zip(before, module.parameters(), strict=True))


def filled_model(**kwargs) -> MADDPG:
    model = make_model("MlpPolicy", n_agents=2, **kwargs)
    model.learn(30)  # learning_starts=0: the buffer holds 30 joint transitions, the model has trained
    return model


def test_critic_warmup_updates_only_the_critics_first():
    model = filled_model(critic_warmup_steps=5)
    model._n_updates = 0
    model.logger.name_to_value.clear()
    actor, critic = parameters_of(model.actor), parameters_of(model.critic)
    model.train(gradient_steps=5, batch_size=8)
    assert not changed(actor, model.actor) and changed(critic, model.critic)
    assert "train/actor_loss" not in model.logger.name_to_value
    model.train(gradient_steps=1, batch_size=8)  # update 6: the actors start
    assert changed(actor, model.actor)
    assert "train/actor_loss" in model.logger.name_to_value


def test_policy_delay_updates_actors_and_targets_every_d_steps():
    model = filled_model(policy_delay=3)
    model._n_updates = 0
    actor, actor_target, critic_target = (parameters_of(m) for m in (model.actor, model.actor_target, model.critic_target))
    model.train(gradient_steps=2, batch_size=8)  # updates 1, 2: critics only
    assert not changed(actor, model.actor) and not changed(actor_target, model.actor_target)
    assert not changed(critic_target, model.critic_target)
    model.train(gradient_steps=1, batch_size=8)  # update 3
    assert changed(actor, model.actor) and changed(actor_target, model.actor_target)
    assert changed(critic_target, model.critic_target)


def test_separate_actor_learning_rate():
    model = filled_model(learning_rate=1e-3, actor_learning_rate=2e-4)
    assert model.critic.optimizer.param_groups[0]["lr"] == pytest.approx(1e-3)
    assert model.actor.optimizer.param_groups[0]["lr"] == pytest.approx(2e-4)
    assert model.logger.name_to_value["train/actor_learning_rate"] == pytest.approx(2e-4)
    # A schedule of the progress remaining works as for learning_rate
    model = filled_model(actor_learning_rate=lambda progress: 1e-4 * (0.5 + progress))
    lr = model.actor.optimizer.param_groups[0]["lr"]
    assert lr == pytest.approx(model.logger.name_to_value["train/actor_learning_rate"])
    assert 0.5e-4 <= lr < 1.5e-4  # the schedule at the last update's progress, not its start
    assert model.critic.optimizer.param_groups[0]["lr"] == pytest.approx(1e-3)


def test_max_grad_norm_bounds_each_step():
    # With Adam the first step moves every parameter by about lr whatever the gradient's size, so compare plain SGD:
    # the clipped step is exactly lr * max_grad_norm long.
    venv = make_multiagent_vec_env(TargetReachEnv, n_envs=1, seed=0, env_kwargs=dict(n_agents=2))
    model = MADDPG(
        "MlpPolicy",
        venv,
        learning_starts=0,
        batch_size=8,
        seed=0,
        max_grad_norm=1e-3,
        learning_rate=1.0,
        policy_kwargs=dict(optimizer_class=th.optim.SGD, net_arch=[16, 16], n_quantiles=5),
    )
    model.learn(30)
    critic = parameters_of(model.critic)
    model.train(gradient_steps=1, batch_size=8)
    step = th.sqrt(sum(((a - b) ** 2).sum() for a, b in zip(critic, model.critic.parameters(), strict=True)))
    assert step.item() == pytest.approx(1e-3, rel=1e-3)


def test_target_policy_smoothing_changes_the_targets_only_when_on():
    batch = hand_batch(filled_model())
    plain = filled_model()
    with th.no_grad():
        assert th.equal(plain.critic_loss(batch)[0], plain.critic_loss(batch)[0])
    smoothed = filled_model(target_policy_noise=0.3, target_noise_clip=0.1)
    th.manual_seed(0)
    first = smoothed.critic_loss(batch)[0]
    second = smoothed.critic_loss(batch)[0]
    assert not th.equal(first, second)  # a new noise sample each time
    smoothed.target_policy_noise = 0.0
    assert th.equal(smoothed.critic_loss(batch)[0], smoothed.critic_loss(batch)[0])


def test_saturation_statistics_are_logged_per_agent():
    model = filled_model()
    batch_obs = th.as_tensor(model.replay_buffer.sample(8).observations)
    # Push actor 0 into saturation: a huge output bias
    with th.no_grad():
        model.actor.mu.net[-1].bias[0].fill_(50.0)
    model.train(gradient_steps=1, batch_size=8)
    logged = model.logger.name_to_value
    assert logged["train/actor_saturation_agent_0"] == pytest.approx(1.0)
    assert logged["train/actor_saturation_agent_1"] < 1.0
    assert logged["train/actor_preactivation_agent_0"] > 40.0
    pre = model.actor.preactivations(batch_obs)
    assert logged["train/actor_saturation"] == pytest.approx(
        (logged["train/actor_saturation_agent_0"] + logged["train/actor_saturation_agent_1"]) / 2
    )
    assert pre.shape == (8, 2, 2)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(policy_delay=0), "policy_delay"),
        (dict(policy_delay=1.5), "policy_delay"),
        (dict(critic_warmup_steps=-1), "critic_warmup_steps"),
        (dict(max_grad_norm=0.0), "max_grad_norm"),
        (dict(max_grad_norm=float("inf")), "max_grad_norm"),
        (dict(target_policy_noise=-0.1), "target_policy_noise"),
        (dict(target_noise_clip=float("nan")), "target_noise_clip"),
        (dict(actor_learning_rate=0.0), "actor_learning_rate"),
        (dict(actor_learning_rate="fast"), "actor_learning_rate"),
    ],
)
def test_stabiliser_arguments_are_validated(kwargs, match):
    venv = make_multiagent_vec_env(TargetReachEnv, n_envs=1, seed=0, env_kwargs=dict(n_agents=2))
    with pytest.raises(ValueError, match=match):
        MADDPG("MlpPolicy", venv, **kwargs)


# ---------------------------------------------------------------------------------------------------------------------
# ReportCNN: padding and coordinate channels
# ---------------------------------------------------------------------------------------------------------------------
def unread_cells(cnn: ReportCNN, size: int) -> int:
    """Number of pixels of a (3, size, size) image whose change leaves the encoder's output unchanged."""
    cnn.eval()
    base = th.zeros(1, 3, size, size)
    with th.no_grad():
        reference = cnn(base)
        unread = 0
        for row in range(size):
            for col in range(size):
                image = base.clone()
                image[0, :, row, col] = 1.0
                unread += int(th.equal(cnn(image), reference))
    return unread


def test_padding_one_reads_every_cell_of_the_map():
    space = spaces.Box(0, 255, (3, 16, 16), np.uint8)
    th.manual_seed(0)
    # Without padding, the last row and column are never read: 31 of the 256 cells
    assert unread_cells(ReportCNN(space), 16) == 31
    assert unread_cells(ReportCNN(space, padding=1), 16) == 0
    assert unread_cells(ReportCNN(space, padding=1, coord_channels=True), 16) == 0
    assert ReportCNN(space, padding=1).features_dim == 64 * 2 * 2


def test_coord_channels_tell_positions_apart_for_a_stacked_encoder():
    space = spaces.Box(0, 255, (3, 16, 16), np.uint8)
    th.manual_seed(0)
    cnn = ReportCNN(space, n_agents=2, padding=1, coord_channels=True)
    assert cnn.cnn[0].in_channels == 2 * 5
    out = cnn(th.zeros(4, 2, 3, 16, 16))
    assert out.shape == (4, 2, cnn.features_dim)
    # The coordinate channels are constants, not parameters
    assert all("coords" not in name for name, _ in cnn.named_parameters())
    assert "coords" not in cnn.state_dict()


def test_position_channel_appends_the_marked_cells_centre_and_maximum():
    space = spaces.Box(0, 255, (3, 16, 16), np.uint8)
    th.manual_seed(0)
    cnn = ReportCNN(space, n_agents=2, padding=1, coord_channels=True, position_channel=1)
    assert cnn.features_dim == 64 * 2 * 2 + 3
    images = th.zeros(2, 2, 3, 16, 16)
    images[:, 0, 1, 3, 5] = 0.8  # agent 0's cell: row 3, column 5 -> (5 / 15, 3 / 15), level 0.8
    images[0, 1, 1, 15, 0] = images[0, 1, 1, 15, 1] = 0.5  # two marked pixels: their mean column 0.5 / 15, row 1
    out = cnn(images)  # batch row 1, agent 1: an empty channel gives 0, not 0 / 0
    expected = th.tensor([[[5 / 15, 3 / 15, 0.8], [0.5 / 15, 1.0, 0.5]], [[5 / 15, 3 / 15, 0.8], [0.0, 0.0, 0.0]]])
    assert th.allclose(out[..., -3:], expected, atol=1e-6)
    # The same numbers with one encoder on 4-D input, and the gradient reaches the convolutions as before
    single = ReportCNN(space, padding=1, position_channel=1)
    assert th.allclose(single(images[:, 0])[:, -3:], expected[:, 0], atol=1e-6)
    single(images[:, 0]).sum().backward()
    assert single.cnn[0].weight.grad is not None


@pytest.mark.parametrize(
    "kwargs",
    [dict(padding=2), dict(padding=True), dict(coord_channels=1), dict(position_channel=3), dict(position_channel=True)],
)
def test_report_cnn_options_are_validated(kwargs):
    with pytest.raises((ValueError, TypeError), match=next(iter(kwargs))):
        ReportCNN(spaces.Box(0, 255, (3, 16, 16), np.uint8), **kwargs)


# ---------------------------------------------------------------------------------------------------------------------
# The noise schedule counts timesteps
# ---------------------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("n_copies", [1, 8])
def test_noise_schedule_counts_timesteps_with_any_number_of_copies(n_copies):
    venv = make_multiagent_vec_env(TargetReachEnv, n_envs=n_copies, seed=0, env_kwargs=dict(n_agents=2))
    noise = DecayingGaussianNoise(np.zeros(2), sigma=1.0, final_sigma=0.1, decay=0.99)
    model = MADDPG(
        "MlpPolicy",
        venv,
        learning_starts=0,
        buffer_size=2000,
        batch_size=8,
        train_freq=10,
        action_noise=noise,
        seed=0,
        policy_kwargs=dict(net_arch=[8], n_quantiles=2),
    )
    model.learn(400)
    assert model.num_timesteps == 400
    # The last VecEnv step was drawn at timestep 400 - n_copies; every copy's noise follows the same counter
    expected = 0.1 + 0.9 * 0.99 ** (400 - n_copies)
    sigmas = [float(np.mean(n.current_sigma)) for n in model.action_noise.noises]
    # current_sigma is the scale of the next call: one call after timestep 400 - n_copies
    np.testing.assert_allclose(sigmas, 0.1 + 0.9 * 0.99 ** (400 - n_copies + 1), rtol=1e-9)
    assert sigmas[0] < expected
    assert model.logger.name_to_value["train/noise_std"] == pytest.approx(sigmas[0])


def test_row_batched_noise_draws_what_sb3s_row_by_row_noise_draws():
    from stable_baselines3.common.noise import VectorizedActionNoise

    from sb3_maddpg.common.noise import DecayingGaussianNoise, RowBatchedActionNoise, set_noise_timestep

    base = DecayingGaussianNoise(mean=np.zeros(2), sigma=1.0, final_sigma=0.1, decay=0.9)
    batched, row_by_row = RowBatchedActionNoise(base, 6), VectorizedActionNoise(base, 6)
    for timestep in (0, 3, 40):
        set_noise_timestep(batched, timestep)
        set_noise_timestep(row_by_row, timestep)
        np.random.seed(timestep)
        expected = row_by_row()
        np.random.seed(timestep)
        drawn = batched()
        assert drawn.shape == (6, 2) and drawn.dtype == np.float32
        np.testing.assert_array_equal(drawn, expected)
        assert [noise.timestep for noise in batched.noises] == [noise.timestep for noise in row_by_row.noises]
    batched.reset([0, 1])  # SB3's per-row reset at an episode end of one copy


def test_learn_wraps_the_noise_in_one_row_batched_noise():
    from sb3_maddpg.common.noise import RowBatchedActionNoise

    venv = make_multiagent_vec_env(TargetReachEnv, n_envs=2, seed=0, env_kwargs=dict(n_agents=3))
    model = MADDPG("MlpPolicy", venv, learning_starts=0, batch_size=8, buffer_size=100, seed=0)
    model.learn(10)
    assert isinstance(model.action_noise, RowBatchedActionNoise) and model.action_noise.n_envs == 6
