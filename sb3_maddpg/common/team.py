"""
The team of a multi-agent algorithm: its agents, their names and spaces, read from the VecEnv of
``make_multiagent_vec_env`` (one row per agent and copy, row = copy * n_agents + agent), the refusal of another team
in ``predict``, ``set_env`` and ``load(env=...)``, and the actions of agents with spaces of their own.

``MultiAgentTeam`` is a mixin of ``MultiAgentOffPolicyAlgorithm`` (``sb3_maddpg.common.off_policy_algorithm``), which
reads the team when it is built; it overrides SB3's ``set_env`` and ``predict`` and calls theirs.
"""

from typing import Any

import numpy as np
from stable_baselines3.common.noise import ActionNoise, VectorizedActionNoise
from stable_baselines3.common.type_aliases import GymEnv
from stable_baselines3.common.vec_env import VecEnv

from sb3_maddpg.common.actions import is_discrete
from sb3_maddpg.common.agent_spaces import AgentSpaces
from sb3_maddpg.common.validation import check_int
from sb3_maddpg.common.vec_env import is_agent_dict, rows_from_agent_dict


def default_agent_names(n_agents: int) -> list[str]:
    """The names of a team whose env does not name its agents: ``agent_0``, ``agent_1``, ..."""
    return [f"agent_{i}" for i in range(n_agents)]


def _describe_team(names: list[str]) -> str:
    shown = ", ".join(names) if len(names) <= 8 else f"{', '.join(names[:3])}, ..., {names[-1]}"
    return f"{len(names)} agent{'s' if len(names) != 1 else ''} ({shown})"


def first_non_finite(values: np.ndarray) -> str:
    """The first NaN or infinite value of an array and its index, for messages."""
    if values.ndim == 0:
        return str(values)
    index = np.unravel_index(int(np.flatnonzero(~np.isfinite(values))[0]), values.shape)
    return f"{values[index]} at index {tuple(int(i) for i in index)}"


class MultiAgentTeam:
    """
    The team's part of ``MultiAgentOffPolicyAlgorithm`` (a mixin before SB3's ``OffPolicyAlgorithm`` in its bases):
    ``n_agents``, ``agent_names``, ``agent_spaces`` (each agent's own spaces where they differ, the VecEnv's being
    padded; None when all agents share them) and ``departures`` (agents may leave before the episode ends).
    """

    n_agents: int | None
    agent_names: list[str] | None
    agent_spaces: AgentSpaces | None
    departures: bool

    @property
    def n_copies(self) -> int:
        """Number of environment copies: VecEnv rows / n_agents."""
        assert self.n_agents is not None
        return self.n_envs // self.n_agents

    def _read_agents(self, env: VecEnv, n_agents: int | None) -> None:
        """Set ``n_agents`` and ``agent_names`` from the env (or the argument) and check the VecEnv's rows and team."""
        env_n_agents = getattr(env, "n_agents", None)
        if n_agents is not None:
            check_int("n_agents", n_agents, low=1)
        names = getattr(env, "possible_agents", None)
        if env_n_agents is not None and n_agents is not None and env_n_agents != n_agents:
            if self.agent_names is not None and names is not None:
                # a model that knows its team (loaded, or set_env) on a VecEnv of another team
                self.check_team([str(name) for name in names], "the VecEnv")
            raise ValueError(f"n_agents={n_agents} disagrees with the env's n_agents={env_n_agents}")
        n_agents = n_agents if n_agents is not None else env_n_agents
        if n_agents is None:
            n_agents = self.n_agents  # restored by load()
        if n_agents is None:
            raise ValueError(
                f"{type(self).__name__} needs the number of agents: build the env with "
                "sb3_maddpg.make_multiagent_vec_env (it sets `n_agents`) or pass n_agents=..."
            )
        if env.num_envs % n_agents != 0:
            raise ValueError(
                f"the VecEnv has {env.num_envs} rows, which is not a multiple of n_agents={n_agents}; "
                "rows must be agent-major inside each copy (row = copy * n_agents + agent)"
            )
        env_agent_spaces = getattr(env, "agent_spaces", None)
        if self.agent_names is not None and env_agent_spaces != self.agent_spaces:
            # a model that knows its team's spaces (loaded, or set_env) on a VecEnv whose agents' spaces differ
            raise ValueError(
                f"this {type(self).__name__} model's agents have the spaces {self.agent_spaces or 'of the VecEnv'}, "
                f"but the VecEnv's agents have {env_agent_spaces or 'its spaces'}"
            )
        self.agent_spaces = env_agent_spaces
        # Agents may leave before the episode ends (make_multiagent_vec_env's black_death): the losses read it
        self.departures = bool(getattr(env, "departures", False))
        self.n_agents = int(n_agents)
        if names is not None and len(names) == self.n_agents:
            names = [str(name) for name in names]
            if self.agent_names is not None and self.agent_names != default_agent_names(self.n_agents):
                self.check_team(names, "the VecEnv")
            self.agent_names = names
        elif self.agent_names is None or len(self.agent_names) != self.n_agents:
            self.agent_names = default_agent_names(self.n_agents)

    def _check_action_noise(self, action_noise: ActionNoise | None, n_rows: int) -> None:
        """
        Refuse a noise of another shape than the actions (NumPy would broadcast a 1-D noise silently, or fail at the
        first step), or a ``VectorizedActionNoise`` for another number of VecEnv rows.
        """
        if action_noise is None:
            return
        if is_discrete(self.action_space):
            raise ValueError(
                f"action_noise applies to continuous (Box) actions; with {self.action_space} actions the rollouts explore "
                "by sampling the actors' logits (Gumbel-max): leave action_noise=None"
            )
        action_shape = tuple(self.action_space.shape)  # type: ignore[arg-type]
        if isinstance(action_noise, VectorizedActionNoise):
            if action_noise.n_envs != n_rows:
                raise ValueError(
                    f"action_noise is a VectorizedActionNoise for {action_noise.n_envs} rows, but the VecEnv has {n_rows} "
                    f"rows ({self.n_copies} copies x {self.n_agents} agents); give one noise of shape {action_shape} "
                    "and it is applied to every row"
                )
            action_noise = action_noise.noises[0]
        mean = getattr(action_noise, "_mu", None)
        if mean is not None and np.shape(mean) != action_shape:
            raise ValueError(
                f"action_noise has shape {np.shape(mean)}, but each agent's action has shape {action_shape}: give a "
                f"mean (and sigma) of shape {action_shape}"
            )

    def check_team(self, names: list[str], where: str) -> None:
        """
        Refuse a team other than the model's: a model of N agents reads the rows of a larger team as several copies
        of its own, and would act and report plausible but wrong numbers.

        :param names: the agents of the VecEnv (or observations) the model is asked to act on, in row order
        :param where: what holds them, for the message
        :raises ValueError: naming both teams
        """
        assert self.n_agents is not None
        own = self.agent_names or default_agent_names(self.n_agents)
        same_names = own == names or own == default_agent_names(self.n_agents)
        if len(names) != self.n_agents or not same_names:
            raise ValueError(
                f"this {type(self).__name__} model acts for a team of {_describe_team(own)}, but {where} has a team "
                f"of {_describe_team(names)}; use an env with the model's team (the same agents and n_agents)"
            )

    def set_env(self, env: GymEnv, force_reset: bool = True) -> None:
        names = getattr(env, "possible_agents", None)
        if names is not None:
            self.check_team([str(name) for name in names], "the VecEnv")
        super().set_env(env, force_reset=force_reset)
        assert self.env is not None
        self._read_agents(self.env, self.n_agents)

    def predict(
        self,
        observation: np.ndarray | dict[str, np.ndarray],
        state: tuple[np.ndarray, ...] | None = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = False,
    ) -> tuple[np.ndarray | dict[str, np.ndarray], tuple[np.ndarray, ...] | None]:
        """
        Actions of SB3's rows (row = copy * n_agents + agent; row r is acted on by the policy's agent r mod n_agents),
        or, given a PettingZoo ``ParallelEnv``'s observation dict (agent -> observation), the dict of the agents' actions.

        Observations from ``make_multiagent_vec_env`` carry their team (:class:`~sb3_maddpg.common.vec_env.AgentRows`):
        those of another team than the model's are refused, wherever they come from (``evaluate_policy``, RL Zoo's
        ``enjoy``, a loop of your own).

        :param observation: the observation rows, or a dict agent -> observation of the model's agents (those still
            in the episode; an agent missing from the dict gets no action)
        :param state: unused (no recurrent policy)
        :param episode_start: unused
        :param deterministic: unused: the actors are deterministic, exploration noise is added during ``learn``
        :return: the actions (rows, or a dict agent -> action) and None
        """
        if is_agent_dict(observation):
            assert self.agent_names is not None
            self._check_agent_observations(observation)  # type: ignore[arg-type]
            padded_shape = tuple(self.observation_space.shape) if self.agent_spaces is not None else None  # type: ignore[arg-type]
            rows, agents = rows_from_agent_dict(observation, self.agent_names, padded_shape)  # type: ignore[arg-type]
            actions, state = self.predict(rows, state, episode_start, deterministic)
            return {
                agent: self._own_action(row, actions[row]) for row, agent in enumerate(self.agent_names) if agent in agents
            }, state
        names = getattr(observation, "possible_agents", None)
        if names is not None:
            self.check_team(list(names), "the observations' VecEnv")
        if isinstance(observation, np.ndarray):
            expected = np.dtype(self.observation_space.dtype)
            if expected.kind in "ui" and observation.dtype.kind == "f":
                raise TypeError(
                    f"predict: the observations are {observation.dtype}, but the model's observation space is {expected} "
                    f"(images of 0-255, as the env gives them); pass the env's observations unchanged"
                )
            if observation.dtype.kind == "f" and not np.isfinite(observation).all():
                raise ValueError(f"predict: the observations hold NaN or infinite values ({first_non_finite(observation)})")
        return super().predict(observation, state, episode_start, deterministic)

    def _check_agent_observations(self, observations: dict[str, Any]) -> None:
        """
        Refuse, naming the agent, an observation of a PettingZoo dict that is not of the agent's own shape: another
        agent's (which may fit the padded rows), or, for a model trained with ``black_death=True``, one without the
        in-episode entry those observations end with.

        :param observations: agent -> observation, as ``predict`` gets them
        """
        assert self.agent_names is not None and self.n_agents is not None
        if self.agent_spaces is not None:
            shapes = [tuple(space.shape) for space in self.agent_spaces.observation_spaces]
        else:
            shapes = [tuple(self.observation_space.shape)] * self.n_agents  # type: ignore[arg-type]
        for agent, value in observations.items():
            if agent not in self.agent_names:
                continue  # named by rows_from_agent_dict, with the team
            shape, own = np.shape(value), shapes[self.agent_names.index(agent)]
            if shape == own:
                continue
            if self.departures and shape[:-1] == own[:-1] and shape[-1:] == (own[-1] - 1,):
                raise ValueError(
                    f"predict: the observation of {agent!r} has {shape[-1]} entries, and the model's {own[-1]}: it was "
                    "trained with black_death=True, whose observations end with an in-episode entry (1.0 while the agent "
                    "is in the episode, 0.0 once it has left); pass np.append(observation, 1.0) for each agent in the "
                    "dict, or step the env made by make_multiagent_vec_env(..., black_death=True)"
                )
            if self.agent_spaces is not None:
                raise ValueError(
                    f"predict: the observation of {agent!r} has the shape {shape}, but {agent!r}'s own observations "
                    f"have the shape {own}; pass each agent its own observation (another agent's width is not accepted, "
                    "even where it fits the padded rows)"
                )

    def _own_action(self, agent: int, action: np.ndarray) -> np.ndarray:
        """Agent ``agent``'s action in its own space: a padded Box action cut to the agent's width."""
        if self.agent_spaces is None or is_discrete(self.action_space):
            return action
        return action[: int(self.agent_spaces.action_widths[agent])]

    def _mask_padded_actions(self, action: np.ndarray, buffer_action: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """
        For agents with action spaces of their own: no padded entry reaches the replay buffer. Box: the padded
        entries (random, or exploration noise) become 0. Discrete: a random action beyond an agent's n is drawn
        again from the agent's own actions (uniformly, with the action space's generator).

        :param action: the env's actions (rows)
        :param buffer_action: the actions to store (rows)
        :return: both, masked
        """
        if self.agent_spaces is None:
            return action, buffer_action
        assert self.n_agents is not None
        widths = np.tile(self.agent_spaces.action_widths, len(action) // self.n_agents)  # (rows,)
        if is_discrete(self.action_space):
            start = int(self.action_space.start)  # type: ignore[attr-defined]
            invalid = np.asarray(action) - start >= widths
            if invalid.any():
                action = np.array(action, copy=True)
                action[invalid] = start + self.action_space.np_random.integers(0, widths[invalid])
            return action, action
        padded = np.arange(buffer_action.shape[-1])[None, :] >= widths[:, None]
        buffer_action = np.where(padded, 0.0, buffer_action).astype(buffer_action.dtype, copy=False)
        return self.policy.unscale_action(buffer_action), buffer_action
