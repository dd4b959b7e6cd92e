"""
The copies of a multi-agent VecEnv in worker processes (``SubprocMultiAgentVecEnv``), as SB3's ``SubprocVecEnv`` for
the VecEnv of ``sb3_maddpg.common.vec_env``: each worker runs an in-process ``MultiAgentVecEnv`` of consecutive copies.
"""

import multiprocessing as mp
from collections.abc import Callable
from copy import deepcopy
from typing import Any

import numpy as np
from pettingzoo.utils.env import ParallelEnv
from stable_baselines3.common.vec_env import VecEnv
from stable_baselines3.common.vec_env.base_vec_env import CloudpickleWrapper, VecEnvIndices, VecEnvStepReturn

from sb3_maddpg.common.agent_spaces import AgentSpaces
from sb3_maddpg.common.vec_env import CopySeeds, MultiAgentVecEnv, in_process_vec_env, tag_team


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


class SubprocMultiAgentVecEnv(CopySeeds, VecEnv):
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
                lambda copies=copies: in_process_vec_env(env_fn(**(env_kwargs or {})), copies, black_death)
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
