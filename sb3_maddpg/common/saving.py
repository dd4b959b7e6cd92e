"""
Saving and loading a multi-agent algorithm: atomic saves that carry the random states (so that a resumed run continues
exactly), loading that reads a model file without running code from it and refuses another algorithm's model, and the
joint replay buffer's file, laid out again for another number of environment copies.

``SavedMultiAgentModel`` is a mixin of ``MultiAgentOffPolicyAlgorithm`` (``sb3_maddpg.common.off_policy_algorithm``);
it overrides SB3's ``save``, ``load``, ``save_replay_buffer`` and ``load_replay_buffer`` and calls theirs.
"""

import io
import os
import pathlib
import pickle
from collections.abc import Iterable
from typing import Any, ClassVar, TypeVar

import numpy as np
import torch as th
from stable_baselines3.common.save_util import open_path
from stable_baselines3.common.type_aliases import GymEnv

from sb3_maddpg.common.actions import action_width
from sb3_maddpg.common.atomic import atomic_save
from sb3_maddpg.common.buffers import MultiAgentReplayBuffer
from sb3_maddpg.common.device_buffer import DeviceReplayBuffer
from sb3_maddpg.common.model_files import READ_ERRORS, read_maddpg_data, restricted_loads
from sb3_maddpg.common.random_state import capture_random_states, restore_random_states

SelfSavedMultiAgentModel = TypeVar("SelfSavedMultiAgentModel", bound="SavedMultiAgentModel")


def algorithm_of_policy(policy_class: Any) -> type | None:
    """
    The algorithm of this library that saved a model, told by its saved policy class: the algorithm whose
    ``MlpPolicy`` is the most derived base of that class (``MATD3`` for MATD3's twin-critic policies, ``MADDPG`` for
    MADDPG's). An algorithm is known once its module is imported, which unpickling its policy class does (the policy
    module's package imports the algorithm).

    :param policy_class: the model's saved ``policy_class``
    :return: the algorithm class, or None for a class that is no algorithm's policy
    """
    if not isinstance(policy_class, type):
        return None
    candidates: list[tuple[type, type]] = []
    # every class that saves as this library's models do: MultiAgentOffPolicyAlgorithm and its algorithms
    stack: list[type] = [SavedMultiAgentModel]
    while stack:
        algorithm = stack.pop()
        stack.extend(algorithm.__subclasses__())
        base = getattr(algorithm, "policy_aliases", {}).get("MlpPolicy")
        if base is not None and issubclass(policy_class, base):
            candidates.append((algorithm, base))
    if not candidates:
        return None
    closest = max((base for _, base in candidates), key=lambda base: len(base.__mro__))
    # the first algorithm with that policy (MATD3, not a subclass of it)
    return min((algorithm for algorithm, base in candidates if base is closest), key=lambda algorithm: len(algorithm.__mro__))


class SavedMultiAgentModel:
    """
    The saving and loading part of ``MultiAgentOffPolicyAlgorithm`` (a mixin before SB3's ``OffPolicyAlgorithm`` in
    its bases).
    """

    #: class parameters that every saved model of the algorithm has and no SB3 algorithm saves: ``load`` refuses a
    #: file without one of them with a one-line error (a subclass adds its own)
    saved_model_keys: ClassVar[tuple[str, ...]] = ("n_agents",)

    def save(
        self,
        path: str | pathlib.Path | io.BufferedIOBase,
        exclude: Iterable[str] | None = None,
        include: Iterable[str] | None = None,
    ) -> None:
        """
        Save the model as SB3 does (a zip of the class parameters and the networks), atomically: it is written to a
        temporary file in the same folder and moved into place, so an interrupted save leaves the previous file whole.
        The random states (Python, NumPy, PyTorch, the action space, the env copies' last resets) are saved with it,
        and ``load`` restores them: see ``sb3_maddpg.common.random_state``.

        :param path: the file (``.zip`` is added when the name has no suffix), or an open binary file
        :param exclude: names of parameters to leave out, in addition to the default ones
        :param include: names of parameters to save although they are excluded by default
        """
        self._saved_random_states = capture_random_states(self)
        try:
            base_save = super().save
            atomic_save(lambda file: base_save(file, exclude=exclude, include=include), path, suffix="zip")
        finally:
            del self._saved_random_states

    @classmethod
    def load(  # type: ignore[override]
        cls: type[SelfSavedMultiAgentModel],
        path: str | pathlib.Path | io.BufferedIOBase,
        env: GymEnv | None = None,
        device: th.device | str = "auto",
        custom_objects: dict[str, Any] | None = None,
        print_system_info: bool = False,
        force_reset: bool = True,
        **kwargs: Any,
    ) -> SelfSavedMultiAgentModel:
        """
        Load a model saved by ``save`` (as SB3's ``load``), after checking that the file is an intact model of this
        library, without running code from it (see ``sb3_maddpg.common.model_files``), and restore the random states
        saved with it (the generators continue where they were when it was saved; call ``set_random_seed`` afterwards
        to reseed instead). With ``env``, the env must have the model's team.

        :param path: the model file (``.zip`` may be left out) or an open binary file
        :param env: the environment to act and learn on (None: only to predict)
        :param device: the device of the networks
        :param custom_objects: objects to use instead of the saved ones (as in SB3), e.g. a learning rate saved as code
        :param print_system_info: print the system info of the saved model and of this one
        :param force_reset: reset the env before the next ``learn`` (as in SB3)
        :param kwargs: attributes to change while loading (as in SB3)
        :return: the model
        :raises ValueError: if the file is not a model of this library or is damaged, or the env's team is not the model's
        """
        # Every pickled class parameter is read here, without running code (model_files.restricted_loads), and handed
        # to SB3 as custom_objects, so that SB3's load unpickles none; those that ``kwargs`` replace are not read.
        given = {**{key: value for key, value in kwargs.items() if key != "policy_kwargs"}, **(custom_objects or {})}
        custom_objects = read_maddpg_data(path, None, given, cls.saved_model_keys)  # type: ignore[arg-type]
        cls._check_saved_algorithm(custom_objects.get("policy_class"), path)
        try:
            model = super().load(path, env, device, custom_objects, print_system_info, force_reset, **kwargs)
        except READ_ERRORS as error:
            first_line = str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
            name = os.fspath(path) if isinstance(path, str | os.PathLike) else "the model file"
            raise ValueError(f"{name} is damaged or was saved by an incompatible version: {first_line}") from error
        states = model.__dict__.pop("_saved_random_states", None)
        if states is not None:
            restore_random_states(model, states)
        return model

    @classmethod
    def _check_saved_algorithm(cls, policy_class: Any, path: str | pathlib.Path | io.BufferedIOBase) -> None:
        """
        Refuse a model saved by another algorithm of this library: a MATD3 model loaded as MADDPG would lose its twin
        critics' delay and smoothing, a MADDPG model loaded as MATD3 would train on with one critic.

        :param policy_class: the saved policy class
        :param path: the model file, for the message
        :raises ValueError: naming both algorithms
        """
        saved = algorithm_of_policy(policy_class)
        if saved is None or saved.policy_aliases.get("MlpPolicy") is cls.policy_aliases.get("MlpPolicy"):
            return
        name = os.fspath(path) if isinstance(path, str | os.PathLike) else "the model file"
        raise ValueError(
            f"{name} is a {saved.__name__} model (its policy is {policy_class.__module__}.{policy_class.__qualname__}), "
            f"not a {cls.__name__} model: load it with {saved.__name__}.load (on the command line: "
            f"--algo {saved.__name__.lower()})"
        )

    def save_replay_buffer(self, path: str | pathlib.Path | io.BufferedIOBase) -> None:
        """
        Save the replay buffer as a pickle file, atomically (see ``save``).

        :param path: the file (``.pkl`` is added when the name has no suffix), or an open binary file
        """
        assert self.replay_buffer is not None, "The replay buffer is not defined"
        atomic_save(super().save_replay_buffer, path, suffix="pkl")  # type: ignore[arg-type]

    def load_replay_buffer(self, path: str | pathlib.Path | io.BufferedIOBase, truncate_last_traj: bool = True) -> None:
        """
        Load a replay buffer saved by ``save_replay_buffer``, after checking that it is whole (its fields agree with
        each other, its rewards are finite: ``MultiAgentReplayBuffer.check_loaded``) and fits this model: the same
        agents, observation shape and dtype, and action size. A buffer from another number of environment copies is laid
        out again for this model's copies (``MultiAgentReplayBuffer.with_copies``): every joint transition is kept,
        up to this model's ``buffer_size``.

        :param path: the pickle file, or an open binary file
        :param truncate_last_traj: unused (only for SB3's ``HerReplayBuffer``)
        :raises ValueError: if the buffer is damaged, or does not fit, naming its shapes and the model's
        """
        name = os.fspath(path) if isinstance(path, str | os.PathLike) else "the replay buffer file"
        try:
            # A pickle file: read without running code (only what a replay buffer of this library is made of)
            with open_path(path, "r", self.verbose, suffix="pkl") as file:
                buffer = restricted_loads(file.read())
        except (pickle.UnpicklingError, EOFError, AttributeError, ImportError) as error:
            raise ValueError(f"{name} is not a replay buffer that can be read here, or is damaged: {error}") from error
        self.replay_buffer = self._fit_replay_buffer(buffer, name)
        self.replay_buffer.device = self.device

    def _fit_replay_buffer(self, buffer: Any, name: str) -> MultiAgentReplayBuffer:
        """Check that a loaded buffer fits the model; lay it out for the model's number of copies."""
        if not isinstance(buffer, MultiAgentReplayBuffer):
            raise TypeError(f"{name} holds a {type(buffer).__name__}, not a MultiAgentReplayBuffer of joint transitions")
        buffer.check_loaded(name)
        assert self.n_agents is not None
        obs_shape, obs_dtype = tuple(self.observation_space.shape), self.observation_space.dtype  # type: ignore[arg-type]
        action_dim = action_width(self.action_space)
        buffer_dtype = np.dtype(buffer.observation_space.dtype)  # type: ignore[arg-type]
        found = (buffer.n_agents, tuple(buffer.obs_shape), buffer_dtype, buffer.action_dim)
        if found != (self.n_agents, obs_shape, obs_dtype, action_dim):
            raise ValueError(
                f"the replay buffer {name} holds joint transitions of {buffer.n_agents} agents with observations "
                f"{tuple(buffer.obs_shape)} {buffer_dtype} and actions ({buffer.action_dim},), but this "
                f"model has {self.n_agents} agents with observations {obs_shape} {obs_dtype} and actions ({action_dim},); "
                "load a buffer saved with the same env configuration"
            )
        n_copies = self.n_envs // self.n_agents
        # Another number of copies, or another buffer_size (e.g. -params buffer_size:... on resume): laid out again
        if buffer.n_copies != n_copies or buffer.buffer_size != max(self.buffer_size // n_copies, 1):
            if self.verbose >= 1:
                print(
                    f"Laying the replay buffer out again: {buffer.n_copies} environment copies -> {n_copies}, "
                    f"{buffer.buffer_size * buffer.n_copies} -> {self.buffer_size} joint transitions"
                )
            buffer = buffer.with_copies(n_copies, self.buffer_size)
        # Storage where this model keeps its buffer: on its device (storage_device) or in host memory
        assert self.replay_buffer_class is not None
        on_device = issubclass(self.replay_buffer_class, DeviceReplayBuffer)
        storage = self.replay_buffer_kwargs.get("storage_device", self.device) if on_device else None
        if isinstance(buffer, DeviceReplayBuffer) != on_device or (on_device and buffer.storage_device != storage):
            target = DeviceReplayBuffer if on_device else MultiAgentReplayBuffer
            buffer = target.from_buffer(buffer, storage_device=storage, device=self.device)
        return buffer
