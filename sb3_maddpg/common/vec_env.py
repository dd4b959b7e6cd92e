"""
From a PettingZoo ParallelEnv to an SB3 VecEnv with one row per agent and environment copy, in this process
(``MultiAgentVecEnv``); the copies in worker processes are ``sb3_maddpg.common.subproc_vec_env``'s, and
``make_multiagent_vec_env`` (``sb3_maddpg.common.env_util``) builds either.
"""

import time
from copy import deepcopy
from typing import Any

import numpy as np
import supersuit as ss
from pettingzoo.utils.env import ParallelEnv
from pettingzoo.utils.wrappers import BaseParallelWrapper
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper
from stable_baselines3.common.vec_env.base_vec_env import VecEnvIndices, VecEnvStepReturn

from sb3_maddpg.common.agent_spaces import AgentSpaces, read_agent_spaces
from sb3_maddpg.common.departures import KeepDepartedAgents


class AgentRows(np.ndarray):
    """
    The observations of a multi-agent VecEnv: a plain ``np.ndarray`` of rows (row = copy * n_agents + agent) that also
    carries the env's team in ``possible_agents``, so that ``MADDPG.predict`` can refuse observations of another team
    (a 2-agent model would otherwise read 4 UAVs as 2 copies of its team). Views and slices keep the team; pickling
    and ``np.asarray`` give a plain array.
    """

    possible_agents: tuple[str, ...] | None = None

    def __array_finalize__(self, obj: Any) -> None:
        if obj is not None:
            self.possible_agents = getattr(obj, "possible_agents", None)

    def __reduce_ex__(self, protocol: Any) -> Any:
        # Saved as a plain array: files never refer to this class
        return np.asarray(self).__reduce_ex__(protocol)


def tag_team(observations: np.ndarray, possible_agents: tuple[str, ...]) -> AgentRows:
    """
    :param observations: a VecEnv's observation rows
    :param possible_agents: the team, in row order inside a copy
    :return: the same data as :class:`AgentRows` carrying the team
    """
    tagged = np.asarray(observations).view(AgentRows)
    tagged.possible_agents = possible_agents
    return tagged


def is_agent_dict(observation: Any) -> bool:
    """
    :param observation: what ``predict`` was given
    :return: whether it is a PettingZoo ``ParallelEnv``'s observation dict (agent -> observation)
    """
    return isinstance(observation, dict)


def rows_from_agent_dict(
    observations: dict[str, Any], agents: list[str], padded_shape: tuple[int, ...] | None = None
) -> tuple[AgentRows, set[str]]:
    """
    The rows of one environment copy from a PettingZoo observation dict, in the team's row order.

    :param observations: agent -> observation, for the agents still in the episode (a subset of ``agents``)
    :param agents: the team, in row order
    :param padded_shape: for agents with observation spaces of their own, the padded shape: each observation is
        padded with zeros at the end of each dimension (SuperSuit's ``pad_observations_v0``)
    :return: the rows (an agent missing from the dict gets a row of zeros) and the agents present
    """
    unknown = [str(agent) for agent in observations if agent not in agents]
    if unknown or not observations:
        raise ValueError(
            f"expected an observation dict of the team's agents ({', '.join(agents)}), got the keys "
            f"{', '.join(map(str, observations)) or 'none'}"
        )
    arrays = {agent: np.asarray(observation) for agent, observation in observations.items()}
    if padded_shape is not None:
        for agent, array in arrays.items():
            if array.ndim != len(padded_shape) or any(
                size > padded for size, padded in zip(array.shape, padded_shape, strict=True)
            ):
                raise ValueError(
                    f"the observation of {agent!r} has the shape {array.shape}, which does not fit the padded {padded_shape}"
                )
            arrays[agent] = np.pad(array, [(0, padded - size) for size, padded in zip(array.shape, padded_shape, strict=True)])
    first = next(iter(arrays.values()))
    rows = np.stack([arrays[agent] if agent in arrays else np.zeros_like(first) for agent in agents])
    return tag_team(rows, tuple(agents)), set(observations)


def env_generator(env: Any) -> np.random.Generator | None:
    """
    The random generator of a ParallelEnv, where it can be read: its ``np_random`` attribute (Gymnasium's name).

    :param env: the environment
    :return: the generator, or None
    """
    try:
        generator = getattr(env, "np_random", None)
    except Exception:  # a property that fails before the first reset
        return None
    return generator if isinstance(generator, np.random.Generator) else None


class _SeparateResetInfos(BaseParallelWrapper):
    """
    Hands SuperSuit empty reset infos and keeps the real ones in ``last_reset_infos``.

    At an automatic reset SuperSuit merges the reset infos into the final step's infos, so keys present in both
    (e.g. ``coverage``) would report the new episode's first value instead of the finished episode's last one.
    ``MultiAgentVecEnv`` puts the reset infos in ``reset_infos`` instead, as SB3's own VecEnvs do.

    :param env: the ParallelEnv
    """

    def __init__(self, env: ParallelEnv) -> None:
        super().__init__(env)
        self.last_reset_infos: dict[str, dict[str, Any]] = {}
        # How the last reset can be replayed: the seed of the last seeded reset, whether the last reset was seeded, and
        # otherwise the generator state just before it (None where the env's generator cannot be read)
        self.reset_record: dict[str, Any] = {"seed": None, "seeded": False, "generator": None}

    @property
    def possible_agents(self) -> list[str]:  # type: ignore[override]
        return self.env.possible_agents

    @property
    def agents(self) -> list[str]:  # type: ignore[override]
        return self.env.agents

    @property
    def metadata(self) -> dict[str, Any]:  # type: ignore[override]
        return self.env.metadata

    @property
    def render_mode(self) -> str | None:  # type: ignore[override]
        return getattr(self.env, "render_mode", None)

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        generator = env_generator(self.env)
        self.reset_record = {
            "seed": seed if seed is not None else self.reset_record["seed"],
            "seeded": seed is not None,
            "generator": None if seed is not None or generator is None else deepcopy(generator.bit_generator.state),
        }
        observations, infos = self.env.reset(seed=seed, options=options)
        self.last_reset_infos = infos
        self._check_whole_team(observations, "missing at reset")
        return observations, {agent: {} for agent in observations}

    def step(self, actions: dict) -> tuple[dict, dict, dict, dict, dict]:
        observations, rewards, terminations, truncations, infos = self.env.step(actions)
        if self.env.agents:  # at an episode's end every agent may leave at once
            self._check_whole_team(observations, "left before the episode's end", self.env.agents)
        return observations, rewards, terminations, truncations, infos

    def _check_whole_team(self, observations: dict, when: str, agents: list[str] | None = None) -> None:
        """Agents that leave before the others (or join late) need black_death=True: say so where it happens."""
        staying = set(observations if agents is None else agents) & set(observations)
        missing = [agent for agent in self.env.possible_agents if agent not in staying]
        if missing:
            raise ValueError(
                f"{', '.join(map(str, missing))} {when}: agents that are not in the episode while others are need "
                "make_multiagent_vec_env(..., black_death=True) (their rows are kept, with zero observations, and left "
                "out of the losses)"
            )


class CopySeeds:
    """
    Seeding and reset replay shared by :class:`MultiAgentVecEnv` and :class:`SubprocMultiAgentVecEnv`: copy c is
    seeded with ``seed + c`` at the next reset, wherever it runs.
    """

    n_agents: int
    n_copies: int
    num_envs: int
    _base_seed: int | None
    _pending_reset_states: list[dict[str, Any]] | None

    def seed(self, seed: int | None = None) -> list[int | None]:
        """
        Seed the copies at the next reset: copy c gets ``seed + c``.

        :param seed: base seed; a random one when None
        :return: the seed of each row
        """
        if seed is None:
            seed = int(np.random.randint(0, np.iinfo(np.uint32).max, dtype=np.uint32))
        self._base_seed = int(seed)
        return [self._base_seed + row // self.n_agents for row in range(self.num_envs)]

    def set_options(self, options: list[dict] | dict | None = None) -> None:
        """Options for the next reset (the first copy's options are passed to every copy)."""
        VecEnv.set_options(self, options)  # type: ignore[arg-type]

    def restore_reset_states(self, states: list[dict[str, Any]]) -> bool:
        """
        Make the next ``reset()`` replay the resets recorded by :meth:`reset_states` (of another VecEnv with the same
        env and number of copies): each copy is reset with its recorded seed, then, if its recorded reset was not
        seeded, its generator is set to the recorded state and it is reset again. For an env whose reset depends only
        on its seed history and its generator (``uav_coverage``, ``start="fixed"`` or ``"random"``), the copies then
        start exactly where the recorded ones were after their last reset.

        :param states: from :meth:`reset_states`
        :return: whether they can be replayed (same number of copies, every recorded seed known)
        """
        if len(states) != self.n_copies or any(state.get("seed") is None for state in states):
            return False
        self._pending_reset_states = deepcopy(states)
        return True


class MultiAgentVecEnv(CopySeeds, VecEnvWrapper):
    """
    SuperSuit's SB3 VecEnv of a PettingZoo ParallelEnv, with what it lacks under gymnasium 1.x.

    Rows are agent-major inside each copy: row = copy * n_agents + agent. On top of SuperSuit this wrapper

    - passes seeds to the copies at the next reset: ``seed(s)`` gives copy c the seed ``s + c``
      (and a random base seed when none was set, so copies never start as clones of each other);
    - reports ``done`` for every row of a copy when that copy's joint episode ends (SuperSuit resets a copy only
      when all its agents are done), with ``terminal_observation`` and, where the episode was truncated and not
      terminated, ``TimeLimit.truncated = True`` in the infos;
    - keeps the final step's infos at an episode end and puts the infos of the automatic reset in ``reset_infos``
      (SuperSuit would merge them, the reset's values overwriting the final step's);
    - adds SB3's episode statistics once per joint episode, in the info of the copy's agent 0 row:
      ``{"r": team return (sum over agents and steps), "l": joint steps, "t": seconds since creation,
      "agent_r": {agent: that agent's return}}``;
    - returns observations as :class:`AgentRows`, which carry the team (``possible_agents``) to ``MADDPG.predict``;
    - can replay each copy's last reset (:meth:`reset_states`, :meth:`restore_reset_states`), which ``MADDPG`` saves
      and restores so that a run resumed at an episode boundary continues exactly.

    It reads terminations and truncations from the gymnasium-level vector env inside SuperSuit's SB3 wrapper,
    because that wrapper merges them into ``dones`` and ignores seeds.

    :param venv: the VecEnv returned by ``supersuit.concat_vec_envs_v1(..., base_class="stable_baselines3")``
    :param possible_agents: agent names, in row order inside a copy
    :param agent_spaces: each agent's own spaces where they differ (the VecEnv's spaces are then the padded ones);
        None where all agents share the VecEnv's spaces
    """

    def __init__(self, venv: VecEnv, possible_agents: list[str], agent_spaces: AgentSpaces | None = None) -> None:
        self.possible_agents = list(possible_agents)
        self.n_agents = len(self.possible_agents)
        self.agent_spaces = agent_spaces
        # Whether agents may leave before the episode ends (make_multiagent_vec_env's black_death)
        self.departures = False
        if venv.num_envs % self.n_agents != 0:
            raise ValueError(f"the VecEnv has {venv.num_envs} rows, not a multiple of the {self.n_agents} agents")
        self.n_copies = venv.num_envs // self.n_agents
        super().__init__(venv)
        self._base_seed: int | None = None
        self._pending_reset_states: list[dict[str, Any]] | None = None
        self._episode_returns = np.zeros(self.n_copies, dtype=np.float64)
        self._agent_returns = np.zeros((self.n_copies, self.n_agents), dtype=np.float64)
        self._episode_lengths = np.zeros(self.n_copies, dtype=np.int64)
        self._t_start = time.time()

    @property
    def _gym_vec_env(self) -> Any:
        # SuperSuit's SB3VecEnvWrapper keeps the gymnasium-level vector env as `.venv`
        return self.venv.venv  # type: ignore[attr-defined]

    @property
    def parallel_envs(self) -> list[ParallelEnv]:
        """The PettingZoo ParallelEnv of each copy (copy c drives rows c * n_agents ... (c + 1) * n_agents - 1)."""
        return [markov_env.par_env.env for markov_env in self._gym_vec_env.vec_envs]

    def _copy_reset_infos(self, copy: int) -> list[dict[str, Any]]:
        infos = self._gym_vec_env.vec_envs[copy].par_env.last_reset_infos
        return [dict(infos.get(agent, {})) for agent in self.possible_agents]

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """Attribute of the ParallelEnv behind each row (rows of one copy share their env)."""
        envs = self.parallel_envs
        return [getattr(envs[row // self.n_agents], attr_name) for row in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """Set an attribute of the ParallelEnv behind the given rows (once per copy)."""
        envs = self.parallel_envs
        for copy in sorted({row // self.n_agents for row in self._get_indices(indices)}):
            setattr(envs[copy], attr_name, value)

    def env_method(self, method_name: str, *method_args, indices: VecEnvIndices = None, **method_kwargs) -> list[Any]:
        """Call a method of the ParallelEnv behind each row (once per copy; the result is repeated for its rows)."""
        envs = self.parallel_envs
        rows = list(self._get_indices(indices))
        results = {
            copy: getattr(envs[copy], method_name)(*method_args, **method_kwargs)
            for copy in sorted({row // self.n_agents for row in rows})
        }
        return [results[row // self.n_agents] for row in rows]

    def env_is_wrapped(self, wrapper_class: type, indices: VecEnvIndices = None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]

    def reset_states(self) -> list[dict[str, Any]]:
        """
        What replays each copy's last reset: the seed of its last seeded reset, and, when its last reset was not
        seeded (an automatic reset at an episode end), its generator state just before that reset (None where the
        env's generator cannot be read: see :func:`env_generator`).

        :return: one dict per copy
        """
        return [deepcopy(markov_env.par_env.reset_record) for markov_env in self._gym_vec_env.vec_envs]

    def _replay_resets(self, states: list[dict[str, Any]], options: dict | None) -> np.ndarray:
        observations = []
        for markov_env, state in zip(self._gym_vec_env.vec_envs, states, strict=True):
            obs, _ = markov_env.reset(seed=int(state["seed"]), options=options)
            generator = env_generator(markov_env.par_env.env)
            if not state["seeded"] and state["generator"] is not None and generator is not None:
                generator.bit_generator.state = state["generator"]
                obs, _ = markov_env.reset(seed=None, options=options)
            observations.append(obs)
        return self._gym_vec_env.concat_obs(observations)

    def reset(self) -> np.ndarray:
        options = self._options[0] if self._options and self._options[0] else None
        if self._pending_reset_states is not None:
            obs = self._replay_resets(self._pending_reset_states, options)
            self._pending_reset_states = None
        else:
            if self._base_seed is None:
                self.seed(None)
            obs, _ = self._gym_vec_env.reset(seed=self._base_seed, options=options)
        self._base_seed = None
        self._reset_options()
        self.reset_infos = [info for copy in range(self.n_copies) for info in self._copy_reset_infos(copy)]
        self._episode_returns[:] = 0.0
        self._agent_returns[:] = 0.0
        self._episode_lengths[:] = 0
        return tag_team(obs, tuple(self.possible_agents))

    def step_async(self, actions: np.ndarray) -> None:
        self._gym_vec_env.step_async(actions)

    def render(self, mode: str | None = None) -> np.ndarray | None:
        """The first copy's frame, drawn in the env's own ``render_mode`` (PettingZoo envs take no mode argument)."""
        return self._gym_vec_env.render()

    def step_wait(self) -> VecEnvStepReturn:
        obs, rewards, terminations, truncations, raw_infos = self._gym_vec_env.step_wait()
        # Own dict per row: an env may share one info dict between agents
        infos = [dict(info) for info in raw_infos]
        n_agents = self.n_agents
        terminations = np.asarray(terminations, dtype=bool).reshape(self.n_copies, n_agents)
        truncations = np.asarray(truncations, dtype=bool).reshape(self.n_copies, n_agents)
        copy_done = (terminations | truncations).all(axis=1)
        rewards = np.asarray(rewards, dtype=np.float32)
        self._episode_returns += rewards.reshape(self.n_copies, n_agents).sum(axis=1)
        self._agent_returns += rewards.reshape(self.n_copies, n_agents)
        self._episode_lengths += 1
        for copy in np.flatnonzero(copy_done):
            for agent in range(n_agents):
                row = copy * n_agents + agent
                infos[row]["TimeLimit.truncated"] = bool(truncations[copy, agent] and not terminations[copy, agent])
            infos[copy * n_agents]["episode"] = {
                "r": float(self._episode_returns[copy]),
                "l": int(self._episode_lengths[copy]),
                "t": round(time.time() - self._t_start, 6),
                "agent_r": dict(zip(self.possible_agents, map(float, self._agent_returns[copy]), strict=True)),
            }
            self._episode_returns[copy] = 0.0
            self._agent_returns[copy] = 0.0
            self._episode_lengths[copy] = 0
            self.reset_infos[copy * n_agents : (copy + 1) * n_agents] = self._copy_reset_infos(copy)
        dones = np.repeat(copy_done, n_agents)
        return tag_team(obs, tuple(self.possible_agents)), rewards, dones, infos


def in_process_vec_env(
    parallel_env: ParallelEnv, n_envs: int, black_death: bool = False, agent_spaces: AgentSpaces | None = None
) -> MultiAgentVecEnv:
    """
    ``n_envs`` copies of ``parallel_env``'s task in this process, with SuperSuit (``pettingzoo_env_to_vec_env_v1`` then
    ``concat_vec_envs_v1(..., base_class="stable_baselines3")``): what ``make_multiagent_vec_env`` builds in this
    process, and each worker of :class:`~sb3_maddpg.common.subproc_vec_env.SubprocMultiAgentVecEnv` in its own. The
    arguments are checked by ``make_multiagent_vec_env``.

    :param parallel_env: one copy of the env
    :param n_envs: number of environment copies
    :param black_death: agents may leave before the episode ends (see ``make_multiagent_vec_env``)
    :param agent_spaces: the env's ``read_agent_spaces``, when already read
    :return: the VecEnv, not seeded
    """
    if agent_spaces is None:
        agent_spaces = read_agent_spaces(parallel_env)
    possible_agents = list(parallel_env.possible_agents)
    if not agent_spaces.homogeneous:
        # One layout for all rows: SuperSuit pads observations with zeros and actions to the widest agent's, and
        # cuts each agent's action back to its own space before the env (the networks mask the padded entries)
        parallel_env = ss.pad_action_space_v0(ss.pad_observations_v0(parallel_env))
    if black_death:
        parallel_env = KeepDepartedAgents(parallel_env)
    markov_env = ss.pettingzoo_env_to_vec_env_v1(_SeparateResetInfos(parallel_env))
    sb3_env = ss.concat_vec_envs_v1(markov_env, int(n_envs), num_cpus=0, base_class="stable_baselines3")
    venv = MultiAgentVecEnv(sb3_env, possible_agents, None if agent_spaces.homogeneous else agent_spaces)
    venv.departures = black_death
    return venv
