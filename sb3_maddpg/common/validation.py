"""
Argument checks shared by ``MADDPG``, its policies and the VecEnv helper: each raises where the input enters, with one
line naming the argument, the value given and what is accepted.
"""

import math
import os
from numbers import Integral, Real
from typing import Any

import numpy as np
import torch as th
from gymnasium import spaces
from pettingzoo.utils.env import ParallelEnv
from stable_baselines3.common.noise import ActionNoise
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from torch import nn

from sb3_maddpg.common.actions import check_action_space
from sb3_maddpg.common.groups import check_groups


def check_int(name: str, value: Any, minimum: int | None = None) -> int:
    """
    :param name: the argument's name
    :param value: the value given
    :param minimum: the smallest accepted value
    :return: the value as an int
    """
    if isinstance(value, bool) or not isinstance(value, Integral) or (minimum is not None and value < minimum):
        accepted = "an integer" if minimum is None else f"an integer >= {minimum}"
        raise ValueError(f"{name} must be {accepted}, got {value!r}")
    return int(value)


def check_number(name: str, value: Any, low: float | None = None, high: float | None = None, low_open: bool = False) -> float:
    """
    A finite real number in ``[low, high]`` (``(low, high]`` with ``low_open``).

    :param name: the argument's name
    :param value: the value given
    :param low: the lower bound (None: unbounded)
    :param high: the upper bound, included (None: unbounded)
    :param low_open: exclude ``low``
    :return: the value as a float
    """
    ok = isinstance(value, Real) and not isinstance(value, bool) and math.isfinite(float(value))
    if ok and low is not None:
        ok = float(value) > low if low_open else float(value) >= low
    if ok and high is not None:
        ok = float(value) <= high
    if not ok:
        if low is not None and high is not None:
            accepted = f"a number in {'(' if low_open else '['}{low:g}, {high:g}]"
        elif low is not None:
            accepted = f"a finite number {'>' if low_open else '>='} {low:g}"
        else:
            accepted = "a finite number"
        raise ValueError(f"{name} must be {accepted}, got {value!r}")
    return float(value)


def check_bool(name: str, value: Any) -> bool:
    """
    :param name: the argument's name
    :param value: the value given
    :return: the value
    """
    if not isinstance(value, bool):
        raise TypeError(f"{name} must be True or False, got {value!r}")
    return value


def check_optional_dict(name: str, value: Any) -> dict[str, Any]:
    """
    :param name: the argument's name
    :param value: a dict of keyword arguments, or None
    :return: the dict (empty for None)
    """
    if value is None:
        return {}
    if not isinstance(value, dict) or not all(isinstance(key, str) for key in value):
        raise TypeError(f"{name} must be a dict of keyword arguments (str keys) or None, got {value!r}")
    return value


def check_subclass(name: str, value: Any, base: type) -> type:
    """
    :param name: the argument's name
    :param value: the class given
    :param base: the class it must derive from
    :return: the class
    """
    if not (isinstance(value, type) and issubclass(value, base)):
        raise TypeError(f"{name} must be a subclass of {base.__module__}.{base.__qualname__}, got {value!r}")
    return value


def check_seed(name: str, value: Any) -> int | None:
    """
    :param name: the argument's name
    :param value: None or a seed
    :return: the seed
    """
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, Integral) or not 0 <= value < 2**32:
        raise ValueError(f"{name} must be None or an integer in [0, 2**32), got {value!r}")
    return int(value)


def check_net_arch(value: Any) -> None:
    """
    ``net_arch`` of a MADDPG policy: a list of positive layer sizes, or a dict with lists ``pi`` and ``qf``.

    :param value: the value given (None: the default)
    """
    if value is None:
        return
    if isinstance(value, dict):
        unknown = sorted(set(value) - {"pi", "qf"})
        if unknown or not {"pi", "qf"} <= set(value):
            raise ValueError(f"net_arch as a dict must have exactly the keys 'pi' (actors) and 'qf' (critics), got {value!r}")
        for key in ("pi", "qf"):
            _check_layer_sizes(f"net_arch[{key!r}]", value[key])
        return
    _check_layer_sizes("net_arch", value)


def _check_layer_sizes(name: str, sizes: Any) -> None:
    if not isinstance(sizes, list | tuple) or not all(
        isinstance(size, Integral) and not isinstance(size, bool) and size >= 1 for size in sizes
    ):
        raise ValueError(
            f"{name} must be a list of hidden layer sizes, each an integer >= 1 (e.g. [64, 64]; [] for none), got {sizes!r}"
        )


def check_policy_arguments(
    n_agents: Any,
    share_actor: Any,
    share_features_extractor: Any,
    n_quantiles: Any,
    n_critics: Any,
    net_arch: Any,
    activation_fn: Any,
    features_extractor_class: Any,
    features_extractor_kwargs: Any,
    normalize_images: Any,
    optimizer_class: Any,
    optimizer_kwargs: Any,
) -> None:
    """
    Check the arguments of ``MADDPGPolicy`` (parameters as there).
    """
    check_int("n_agents", n_agents, 1)
    check_bool("share_actor", share_actor)
    check_bool("share_features_extractor", share_features_extractor)
    check_int("n_quantiles", n_quantiles, 1)
    check_int("n_critics", n_critics, 1)
    check_net_arch(net_arch)
    check_subclass("activation_fn", activation_fn, nn.Module)
    check_subclass("features_extractor_class", features_extractor_class, BaseFeaturesExtractor)
    check_optional_dict("features_extractor_kwargs", features_extractor_kwargs)
    check_bool("normalize_images", normalize_images)
    check_subclass("optimizer_class", optimizer_class, th.optim.Optimizer)
    check_optional_dict("optimizer_kwargs", optimizer_kwargs)


def check_off_policy_arguments(algorithm: str, arguments: dict[str, Any]) -> None:
    """
    Check the arguments of a multi-agent off-policy algorithm that SB3 would accept silently or let fail deep inside
    (parameters as in ``MultiAgentOffPolicyAlgorithm``; ``policy_kwargs`` are checked again by the policy when it is
    built).

    :param algorithm: the algorithm's name, for the messages
    :param arguments: argument name -> value
    """
    from sb3_maddpg.common.buffers import MultiAgentReplayBuffer

    env = arguments["env"]
    if isinstance(env, ParallelEnv):
        raise TypeError(
            f"{algorithm} takes an SB3 VecEnv with one row per agent, not a PettingZoo ParallelEnv: "
            "wrap it with sb3_maddpg.make_multiagent_vec_env(env_fn, n_envs=...)"
        )
    if env is not None and not isinstance(env, str):
        # action_noise against the action space: MultiAgentOffPolicyAlgorithm._check_action_noise, once the env is read
        check_action_space(env.action_space, algorithm)
    if env is not None and not isinstance(env, str) and not isinstance(env.observation_space, spaces.Box):
        raise TypeError(f"{algorithm} accepts Box observation spaces (vectors or images), got {env.observation_space}")
    learning_rate = arguments["learning_rate"]
    if not callable(learning_rate):
        check_number("learning_rate", learning_rate, 0.0, low_open=True)
    check_int("buffer_size", arguments["buffer_size"], 1)
    check_int("batch_size", arguments["batch_size"], 1)
    check_int("learning_starts", arguments["learning_starts"], 0)
    check_number("tau", arguments["tau"], 0.0, 1.0)
    check_number("gamma", arguments["gamma"], 0.0, 1.0)
    _check_train_freq(arguments["train_freq"])
    if check_int("gradient_steps", arguments["gradient_steps"], -1) == 0:
        raise ValueError("gradient_steps must be an integer >= 1, or -1 (as many as timesteps collected), got 0 (no update)")
    check_bool("flush_denormals", arguments["flush_denormals"])
    check_action_noise(arguments["action_noise"])
    replay_buffer_class = arguments["replay_buffer_class"]
    if replay_buffer_class is not None and not (
        isinstance(replay_buffer_class, type) and issubclass(replay_buffer_class, MultiAgentReplayBuffer)
    ):
        raise TypeError(
            f"replay_buffer_class must be MultiAgentReplayBuffer or a subclass ({algorithm} samples joint transitions), "
            f"got {replay_buffer_class!r}"
        )
    check_optional_dict("replay_buffer_kwargs", arguments["replay_buffer_kwargs"])
    check_int("stats_window_size", arguments["stats_window_size"], 1)
    tensorboard_log = arguments["tensorboard_log"]
    if tensorboard_log is not None and not isinstance(tensorboard_log, str | os.PathLike):
        raise TypeError(f"tensorboard_log must be a folder path or None, got {tensorboard_log!r}")
    policy_kwargs = check_optional_dict("policy_kwargs", arguments["policy_kwargs"])
    if "net_arch" in policy_kwargs:
        check_net_arch(policy_kwargs["net_arch"])
    check_int("verbose", arguments["verbose"], 0)
    check_seed("seed", arguments["seed"])
    device = arguments["device"]
    if not isinstance(device, str | th.device):
        raise TypeError(f"device must be 'auto', 'cpu', 'cuda', 'cuda:N' or a torch.device, got {device!r}")
    if isinstance(device, str) and device != "auto":
        try:
            th.device(device)
        except RuntimeError as error:
            raise ValueError(f"device must be 'auto', 'cpu', 'cuda', 'cuda:N' or a torch.device, got {device!r}") from error


# The parameters of SB3's noises (NormalActionNoise, OrnsteinUhlenbeckActionNoise) and DecayingGaussianNoise: attribute ->
# (argument name, whether it must be >= 0)
_NOISE_PARAMETERS = {
    "_mu": ("mean", False),
    "_sigma": ("sigma", True),
    "_final_sigma": ("final_sigma", True),
    "_theta": ("theta", True),
    "_dt": ("dt", True),
}


def check_action_noise(action_noise: Any) -> None:
    """
    ``action_noise``: None or an SB3 ``ActionNoise`` whose parameters are finite, its standard deviations >= 0 (NumPy
    would only refuse a negative sigma at the first noisy step, and a NaN one would make every action NaN).

    :param action_noise: the value given (a ``VectorizedActionNoise``: each row's noise is checked)
    """
    if action_noise is None:
        return
    if not isinstance(action_noise, ActionNoise):
        raise TypeError(f"action_noise must be an SB3 ActionNoise or None, got {action_noise!r}")
    for noise in getattr(action_noise, "noises", None) or [action_noise]:
        for attribute, (name, non_negative) in _NOISE_PARAMETERS.items():
            if not hasattr(noise, attribute):
                continue
            value = getattr(noise, attribute)
            try:
                values = np.asarray(value, dtype=np.float64)
            except (TypeError, ValueError):
                values = np.asarray(np.nan)
            if not np.isfinite(values).all() or (non_negative and (values < 0).any()):
                accepted = "finite numbers >= 0" if non_negative else "finite numbers"
                raise ValueError(f"action_noise: {type(noise).__name__}'s {name} must be {accepted}, got {value!r}")


def check_maddpg_arguments(algorithm: str, arguments: dict[str, Any]) -> None:
    """
    Check the arguments that MADDPG (and MATD3, built on it) adds to the off-policy ones (parameters as in ``MADDPG``).

    :param algorithm: the algorithm's name, for the messages
    :param arguments: argument name -> value
    """
    cvar_alpha = arguments["cvar_alpha"]
    if isinstance(cvar_alpha, bool) or not isinstance(cvar_alpha, Real) or not 0.0 < cvar_alpha <= 1.0:
        raise ValueError(f"cvar_alpha must be a number in (0, 1] (1 = risk-neutral mean), got {cvar_alpha!r}")
    check_int("cvar_alpha_anneal_steps (0: no annealing)", arguments["cvar_alpha_anneal_steps"], 0)
    if arguments["cvar_alpha_anneal_steps"] > 0 and arguments["cuda_graph"]:
        raise ValueError(
            "cvar_alpha_anneal_steps changes the risk level as training goes, which a CUDA graph cannot follow (it "
            "records one): leave cuda_graph=False or cvar_alpha_anneal_steps=0"
        )
    check_bool("share_actor", arguments["share_actor"])
    check_groups(arguments["groups"])
    if arguments["groups"] is not None and arguments["share_actor"]:
        raise ValueError("share_actor=True shares one actor between all agents; give groups or share_actor, not both")
    policy_kwargs = arguments["policy_kwargs"]
    if isinstance(policy_kwargs, dict) and "share_actor" in policy_kwargs:
        raise ValueError(
            f"share_actor is an argument of {algorithm}, not a policy kwarg: use {algorithm}(..., share_actor=True)"
        )
    if isinstance(policy_kwargs, dict) and "mean_anchored_quantiles" in policy_kwargs:
        raise ValueError(
            f"mean_anchored_quantiles is an argument of {algorithm} (it sets the loss and the critics' mean head), "
            f"not a policy kwarg: use {algorithm}(..., mean_anchored_quantiles=True)"
        )
    check_number("actor_reg (0 turns the penalty off)", arguments["actor_reg"], 0.0)
    check_number(
        "gumbel_temperature (the Gumbel-softmax temperature, default 1.0)", arguments["gumbel_temperature"], 0.0, low_open=True
    )
    check_bool("mean_anchored_quantiles", arguments["mean_anchored_quantiles"])
    if arguments["mean_loss"] not in ("huber", "squared"):
        raise ValueError(
            f"mean_loss must be 'huber' (the default) or 'squared' (the squared TD error), got {arguments['mean_loss']!r}"
        )
    check_bool("cuda_graph", arguments["cuda_graph"])
    check_bool("bf16_autocast", arguments["bf16_autocast"])
    check_bool("compile_quantile_loss", arguments["compile_quantile_loss"])
    check_int("policy_delay", arguments["policy_delay"], 1)
    check_int("critic_warmup_steps", arguments["critic_warmup_steps"], 0)
    if arguments["max_grad_norm"] is not None:
        check_number("max_grad_norm (None for no clipping)", arguments["max_grad_norm"], low=0.0, low_open=True)
    check_number("target_policy_noise", arguments["target_policy_noise"], low=0.0)
    check_number("target_noise_clip", arguments["target_noise_clip"], low=0.0)
    actor_learning_rate = arguments["actor_learning_rate"]
    if actor_learning_rate is not None and not callable(actor_learning_rate):
        check_number("actor_learning_rate (None: learning_rate; or a schedule)", actor_learning_rate, low=0.0, low_open=True)


def _check_train_freq(train_freq: Any) -> None:
    accepted = "an integer >= 1 (VecEnv steps) or a tuple (k >= 1, 'step' or 'episode')"
    if isinstance(train_freq, tuple) and len(train_freq) == 2:
        frequency, unit = train_freq
        unit = getattr(unit, "value", unit)  # SB3's TrainFrequencyUnit
        if unit in ("step", "episode") and not isinstance(frequency, bool) and isinstance(frequency, Integral):
            if frequency >= 1:
                return
    elif not isinstance(train_freq, bool) and isinstance(train_freq, Integral) and train_freq >= 1:
        return
    raise ValueError(f"train_freq must be {accepted}, got {train_freq!r}")
