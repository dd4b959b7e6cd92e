"""From a PettingZoo ParallelEnv to an SB3 VecEnv with one row per agent and environment copy."""

import multiprocessing as mp
import os
import time
from collections.abc import Callable
from copy import deepcopy
from numbers import Integral
from typing import Any

import numpy as np
import supersuit as ss
from pettingzoo.utils.env import ParallelEnv
from pettingzoo.utils.wrappers import BaseParallelWrapper
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecEnv, VecEnvWrapper
from stable_baselines3.common.vec_env.base_vec_env import CloudpickleWrapper, VecEnvIndices, VecEnvStepReturn

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


class _CopySeeds:
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


class MultiAgentVecEnv(_CopySeeds, VecEnvWrapper):
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


def _subproc_worker(remote: Any, parent_remote: Any, make_venv: CloudpickleWrapper) -> None:
    """
    The loop of one worker process of :class:`SubprocMultiAgentVecEnv`: it owns an in-process
    :class:`MultiAgentVecEnv` of consecutive copies and answers the parent's commands.

    :param remote: this process's end of the pipe
    :param parent_remote: the parent's end (closed here)
    :param make_venv: builds the worker's VecEnv
    """
    parent_remote.close()
    venv: MultiAgentVecEnv = make_venv.var()
    while True:
        try:
            command, data = remote.recv()
        except EOFError:
            break
        if command == "close":
            venv.close()
            remote.close()
            break
        try:
            if command == "step":
                venv.step_async(data)
                obs, rewards, dones, infos = venv.step_wait()
                reply: Any = (np.asarray(obs), rewards, dones, infos, venv.reset_infos)
            elif command == "reset":
                seed, options, states = data
                if states is not None:
                    venv.restore_reset_states(states)
                else:
                    venv.seed(seed)
                venv.set_options(options)
                obs = venv.reset()
                reply = (np.asarray(obs), venv.reset_infos)
            elif command == "attr":
                reply = getattr(venv, data)
            elif command == "call":
                method, args, kwargs = data
                reply = getattr(venv, method)(*args, **kwargs)
            else:
                raise NotImplementedError(f"unknown command {command!r}")
        except Exception as error:
            # Raised again in the parent, as it would be with the copies in one process
            remote.send(("error", error))
        else:
            remote.send(("ok", reply))


class SubprocMultiAgentVecEnv(_CopySeeds, VecEnv):
    """
    The multi-agent VecEnv of :func:`make_multiagent_vec_env` with its copies in worker processes.

    Each worker runs a :class:`MultiAgentVecEnv` of consecutive copies (SuperSuit's in-process concatenation) and
    the copies keep the seeds they have in one process: copy c is reset with ``seed + c``. (SuperSuit's own
    multi-process concatenation gives process p the seed ``seed + p`` and its copies ``seed + p + i``, so copies
    of different processes share seeds.) Rows, infos, ``reset_infos``, episode statistics, seeding,
    :meth:`reset_states` and :meth:`restore_reset_states` are those of :class:`MultiAgentVecEnv`, so for the same
    seed and actions both give the same observations, rewards, dones and infos (but for the wall-clock ``t`` of the
    episode statistics). Processes are started as by SB3's ``SubprocVecEnv`` (``forkserver`` where available).

    :param env_fn: function returning a PettingZoo ParallelEnv (picklable with cloudpickle)
    :param n_envs: number of environment copies
    :param env_kwargs: keyword arguments of ``env_fn``
    :param n_processes: worker processes (the copies are split as evenly as possible); at most ``n_envs``
    :param start_method: ``multiprocessing`` start method (default: ``forkserver`` where available, else ``spawn``)
    :param black_death: agents may leave before the episode ends (see :func:`make_multiagent_vec_env`)
    """

    def __init__(
        self,
        env_fn: Callable[..., ParallelEnv],
        n_envs: int,
        env_kwargs: dict[str, Any] | None = None,
        n_processes: int = 2,
        start_method: str | None = None,
        black_death: bool = False,
    ) -> None:
        n_processes = min(n_processes, n_envs)
        # Copies of worker p: first_copies[p] ... first_copies[p + 1] - 1
        self.first_copies = [round(p * n_envs / n_processes) for p in range(n_processes + 1)]
        if start_method is None:
            start_method = "forkserver" if "forkserver" in mp.get_all_start_methods() else "spawn"
        context = mp.get_context(start_method)
        self.remotes, self.processes = [], []
        for p in range(n_processes):
            copies = self.first_copies[p + 1] - self.first_copies[p]
            make_venv = CloudpickleWrapper(
                lambda copies=copies: make_multiagent_vec_env(env_fn, copies, env_kwargs=env_kwargs, black_death=black_death)
            )
            remote, work_remote = context.Pipe()
            process = context.Process(target=_subproc_worker, args=(work_remote, remote, make_venv), daemon=True)
            process.start()
            work_remote.close()
            self.remotes.append(remote)
            self.processes.append(process)
        self.closed = False
        self._final_reset_states: list[dict[str, Any]] = []
        self.possible_agents: list[str] = self._request(0, "attr", "possible_agents")
        self.n_agents = len(self.possible_agents)
        self.n_copies = n_envs
        self.agent_spaces: AgentSpaces | None = self._request(0, "attr", "agent_spaces")
        self.departures: bool = self._request(0, "attr", "departures")
        observation_space, action_space = (self._request(0, "attr", name) for name in ("observation_space", "action_space"))
        super().__init__(n_envs * self.n_agents, observation_space, action_space)
        self._base_seed: int | None = None
        self._pending_reset_states: list[dict[str, Any]] | None = None

    @property
    def n_processes(self) -> int:
        """The number of worker processes."""
        return len(self.processes)

    def _receive(self, worker: int) -> Any:
        status, reply = self.remotes[worker].recv()
        if status == "error":
            raise reply
        return reply

    def _receive_all(self) -> list[Any]:
        # Every worker's reply is read before any error is raised, so that the pipes stay in step
        replies = [self.remotes[worker].recv() for worker in range(self.n_processes)]
        for status, reply in replies:
            if status == "error":
                raise reply
        return [reply for _, reply in replies]

    def _request(self, worker: int, command: str, data: Any) -> Any:
        self.remotes[worker].send((command, data))
        return self._receive(worker)

    def _call(self, worker: int, method: str, *args: Any, **kwargs: Any) -> Any:
        return self._request(worker, "call", (method, args, kwargs))

    def _worker_rows(self, indices: VecEnvIndices) -> dict[int, tuple[list[int], list[int]]]:
        """For each worker with rows among ``indices``: the rows (as given) and the worker's own row numbers."""
        rows_by_worker: dict[int, tuple[list[int], list[int]]] = {}
        for row in self._get_indices(indices):
            copy = row // self.n_agents
            worker = int(np.searchsorted(self.first_copies, copy, side="right")) - 1
            rows, local = rows_by_worker.setdefault(worker, ([], []))
            rows.append(row)
            local.append(row - self.first_copies[worker] * self.n_agents)
        return rows_by_worker

    def reset(self) -> np.ndarray:
        options = self._options[0] if self._options and self._options[0] else None
        states = self._pending_reset_states
        if states is None and self._base_seed is None:
            self.seed(None)
        for p, remote in enumerate(self.remotes):
            first, last = self.first_copies[p], self.first_copies[p + 1]
            seed = None if states is not None else self._base_seed + first  # type: ignore[operator]
            remote.send(("reset", (seed, options, None if states is None else states[first:last])))
        results = self._receive_all()
        self._base_seed = None
        self._pending_reset_states = None
        self._reset_options()
        self.reset_infos = [info for _, reset_infos in results for info in reset_infos]
        return tag_team(np.concatenate([obs for obs, _ in results]), tuple(self.possible_agents))

    def step_async(self, actions: np.ndarray) -> None:
        for p, remote in enumerate(self.remotes):
            start, end = self.first_copies[p] * self.n_agents, self.first_copies[p + 1] * self.n_agents
            remote.send(("step", actions[start:end]))

    def step_wait(self) -> VecEnvStepReturn:
        obs, rewards, dones, infos, reset_infos = zip(*self._receive_all(), strict=True)
        self.reset_infos = [info for worker_infos in reset_infos for info in worker_infos]
        return (
            tag_team(np.concatenate(obs), tuple(self.possible_agents)),
            np.concatenate(rewards),
            np.concatenate(dones),
            [info for worker_infos in infos for info in worker_infos],
        )

    def reset_states(self) -> list[dict[str, Any]]:
        """
        As :meth:`MultiAgentVecEnv.reset_states`, one dict per copy in copy order; after :meth:`close`, those of the
        last resets before it (RL Zoo closes the env before it saves the model, which saves these).
        """
        if self.closed:
            return deepcopy(self._final_reset_states)
        return [state for p in range(self.n_processes) for state in self._call(p, "reset_states")]

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """Attribute of the ParallelEnv behind each row (rows of one copy share their env)."""
        values: dict[int, Any] = {}
        for worker, (rows, local) in self._worker_rows(indices).items():
            values.update(zip(rows, self._call(worker, "get_attr", attr_name, local), strict=True))
        return [values[row] for row in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """Set an attribute of the ParallelEnv behind the given rows (once per copy)."""
        for worker, (_, local) in self._worker_rows(indices).items():
            self._call(worker, "set_attr", attr_name, value, local)

    def env_method(self, method_name: str, *method_args, indices: VecEnvIndices = None, **method_kwargs) -> list[Any]:
        """Call a method of the ParallelEnv behind each row (once per copy; the result is repeated for its rows)."""
        values: dict[int, Any] = {}
        for worker, (rows, local) in self._worker_rows(indices).items():
            results = self._call(worker, "env_method", method_name, *method_args, indices=local, **method_kwargs)
            values.update(zip(rows, results, strict=True))
        return [values[row] for row in self._get_indices(indices)]

    def env_is_wrapped(self, wrapper_class: type, indices: VecEnvIndices = None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]

    def close(self) -> None:
        if self.closed:
            return
        try:
            self._final_reset_states = self.reset_states()
            for remote in self.remotes:
                remote.send(("close", None))
        except (BrokenPipeError, EOFError, ConnectionResetError):
            # a worker that has died (its error was raised at the call that found it)
            for process in self.processes:
                process.terminate()
        for process in self.processes:
            process.join()
        self.closed = True


def _check_vec_env_cls(vec_env_cls: Any, n_processes: int | None) -> bool:
    """
    :param vec_env_cls: ``None``, ``"dummy"``, ``"subproc"``, or SB3's ``DummyVecEnv`` or ``SubprocVecEnv``
    :param n_processes: the number of worker processes asked for
    :return: whether the copies run in worker processes
    """
    if vec_env_cls in (None, "dummy", DummyVecEnv):
        subproc = False
    elif vec_env_cls in ("subproc", SubprocVecEnv):
        subproc = True
    else:
        raise ValueError(f"vec_env_cls must be None, 'dummy', 'subproc', DummyVecEnv or SubprocVecEnv, got {vec_env_cls!r}")
    if n_processes is not None:
        if isinstance(n_processes, bool) or not isinstance(n_processes, Integral) or n_processes < 1:
            raise ValueError(f"n_processes must be None or an integer >= 1 (worker processes), got {n_processes!r}")
        if not subproc and n_processes > 1:
            raise ValueError(f"n_processes={n_processes} needs vec_env_cls='subproc' (the copies run in this process)")
    return subproc


def make_multiagent_vec_env(
    env_fn: Callable[..., ParallelEnv],
    n_envs: int = 1,
    seed: int | None = None,
    env_kwargs: dict[str, Any] | None = None,
    vec_env_cls: str | type[VecEnv] | None = None,
    n_processes: int | None = None,
    black_death: bool = False,
) -> "MultiAgentVecEnv | SubprocMultiAgentVecEnv":
    """
    Build an SB3 VecEnv from a PettingZoo ParallelEnv with SuperSuit
    (``pettingzoo_env_to_vec_env_v1`` then ``concat_vec_envs_v1(..., base_class="stable_baselines3")``).

    The VecEnv has ``n_envs * n_agents`` rows, agent-major inside each copy (row = copy * n_agents + agent), and the
    attributes ``n_agents``, ``n_copies``, ``possible_agents`` and ``agent_spaces``. See ``MultiAgentVecEnv`` for
    seeding, infos and episode statistics. Observation spaces are Boxes (vectors or images), action spaces Box or
    Discrete (a Discrete env receives one integer per row). Agents may have spaces of their own (MPE2's
    ``simple_speaker_listener``, ``simple_adversary``, ...): the VecEnv's spaces are then the padded ones of
    SuperSuit's ``pad_observations_v0`` and ``pad_action_space_v0``, and ``agent_spaces``
    (:class:`~sb3_maddpg.common.agent_spaces.AgentSpaces`) tells the algorithm which entries are each agent's own.

    :param env_fn: function returning a PettingZoo ParallelEnv, e.g. ``uav_coverage_v0.parallel_env``
    :param n_envs: number of environment copies
    :param seed: base seed; copy c is reset with ``seed + c`` at the first reset
    :param env_kwargs: keyword arguments of ``env_fn``
    :param vec_env_cls: where the copies run: ``None`` or ``"dummy"`` (or SB3's ``DummyVecEnv``) in this process,
        ``"subproc"`` (or ``SubprocVecEnv``) in worker processes (:class:`SubprocMultiAgentVecEnv`), with the same
        per-copy seeds
    :param n_processes: worker processes with ``"subproc"`` (default: one per CPU core, at most ``n_envs``)
    :param black_death: agents may leave before the episode ends (:class:`~sb3_maddpg.common.departures.KeepDepartedAgents`,
        as SuperSuit's ``black_death_v3``): their rows stay, with zero observations and rewards, each vector observation
        gets a last entry that is 1 while its agent is in the episode and 0 after, the env gets no action for an agent
        that has left, and the algorithm leaves its rows out of the losses. The VecEnv's ``departures`` is then True
    :return: the VecEnv
    """
    if not callable(env_fn) or isinstance(env_fn, ParallelEnv):
        raise TypeError(
            f"env_fn must be a function returning a PettingZoo ParallelEnv (e.g. uav_coverage_v0.parallel_env), got {env_fn!r}"
        )
    if isinstance(n_envs, bool) or not isinstance(n_envs, Integral) or n_envs < 1:
        raise ValueError(f"n_envs must be an integer >= 1 (environment copies), got {n_envs!r}")
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, Integral) or not 0 <= seed < 2**32):
        raise ValueError(f"seed must be None or an integer in [0, 2**32), got {seed!r}")
    if env_kwargs is not None and not isinstance(env_kwargs, dict):
        raise TypeError(f"env_kwargs must be a dict of keyword arguments of env_fn or None, got {env_kwargs!r}")
    subproc = _check_vec_env_cls(vec_env_cls, n_processes)
    if not isinstance(black_death, bool):
        raise TypeError(f"black_death must be True or False, got {black_death!r}")
    parallel_env = env_fn(**(env_kwargs or {}))
    if not isinstance(parallel_env, ParallelEnv):
        raise TypeError(
            f"env_fn must return a PettingZoo ParallelEnv, got {type(parallel_env).__name__}; "
            "for an AEC env use pettingzoo.utils.conversions.aec_to_parallel"
        )
    agent_spaces = read_agent_spaces(parallel_env)
    venv: MultiAgentVecEnv | SubprocMultiAgentVecEnv
    if subproc:
        # The env was built and checked here, where its errors are readable, before any worker process starts
        parallel_env.close()
        n_processes = n_processes if n_processes is not None else os.cpu_count() or 1
        venv = SubprocMultiAgentVecEnv(
            env_fn, int(n_envs), env_kwargs=env_kwargs, n_processes=n_processes, black_death=black_death
        )
        if seed is not None:
            venv.seed(seed)
        return venv
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
    if seed is not None:
        venv.seed(seed)
    return venv


def find_multiagent_vec_env(env: VecEnv | None) -> "MultiAgentVecEnv | SubprocMultiAgentVecEnv | None":
    """
    :param env: a VecEnv, possibly wrapped (``VecNormalize``, monitors, ...)
    :return: the :class:`MultiAgentVecEnv` inside it, or None
    """
    while env is not None:
        if isinstance(env, (MultiAgentVecEnv, SubprocMultiAgentVecEnv)):
            return env
        env = getattr(env, "venv", None)
    return None
