"""A UAV env's episode state can be taken and given back: the same actions then give the same steps."""

import numpy as np
import pytest

from sb3_maddpg.zoo.registry import make_multiagent_env


def random_actions(env, rng: np.random.Generator) -> dict[str, np.ndarray]:
    return {agent: rng.uniform(0, 1, 2).astype(np.float32) for agent in env.agents}


def play(env, actions: list[dict[str, np.ndarray]]) -> list[tuple]:
    """The steps' observations, rewards, terminations, truncations and infos, until the actions or the episode end."""
    steps = []
    for joint in actions:
        if not env.agents:
            break
        steps.append(env.step({agent: action for agent, action in joint.items() if agent in env.agents}))
    return steps


def same_steps(first: list[tuple], second: list[tuple]) -> bool:
    if len(first) != len(second):
        return False
    for (obs_a, *rest_a), (obs_b, *rest_b) in zip(first, second, strict=True):
        if obs_a.keys() != obs_b.keys() or not all(np.array_equal(obs_a[k], obs_b[k]) for k in obs_a):
            return False
        if rest_a != rest_b:
            return False
    return True


# the storm task strikes at random and the hazardous one draws gusts and link failures: the generator travels along
@pytest.mark.parametrize("env_id", ["uav_coverage_cpu_v1", "uav_coverage_storm_cpu_v1", "uav_coverage_hazard_cpu_v1"])
def test_restore_replays_the_same_steps_to_the_episode_end(env_id: str):
    env = make_multiagent_env(env_id, max_cycles=40)
    env.reset(seed=5)
    rng = np.random.default_rng(0)
    play(env, [random_actions(env, rng) for _ in range(10)])
    snapshot = env.snapshot()
    actions = [random_actions(env, rng) for _ in range(40)]
    first = play(env, actions)
    assert len(first) == 30 and not env.agents  # the episode ended (max_cycles 40)
    env.restore(snapshot)
    second = play(env, actions)
    env.restore(snapshot)  # the snapshot is unchanged by what the env did since
    third = play(env, actions)
    assert same_steps(first, second) and same_steps(first, third)
    # another action from the snapshot gives another step: the state is the env's, not a recording
    env.restore(snapshot)
    other = play(env, [{agent: np.full(2, 0.5, np.float32) for agent in env.agents}])
    assert not np.array_equal(other[0][0]["uav_0"], first[0][0]["uav_0"]) or other[0][1] != first[0][1]


def test_restore_refuses_what_is_not_a_snapshot_of_this_team():
    env = make_multiagent_env("uav_coverage_cpu_v1")
    env.reset(seed=0)
    with pytest.raises(TypeError, match="restore takes a UAVCoverageSnapshot"):
        env.restore({"core": None})
    other = make_multiagent_env("uav_coverage_cpu_v1", n_uavs=3)
    other.reset(seed=0)
    with pytest.raises(ValueError, match="the snapshot has 3 UAVs, this env 6"):
        env.restore(other.snapshot())
