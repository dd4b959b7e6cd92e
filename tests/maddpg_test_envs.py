"""Tiny PettingZoo ParallelEnvs for the algorithm's tests (no dependency on the project's own environment)."""

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv


class TargetReachEnv(ParallelEnv):
    """
    Cooperative vector-observation task. Each agent i sits at p_i in [-1, 1]^2 and has a target g_i; it sees
    (p_i, g_i) and moves by 0.3 * a_i with a_i in [-1, 1]^2 (positions clipped to the square). All agents receive
    the team reward -mean_i ||p_i - g_i|| after moving. Episodes are truncated after ``max_cycles`` steps;
    with ``terminate_on_success`` they terminate once every agent is within 0.1 of its target.

    :param n_agents: number of agents
    :param max_cycles: episode length
    :param terminate_on_success: end the episode (termination) when all agents reached their targets
    :param action_low: lower bound of the action box (the box is rescaled to [-1, 1] internally)
    """

    metadata = {"render_modes": [], "name": "target_reach_v0"}

    def __init__(self, n_agents: int = 2, max_cycles: int = 5, terminate_on_success: bool = False, action_low: float = -1.0):
        self.possible_agents = [f"agent_{i}" for i in range(n_agents)]
        self.agents = []
        self.max_cycles = max_cycles
        self.terminate_on_success = terminate_on_success
        self.action_low = action_low
        self.render_mode = None
        self._rng = np.random.default_rng()

    def observation_space(self, agent):
        return spaces.Box(-1.0, 1.0, (4,), np.float32)

    def action_space(self, agent):
        return spaces.Box(self.action_low, 1.0, (2,), np.float32)

    def _obs(self):
        return {a: np.concatenate([self.pos[i], self.goal[i]]).astype(np.float32) for i, a in enumerate(self.agents)}

    def reset(self, seed=None, options=None):
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        self.agents = list(self.possible_agents)
        n = len(self.agents)
        self.pos = self._rng.uniform(-1, 1, (n, 2))
        self.goal = self._rng.uniform(-1, 1, (n, 2))
        self.t = 0
        return self._obs(), {a: {} for a in self.agents}

    def step(self, actions):
        act = np.stack([np.asarray(actions[a], dtype=np.float64) for a in self.agents])
        act = np.clip(act, self.action_low, 1.0)
        # rescale [low, 1] -> [-1, 1]
        act = 2.0 * (act - self.action_low) / (1.0 - self.action_low) - 1.0
        self.pos = np.clip(self.pos + 0.3 * act, -1, 1)
        self.t += 1
        dist = np.linalg.norm(self.pos - self.goal, axis=1)
        reward = float(-dist.mean())
        success = self.terminate_on_success and bool((dist < 0.1).all())
        truncated = self.t >= self.max_cycles and not success
        obs = self._obs()
        rewards = {a: reward for a in self.agents}
        terms = {a: success for a in self.agents}
        truncs = {a: truncated for a in self.agents}
        infos = {a: {"distance": float(dist[i])} for i, a in enumerate(self.agents)}
        if success or truncated:
            self.agents = []
        return obs, rewards, terms, truncs, infos


class CountingImageEnv(ParallelEnv):
    """
    Image-observation env whose observations encode (episode step, agent) so tests can check what was stored:
    every pixel of agent i's observation at step t equals ``(10 * t + i) % 256`` (uint8, shape (3, size, size)).
    Every info holds ``t``. Rewards are ``t + 0.1 * i``; episodes terminate after ``episode_length`` steps
    (or are truncated, with ``truncate=True``).

    :param n_agents: number of agents
    :param size: image side
    :param episode_length: steps per episode
    :param truncate: end episodes by truncation instead of termination
    """

    metadata = {"render_modes": [], "name": "counting_image_v0"}

    def __init__(self, n_agents: int = 2, size: int = 16, episode_length: int = 4, truncate: bool = False):
        self.possible_agents = [f"agent_{i}" for i in range(n_agents)]
        self.agents = []
        self.size = size
        self.episode_length = episode_length
        self.truncate = truncate
        self.render_mode = None
        self.t = 0

    def observation_space(self, agent):
        return spaces.Box(0, 255, (3, self.size, self.size), np.uint8)

    def action_space(self, agent):
        return spaces.Box(0.0, 1.0, (2,), np.float32)

    def _obs(self):
        return {a: np.full((3, self.size, self.size), (10 * self.t + i) % 256, np.uint8) for i, a in enumerate(self.agents)}

    def reset(self, seed=None, options=None):
        self.agents = list(self.possible_agents)
        self.t = 0
        return self._obs(), {a: {"t": 0} for a in self.agents}

    def step(self, actions):
        self.t += 1
        done = self.t >= self.episode_length
        obs = self._obs()
        rewards = {a: self.t + 0.1 * i for i, a in enumerate(self.agents)}
        terms = {a: done and not self.truncate for a in self.agents}
        truncs = {a: done and self.truncate for a in self.agents}
        infos = {a: {"t": self.t} for a in self.agents}
        if done:
            self.agents = []
        return obs, rewards, terms, truncs, infos


class DiscreteTargetReachEnv(TargetReachEnv):
    """
    ``TargetReachEnv`` with MPE's ``Discrete(5)`` moves instead of a Box: 0 stays, 1 to 4 move 0.3 left, right,
    down, up. ``step`` refuses anything but an integer of the space, so tests see what the env receives.

    :param n_agents: number of agents
    :param max_cycles: episode length
    """

    MOVES = np.array([[0.0, 0.0], [-1.0, 0.0], [1.0, 0.0], [0.0, -1.0], [0.0, 1.0]])
    metadata = {"render_modes": [], "name": "discrete_target_reach_v0"}

    def __init__(self, n_agents: int = 2, max_cycles: int = 5):
        super().__init__(n_agents=n_agents, max_cycles=max_cycles)

    def action_space(self, agent):
        return spaces.Discrete(5)

    def step(self, actions):
        for agent, action in actions.items():
            if not isinstance(action, int | np.integer) or not 0 <= action < 5:
                raise TypeError(f"{agent} got the action {action!r} ({type(action).__name__}), not an integer in [0, 5)")
        return super().step({agent: self.MOVES[action] for agent, action in actions.items()})


class MixedSpacesEnv(ParallelEnv):
    """
    Two agents with spaces of their own. The "mover" sits at p in [-1, 1]^2 with a target g, sees (p, g) (4 numbers)
    and moves by 0.3 * a, a in [-1, 1]^2. The "slider" sits at x in [-1, 1] with a target h, sees (x, h) (2 numbers)
    and moves by 0.3 * b, b in [-1, 1] (one number). Team reward: -(|p - g| + |x - h|) / 2. ``step`` refuses an
    action outside the agent's own space (shape included), so tests see what the env receives; with
    ``discrete=True`` the mover has MPE's Discrete(5) moves and the slider Discrete(3) (stay, left, right).

    :param max_cycles: episode length
    :param discrete: Discrete actions instead of Boxes
    """

    metadata = {"render_modes": [], "name": "mixed_spaces_v0"}
    MOVES = np.array([[0.0, 0.0], [-1.0, 0.0], [1.0, 0.0], [0.0, -1.0], [0.0, 1.0]])
    SLIDES = np.array([[0.0], [-1.0], [1.0]])

    def __init__(self, max_cycles: int = 5, discrete: bool = False):
        self.possible_agents = ["mover", "slider"]
        self.agents = []
        self.max_cycles = max_cycles
        self.discrete = discrete
        self.render_mode = None
        self._rng = np.random.default_rng()
        self.received: list[dict] = []

    def observation_space(self, agent):
        return spaces.Box(-1.0, 1.0, (4,) if agent == "mover" else (2,), np.float32)

    def action_space(self, agent):
        if self.discrete:
            return spaces.Discrete(5 if agent == "mover" else 3)
        return spaces.Box(-1.0, 1.0, (2,) if agent == "mover" else (1,), np.float32)

    def _obs(self):
        return {
            "mover": np.concatenate([self.pos, self.goal]).astype(np.float32),
            "slider": np.array([self.x, self.h], dtype=np.float32),
        }

    def reset(self, seed=None, options=None):
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        self.agents = list(self.possible_agents)
        self.pos, self.goal = self._rng.uniform(-1, 1, 2), self._rng.uniform(-1, 1, 2)
        self.x, self.h = self._rng.uniform(-1, 1), self._rng.uniform(-1, 1)
        self.t = 0
        return self._obs(), {a: {} for a in self.agents}

    def step(self, actions):
        for agent, action in actions.items():
            space = self.action_space(agent)
            if self.discrete and not isinstance(action, int | np.integer):
                raise TypeError(f"{agent} got {action!r} ({type(action).__name__}), not an integer")
            if not space.contains(np.asarray(action, dtype=space.dtype) if not self.discrete else int(action)):
                raise ValueError(f"{agent} got the action {action!r}, outside its space {space}")
        self.received.append(dict(actions))
        if self.discrete:
            move, slide = self.MOVES[actions["mover"]], self.SLIDES[actions["slider"]][0]
        else:
            move, slide = np.asarray(actions["mover"], dtype=np.float64), float(actions["slider"][0])
        self.pos = np.clip(self.pos + 0.3 * move, -1, 1)
        self.x = float(np.clip(self.x + 0.3 * slide, -1, 1))
        self.t += 1
        reward = -(np.linalg.norm(self.pos - self.goal) + abs(self.x - self.h)) / 2
        truncated = self.t >= self.max_cycles
        obs = self._obs()
        rewards = {a: float(reward) for a in self.agents}
        terms = {a: False for a in self.agents}
        truncs = {a: truncated for a in self.agents}
        infos = {a: {} for a in self.agents}
        if truncated:
            self.agents = []
        return obs, rewards, terms, truncs, infos


class MixedImageEnv(ParallelEnv):
    """
    Two agents whose image observations differ in size: agent_0 sees 2 x 16 x 16 pixels, agent_1 2 x 20 x 24, each
    filled with a value that encodes the step. Box actions of two numbers in [0, 1]; reward 1 per step.

    :param episode_length: steps per episode
    """

    metadata = {"render_modes": [], "name": "mixed_image_v0"}
    SHAPES = {"agent_0": (2, 16, 16), "agent_1": (2, 20, 24)}

    def __init__(self, episode_length: int = 4):
        self.possible_agents = ["agent_0", "agent_1"]
        self.agents = []
        self.episode_length = episode_length
        self.render_mode = None
        self.t = 0

    def observation_space(self, agent):
        return spaces.Box(0, 255, self.SHAPES[agent], np.uint8)

    def action_space(self, agent):
        return spaces.Box(0.0, 1.0, (2,), np.float32)

    def _obs(self):
        return {a: np.full(self.SHAPES[a], 20 * self.t + 7 * i + 1, np.uint8) for i, a in enumerate(self.agents)}

    def reset(self, seed=None, options=None):
        self.agents = list(self.possible_agents)
        self.t = 0
        return self._obs(), {a: {} for a in self.agents}

    def step(self, actions):
        self.t += 1
        done = self.t >= self.episode_length
        obs = self._obs()
        rewards = {a: 1.0 for a in self.agents}
        terms = {a: False for a in self.agents}
        truncs = {a: done for a in self.agents}
        infos = {a: {} for a in self.agents}
        if done:
            self.agents = []
        return obs, rewards, terms, truncs, infos
