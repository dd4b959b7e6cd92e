"""PettingZoo ``ParallelEnv`` over :class:`~sb3_maddpg_envs.uav_coverage.core.UAVCoverageCore`.

All UAVs move at once, so the parallel env is the real one; the AEC form is PettingZoo's ``parallel_to_aec``.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.utils import EzPickle
from pettingzoo import ParallelEnv
from pettingzoo.utils import wrappers
from pettingzoo.utils.conversions import parallel_to_aec
from pettingzoo.utils.env import AECEnv

from ..validation import MAX_STEPS, check_int
from .core import UAVCoverageCore
from .task_tools import TASK_TOOLS

__all__ = ["UAVCoverageEnv", "env", "parallel_env", "raw_env"]


@dataclass(frozen=True)
class UAVCoverageSnapshot:
    """
    The state of an episode, taken by ``UAVCoverageEnv.snapshot`` and given back by ``restore``: the simulation with
    its random generator, and the live agents. A private copy: stepping the env changes nothing in it.
    """

    core: UAVCoverageCore
    agents: tuple[str, ...]


class UAVCoverageEnv(ParallelEnv, EzPickle):
    """
    Multi-UAV coverage as a PettingZoo ``ParallelEnv``.

    Agents ``uav_0 ... uav_{N-1}``; observation ``Box(0, 255, (C, S, S), uint8)`` (C = 3, or 4 with
    ``teammate_channel=True``); action ``Box(0, 1, (2,), float32)``
    = (direction / 2 pi, distance / l_max). Every agent's info holds ``coverage``, ``fairness``, ``energy``,
    ``energy_efficiency``, ``wall_hits`` and ``disconnections`` at every step (and after reset).

    :param render_mode: ``None`` or ``"rgb_array"``
    :param name: the env's name in ``metadata`` (the versioned modules set it)
    :param core_kwargs: the parameters of :class:`~.config.UAVCoverageConfig` (``map_size``, ``n_uavs``, ``pois``, ...)
    """

    metadata = {
        "render_modes": ["rgb_array"],
        "name": "uav_coverage_v0",
        "is_parallelizable": True,
        "render_fps": 10,
        # The info keys reported at an episode's end that a training run logs (sb3_maddpg's EpisodeMetricsCallback
        # and the monitor file); wall hits and disconnections count one UAV's events, the team's are their sum
        "episode_metrics": ("coverage", "fairness", "energy", "energy_efficiency", "wall_hits", "disconnections"),
        "per_agent_episode_metrics": ("wall_hits", "disconnections"),
    }
    # What sb3_maddpg's evaluation may ask of the task beyond the PettingZoo API (its plug-in point): the greedy
    # baselines, the random start of evaluation episodes, the heat map and the TensorBoard pictures
    task_tools = TASK_TOOLS

    def __init__(self, render_mode: str | None = None, name: str = "uav_coverage_v0", **core_kwargs: Any) -> None:
        EzPickle.__init__(self, render_mode=render_mode, name=name, **core_kwargs)
        self.metadata = {**self.metadata, "name": name}
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be None or one of {self.metadata['render_modes']}, got {render_mode!r}")
        self.render_mode = render_mode
        self.core = UAVCoverageCore(**core_kwargs)
        n, size, channels = self.core.n_uavs, self.core.obs_size, self.core.n_obs_channels
        self.possible_agents = [f"uav_{i}" for i in range(n)]
        self.agents: list[str] = []
        # One space object per agent, built once: observation_space(agent) must return the same object every call, and
        # separate objects let each agent's action space be seeded on its own.
        self._observation_spaces = {
            agent: spaces.Box(0, 255, (channels, size, size), dtype=np.uint8) for agent in self.possible_agents
        }
        self._action_spaces = {agent: spaces.Box(0.0, 1.0, (2,), dtype=np.float32) for agent in self.possible_agents}
        self.state_space = spaces.Box(0, 255, (3, size, size), dtype=np.uint8)

    # -----------------------------------------------------------------------------------------------------------------
    def observation_space(self, agent: str) -> spaces.Box:
        return self._observation_spaces[agent]

    def action_space(self, agent: str) -> spaces.Box:
        return self._action_spaces[agent]

    @property
    def np_random(self) -> np.random.Generator | None:
        """The generator the episodes draw from (seeded by ``reset(seed=...)``); None before the first reset."""
        return self.core._rng

    @property
    def max_cycles(self) -> int:
        """T, steps per episode (PettingZoo's test helpers set it)."""
        return self.core.max_cycles

    @max_cycles.setter
    def max_cycles(self, value: int) -> None:
        self.core.max_cycles = check_int("max_cycles", value, low=1, high=MAX_STEPS)

    def snapshot(self) -> UAVCoverageSnapshot:
        """
        The episode's state, to come back to with ``restore``: what a step does next depends on nothing else, hazards'
        random draws included. A candidate action's return over H steps then costs H steps instead of a replay of the
        episode (``copy.deepcopy`` of the env does not serve: like every ``EzPickle`` env it builds a new env from the
        constructor's arguments).

        :return: a private copy of the state
        """
        return UAVCoverageSnapshot(copy.deepcopy(self.core), tuple(self.agents))

    def restore(self, snapshot: UAVCoverageSnapshot) -> None:
        """
        Return to a state taken by ``snapshot`` (any number of times: the snapshot stays as it was).

        :param snapshot: from ``snapshot`` of an env with the same agents
        """
        if not isinstance(snapshot, UAVCoverageSnapshot):
            raise TypeError(f"restore takes a UAVCoverageSnapshot from snapshot(), got {type(snapshot).__name__}")
        if snapshot.core.n_uavs != self.core.n_uavs:
            raise ValueError(f"the snapshot has {snapshot.core.n_uavs} UAVs, this env {self.core.n_uavs}")
        self.core = copy.deepcopy(snapshot.core)
        self.agents = list(snapshot.agents)

    # -----------------------------------------------------------------------------------------------------------------
    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, dict[str, Any]]]:
        """
        Start an episode.

        :param seed: seeds the environment's random generator (start positions, uniform PoIs)
        :param options: unused
        :return: observations and infos, one entry per agent
        """
        obs = self.core.reset(seed=seed)
        self.agents = self.possible_agents[:]
        infos = self.core.infos()
        return dict(zip(self.agents, obs, strict=True)), dict(zip(self.agents, infos, strict=True))

    def step(
        self, actions: dict[str, np.ndarray]
    ) -> tuple[
        dict[str, np.ndarray],
        dict[str, float],
        dict[str, bool],
        dict[str, bool],
        dict[str, dict[str, Any]],
    ]:
        """
        Move every UAV at once.

        :param actions: one action per live agent, each in [0, 1]^2 (values outside are clipped)
        :return: observations, rewards, terminations, truncations and infos, one entry per agent
        :raises ValueError: if an agent's action is missing or not finite
        """
        agents = self.agents
        if not agents:
            raise RuntimeError("the episode has ended: call reset() before step()")
        unknown = set(actions) - set(agents)
        if unknown:
            raise ValueError(f"actions names agents that are not live: {sorted(map(str, unknown))}; live agents: {agents}")
        joint = np.empty((len(agents), 2), dtype=np.float64)
        for i, agent in enumerate(agents):
            if agent not in actions:
                raise ValueError(f"actions is missing the action of agent {agent!r}; every live agent must act")
            try:
                joint[i] = np.asarray(actions[agent], dtype=np.float64).reshape(2)
            except (TypeError, ValueError) as error:
                raise ValueError(
                    f"the action of agent {agent!r} must be 2 numbers (direction, distance ratio) in [0, 1], "
                    f"got {actions[agent]!r}"
                ) from error
        obs, rewards, terminated, truncated = self.core.step(joint)
        infos = self.core.infos()
        observations = dict(zip(agents, obs, strict=True))
        reward_dict = dict(zip(agents, rewards.tolist(), strict=True))
        terminations = dict.fromkeys(agents, terminated)
        truncations = dict.fromkeys(agents, truncated)
        info_dict = dict(zip(agents, infos, strict=True))
        if terminated or truncated:
            self.agents = []
        return observations, reward_dict, terminations, truncations, info_dict

    def state(self) -> np.ndarray:
        """Global view (3, S, S) uint8: the observation image with channel 1 showing every active UAV."""
        return self.core.state()

    def render(self) -> np.ndarray | None:
        """
        Draw the map as an RGB frame.

        :return: (H, W, 3) uint8 with ``render_mode="rgb_array"``, otherwise None (with a warning)
        """
        if self.render_mode is None:
            import gymnasium

            gymnasium.logger.warn(
                "You are calling render() without specifying a render mode: pass render_mode='rgb_array' to the env."
            )
            return None
        from .rendering import render_frame

        return render_frame(self.core)

    def close(self) -> None:
        """Nothing to release: rendering draws off-screen."""


def parallel_env(**kwargs: Any) -> UAVCoverageEnv:
    """
    The environment as a PettingZoo ``ParallelEnv``.

    :param kwargs: ``render_mode`` and the parameters of :class:`~.config.UAVCoverageConfig`
    """
    return UAVCoverageEnv(**kwargs)


def raw_env(**kwargs: Any) -> AECEnv:
    """
    The environment as an AEC env (PettingZoo's ``parallel_to_aec``), without wrappers.

    :param kwargs: ``render_mode`` and the parameters of :class:`~.config.UAVCoverageConfig`
    """
    return parallel_to_aec(parallel_env(**kwargs))


def env(**kwargs: Any) -> AECEnv:
    """
    The environment as a wrapped AEC env.

    Only the order-enforcing wrapper is added: the env itself clips out-of-range actions and raises ``ValueError`` on
    NaN, so PettingZoo's clipping wrapper would only add a warning per step (and an ``AssertionError`` on NaN).

    :param kwargs: ``render_mode`` and the parameters of :class:`~.config.UAVCoverageConfig`
    """
    return wrappers.OrderEnforcingWrapper(raw_env(**kwargs))
