"""
The library's algorithms by name: the one list that the command line, the RL Zoo integration and the Hub commands
read. Adding an algorithm is one folder (its class and policies, on ``MultiAgentOffPolicyAlgorithm``), one line here
and its hyperparameter file ``zoo_configs/<name>.yml``.

The classes are imported when first asked for, so that reading the names (e.g. for ``--help``) does not import torch.
"""

import importlib

__all__ = ["ALGORITHMS", "ALGORITHM_NAMES", "algorithm_class"]

#: name (RL Zoo's ``--algo``) -> "module:class"
ALGORITHMS: dict[str, str] = {
    "maddpg": "sb3_maddpg.maddpg:MADDPG",
    "matd3": "sb3_maddpg.matd3:MATD3",
}
#: the names, in the order of ``ALGORITHMS``
ALGORITHM_NAMES: tuple[str, ...] = tuple(ALGORITHMS)


def algorithm_class(name: str) -> type:
    """
    :param name: an algorithm's name (a key of ``ALGORITHMS``)
    :return: its class
    :raises ValueError: for a name that is no algorithm of this library
    """
    if name not in ALGORITHMS:
        raise ValueError(f"unknown algorithm {name!r}: the library's algorithms are {', '.join(ALGORITHM_NAMES)}")
    module, _, attribute = ALGORITHMS[name].partition(":")
    return getattr(importlib.import_module(module), attribute)
