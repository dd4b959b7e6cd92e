"""sb3_maddpg: multi-agent DDPG and TD3 with centralised quantile-CVaR critics for Stable-Baselines3."""

import importlib
from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

__all__ = ["MADDPG", "MATD3", "__version__", "evaluate_policy", "make_multiagent_vec_env"]

# The public names, imported when first used (PEP 562): `from sb3_maddpg import MADDPG` works as an eager import
# would, and `python -m sb3_maddpg --help` or `--version` does not import torch.
_LAZY = {
    "MADDPG": "sb3_maddpg.maddpg",
    "MATD3": "sb3_maddpg.matd3",
    "evaluate_policy": "sb3_maddpg.common.evaluation",
    "make_multiagent_vec_env": "sb3_maddpg.common.env_util",
}

if TYPE_CHECKING:
    from sb3_maddpg.common.env_util import make_multiagent_vec_env
    from sb3_maddpg.common.evaluation import evaluate_policy
    from sb3_maddpg.maddpg import MADDPG
    from sb3_maddpg.matd3 import MATD3


def __getattr__(name: str) -> Any:
    if name not in _LAZY:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(_LAZY[name]), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
