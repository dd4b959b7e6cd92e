"""Groups of agents that share their networks (parameter sharing), from the ``groups`` argument of the algorithms."""

from collections.abc import Sequence
from typing import Any

from sb3_maddpg.common.agent_spaces import AgentSpaces
from sb3_maddpg.common.callbacks import agent_team

GROUPS_ACCEPTED = (
    "None (every agent its own actor and critic), 'teams' (the agents of each team by PettingZoo's naming share them: "
    "adversary_0, adversary_1, ... one group), or a list of groups, each a list of agent names (agents not listed "
    "keep their own)"
)


def check_groups(groups: Any) -> Any:
    """
    Check the form of a ``groups`` argument where it enters (the agents' names are checked once the env is known).

    :param groups: the argument
    :return: the argument
    :raises TypeError: if it is none of the accepted forms
    """
    if groups is None or (isinstance(groups, str) and groups == "teams"):
        return groups
    if isinstance(groups, Sequence) and not isinstance(groups, str):
        if all(isinstance(group, Sequence) and not isinstance(group, str) for group in groups):
            if all(isinstance(name, str) for group in groups for name in group):
                return groups
    raise TypeError(f"groups must be {GROUPS_ACCEPTED}; got {groups!r}")


def agent_groups(groups: Any, agent_names: Sequence[str], agent_spaces: AgentSpaces | None) -> tuple[int, ...] | None:
    """
    The group of each agent, numbered 0, 1, ... in the order of the agents' first appearance.

    :param groups: the ``groups`` argument (see :func:`check_groups`)
    :param agent_names: the team, in row order
    :param agent_spaces: each agent's own spaces where they differ (agents of one group must share them)
    :return: one group index per agent; None without groups
    :raises ValueError: an unknown or repeated agent name, or a group of agents with different spaces
    """
    check_groups(groups)
    if groups is None:
        return None
    names = [str(name) for name in agent_names]
    if groups == "teams":
        keys = [agent_team(name) for name in names]
    else:
        owner: dict[str, int] = {}
        for index, group in enumerate(groups):
            for name in group:
                if name not in names:
                    raise ValueError(f"groups: {name!r} is not an agent of this env; its agents: {', '.join(names)}")
                if name in owner:
                    raise ValueError(f"groups: {name!r} is in more than one group")
                owner[name] = index
        keys = [f"group {owner[name]}" if name in owner else f"agent {name}" for name in names]
    numbers: dict[str, int] = {}
    indices = tuple(numbers.setdefault(key, len(numbers)) for key in keys)
    if agent_spaces is not None:
        for group in set(indices):
            members = [i for i, index in enumerate(indices) if index == group]
            first = members[0]
            same = all(
                agent_spaces.observation_spaces[i] == agent_spaces.observation_spaces[first]
                and agent_spaces.action_spaces[i] == agent_spaces.action_spaces[first]
                for i in members
            )
            if not same:
                raise ValueError(
                    f"groups: the agents {', '.join(names[i] for i in members)} share networks but not their spaces; "
                    "a group holds agents with the same observation and action spaces"
                )
    return indices
