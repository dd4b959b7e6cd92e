"""
Argument checks shared by ``MADDPG``, its policies and the VecEnv helper: each raises where the input enters, with one
line naming the argument, the value given and what is accepted.

Each check takes the argument's name and value and returns the value (as an int or float for the numbers), so that an
argument is checked where it is stored (``self.policy_delay = check_int("policy_delay", policy_delay, low=1)``) or
handed to SB3, which stores it. The bounds are closed unless ``low_open``/``high_open`` say otherwise, and None means
unbounded; the task package ``sb3_maddpg_envs`` has the same ``check_int`` and ``check_number`` in a module of its own.
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

from sb3_maddpg.common.actions import check_action_space


def check_int(name: str, value: Any, low: int | None = None, high: int | None = None) -> int:
    """
    An integer in ``[low, high]`` (the same helper as the task package's ``sb3_maddpg_envs`` validation module).

    :param name: the argument's name
    :param value: the value given
    :param low: the smallest accepted value (None: unbounded)
    :param high: the largest accepted value (None: unbounded)
    :return: the value as an int
    """
    ok = isinstance(value, Integral) and not isinstance(value, bool)
    if ok and low is not None:
        ok = int(value) >= low
    if ok and high is not None:
        ok = int(value) <= high
    if not ok:
        if low is not None and high is not None:
            accepted = f"an integer in [{low}, {high}]"
        elif low is not None:
            accepted = f"an integer >= {low}"
        elif high is not None:
            accepted = f"an integer <= {high}"
        else:
            accepted = "an integer"
        raise ValueError(f"{name} must be {accepted}, got {value!r}")
    return int(value)


def check_number(
    name: str,
    value: Any,
    low: float | None = None,
    high: float | None = None,
    low_open: bool = False,
    high_open: bool = False,
) -> float:
    """
    A finite real number in ``[low, high]``; ``low_open`` and ``high_open`` exclude the bound (the same helper as the
    task package's ``sb3_maddpg_envs`` validation module).

    :param name: the argument's name
    :param value: the value given
    :param low: the lower bound (None: unbounded)
    :param high: the upper bound (None: unbounded)
    :param low_open: exclude ``low``
    :param high_open: exclude ``high``
    :return: the value as a float
    """
    ok = isinstance(value, Real) and not isinstance(value, bool) and math.isfinite(float(value))
    if ok and low is not None:
        ok = float(value) > low if low_open else float(value) >= low
    if ok and high is not None:
        ok = float(value) < high if high_open else float(value) <= high
    if not ok:
        if low is not None and high is not None:
            accepted = f"a number in {'(' if low_open else '['}{low:g}, {high:g}{')' if high_open else ']'}"
        elif low is not None:
            accepted = f"a finite number {'>' if low_open else '>='} {low:g}"
        elif high is not None:
            accepted = f"a finite number {'<' if high_open else '<='} {high:g}"
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


def check_net_arch(value: Any) -> Any:
    """
    ``net_arch`` of a MADDPG policy: a list of positive layer sizes, or a dict with lists ``pi`` and ``qf``.

    :param value: the value given (None: the default)
    :return: the value
    """
    if value is None:
        return None
    if isinstance(value, dict):
        unknown = sorted(set(value) - {"pi", "qf"})
        if unknown or not {"pi", "qf"} <= set(value):
            raise ValueError(f"net_arch as a dict must have exactly the keys 'pi' (actors) and 'qf' (critics), got {value!r}")
        for key in ("pi", "qf"):
            _check_layer_sizes(f"net_arch[{key!r}]", value[key])
        return value
    _check_layer_sizes("net_arch", value)
    return value


def _check_layer_sizes(name: str, sizes: Any) -> None:
    if not isinstance(sizes, list | tuple) or not all(
        isinstance(size, Integral) and not isinstance(size, bool) and size >= 1 for size in sizes
    ):
        raise ValueError(
            f"{name} must be a list of hidden layer sizes, each an integer >= 1 (e.g. [64, 64]; [] for none), got {sizes!r}"
        )


def check_vec_env(algorithm: str, env: Any) -> Any:
    """
    ``env`` of a multi-agent off-policy algorithm: not a PettingZoo env, and (when given as an env) spaces it can
    act in; the action noise is checked against the action space once the team is read
    (``MultiAgentOffPolicyAlgorithm._check_action_noise``).

    :param algorithm: the algorithm's name, for the messages
    :param env: the value given
    :return: the env
    """
    if isinstance(env, ParallelEnv):
        raise TypeError(
            f"{algorithm} takes an SB3 VecEnv with one row per agent, not a PettingZoo ParallelEnv: "
            "wrap it with sb3_maddpg.make_multiagent_vec_env(env_fn, n_envs=...)"
        )
    if env is not None and not isinstance(env, str):
        check_action_space(env.action_space, algorithm)
    if env is not None and not isinstance(env, str) and not isinstance(env.observation_space, spaces.Box):
        raise TypeError(f"{algorithm} accepts Box observation spaces (vectors or images), got {env.observation_space}")
    return env


def check_learning_rate(name: str, value: Any) -> Any:
    """
    :param name: the argument's name (with what its default is, where it has one)
    :param value: a number > 0 or a schedule (a callable), as given
    :return: the value
    """
    if not callable(value):
        check_number(name, value, low=0.0, low_open=True)
    return value


def check_gradient_steps(value: Any) -> int:
    """
    :param value: the value given (an integer >= 1, or -1)
    :return: the value as an int
    """
    if check_int("gradient_steps", value, low=-1) == 0:
        raise ValueError("gradient_steps must be an integer >= 1, or -1 (as many as timesteps collected), got 0 (no update)")
    return int(value)


def check_replay_buffer_class(algorithm: str, value: Any) -> Any:
    """
    :param algorithm: the algorithm's name, for the message
    :param value: None or the class given
    :return: the value
    """
    from sb3_maddpg.common.buffers import MultiAgentReplayBuffer

    if value is not None and not (isinstance(value, type) and issubclass(value, MultiAgentReplayBuffer)):
        raise TypeError(
            f"replay_buffer_class must be MultiAgentReplayBuffer or a subclass ({algorithm} samples joint transitions), "
            f"got {value!r}"
        )
    return value


def check_tensorboard_log(value: Any) -> Any:
    """
    :param value: None or a folder path
    :return: the value
    """
    if value is not None and not isinstance(value, str | os.PathLike):
        raise TypeError(f"tensorboard_log must be a folder path or None, got {value!r}")
    return value


def check_policy_kwargs(value: Any) -> dict[str, Any]:
    """
    ``policy_kwargs`` of an algorithm, where they enter: a dict of keyword arguments whose ``net_arch`` (the argument
    SB3 would let fail deep inside) has the accepted form; the policy checks the others when it is built.

    :param value: the value given
    :return: the dict (empty for None)
    """
    policy_kwargs = check_optional_dict("policy_kwargs", value)
    if "net_arch" in policy_kwargs:
        check_net_arch(policy_kwargs["net_arch"])
    return policy_kwargs


def check_device(value: Any) -> Any:
    """
    :param value: the value given
    :return: the value
    """
    if not isinstance(value, str | th.device):
        raise TypeError(f"device must be 'auto', 'cpu', 'cuda', 'cuda:N' or a torch.device, got {value!r}")
    if isinstance(value, str) and value != "auto":
        try:
            th.device(value)
        except RuntimeError as error:
            raise ValueError(f"device must be 'auto', 'cpu', 'cuda', 'cuda:N' or a torch.device, got {value!r}") from error
    return value


# The parameters of SB3's noises (NormalActionNoise, OrnsteinUhlenbeckActionNoise) and DecayingGaussianNoise: attribute ->
# (argument name, whether it must be >= 0)
_NOISE_PARAMETERS = {
    "_mu": ("mean", False),
    "_sigma": ("sigma", True),
    "_final_sigma": ("final_sigma", True),
    "_theta": ("theta", True),
    "_dt": ("dt", True),
}


def check_action_noise(action_noise: Any) -> Any:
    """
    ``action_noise``: None or an SB3 ``ActionNoise`` whose parameters are finite, its standard deviations >= 0 (NumPy
    would only refuse a negative sigma at the first noisy step, and a NaN one would make every action NaN).

    :param action_noise: the value given (a ``VectorizedActionNoise``: each row's noise is checked)
    :return: the value
    """
    if action_noise is None:
        return None
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
    return action_noise


def check_cvar_alpha(value: Any) -> float:
    """
    :param value: the CVaR level given, in (0, 1]
    :return: the value as a float
    """
    if isinstance(value, bool) or not isinstance(value, Real) or not 0.0 < value <= 1.0:
        raise ValueError(f"cvar_alpha must be a number in (0, 1] (1 = risk-neutral mean), got {value!r}")
    return float(value)


def check_actor_learning_rate(value: Any) -> Any:
    """
    :param value: None (the actors take ``learning_rate``), a number > 0 or a schedule
    :return: the value
    """
    return None if value is None else check_learning_rate("actor_learning_rate (None: learning_rate; or a schedule)", value)


def check_max_grad_norm(value: Any) -> float | None:
    """
    :param value: None (no clipping) or a number > 0
    :return: the value (a float, or None)
    """
    return None if value is None else check_number("max_grad_norm (None for no clipping)", value, low=0.0, low_open=True)


def check_mean_loss(value: Any) -> str:
    """
    :param value: the loss of the critics' mean given
    :return: the value
    """
    if value not in ("huber", "squared"):
        raise ValueError(f"mean_loss must be 'huber' (the default) or 'squared' (the squared TD error), got {value!r}")
    return value


def check_train_freq(train_freq: Any) -> Any:
    """
    :param train_freq: the value given: VecEnv steps, or a tuple (k, "step" or "episode")
    :return: the value
    """
    accepted = "an integer >= 1 (VecEnv steps) or a tuple (k >= 1, 'step' or 'episode')"
    if isinstance(train_freq, tuple) and len(train_freq) == 2:
        frequency, unit = train_freq
        unit = getattr(unit, "value", unit)  # SB3's TrainFrequencyUnit
        if unit in ("step", "episode") and not isinstance(frequency, bool) and isinstance(frequency, Integral):
            if frequency >= 1:
                return train_freq
    elif not isinstance(train_freq, bool) and isinstance(train_freq, Integral) and train_freq >= 1:
        return train_freq
    raise ValueError(f"train_freq must be {accepted}, got {train_freq!r}")
