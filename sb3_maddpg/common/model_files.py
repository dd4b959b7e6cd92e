"""
Checks of a saved model file before SB3 loads it: a clear message for a file that is not a MADDPG model or is damaged;
and the reading of its pickled parts without running code.

SB3 saves the class parameters it cannot write as JSON (spaces, noise, schedules, classes) as cloudpickle strings inside
the zip's JSON ``data`` member, and a replay buffer as a pickle file: unpickling either can run any code the file
names. Here they are unpickled only after the file is recognised as a MADDPG model, and only with
:func:`restricted_loads`, which builds the classes and functions a model of this library is made of (NumPy arrays and
generators, Gymnasium spaces, torch tensors and devices, SB3's and this library's noises, schedules, buffers, policies
and layers) and refuses every other reference with a ``ValueError``. A function saved by value (a ``lambda`` learning
rate) is code, so it is refused too: pass it again with ``custom_objects`` (SB3's way to replace saved objects).
Importing a module runs its code, so a reference is judged by its module's name before anything is imported: only the
modules of an explicit list are imported, other modules of the same packages are looked up only when already loaded,
and a ``__main__`` never; a name is looked up among the module's own attributes only.
"""

import base64
import importlib
import io
import json
import os
import pathlib
import pickle
import pickletools
import sys
import zipfile
import zlib
from types import ModuleType
from typing import Any

# Class parameters rebuilt from others by ``_setup_model``: when saved as code, they are not needed
DERIVED_KEYS = frozenset({"lr_schedule", "actor_lr_schedule"})

# Class parameters every saved MADDPG model has and no SB3 algorithm saves
MADDPG_KEYS = ("n_agents", "cvar_alpha")
# What reading a damaged zip member can raise (zip, zlib, JSON, pickle and torch's stream reader)
READ_ERRORS = (zipfile.BadZipFile, zlib.error, EOFError, json.JSONDecodeError, UnicodeDecodeError, RuntimeError)


def resolve_model_path(path: str | os.PathLike) -> pathlib.Path:
    """
    The file SB3's ``load`` opens for ``path``: the path itself, else the path with ``.zip`` added.

    :param path: as given to ``load``
    :return: the file
    """
    target = pathlib.Path(path)
    if not target.exists() and pathlib.Path(f"{target}.zip").exists():
        target = pathlib.Path(f"{target}.zip")
    if target.is_dir():
        raise ValueError(f"{os.fspath(target)} is a folder, not a saved model (.zip)")
    if not target.exists():
        raise FileNotFoundError(f"model file {os.fspath(path)} not found (also tried {os.fspath(path)}.zip)")
    return target


# The functions a model or replay buffer pickle calls to rebuild arrays, generators and tensors
_FUNCTIONS = {
    ("numpy._core.numeric", "_frombuffer"),
    ("numpy.core.numeric", "_frombuffer"),
    ("numpy._core.multiarray", "_reconstruct"),
    ("numpy.core.multiarray", "_reconstruct"),
    ("numpy._core.multiarray", "scalar"),
    ("numpy.core.multiarray", "scalar"),
    ("numpy.random._pickle", "__generator_ctor"),
    ("numpy.random._pickle", "__bit_generator_ctor"),
    ("numpy.random._pickle", "__randomstate_ctor"),
    ("numpy.random.bit_generator", "__pyx_unpickle_SeedSequence"),
    ("torch._utils", "_rebuild_tensor_v2"),
    ("torch._utils", "_rebuild_parameter"),
    ("copyreg", "_reconstructor"),
    ("collections", "deque"),
    ("collections", "OrderedDict"),
}
_BUILTINS = frozenset({"object", "dict", "list", "tuple", "set", "frozenset", "int", "float", "complex", "bool", "str"})
# Packages (and gymnasium.spaces) whose classes may be built, and only classes derived from those of _allowed_bases
# (a logger or a VecEnv class of the same packages opens files or starts processes when built)
_CLASS_MODULES = ("numpy", "stable_baselines3", "sb3_maddpg", "sb3_contrib", "rl_zoo3", "torch")
# The modules of those packages that a pickle may make the unpickler import: importing a module runs its top-level code
# (a package's ``__main__``, a script), so another module of those packages is looked up only when it is already loaded
# (then nothing runs), and never imported
_IMPORTABLE_MODULES = frozenset(
    {
        *(module for module, _ in _FUNCTIONS),
        "numpy",
        "numpy.dtypes",
        "numpy.random._generator",
        "numpy.random._mt19937",
        "numpy.random._pcg64",
        "numpy.random._philox",
        "numpy.random._sfc64",
        "numpy.random.bit_generator",
        "numpy.random.mtrand",
        "torch",
        "torch.nn.modules.activation",
        "torch.optim.adam",
        "torch.optim.adamw",
        "torch.optim.rmsprop",
        "torch.optim.sgd",
        "gymnasium.spaces.box",
        "gymnasium.spaces.dict",
        "gymnasium.spaces.discrete",
        "gymnasium.spaces.multi_binary",
        "gymnasium.spaces.multi_discrete",
        "gymnasium.spaces.tuple",
        "stable_baselines3.common.buffers",
        "stable_baselines3.common.noise",
        "stable_baselines3.common.torch_layers",
        "stable_baselines3.common.type_aliases",
        "stable_baselines3.common.utils",
        "rl_zoo3.utils",
        "sb3_maddpg.common.agent_spaces",
        "sb3_maddpg.common.buffers",
        "sb3_maddpg.common.device_buffer",
        "sb3_maddpg.common.noise",
        "sb3_maddpg.common.torch_layers",
        "sb3_maddpg.maddpg.critics",
        "sb3_maddpg.maddpg.policies",
        "sb3_maddpg.matd3.policies",
    }
)


def _class_module(module: str) -> ModuleType | None:
    """
    The module a pickle names for a class, if it may be read: one of the packages of ``_CLASS_MODULES`` (or
    gymnasium.spaces), no ``__main__``, imported only when it is in ``_IMPORTABLE_MODULES`` (else only if already
    loaded). Decided from the name alone, before anything is imported.
    """
    parts = module.split(".")
    if "__main__" in parts or not (parts[0] in _CLASS_MODULES or module.startswith("gymnasium.spaces")):
        return None
    if module in _IMPORTABLE_MODULES:
        try:
            return importlib.import_module(module)
        except ImportError:  # an optional package (rl_zoo3, sb3_contrib) not installed
            return None
    return sys.modules.get(module)


def _allowed_bases() -> tuple[type, ...]:
    import numpy as np
    import torch as th
    from gymnasium.spaces import Space
    from stable_baselines3.common.buffers import ReplayBuffer
    from stable_baselines3.common.noise import ActionNoise
    from stable_baselines3.common.type_aliases import TrainFreq, TrainFrequencyUnit
    from stable_baselines3.common.utils import ConstantSchedule, FloatSchedule, LinearSchedule

    from sb3_maddpg.common.agent_spaces import AgentSpaces

    schedules: tuple[type, ...] = (ConstantSchedule, FloatSchedule, LinearSchedule)
    try:
        from rl_zoo3.utils import SimpleLinearSchedule

        schedules += (SimpleLinearSchedule,)
    except ImportError:
        pass
    generators = (np.random.BitGenerator, np.random.SeedSequence, np.random.Generator, np.random.RandomState)
    return (
        *schedules,
        *generators,
        np.generic,
        np.dtype,
        Space,
        AgentSpaces,
        ReplayBuffer,
        ActionNoise,
        TrainFreq,
        TrainFrequencyUnit,
        th.nn.Module,
        th.optim.Optimizer,
        th.device,
        th.Size,
    )


def _load_storage(data: bytes) -> Any:
    """torch's ``storage._load_from_bytes`` (a tensor's storage inside a pickle), with torch's safe ``weights_only``."""
    import torch as th

    return th.load(io.BytesIO(data), weights_only=True)


class _RestrictedUnpickler(pickle.Unpickler):
    """
    An unpickler that builds only what a model of this library is made of (see the module's docstring).

    :param file: the pickle
    :param extra_classes: classes also built (already imported by the caller), found by their module and name
    """

    def __init__(self, file: io.BytesIO, extra_classes: tuple[type, ...] = ()) -> None:
        super().__init__(file)
        self._extra = {(cls.__module__, cls.__qualname__): cls for cls in extra_classes}

    def find_class(self, module: str, name: str) -> Any:
        if (module, name) == ("torch.storage", "_load_from_bytes"):
            return _load_storage
        if (module, name) in self._extra:
            return self._extra[module, name]
        if (module, name) in _FUNCTIONS or (module == "builtins" and name in _BUILTINS):
            return super().find_class(module, name)
        source = _class_module(module)
        # The module's own attributes only: a module's __getattr__ may import (numpy.f2py, ...), and a dotted name
        # reaches into other modules
        value = vars(source).get(name) if source is not None and "." not in name else None
        if value is not None:
            import numpy as np
            import torch as th

            if isinstance(value, th.dtype) or value is np.ndarray:
                return value
            if isinstance(value, type) and issubclass(value, _allowed_bases()):
                return value
        raise pickle.UnpicklingError(f"it refers to {module}.{name}, which is not part of a model of this library")


def restricted_loads(data: bytes, extra_classes: tuple[type, ...] = ()) -> Any:
    """
    Unpickle ``data`` building only what a model or replay buffer of this library is made of.

    :param data: a pickle (or cloudpickle) string
    :param extra_classes: classes also built (e.g. ``VecNormalize`` for a run's ``vecnormalize.pkl``)
    :return: the object
    :raises pickle.UnpicklingError: naming the first reference that is refused
    """
    return _RestrictedUnpickler(io.BytesIO(data), extra_classes).load()


def read_class_parameters(
    raw: dict[str, Any], keys: tuple[str, ...] | None, name: str, custom_objects: dict[str, Any] | None = None
) -> dict[str, Any]:
    """
    SB3's ``json_to_data`` with :func:`restricted_loads` in place of ``cloudpickle.loads``.

    :param raw: the JSON of the zip's ``data`` member
    :param keys: the parameters to read (None: all)
    :param name: the file, for messages
    :param custom_objects: parameters given instead of the saved ones (not read)
    :return: the parameters
    :raises ValueError: naming the parameter and what it refers to
    """
    custom_objects = custom_objects or {}
    data: dict[str, Any] = {}
    for key, item in raw.items():
        if keys is not None and key not in keys:
            continue
        if key in custom_objects:
            data[key] = custom_objects[key]
        elif isinstance(item, dict) and ":serialized:" in item:
            try:
                data[key] = restricted_loads(base64.b64decode(item[":serialized:"].encode()))
            except pickle.UnpicklingError as error:
                if key in DERIVED_KEYS:
                    data[key] = None  # rebuilt from learning_rate by _setup_model
                    continue
                raise ValueError(
                    f"{name}: the saved {key!r} cannot be read safely: {error}; if you trust the file, pass the object "
                    f"with custom_objects={{{key!r}: ...}}"
                ) from error
            except Exception as error:
                raise ValueError(f"{name} is damaged: its {key!r} cannot be read ({error})") from error
        else:
            data[key] = item
    return data


def _saved_by(raw: dict[str, Any]) -> str:
    """What saved a zip whose data lacks MADDPG's parameters, as far as its JSON tells (nothing is unpickled)."""
    policy_class = raw.get("policy_class")
    if not isinstance(policy_class, dict):
        return "something else than SB3 (its data has no policy_class)"
    try:
        # A class saved by reference is a pickle of two strings (its module and name): read them, run nothing
        ops = pickletools.genops(base64.b64decode(policy_class[":serialized:"].encode()))
        strings = [arg for op, arg, _ in ops if op.name in ("SHORT_BINUNICODE", "BINUNICODE", "UNICODE")]
        name = f"{strings[0]}.{strings[1]}"
    except Exception:
        name = "a policy class that cannot be read here"
    return f"another algorithm (its policy is {name})"


def read_maddpg_data(
    source: str | os.PathLike | io.BufferedIOBase,
    keys: tuple[str, ...] | None = (),
    custom_objects: dict[str, Any] | None = None,
    required_keys: tuple[str, ...] = MADDPG_KEYS,
) -> dict[str, Any]:
    """
    Check that a saved model is an intact MADDPG zip and read some of its class parameters, without loading weights
    and without running code (see :func:`read_class_parameters`).

    :param source: the model file (``.zip`` may be left out, as with SB3's ``load``) or an open binary file (read from
        its current position, then put back there)
    :param keys: class parameters to deserialise and return (e.g. ``("n_agents", "observation_space")``; None: all)
    :param custom_objects: parameters given instead of the saved ones
    :param required_keys: the class parameters every model of the algorithm saves (the loading algorithm's
        ``saved_model_keys``; default: those of MADDPG and MATD3): a file without one is not its model
    :return: those parameters
    :raises ValueError: one line saying that the file is not a MADDPG model, or is damaged, and which
    """
    if isinstance(source, str | os.PathLike):
        target = resolve_model_path(source)
        name, opened, start = os.fspath(target), open(target, "rb"), 0
    else:
        name, opened, start = getattr(source, "name", "the model file"), source, source.tell()
    try:
        try:
            archive = zipfile.ZipFile(opened)
        except zipfile.BadZipFile as error:
            opened.seek(start)
            if opened.read(4) == b"PK\x03\x04":
                raise ValueError(f"{name} is damaged: it is a truncated or corrupted zip file") from error
            raise ValueError(f"{name} is not a MADDPG model: it is not a zip file (SB3 saves models as .zip)") from error
        with archive:
            try:
                damaged = archive.testzip()
            except READ_ERRORS as error:
                raise ValueError(f"{name} is damaged: its members cannot be read ({error})") from error
            if damaged is not None:
                raise ValueError(f"{name} is damaged: its member {damaged!r} fails the zip's CRC check")
            if "data" not in archive.namelist():
                members = ", ".join(archive.namelist()) or "none"
                raise ValueError(f"{name} is not a MADDPG model: it has no 'data' member (its members: {members})")
            try:
                raw = json.loads(archive.read("data").decode())
            except READ_ERRORS as error:
                raise ValueError(f"{name} is damaged: its 'data' member is not valid JSON ({error})") from error
        if not isinstance(raw, dict) or any(key not in raw for key in required_keys):
            saved_by = _saved_by(raw if isinstance(raw, dict) else {})
            raise ValueError(f"{name} is not a MADDPG model: it was saved by {saved_by}")
        return read_class_parameters(raw, keys, name, custom_objects)
    finally:
        if opened is not source:
            opened.close()
        else:
            opened.seek(start)
