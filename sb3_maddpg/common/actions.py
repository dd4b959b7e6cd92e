"""
The action spaces the algorithms accept, and what a ``Discrete`` one needs: its one-hot width and the Gumbel-softmax
of the MADDPG paper (Lowe et al. 2017, https://arxiv.org/abs/1706.02275, Appendix; Jang et al. 2017,
https://arxiv.org/abs/1611.01144).

A ``Box`` action is the actor's tanh output, rescaled to the space's bounds. A ``Discrete(n)`` action is an integer
for the env and a one-hot vector of width n for the critics and the replay buffer; the actor outputs n logits:

- acting: ``predict(deterministic=True)`` takes their argmax; exploration (``deterministic=False``, the rollouts)
  draws a Gumbel-max sample, argmax(logits + g) with g ~ Gumbel(0, 1), which is a sample of softmax(logits);
- the actor update: the straight-through Gumbel-softmax sample, one-hot in the forward pass (the critic sees a
  one-hot action, as in the buffer) with the gradient of the relaxed sample softmax((logits + g) / temperature);
- the target actors: the one-hot argmax (see ``MADDPG``'s docstring for why).
"""

from typing import Any

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.preprocessing import get_action_dim
from torch.nn import functional as F

#: The action spaces of the agents that the algorithms accept
SUPPORTED_ACTION_SPACES = (spaces.Box, spaces.Discrete)


def check_action_space(action_space: Any, who: str) -> None:
    """
    Refuse an agent action space the algorithms cannot act in, saying what is accepted.

    :param action_space: one agent's action space
    :param who: what checks it, for the message (``"MADDPG"``, ``"MADDPGPolicy"``, ...)
    :raises TypeError: for any space but ``Box`` and ``Discrete``
    :raises ValueError: for a ``Box`` without entries (the actors would output nothing)
    """
    if isinstance(action_space, spaces.Box) and action_space.shape is not None and int(np.prod(action_space.shape)) == 0:
        raise ValueError(
            f"{who} needs at least one action entry per agent; got the empty action space {action_space} "
            "(give the agent a Box of shape (n,) with n >= 1)"
        )
    if isinstance(action_space, SUPPORTED_ACTION_SPACES):
        return
    if isinstance(action_space, spaces.MultiDiscrete):
        raise TypeError(
            f"{who} accepts Box (continuous) and Discrete action spaces; MultiDiscrete ({action_space}) is not supported "
            "yet: give each agent one Discrete space over the product of the choices (as MPE2 does for moves and "
            "messages)"
        )
    raise TypeError(f"{who} accepts Box (continuous) and Discrete action spaces, got {action_space}")


def is_discrete(action_space: spaces.Space) -> bool:
    """
    :param action_space: one agent's action space
    :return: whether its actions are integers (one-hot vectors for the critics and the buffer)
    """
    return isinstance(action_space, spaces.Discrete)


def action_width(action_space: spaces.Space) -> int:
    """
    The size of one agent's action as the actors output it and the critics and the buffer read it.

    :param action_space: one agent's action space
    :return: ``n`` for ``Discrete(n)`` (the one-hot vector), SB3's ``get_action_dim`` otherwise
    """
    if isinstance(action_space, spaces.Discrete):
        return int(action_space.n)
    return get_action_dim(action_space)


def one_hot(actions: np.ndarray, action_space: spaces.Discrete) -> np.ndarray:
    """
    :param actions: integer actions of the space, any shape S
    :param action_space: their ``Discrete(n, start)`` space
    :return: their one-hot vectors, float32 (*S, n)
    :raises ValueError: for an action outside the space
    """
    actions = np.asarray(actions)
    index = actions - int(action_space.start)
    n = int(action_space.n)
    if actions.dtype.kind not in "iu" or (index.size > 0 and (index.min() < 0 or index.max() >= n)):
        raise ValueError(
            f"actions of {action_space} must be integers in [{action_space.start}, {action_space.start + n}), got {actions}"
        )
    return np.eye(n, dtype=np.float32)[index]


def one_hot_argmax(logits: th.Tensor) -> th.Tensor:
    """
    :param logits: (..., n)
    :return: the one-hot vector of each argmax, (..., n), in the logits' dtype
    """
    return F.one_hot(logits.argmax(dim=-1), logits.shape[-1]).to(logits.dtype)


def gumbel_max_sample(logits: th.Tensor) -> th.Tensor:
    """
    A sample of softmax(logits) by the Gumbel-max trick: argmax(logits + g), g ~ Gumbel(0, 1) (g = -log E with
    E ~ Exponential(1), as ``torch.nn.functional.gumbel_softmax`` draws it). A temperature would not change it:
    argmax((logits + g) / t) = argmax(logits + g).

    :param logits: (..., n)
    :return: the sampled indices, (...), int64
    """
    gumbels = -th.empty_like(logits).exponential_().log()
    return (logits + gumbels).argmax(dim=-1)


def straight_through_gumbel_softmax(logits: th.Tensor, temperature: float) -> th.Tensor:
    """
    The straight-through Gumbel-softmax sample (Jang et al. 2017), what the MADDPG paper's actors are trained with
    for discrete actions: the forward value is the one-hot vector of argmax(logits + g), and the gradient is that of
    the relaxed sample y = softmax((logits + g) / temperature), g ~ Gumbel(0, 1). This is
    ``torch.nn.functional.gumbel_softmax(logits, tau=temperature, hard=True)``, computed in float32.

    :param logits: (..., n)
    :param temperature: the relaxation's temperature (> 0): lower is closer to the one-hot sample (less biased
        gradient, larger variance), higher is smoother
    :return: one-hot samples (..., n), differentiable with respect to ``logits``
    """
    return F.gumbel_softmax(logits.float(), tau=temperature, hard=True)
