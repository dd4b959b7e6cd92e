"""
# UAV coverage, version 1

The simulation of `uav_coverage_v0` (the report's task) with other defaults, chosen so that a team of MADDPG agents
can learn it. Every difference is an env parameter that v0 also accepts, so any v1 rule can be switched back; the
metrics (c_T, f_T, e_T, eta_T), the baselines and the evaluation protocol are the same, so results on v0 and v1
compare directly. `docs/environment.md` lists each difference with the reason and the measurements behind it.

| parameter | v0 | v1 |
|---|---|---|
| `action_mode` | `"polar"` | `"cartesian"`: (dx, dy) = (2a - 1) l_max, a = (0.5, 0.5) hovers |
| `wall_mode` | `"refuse"` | `"clip"`: stop at the boundary, charged `wall_penalty` x overshoot / l_max |
| `wall_penalty` | 10 | 1 |
| `reward_mode` | `"report"` | `"coverage"`: each UAV's share of the step's fairness-weighted coverage, minus its energy |
| `comm_penalty` | 1 | 0.1 |
| `start` | `"fixed"` | `"random"`: new start positions every episode, as in the evaluation |
| `position_mark` | `"cell"` | `"exact"`: each UAV drawn as an anti-aliased square at its exact position, not on its cell |
| `teammate_channel` | False | True: a fourth observation channel shows the active teammates within radio range R |

```python
uav_coverage_v1.parallel_env(**V1_DEFAULTS, obs_size=16)   # any parameter of v0 can be given
uav_coverage_v1.parallel_env(**HAZARDS, obs_size=16)        # the hazardous task (uav_coverage_hazard_cpu_v1)
uav_coverage_v1.parallel_env(**STORM, obs_size=16)          # the storm task (uav_coverage_storm_cpu_v1)
uav_coverage_v1.parallel_env(**STORM_V2, obs_size=16)       # the storm task redesigned (uav_coverage_storm_cpu_v2)
```

Hazards are off by default (v0 and v1 as above); `HAZARDS` switches on the setting of the hazardous task, where
a team hugging the walls has the better mean team return and one keeping a margin the better worst decile
(docs/environment.md, "Hazards"). `STORM` switches on the storm task instead: no gusts, a storm over the middle of the
map that can strike a UAV hovering there and ground it; covering the middle from inside pays on average, keeping out
of it has the better worst decile. `STORM_V2` redesigns it for a critic that looks about 10 steps ahead: a smaller
zone drawn in the observations, strikes at 7 % of a UAV's steps there, each costing at once and grounding for 3 steps.

The tasks are the scenarios of ``sb3_maddpg_envs.uav_coverage.scenarios`` (``V1``, ``HAZARD``, ``STORM_TASK``,
``STORM_V2_TASK``), where ``V1_DEFAULTS``, ``HAZARDS``, ``STORM`` and ``STORM_V2`` are defined and explained.
"""

from typing import Any

from pettingzoo.utils.env import AECEnv

from sb3_maddpg_envs.uav_coverage import uav_coverage
from sb3_maddpg_envs.uav_coverage.scenarios import (
    HAZARD,
    HAZARDS,
    STORM,
    STORM_TASK,
    STORM_V2,
    STORM_V2_TASK,
    V1,
    V1_DEFAULTS,
)

__all__ = [
    "HAZARDS",
    "STORM",
    "STORM_V2",
    "V1_DEFAULTS",
    "env",
    "hazard_parallel_env",
    "parallel_env",
    "raw_env",
    "storm_parallel_env",
    "storm_v2_parallel_env",
]


def parallel_env(**kwargs: Any) -> uav_coverage.UAVCoverageEnv:
    """
    The environment as a PettingZoo ``ParallelEnv``, with v1's defaults (the scenario ``scenarios.V1``).

    :param kwargs: ``render_mode`` and any parameter of ``UAVCoverageConfig``; they override v1's defaults
    """
    return V1.parallel_env(**kwargs)


def hazard_parallel_env(**kwargs: Any) -> uav_coverage.UAVCoverageEnv:
    """
    The hazardous task as a PettingZoo ``ParallelEnv``: v1's defaults with :data:`HAZARDS` (``scenarios.HAZARD``).

    :param kwargs: as for :func:`parallel_env`; they override v1's defaults and the hazards
    """
    return HAZARD.parallel_env(**kwargs)


def storm_parallel_env(**kwargs: Any) -> uav_coverage.UAVCoverageEnv:
    """
    The storm task as a PettingZoo ``ParallelEnv``: v1's defaults with :data:`STORM` (``scenarios.STORM_TASK``).

    :param kwargs: as for :func:`parallel_env`; they override v1's defaults and the storm
    """
    return STORM_TASK.parallel_env(**kwargs)


def storm_v2_parallel_env(**kwargs: Any) -> uav_coverage.UAVCoverageEnv:
    """
    The storm task redesigned as a PettingZoo ``ParallelEnv``: v1's defaults with :data:`STORM_V2`
    (``scenarios.STORM_V2_TASK``): the zone drawn on channel 0, strikes that cost at once and ground for 3 steps.

    :param kwargs: as for :func:`parallel_env`; they override v1's defaults and the storm
    """
    return STORM_V2_TASK.parallel_env(**kwargs)


def raw_env(**kwargs: Any) -> AECEnv:
    """
    The environment as an AEC env (PettingZoo's ``parallel_to_aec``), without wrappers, with v1's defaults.

    :param kwargs: as for :func:`parallel_env`
    """
    return V1.raw_env(**kwargs)


def env(**kwargs: Any) -> AECEnv:
    """
    The environment as a wrapped AEC env (order enforcing), with v1's defaults.

    :param kwargs: as for :func:`parallel_env`
    """
    return V1.env(**kwargs)
