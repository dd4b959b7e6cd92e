"""
The random states a run depends on, saved with a model and restored when it is loaded, so that a run resumed at an
episode boundary continues exactly as the uninterrupted one (on the same device and library versions).

What is saved: Python's ``random``, NumPy's global generator (it draws SB3's replay buffer samples and the Gaussian
action noises), PyTorch's CPU generator (and the CUDA ones when the model is on a GPU), the generator of the model's
action space (the uniformly random actions before ``learning_starts``) and, for a :class:`MultiAgentVecEnv`, how to
replay each copy's last reset (:meth:`MultiAgentVecEnv.reset_states`). What is not: the state of an episode in
progress (a resumed run starts with a reset, so a run saved mid-episode continues from a new episode), and the
generators of envs that do not expose them as ``np_random``.
"""

import random
from typing import Any

import numpy as np
import torch as th
from stable_baselines3.common.base_class import BaseAlgorithm

from sb3_maddpg.common.env_util import find_multiagent_vec_env


def capture_random_states(model: BaseAlgorithm) -> dict[str, Any]:
    """
    :param model: the algorithm
    :return: the states described in the module docstring
    """
    states: dict[str, Any] = {
        "python": random.getstate(),
        "numpy": np.random.get_state(),
        "torch": th.get_rng_state(),
        "action_space": model.action_space.np_random.bit_generator.state,
    }
    if model.device.type == "cuda" and th.cuda.is_available():
        states["torch_cuda"] = th.cuda.get_rng_state_all()
    venv = find_multiagent_vec_env(model.get_env())
    if venv is not None:
        states["env"] = venv.reset_states()
    return states


def restore_random_states(model: BaseAlgorithm, states: dict[str, Any]) -> None:
    """
    Put back the states from :func:`capture_random_states`; the env copies replay their last reset at the next
    ``reset()`` where the model has a :class:`MultiAgentVecEnv` with as many copies.

    :param model: the algorithm, with its env if it has one
    :param states: the saved states
    """
    random.setstate(states["python"])
    np.random.set_state(states["numpy"])
    th.set_rng_state(states["torch"])
    if "torch_cuda" in states and th.cuda.is_available() and len(states["torch_cuda"]) == th.cuda.device_count():
        th.cuda.set_rng_state_all(states["torch_cuda"])
    model.action_space.np_random.bit_generator.state = states["action_space"]
    venv = find_multiagent_vec_env(model.get_env())
    if venv is not None and states.get("env") is not None:
        venv.restore_reset_states(states["env"])
