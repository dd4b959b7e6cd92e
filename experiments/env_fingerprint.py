"""
SHA-256 fingerprints of the UAV coverage env's behaviour, to check that a refactoring of ``envs/uav_coverage/``
changes nothing: run it before and after, the hashes must be equal.

Each case builds a registered env (``uav_coverage_v0``, ``uav_coverage_fast_v0``, ``uav_coverage_v1``,
``uav_coverage_cpu_v1``, with the kwargs of ``sb3_maddpg/zoo/registry.py``, plus a few parameter combinations that
exercise the other rules), then plays several episodes with seeded random actions (drawn in [-0.1, 1.1], so the
clipping is exercised too), resetting with a seed or without one, and hashes every observation, reward,
termination, truncation and info, and the state after each step.

    python experiments/env_fingerprint.py          # one line per case, then the hash of all cases
"""

from __future__ import annotations

import hashlib
import json
from typing import Any

import numpy as np

from sb3_maddpg.zoo.registry import make_multiagent_env

#: (label, registered env id, kwargs over the registered ones, steps)
CASES: list[tuple[str, str, dict[str, Any], int]] = [
    ("v0", "uav_coverage_v0", {}, 400),
    ("v0 random starts", "uav_coverage_v0", {"start": "random"}, 400),
    ("fast_v0", "uav_coverage_fast_v0", {}, 400),
    ("fast_v0 random starts", "uav_coverage_fast_v0", {"start": "random"}, 400),
    ("v1", "uav_coverage_v1", {}, 400),
    ("cpu_v1", "uav_coverage_cpu_v1", {}, 400),
    ("cpu_v1 cell mark, no teammates", "uav_coverage_cpu_v1", {"position_mark": "cell", "teammate_channel": False}, 300),
    ("fast_v0 exact mark, teammates", "uav_coverage_fast_v0", {"position_mark": "exact", "teammate_channel": True}, 300),
    ("fast_v0 clip walls, polar", "uav_coverage_fast_v0", {"wall_mode": "clip", "start": "random"}, 300),
    ("cpu_v1 refuse walls", "uav_coverage_cpu_v1", {"wall_mode": "refuse"}, 300),
    (
        "fast_v0 uniform pois, clip",
        "uav_coverage_fast_v0",
        {"pois": "uniform", "n_pois": 40, "reward_clip": 0.5, "reward_scale": 3.0, "max_cycles": 50},
        300,
    ),
    ("cpu_v1 depletion", "uav_coverage_cpu_v1", {"max_energy": 8.0, "fairness_coef": 1.0, "energy_coef": 2.0}, 300),
    ("fast_v0 depletion", "uav_coverage_fast_v0", {"max_energy": 8.0, "start": "random"}, 300),
    ("cpu_v1 one uav", "uav_coverage_cpu_v1", {"n_uavs": 1}, 200),
    (
        "cpu_v1 image pois, several per cell",
        "uav_coverage_cpu_v1",
        {"map_size": 8, "obs_size": 24, "n_uavs": 3, "pois": np.linspace(0, 1, 35 * 21).reshape(35, 21), "max_cycles": 40},
        200,
    ),
    (
        "fast_v0 array pois",
        "uav_coverage_fast_v0",
        {
            "pois": [[0.2, 0.3], [0.2, 0.31], [5.5, 9.9], [15.9, 0.0]],
            "start": [[1, 1], [2, 2], [3, 3], [4, 4], [5, 5], [6, 6]],
        },
        200,
    ),
]


def fingerprint(env_id: str, kwargs: dict[str, Any], steps: int, seed: int = 0) -> str:
    """Hash of everything the env returns over ``steps`` steps of seeded random actions."""
    digest = hashlib.sha256()
    env = make_multiagent_env(env_id, **kwargs)
    rng = np.random.default_rng(seed)

    def add_dicts(*dicts: dict[str, Any]) -> None:
        for values in dicts:
            for agent, value in values.items():
                digest.update(agent.encode())
                if isinstance(value, np.ndarray):
                    digest.update(str((value.dtype, value.shape)).encode())
                    digest.update(np.ascontiguousarray(value).tobytes())
                else:
                    digest.update(json.dumps(value, sort_keys=True).encode())

    episode = 0
    obs, infos = env.reset(seed=seed)
    add_dicts(obs, infos)
    for _ in range(steps):
        actions = {agent: rng.uniform(-0.1, 1.1, size=2).astype(np.float32) for agent in env.agents}
        obs, rewards, terminations, truncations, infos = env.step(actions)
        rewards = {agent: float(value).hex() for agent, value in rewards.items()}
        add_dicts(obs, rewards, terminations, truncations, infos)
        digest.update(env.state().tobytes())
        if not env.agents:
            episode += 1
            # every other episode continues the generator's stream instead of reseeding
            obs, infos = env.reset(seed=seed + episode if episode % 2 == 0 else None)
            add_dicts(obs, infos)
    env.close()
    return digest.hexdigest()


def main() -> None:
    total = hashlib.sha256()
    for label, env_id, kwargs, steps in CASES:
        value = fingerprint(env_id, kwargs, steps)
        total.update(value.encode())
        print(f"{value}  {label}")
    print(f"{total.hexdigest()}  all cases")


if __name__ == "__main__":
    main()
