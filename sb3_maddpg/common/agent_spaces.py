"""Agents with spaces of their own: each agent's observation and action space, and its entries in the padded layout.

The VecEnv, the replay buffer and the batched networks keep one shape for all agents: observations and actions are
padded to the largest agent's (SuperSuit's ``pad_observations_v0`` and ``pad_action_space_v0``). ``AgentSpaces``
records what each agent really has, so that no network learns from a padded entry and the env never receives one:

- observations: the padded entries are set to 0 before any encoder reads them (constants carry no data, and a
  linear layer's weights on a constant 0 input receive no gradient);
- Box actions: an actor's outputs beyond its agent's width are 0, in the rollouts, in the replay buffer and in
  every critic's input; SuperSuit cuts them off before the env;
- Discrete actions: an actor's logits beyond its agent's n are masked out, so that neither the argmax, nor the
  Gumbel-max exploration, nor the uniform random actions before ``learning_starts`` pick them.
"""

from collections.abc import Sequence

import numpy as np
from gymnasium import spaces
from pettingzoo.utils.env import ParallelEnv

from sb3_maddpg.common.actions import action_width, check_action_space


class AgentSpaces:
    """
    Each agent's own observation and action space, in the order of the VecEnv's rows inside a copy.

    :param observation_spaces: one Box per agent, all with the same number of dimensions and dtype
    :param action_spaces: one Box (1-D) per agent, or one Discrete per agent
    """

    def __init__(
        self, observation_spaces: Sequence[spaces.Box], action_spaces: Sequence[spaces.Box | spaces.Discrete]
    ) -> None:
        self.observation_spaces = tuple(observation_spaces)
        self.action_spaces = tuple(action_spaces)
        if not self.observation_spaces or len(self.observation_spaces) != len(self.action_spaces):
            raise ValueError(
                "AgentSpaces needs one observation space and one action space per agent (at least one agent), "
                f"got {len(self.observation_spaces)} and {len(self.action_spaces)}"
            )

    @property
    def n_agents(self) -> int:
        return len(self.observation_spaces)

    @property
    def homogeneous(self) -> bool:
        """All agents have the first agent's spaces: nothing is padded."""
        first_obs, first_action = self.observation_spaces[0], self.action_spaces[0]
        return all(space == first_obs for space in self.observation_spaces) and all(
            space == first_action for space in self.action_spaces
        )

    @property
    def padded_observation_shape(self) -> tuple[int, ...]:
        return tuple(int(size) for size in np.max([space.shape for space in self.observation_spaces], axis=0))

    @property
    def action_widths(self) -> np.ndarray:
        """Each agent's action width (N,): its Box's size, or its Discrete's n."""
        return np.array([action_width(space) for space in self.action_spaces], dtype=np.int64)

    def observation_mask(self) -> np.ndarray:
        """(N, *padded_observation_shape) booleans: True where agent i's padded observation holds its own entries."""
        shape = self.padded_observation_shape
        mask = np.zeros((self.n_agents, *shape), dtype=bool)
        for i, space in enumerate(self.observation_spaces):
            mask[(i, *(slice(0, size) for size in space.shape))] = True
        return mask

    def action_mask(self) -> np.ndarray:
        """(N, max width) booleans: True for agent i's own action entries (Box) or actions (Discrete)."""
        widths = self.action_widths
        return np.arange(int(widths.max()))[None, :] < widths[:, None]

    def __eq__(self, other: object) -> bool:
        return (
            isinstance(other, AgentSpaces)
            and self.observation_spaces == other.observation_spaces
            and self.action_spaces == other.action_spaces
        )

    def __hash__(self) -> int:
        return hash(repr(self))

    def __repr__(self) -> str:
        agents = ", ".join(
            f"{obs} / {action}" for obs, action in zip(self.observation_spaces, self.action_spaces, strict=True)
        )
        return f"AgentSpaces({agents})"


def read_agent_spaces(parallel_env: ParallelEnv, algorithm: str = "MADDPG") -> AgentSpaces:
    """
    Read and check every agent's spaces. Agents may differ in their observations' sizes (vectors of different
    lengths, images of different sizes) and in their actions' widths (Box sizes, or Discrete n), but all observation
    spaces must be Boxes with the same number of dimensions and dtype, and the action spaces all 1-D Boxes or all
    Discrete (starting at 0) with the same bounds on the entries they share.

    :param parallel_env: the environment
    :param algorithm: the algorithm's name, for the messages
    :return: the agents' spaces
    """
    agents = list(getattr(parallel_env, "possible_agents", []))
    if not agents:
        raise ValueError("the ParallelEnv must list its agents in `possible_agents` (at least one)")
    observation_spaces = [parallel_env.observation_space(agent) for agent in agents]
    action_spaces = [parallel_env.action_space(agent) for agent in agents]
    for agent, obs_space, action_space in zip(agents, observation_spaces, action_spaces, strict=True):
        if not isinstance(obs_space, spaces.Box):
            raise TypeError(f"{algorithm} accepts Box observation spaces (vectors or images), got {obs_space} for {agent!r}")
        check_action_space(action_space, f"{algorithm} (agent {agent!r})")
    first = agents[0]
    layout = AgentSpaces(observation_spaces, action_spaces)
    if layout.homogeneous:
        return layout
    described = "; ".join(
        f"{agent!r}: {obs} / {action}" for agent, obs, action in zip(agents, observation_spaces, action_spaces, strict=True)
    )
    for agent, obs_space in zip(agents, observation_spaces, strict=True):
        if len(obs_space.shape) != len(observation_spaces[0].shape) or obs_space.dtype != observation_spaces[0].dtype:
            raise ValueError(
                "agents with observation spaces of their own must share the number of dimensions and the dtype "
                f"(vectors of different lengths, or images of different sizes); {first!r} has {observation_spaces[0]} "
                f"but {agent!r} has {obs_space}"
            )
    kinds = {isinstance(space, spaces.Discrete) for space in action_spaces}
    if len(kinds) > 1:
        raise ValueError(f"agents must all have Box actions or all Discrete actions, not a mix ({described})")
    if isinstance(action_spaces[0], spaces.Discrete):
        starts = {int(space.start) for space in action_spaces}  # type: ignore[union-attr]
        if starts != {0}:
            raise ValueError(f"agents with Discrete action spaces of different sizes must start them at 0 ({described})")
    else:
        _check_shared_bounds(action_spaces, described)  # type: ignore[arg-type]
    return layout


def _check_shared_bounds(action_spaces: Sequence[spaces.Box], described: str) -> None:
    """The padded action space has one pair of bounds per entry: agents must agree on the entries they share."""
    width = max(space.shape[0] for space in action_spaces)
    low = np.full(width, np.nan)
    high = np.full(width, np.nan)
    for space in action_spaces:
        size = space.shape[0]
        known = ~np.isnan(low[:size])
        if np.any(known & ((low[:size] != space.low) | (high[:size] != space.high))):
            raise ValueError(
                "agents with Box actions of different widths must have the same bounds on the entries they share "
                f"(the padded action space has one pair of bounds per entry); got {described}"
            )
        low[:size] = space.low
        high[:size] = space.high
