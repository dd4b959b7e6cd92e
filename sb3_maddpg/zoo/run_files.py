"""
What a run folder, an Optuna study or a hyperparameter file brings, read as data.

RL Zoo evaluates some string values of a YAML entry as Python (``policy_kwargs: "dict(net_arch=[64, 64])"``,
``normalize``, ``monitor_kwargs``, ...), imports the modules that ``env_wrapper``, ``vec_env_wrapper``, ``callback``
and a dotted ``policy`` name, unpickles a run's ``vecnormalize.pkl`` and reads its ``config.yml`` and ``args.yml`` with
YAML's unsafe loader. Here the same values are read without running anything: expressions are parsed as data
(:func:`parse_value_expression`), a name of code is accepted only from a module already loaded
(:func:`check_code_names`), ``vecnormalize.pkl`` is unpickled with the library's restricted unpickler
(:func:`load_vec_normalize`), and :func:`check_run_folder` checks every file of a run folder RL Zoo would read before
it reads them.
"""

import ast
import os
import pickle
import sys
from pathlib import Path
from typing import Any

from stable_baselines3.common.vec_env import VecEnv, VecNormalize

from sb3_maddpg.zoo.registry import UsageError

# Keys of an RL Zoo entry whose string value RL Zoo evaluates as Python (rl_zoo3.exp_manager, rl_zoo3.utils)
EXPRESSION_KEYS = ("policy_kwargs", "replay_buffer_class", "replay_buffer_kwargs", "monitor_kwargs", "normalize")
# Keys whose value names code (``module.Name``, a dict of one such name to its arguments, or a list of those) that
# RL Zoo imports; ``policy`` only when it holds a dot (else it is an alias of the algorithm, e.g. "MlpPolicy")
CODE_KEYS = ("env_wrapper", "vec_env_wrapper", "callback", "policy")
ACCEPTED_EXPRESSIONS = (
    "numbers, strings, True/False/None, lists, tuples, {...} and dict(...) of those, and PyTorch's activations and "
    "optimisers by name (nn.ReLU, th.optim.Adam)"
)


def _known_names() -> dict[str, Any]:
    """The names an expression may use: PyTorch's activation and optimiser classes, as RL Zoo's entries write them."""
    import torch as th
    from stable_baselines3 import HerReplayBuffer
    from stable_baselines3.common.sb2_compat.rmsprop_tf_like import RMSpropTFLike

    names: dict[str, Any] = {"HerReplayBuffer": HerReplayBuffer, "RMSpropTFLike": RMSpropTFLike}
    for module, prefixes, base in (
        (th.nn.modules.activation, ("nn", "th.nn", "torch.nn"), th.nn.Module),
        (th.optim, ("th.optim", "torch.optim", "optim"), th.optim.Optimizer),
    ):
        for name, value in vars(module).items():
            if isinstance(value, type) and issubclass(value, base) and not name.startswith("_"):
                names.update({f"{prefix}.{name}": value for prefix in prefixes})
    return names


def _dotted_name(node: ast.expr) -> str | None:
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        owner = _dotted_name(node.value)
        return None if owner is None else f"{owner}.{node.attr}"
    return None


def _value(node: ast.expr, names: dict[str, Any]) -> Any:
    """The data an expression node stands for; ValueError naming the first part that is not data."""
    if isinstance(node, ast.Constant):
        return node.value
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub | ast.UAdd) and isinstance(node.operand, ast.Constant):
        if isinstance(node.operand.value, int | float | complex) and not isinstance(node.operand.value, bool):
            return -node.operand.value if isinstance(node.op, ast.USub) else node.operand.value
    if isinstance(node, ast.List | ast.Tuple | ast.Set):
        items = [_value(item, names) for item in node.elts]
        return {ast.List: list, ast.Tuple: tuple, ast.Set: set}[type(node)](items)
    if isinstance(node, ast.Dict) and None not in node.keys:
        return {_value(key, names): _value(value, names) for key, value in zip(node.keys, node.values, strict=True)}  # type: ignore[arg-type]
    if (
        isinstance(node, ast.Call)
        and isinstance(node.func, ast.Name)
        and node.func.id == "dict"
        and not node.args
        and all(keyword.arg is not None for keyword in node.keywords)
    ):
        return {keyword.arg: _value(keyword.value, names) for keyword in node.keywords}
    name = _dotted_name(node)
    if name is not None and name in names:
        return names[name]
    raise ValueError(f"{ast.unparse(node)!r} is not one of them")


def parse_value_expression(text: str, key: str, where: str) -> Any:
    """
    Read a string RL Zoo would evaluate as Python (``policy_kwargs: "dict(net_arch=[64, 64], activation_fn=nn.ReLU)"``)
    as the data it stands for, without evaluating anything.

    :param text: the expression
    :param key: the entry's key, for messages
    :param where: where the value comes from, for messages
    :return: the value
    :raises UsageError: (a ``ValueError``) one line naming the key and what is not data
    """
    try:
        return _value(ast.parse(text.strip(), mode="eval").body, _known_names())
    except (SyntaxError, ValueError, TypeError, RecursionError) as error:
        reason = error.msg if isinstance(error, SyntaxError) else str(error)
        raise UsageError(
            f"{key}: {text!r} in {where} is not read: it is an expression, and only values are accepted here "
            f"({ACCEPTED_EXPRESSIONS}); {reason}"
        ) from error


def _code_names(value: Any) -> list[Any]:
    """The names of code an ``env_wrapper``, ``vec_env_wrapper`` or ``callback`` value holds (RL Zoo's layouts)."""
    items = value if isinstance(value, list) else [value]
    return [next(iter(item)) if isinstance(item, dict) and len(item) == 1 else item for item in items if item is not None]


def check_code_names(key: str, value: Any, where: str) -> None:
    """
    Refuse a name of code (``module.Class``) whose module is not loaded yet: importing a module runs its code, so a
    file may name only what this process has already imported (the libraries' own modules and those of
    ``--gym-packages``); nothing is imported here.

    :param key: ``env_wrapper``, ``vec_env_wrapper``, ``callback`` or ``policy``
    :param value: its value
    :param where: where the value comes from, for messages
    :raises UsageError: one line naming the key, the name and how to accept it
    """
    if key == "policy" and not (isinstance(value, str) and "." in value):
        return
    for name in _code_names(value):
        module, _, attribute = name.rpartition(".") if isinstance(name, str) else ("", "", "")
        loaded = sys.modules.get(module) if module and "__main__" not in module.split(".") else None
        if loaded is None or not callable(vars(loaded).get(attribute)):
            hint = f"; if you trust it, import its module with --gym-packages {module}" if module else ""
            raise UsageError(
                f"{key}: {name!r} in {where} is not read: it names code in a module that is not loaded, and importing "
                f"it would run that module{hint}"
            )


def read_as_data(hyperparams: dict[str, Any], where: str) -> dict[str, Any]:
    """
    An RL Zoo entry with the strings RL Zoo would evaluate read as data (:func:`parse_value_expression`) and its names
    of code checked (:func:`check_code_names`): what RL Zoo then does with it runs no code the entry brings.

    :param hyperparams: the entry (a YAML entry, or an Optuna trial's parameters)
    :param where: where it comes from, for messages
    :return: a copy, with those strings replaced by their values
    :raises UsageError: naming the first value that is code
    """
    read = dict(hyperparams)
    for key in EXPRESSION_KEYS:
        if isinstance(read.get(key), str):
            read[key] = parse_value_expression(read[key], key, where)
    for key in CODE_KEYS:
        if key in read:
            check_code_names(key, read[key], where)
    return read


def load_vec_normalize(path: str | os.PathLike, venv: VecEnv | None = None) -> VecNormalize:
    """
    ``VecNormalize.load`` without running code: a run's ``vecnormalize.pkl`` is unpickled with the library's restricted
    unpickler, which builds only the statistics (``VecNormalize``, ``RunningMeanStd``, arrays and spaces).

    :param path: the ``vecnormalize.pkl`` file
    :param venv: the VecEnv to wrap (None: only read)
    :return: the ``VecNormalize`` wrapper
    :raises UsageError: one line naming the file, what it refers to and how to trust it
    """
    from stable_baselines3.common.running_mean_std import RunningMeanStd

    from sb3_maddpg.common.model_files import restricted_loads

    try:
        statistics = restricted_loads(Path(path).read_bytes(), extra_classes=(VecNormalize, RunningMeanStd))
    except pickle.UnpicklingError as error:
        raise UsageError(
            f"{os.fspath(path)} cannot be read safely, it is not read: {error}; if you trust the file, load it and save "
            "it again in Python: VecNormalize.load(path, venv).save(path)"
        ) from error
    except Exception as error:
        raise UsageError(f"{os.fspath(path)} is damaged: it cannot be read ({type(error).__name__}: {error})") from error
    if type(statistics) is not VecNormalize:
        raise UsageError(f"{os.fspath(path)} does not hold VecNormalize statistics (it holds a {type(statistics).__name__})")
    if venv is not None:
        statistics.set_venv(venv)
    return statistics


def check_run_folder(params_dir: str | os.PathLike) -> None:
    """
    Check, before RL Zoo reads them, the files of a run's ``<run>/<env_id>/`` folder (``enjoy``, ``record-video``,
    ``train -i``): ``config.yml`` and ``args.yml`` must be plain YAML values (:func:`read_run_yaml`, which RL Zoo's
    unsafe loader then reads the same), ``config.yml``'s ``normalize`` a value and its wrappers names of loaded code,
    and ``vecnormalize.pkl`` statistics the restricted unpickler can read (which a plain unpickling then builds the
    same).

    :param params_dir: the folder
    :raises UsageError: one line naming the file and what it holds that would run code
    """
    from sb3_maddpg.evaluation.report import read_run_yaml

    folder = Path(params_dir)
    if not folder.is_dir():
        return
    for name in ("args.yml", "config.yml"):
        if (folder / name).is_file():
            content = read_run_yaml(folder / name)
            if name == "config.yml" and isinstance(content, dict):
                # What enjoy and record-video evaluate or import from it (the run's policy is the model's, not read)
                read_keys = ("normalize", "env_wrapper", "vec_env_wrapper", "callback")
                read_as_data({key: content[key] for key in read_keys if key in content}, os.fspath(folder / name))
    if (folder / "vecnormalize.pkl").is_file():
        load_vec_normalize(folder / "vecnormalize.pkl")
