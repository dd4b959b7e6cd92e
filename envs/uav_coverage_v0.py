"""
# UAV coverage

| Import             | `from sb3_maddpg_envs import uav_coverage_v0`                        |
|--------------------|----------------------------------------------------------------------|
| Actions            | Continuous                                                           |
| Parallel API       | Yes                                                                  |
| Agents             | `agents = [uav_0, ..., uav_{N-1}]` (N = `n_uavs`, default 6)         |
| Action Shape       | (2,): (direction / 2 pi, distance / l_max)                           |
| Action Values      | Box(0.0, 1.0, (2,), float32); outside values are clipped, NaN raises |
| Observation Shape  | (3, S, S), S = `obs_size` (default 80)                               |
| Observation Values | [0, 255] uint8: PoIs, own cell and energy, coverage history          |
| State Shape        | (3, S, S)                                                            |
| State Values       | [0, 255] uint8: as the observation, channel 1 showing every UAV      |

N UAVs fly over an L x L area (default 16 x 16) holding K points of interest (default: the 256 integer lattice
points) and try to cover them evenly for `max_cycles` steps while spending little energy and staying within
communication range of each other. Every agent receives the same shared reward (fairness-weighted coverage gain per
unit of energy plus an entropy bonus) minus its own penalties for hitting the wall or losing every link.

```python
uav_coverage_v0.parallel_env(map_size=16, n_uavs=6, pois="grid", max_energy=500.0, max_distance=3.0,
                             move_energy=1/3, hover_energy=0.5, coverage_range=3.0, comm_range=6.0,
                             wall_penalty=10.0, comm_penalty=1.0, entropy_coef=0.1, eps=1e-4, max_cycles=300,
                             obs_size=80, start="fixed", reward_scale=1.0, reward_clip=None, render_mode=None)
```

See `docs/environment.md` for every parameter, the rules of a step and the metrics.
"""

from sb3_maddpg_envs.uav_coverage.uav_coverage import env, parallel_env, raw_env

__all__ = ["env", "parallel_env", "raw_env"]
