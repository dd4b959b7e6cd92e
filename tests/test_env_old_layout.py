"""
UAV envs and episode snapshots pickled by the code before the env package's config, phases and scenarios (commit
66f00c5) load and step as they did then.

``tests/data/old_layout_uav_env.pickle`` holds, for a storm task with gusts and grounding, a v0 task with uniform PoIs
and a v1 task with image PoIs and given starts, the env (``<case>/env``) and a snapshot taken 12 steps into an episode
(``<case>/snapshot``); ``old_layout_uav_env_steps.npz`` the 10 joint actions played from each and the observations and
rewards they gave then: from the snapshot, and from the env reset with seed 3.
"""

import pickle
from pathlib import Path

import numpy as np
import pytest

from sb3_maddpg.zoo.registry import make_multiagent_env

DATA = Path(__file__).parent / "data"
CASES = {
    "storm": (
        "uav_coverage_storm_cpu_v1",
        {"gust_prob": 0.3, "crash_energy": 5.0, "show_grounded": True, "n_uavs": 4, "max_cycles": 60, "storm_prob": 0.2},
    ),
    "v0_uniform": ("uav_coverage_fast_v0", {"n_uavs": 3, "pois": "uniform", "n_pois": 30}),
    "v1_image": (
        "uav_coverage_cpu_v1",
        {
            "map_size": 8,
            "obs_size": 8,
            "n_uavs": 2,
            "pois": np.linspace(0, 1, 100).reshape(10, 10),
            "start": [[1.5, 2.5], [6.0, 0.5]],
        },
    ),
}


@pytest.fixture(scope="module")
def saved():
    with open(DATA / "old_layout_uav_env.pickle", "rb") as file:
        objects = pickle.load(file)  # the project's own test data
    return objects, np.load(DATA / "old_layout_uav_env_steps.npz")


def play(env, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    obs, rewards = [], []
    for joint in actions:
        step_obs, step_rewards, *_ = env.step({a: joint[i] for i, a in enumerate(env.possible_agents) if a in env.agents})
        obs.append(np.stack([step_obs[a] for a in env.possible_agents]))
        rewards.append([step_rewards[a] for a in env.possible_agents])
    return np.stack(obs), np.array(rewards)


@pytest.mark.parametrize("case", sorted(CASES))
def test_old_snapshot_restores_and_steps_as_then(saved, case: str):
    objects, expected = saved
    env_id, kwargs = CASES[case]
    env = make_multiagent_env(env_id, **kwargs)
    env.reset(seed=0)
    env.restore(objects[f"{case}/snapshot"])
    obs, rewards = play(env, expected[f"{case}/actions"])
    np.testing.assert_array_equal(obs, expected[f"{case}/snapshot_obs"])
    np.testing.assert_array_equal(rewards, expected[f"{case}/snapshot_rewards"])


@pytest.mark.parametrize("case", sorted(CASES))
def test_old_env_pickle_loads_and_steps_as_then(saved, case: str):
    objects, expected = saved
    env = objects[f"{case}/env"]
    env.reset(seed=3)
    obs, rewards = play(env, expected[f"{case}/actions"])
    np.testing.assert_array_equal(obs, expected[f"{case}/env_obs"])
    np.testing.assert_array_equal(rewards, expected[f"{case}/env_rewards"])
