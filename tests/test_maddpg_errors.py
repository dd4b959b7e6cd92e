"""Bad input is refused where it enters, with a message naming what is accepted."""

import numpy as np
import pytest
import supersuit as ss
from gymnasium import spaces
from maddpg_test_envs import TargetReachEnv
from stable_baselines3.common.noise import NormalActionNoise, OrnsteinUhlenbeckActionNoise, VectorizedActionNoise
from stable_baselines3.common.vec_env import DummyVecEnv

from sb3_maddpg import MADDPG, MATD3, make_multiagent_vec_env
from sb3_maddpg.common.noise import DecayingGaussianNoise


class MultiDiscreteActionEnv(TargetReachEnv):
    def action_space(self, agent):
        return spaces.MultiDiscrete([4, 2])


class MixedActionEnv(TargetReachEnv):
    def action_space(self, agent):
        return spaces.Box(-1.0, 1.0, (2 if agent == "agent_0" else 3,), np.float32)


class BoxAndDiscreteEnv(TargetReachEnv):
    def action_space(self, agent):
        return spaces.Box(-1.0, 1.0, (2,), np.float32) if agent == "agent_0" else spaces.Discrete(5)


class EmptyBoxActionEnv(TargetReachEnv):
    def action_space(self, agent):
        return spaces.Box(-1.0, 1.0, (0,), np.float32)


def raw_supersuit_env(env, n_envs=1):
    """SuperSuit's own VecEnv: no n_agents attribute, SuperSuit's checks only."""
    return ss.concat_vec_envs_v1(ss.pettingzoo_env_to_vec_env_v1(env), n_envs, base_class="stable_baselines3")


def test_multidiscrete_action_space():
    # Box and Discrete are accepted (tests/test_discrete_actions.py); MultiDiscrete is not, yet
    with pytest.raises(TypeError, match="MultiDiscrete .* is not supported yet"):
        make_multiagent_vec_env(MultiDiscreteActionEnv)
    with pytest.raises(TypeError, match=r"Box \(continuous\) and Discrete action spaces; MultiDiscrete"):
        MADDPG("MlpPolicy", raw_supersuit_env(MultiDiscreteActionEnv()), n_agents=2)


def test_an_empty_box_action_space_is_refused_where_the_env_enters():
    message = r"needs at least one action entry per agent; got the empty action space Box\(\[\], \[\], \(0,\), float32\)"
    with pytest.raises(ValueError, match=f"MADDPG \\(agent 'agent_0'\\) {message}"):
        make_multiagent_vec_env(EmptyBoxActionEnv)
    with pytest.raises(ValueError, match=f"MATD3 {message}"):
        MATD3("MlpPolicy", raw_supersuit_env(EmptyBoxActionEnv()), n_agents=2)


def test_agents_with_different_spaces():
    # Different action widths are padded (tests/test_heterogeneous_spaces.py); a Box agent beside a Discrete one is not
    assert make_multiagent_vec_env(MixedActionEnv).agent_spaces.action_widths.tolist() == [2, 3]
    with pytest.raises(ValueError, match="all have Box actions or all Discrete actions, not a mix"):
        make_multiagent_vec_env(BoxAndDiscreteEnv)


def test_rows_not_a_multiple_of_agents():
    venv = raw_supersuit_env(TargetReachEnv(n_agents=3))
    with pytest.raises(ValueError, match="not a multiple of n_agents=2"):
        MADDPG("MlpPolicy", venv, n_agents=2)
    # a VecEnv that says it has 3 agents cannot be used with n_agents=2
    with pytest.raises(ValueError, match="disagrees"):
        MADDPG("MlpPolicy", make_multiagent_vec_env(TargetReachEnv, env_kwargs=dict(n_agents=3)), n_agents=2)
    # nor can predict take a partial joint observation
    model = MADDPG("MlpPolicy", make_multiagent_vec_env(TargetReachEnv, env_kwargs=dict(n_agents=3)))
    with pytest.raises(ValueError, match="multiple of n_agents=3"):
        model.predict(np.zeros((4, 4), np.float32))


def test_number_of_agents_is_required():
    venv = raw_supersuit_env(TargetReachEnv(n_agents=2))
    with pytest.raises(ValueError, match="n_agents"):
        MADDPG("MlpPolicy", venv)
    # with n_agents given, SuperSuit's VecEnv works directly
    model = MADDPG("MlpPolicy", venv, n_agents=2, buffer_size=100, learning_starts=10, batch_size=8)
    model.learn(20)
    with pytest.raises(ValueError, match="n_agents must be an integer >= 1"):
        MADDPG("MlpPolicy", venv, n_agents=0)


def test_parallel_env_and_single_agent_env_are_refused():
    with pytest.raises(TypeError, match="make_multiagent_vec_env"):
        MADDPG("MlpPolicy", TargetReachEnv())
    single = DummyVecEnv([lambda: __import__("gymnasium").make("Pendulum-v1")])
    with pytest.raises(ValueError, match="number of agents"):
        MADDPG("MlpPolicy", single)


@pytest.mark.parametrize("alpha", [0.0, -0.5, 1.5, float("nan"), True, "0.5"])
def test_cvar_alpha_outside_unit_interval(alpha):
    venv = make_multiagent_vec_env(TargetReachEnv)
    with pytest.raises(ValueError, match=r"cvar_alpha must be a number in \(0, 1\]"):
        MADDPG("MlpPolicy", venv, cvar_alpha=alpha)


@pytest.mark.parametrize("n_quantiles", [0, -3, 2.5])
def test_n_quantiles_below_one(n_quantiles):
    venv = make_multiagent_vec_env(TargetReachEnv)
    with pytest.raises(ValueError, match="n_quantiles must be an integer >= 1"):
        MADDPG("MlpPolicy", venv, policy_kwargs=dict(n_quantiles=n_quantiles))


def test_cnn_policy_on_vector_observations():
    venv = make_multiagent_vec_env(TargetReachEnv)
    with pytest.raises(ValueError, match="channel-first image"):
        MADDPG("CnnPolicy", venv)


@pytest.mark.parametrize("algorithm", [MADDPG, MATD3])
@pytest.mark.parametrize("actor_reg", [-1e-3, float("nan"), float("inf"), "0.1", True])
def test_actor_reg_must_be_finite_and_non_negative(algorithm, actor_reg):
    venv = make_multiagent_vec_env(TargetReachEnv)
    with pytest.raises(ValueError, match=r"actor_reg \(0 turns the penalty off\) must be a finite number >= 0"):
        algorithm("MlpPolicy", venv, actor_reg=actor_reg)


@pytest.mark.parametrize(
    ("noise", "message"),
    [
        (NormalActionNoise(np.zeros(2), np.full(2, np.nan)), "NormalActionNoise's sigma must be finite numbers >= 0"),
        (NormalActionNoise(np.zeros(2), -0.1 * np.ones(2)), "NormalActionNoise's sigma must be finite numbers >= 0"),
        (NormalActionNoise(np.full(2, np.inf), np.ones(2)), "NormalActionNoise's mean must be finite numbers, got"),
        (OrnsteinUhlenbeckActionNoise(np.zeros(2), np.ones(2), theta=-1.0), "OrnsteinUhlenbeckActionNoise.s theta must be"),
        (DecayingGaussianNoise(np.zeros(2), sigma=np.nan), "DecayingGaussianNoise's sigma must be finite numbers >= 0"),
        (VectorizedActionNoise(NormalActionNoise(np.zeros(2), -np.ones(2)), 3), "NormalActionNoise's sigma must be"),
    ],
)
def test_action_noise_with_a_nan_or_negative_sigma_is_refused_at_construction(noise, message):
    venv = make_multiagent_vec_env(TargetReachEnv)
    with pytest.raises(ValueError, match=f"action_noise: {message}"):
        MATD3("MlpPolicy", venv, action_noise=noise)


@pytest.mark.parametrize("name", ["buffer_size", "batch_size"])
@pytest.mark.parametrize("value", [0, -5, "10", 2.5])
def test_sizes_must_be_positive_integers(name, value):
    venv = make_multiagent_vec_env(TargetReachEnv)
    with pytest.raises(ValueError, match=f"{name} must be an integer >= 1"):
        MADDPG("MlpPolicy", venv, **{name: value})


def test_replay_buffer_must_store_joint_transitions():
    from stable_baselines3.common.buffers import ReplayBuffer

    venv = make_multiagent_vec_env(TargetReachEnv)
    with pytest.raises(TypeError, match="replay_buffer_class must be MultiAgentReplayBuffer"):
        MADDPG("MlpPolicy", venv, replay_buffer_class=ReplayBuffer)


def test_share_actor_is_an_algorithm_argument():
    venv = make_multiagent_vec_env(TargetReachEnv)
    with pytest.raises(ValueError, match=r"MADDPG\(..., share_actor=True\)"):
        MADDPG("MlpPolicy", venv, policy_kwargs=dict(share_actor=True))


def test_mean_anchored_quantiles_is_an_algorithm_argument():
    with pytest.raises(ValueError, match="mean_anchored_quantiles is an argument of MADDPG"):
        MADDPG("MlpPolicy", make_multiagent_vec_env(TargetReachEnv), policy_kwargs=dict(mean_anchored_quantiles=True))
    with pytest.raises(TypeError, match="mean_anchored_quantiles"):
        MADDPG("MlpPolicy", make_multiagent_vec_env(TargetReachEnv), mean_anchored_quantiles="yes")


def test_mean_loss_must_be_huber_or_squared():
    with pytest.raises(ValueError, match="mean_loss must be 'huber'"):
        MADDPG("MlpPolicy", make_multiagent_vec_env(TargetReachEnv), mean_loss="mse")
    # plain quantiles have no mean to fit
    with pytest.raises(ValueError, match="n_quantiles=1 or with mean_anchored_quantiles=True"):
        MADDPG("MlpPolicy", make_multiagent_vec_env(TargetReachEnv), mean_loss="squared", policy_kwargs=dict(n_quantiles=5))
