"""
SHA-256 fingerprints of the UAV coverage env's behaviour, to check that a refactoring of ``envs/uav_coverage/``
changes nothing: run it before and after, the hashes must be equal.

Each case builds a registered env (``uav_coverage_v0``, ``uav_coverage_fast_v0``, ``uav_coverage_v1``,
``uav_coverage_cpu_v1``, ``uav_coverage_tmc_v1``, ``uav_coverage_hazard_cpu_v1``, ``uav_coverage_storm_cpu_v1``,
``uav_coverage_storm_cpu_v2``, with the kwargs of ``envs/registration.py``, plus parameter combinations that
exercise the other rules: the hazards' gusts, crashes, link failures, storm strikes and their penalty, the storm zone
drawn, grounded steps and depletions among them), then plays several episodes with seeded random actions (drawn in
[-0.1, 1.1], so the clipping is exercised too), resetting with a seed or without one, and hashes every observation,
reward, termination, truncation and info, and the state after each step. The greedy
cases act with the greedy baseline of ``sb3_maddpg.evaluation.baselines`` instead and hash its scores too.

    python experiments/env_fingerprint.py          # one line per case, then the hash of all cases
"""

from __future__ import annotations

import hashlib
import json
from typing import Any

import numpy as np

from sb3_maddpg.zoo.registry import make_multiagent_env
from sb3_maddpg_envs.uav_coverage.baselines import GREEDY_STEP_HEADINGS, greedy_step_scores, step_actions

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
    ("tmc_v1", "uav_coverage_tmc_v1", {}, 600),
    ("hazard_cpu_v1", "uav_coverage_hazard_cpu_v1", {}, 400),
    ("storm_cpu_v1", "uav_coverage_storm_cpu_v1", {}, 400),
    (
        "hazard_cpu_v1 heavy gusts, grounded crashes, depletions",
        "uav_coverage_hazard_cpu_v1",
        {"gust_tail": 1.0, "crash_ground_steps": 4, "grounded_penalty": 0.5, "show_grounded": True, "max_energy": 60.0},
        300,
    ),
    (
        "storm_cpu_v1 frequent strikes, crash energy, clip",
        "uav_coverage_storm_cpu_v1",
        {"storm_prob": 0.1, "crash_energy": 5.0, "show_grounded": True, "reward_clip": 0.5, "max_energy": 80.0},
        300,
    ),
    (
        "fast_v0 gusts, crash energy, link failures",
        "uav_coverage_fast_v0",
        {"gust_prob": 0.5, "gust_tail": 1.0, "crash_energy": 20.0, "link_failure_prob": 0.3, "max_energy": 100.0},
        300,
    ),
    (
        "fast_v0 storm and gusts, grounded",
        "uav_coverage_fast_v0",
        {"storm_zone": (0.0, 0.0, 8.0, 16.0), "storm_prob": 0.05, "crash_ground_steps": 3, "gust_prob": 0.2, "n_uavs": 3},
        300,
    ),
    ("hazard_cpu_v1 one uav", "uav_coverage_hazard_cpu_v1", {"n_uavs": 1, "gust_tail": 1.0}, 200),
    # added with the redesigned storm (2026-12-07): the lines above keep their hashes
    ("storm_cpu_v2", "uav_coverage_storm_cpu_v2", {}, 400),
    (
        "v0 storm zone shown at 5 pixels per cell, strike penalty, gusts",
        "uav_coverage_v0",
        {
            "storm_zone": (2.5, 1.0, 9.3, 7.7),
            "storm_prob": 0.2,
            "storm_penalty": 2.0,
            "crash_ground_steps": 2,
            "show_storm_zone": True,
            "gust_prob": 0.2,
            "n_uavs": 3,
        },
        200,
    ),
]

#: (label, registered env id, kwargs over the registered ones, steps): played by the greedy baseline
GREEDY_CASES: list[tuple[str, str, dict[str, Any], int]] = [
    ("greedy_step tmc_v1", "uav_coverage_tmc_v1", {}, 200),
    ("greedy_step fast_v0", "uav_coverage_fast_v0", {}, 200),
    ("greedy_step cpu_v1 depletion", "uav_coverage_cpu_v1", {"max_energy": 20.0, "max_cycles": 60}, 200),
    ("greedy_step hazard_cpu_v1", "uav_coverage_hazard_cpu_v1", {}, 200),
]


def greedy_actions(env: Any, digest: Any) -> dict[str, np.ndarray]:
    """The greedy baseline's actions, its scores added to the hash."""
    core = env.core
    scores, candidates, _ = greedy_step_scores(core, eps=core.eps)
    digest.update(scores.tobytes())
    digest.update(candidates.tobytes())
    actions = step_actions(np.argmax(scores, axis=1), GREEDY_STEP_HEADINGS, core.action_mode)
    return {agent: actions[env.possible_agents.index(agent)] for agent in env.agents}


def fingerprint(env_id: str, kwargs: dict[str, Any], steps: int, seed: int = 0, greedy: bool = False) -> str:
    """Hash of everything the env returns over ``steps`` steps of seeded random actions (or the greedy's)."""
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
        if greedy:
            actions = greedy_actions(env, digest)
        else:
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
    for label, env_id, kwargs, steps in GREEDY_CASES:
        value = fingerprint(env_id, kwargs, steps, greedy=True)
        total.update(value.encode())
        print(f"{value}  {label}")
    print(f"{total.hexdigest()}  all cases")


if __name__ == "__main__":
    main()
