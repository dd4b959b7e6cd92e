"""What one gradient step of MADDPG (and MATD3) reports per agent, and the batch means it is made of."""

from typing import NamedTuple

import torch as th


class GradientStepStats(NamedTuple):
    """
    What one gradient step reports, per agent (each (N,)); the actor's fields are None in a step without an actor
    update. ``train`` logs their means as ``train/<field>_<agent>``.
    """

    critic_loss: th.Tensor
    q_mean: th.Tensor  # mean quantile of the batch's joint actions
    cvar: th.Tensor  # CVaR_alpha of the batch's joint actions
    # how wide the critic's return distribution is: the mean over the batch of the quantiles' standard deviation
    # (0 with one quantile); a risk-averse user watches it beside the CVaR
    q_spread: th.Tensor
    actor_loss: th.Tensor | None = None
    # the fraction of actor outputs within 1 % of a bound; for Discrete actions, of observations whose most likely
    # action has a probability above 0.99 (the actor has stopped exploring there)
    actor_saturation: th.Tensor | None = None
    actor_preactivation: th.Tensor | None = None  # the mean |pre-tanh output| (|logit| for Discrete actions)


def batch_mean(values: th.Tensor, present: th.Tensor | None) -> th.Tensor:
    """
    Each agent's mean over the batch, (B, N) -> (N,); with ``present`` (B, N), over the rows where the agent is in the
    episode only (an agent that has left has no loss there).
    """
    if present is None:
        return values.mean(dim=0)
    return (values * present).sum(dim=0) / present.sum(dim=0).clamp(min=1.0)
