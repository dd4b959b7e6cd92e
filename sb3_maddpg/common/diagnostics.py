"""
How well each critic sees its own agent's action: the spread of critic i's value over a few candidate actions of
agent i, the teammates' actions held fixed. A critic that cannot resolve its own agent's action (the joint critic of
a large team) scores every candidate alike, and its actor gets no direction from it.
"""

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import torch as th

if TYPE_CHECKING:
    from sb3_maddpg.maddpg.critics import QuantileCriticBase

# Box actions: the candidates are the zero action and this many uniform draws in [-1, 1]^A, the same at every call
N_RANDOM_CANDIDATES = 8


def own_action_candidates(action_dim: int, discrete: bool, device: th.device | str = "cpu") -> th.Tensor:
    """
    The candidate actions of ``own_action_value_range``: the same for every call and every agent, so that the
    measure can be compared along a run.

    :param action_dim: the width of an action as the critics read it (Discrete(n): n)
    :param discrete: one-hot actions: every one of the n actions is a candidate
    :param device: where the candidates go
    :return: (K, action_dim)
    """
    if discrete:
        return th.eye(action_dim, device=device)
    # A generator of its own: the global random state, and so training, is left as it was
    generator = th.Generator().manual_seed(0)
    draws = th.rand(N_RANDOM_CANDIDATES, action_dim, generator=generator) * 2.0 - 1.0
    return th.cat([th.zeros(1, action_dim), draws]).to(device)


@th.no_grad()
def own_action_value_range(
    critic: "QuantileCriticBase",
    features: th.Tensor,
    actions: th.Tensor,
    candidates: th.Tensor,
    present: th.Tensor | None = None,
) -> th.Tensor:
    """
    For each agent i, the mean over the batch of the range (largest minus smallest) of critic i's mean value when
    agent i's action is each candidate in turn and the teammates keep the batch's actions.

    :param critic: the critics (their first network is read)
    :param features: the critics' encodings of the batch's observations, (B, N, F)
    :param actions: the batch's joint actions, (B, N, A)
    :param candidates: the candidate actions (K, A), e.g. from ``own_action_candidates``
    :param present: with agents that leave, (B, N) ones where each agent is in the episode: the mean is over those
        rows only
    :return: (N,)
    """
    values = th.stack(
        [
            critic.quantiles_with_own_actions(features, actions, candidate.expand_as(actions)).mean(dim=-1)
            for candidate in candidates
        ]
    )  # (K, B, N)
    ranges = values.amax(dim=0) - values.amin(dim=0)  # (B, N)
    if present is None:
        return ranges.mean(dim=0)
    return (ranges * present).sum(dim=0) / present.sum(dim=0).clamp(min=1.0)


def own_action_gradients(
    critic: "QuantileCriticBase",
    features: th.Tensor,
    actions: th.Tensor,
    objectives: Sequence[Callable[[th.Tensor], th.Tensor]],
) -> list[th.Tensor]:
    """
    Where each objective of critic i's quantiles pulls agent i's own action: its gradient with respect to that action,
    the teammates keeping the batch's actions (no gradient reaches the critic's weights).

    :param critic: the critics (their first network is read)
    :param features: the critics' encodings of the observations, (B, N, F)
    :param actions: the joint actions, (B, N, A)
    :param objectives: functions of the quantiles (..., n) to a value per leading index, e.g. their mean or ``cvar``
    :return: one (B, N, A) gradient per objective
    """
    gradients = []
    for objective in objectives:
        own = actions.detach().clone().requires_grad_(True)
        value = objective(critic.quantiles_with_own_actions(features, actions, own)).sum()
        (gradient,) = th.autograd.grad(value, own)
        gradients.append(gradient)
    return gradients
