"""Every argument of MADDPG, its policies and make_multiagent_vec_env is checked where it enters."""

import re

import pytest
import torch as th
from maddpg_test_envs import TargetReachEnv

from sb3_maddpg import MADDPG, make_multiagent_vec_env

BAD_MADDPG_ARGUMENTS = [
    ("gamma", 1.5, ValueError, r"gamma must be a number in \[0, 1\], got 1.5"),
    ("gamma", -0.1, ValueError, r"gamma must be a number in \[0, 1\]"),
    ("gamma", "x", ValueError, r"gamma must be a number in \[0, 1\], got 'x'"),
    ("gamma", float("nan"), ValueError, "gamma must be"),
    ("tau", -1, ValueError, r"tau must be a number in \[0, 1\], got -1"),
    ("tau", 2.0, ValueError, "tau must be"),
    ("learning_rate", 0.0, ValueError, r"learning_rate must be a finite number > 0"),
    ("learning_rate", "fast", ValueError, "learning_rate must be"),
    ("learning_starts", -1, ValueError, "learning_starts must be an integer >= 0"),
    ("learning_starts", 1.5, ValueError, "learning_starts must be an integer >= 0"),
    ("train_freq", 0, ValueError, "train_freq must be an integer >= 1"),
    ("train_freq", (1, "epoch"), ValueError, r"or a tuple \(k >= 1, 'step' or 'episode'\), got \(1, 'epoch'\)"),
    ("train_freq", [1, "step"], ValueError, "train_freq must be"),
    ("gradient_steps", -2, ValueError, "gradient_steps must be an integer >= -1"),
    ("action_noise", 0.1, TypeError, "action_noise must be an SB3 ActionNoise or None, got 0.1"),
    ("replay_buffer_kwargs", [1], TypeError, "replay_buffer_kwargs must be a dict"),
    ("share_actor", 1, TypeError, "share_actor must be True or False, got 1"),
    ("stats_window_size", 0, ValueError, "stats_window_size must be an integer >= 1"),
    ("tensorboard_log", 3, TypeError, "tensorboard_log must be a folder path or None"),
    ("policy_kwargs", "dict()", TypeError, "policy_kwargs must be a dict"),
    ("verbose", -1, ValueError, "verbose must be an integer >= 0"),
    ("seed", -1, ValueError, r"seed must be None or an integer in \[0, 2\*\*32\), got -1"),
    ("seed", 1.5, ValueError, "seed must be None or an integer"),
    ("device", "gpu0", ValueError, "device must be 'auto', 'cpu', 'cuda', 'cuda:N' or a torch.device, got 'gpu0'"),
    ("device", 0.5, TypeError, "device must be"),
    ("n_agents", True, ValueError, "n_agents must be an integer >= 1, got True"),
]


@pytest.mark.parametrize(
    ("name", "value", "error", "message"), BAD_MADDPG_ARGUMENTS, ids=[f"{n}={v!r}" for n, v, _, _ in BAD_MADDPG_ARGUMENTS]
)
def test_bad_maddpg_argument_is_refused_naming_it(name, value, error, message) -> None:
    with pytest.raises(error, match=message):
        MADDPG("MlpPolicy", make_multiagent_vec_env(TargetReachEnv), **{name: value})


BAD_POLICY_KWARGS = [
    (dict(net_arch=[-1]), ValueError, r"net_arch must be a list of hidden layer sizes, each an integer >= 1 .*got \[-1\]"),
    (dict(net_arch=[16.5]), ValueError, r"got \[16.5\]"),
    (dict(net_arch=[0]), ValueError, r"got \[0\]"),
    (dict(net_arch=64), ValueError, "net_arch must be a list"),
    (dict(net_arch=dict(pi=[8])), ValueError, "exactly the keys 'pi' .* and 'qf'"),
    (dict(net_arch=dict(pi=[8], qf=[True])), ValueError, r"net_arch\['qf'\] must be a list"),
    (dict(activation_fn="relu"), TypeError, "activation_fn must be a subclass of torch.nn.modules.module.Module"),
    (dict(features_extractor_class=th.nn.Linear), TypeError, "features_extractor_class must be a subclass of"),
    (dict(features_extractor_kwargs=[]), TypeError, "features_extractor_kwargs must be a dict"),
    (dict(normalize_images="yes"), TypeError, "normalize_images must be True or False"),
    (dict(optimizer_class=dict), TypeError, "optimizer_class must be a subclass of torch.optim"),
    (dict(optimizer_kwargs=0.1), TypeError, "optimizer_kwargs must be a dict"),
]


@pytest.mark.parametrize(
    ("policy_kwargs", "error", "message"), BAD_POLICY_KWARGS, ids=[str(k) for k, _, _ in BAD_POLICY_KWARGS]
)
def test_bad_policy_argument_is_refused_naming_it(policy_kwargs, error, message) -> None:
    with pytest.raises(error, match=message):
        MADDPG("MlpPolicy", make_multiagent_vec_env(TargetReachEnv), policy_kwargs=policy_kwargs)


def test_empty_net_arch_and_schedules_are_accepted() -> None:
    model = MADDPG(
        "MlpPolicy",
        make_multiagent_vec_env(TargetReachEnv),
        learning_rate=lambda progress: 1e-3 * progress,
        train_freq=(1, "episode"),
        policy_kwargs=dict(net_arch=dict(pi=[], qf=[8])),
        gamma=1,
        tau=0,
        seed=0,
    )
    assert model.gamma == 1 and model.tau == 0


BAD_VEC_ENV_ARGUMENTS = [
    (dict(env_fn=TargetReachEnv()), TypeError, "env_fn must be a function returning a PettingZoo ParallelEnv"),
    (dict(env_fn="uav_coverage_v0"), TypeError, "env_fn must be a function"),
    (dict(n_envs=True), ValueError, "n_envs must be an integer >= 1 .*got True"),
    (dict(n_envs=0), ValueError, "n_envs must be an integer >= 1"),
    (dict(n_envs=2.0), ValueError, "n_envs must be an integer >= 1"),
    (dict(seed=-1), ValueError, r"seed must be None or an integer in \[0, 2\*\*32\), got -1"),
    (dict(seed="0"), ValueError, "seed must be None or an integer"),
    (dict(env_kwargs=[("n_agents", 2)]), TypeError, "env_kwargs must be a dict"),
]


@pytest.mark.parametrize(
    ("kwargs", "error", "message"),
    BAD_VEC_ENV_ARGUMENTS,
    # without the object's address, so that every pytest-xdist worker collects the same test names
    ids=[re.sub(r" at 0x[0-9a-f]+", "", str(k)) for k, _, _ in BAD_VEC_ENV_ARGUMENTS],
)
def test_bad_vec_env_argument_is_refused_naming_it(kwargs, error, message) -> None:
    arguments = {"env_fn": TargetReachEnv, **kwargs}
    with pytest.raises(error, match=message):
        make_multiagent_vec_env(**arguments)
