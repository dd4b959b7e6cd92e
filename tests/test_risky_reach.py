"""The risky reach task: PettingZoo's API and seed tests, the hazard by hand, and its two optima measured."""

import numpy as np
import pytest
from pettingzoo.test import api_test, parallel_api_test, parallel_seed_test
from risky_testing import play

from sb3_maddpg_envs import risky_reach_v0
from sb3_maddpg_envs.risky_reach_v0 import ZONE, hand_made_policy


def test_pettingzoo_api_and_seeds():
    parallel_api_test(risky_reach_v0.parallel_env(n_agents=3), num_cycles=60)
    api_test(risky_reach_v0.env(max_cycles=10), num_cycles=20)
    parallel_seed_test(lambda: risky_reach_v0.parallel_env(zone_prob=0.5), num_cycles=40)


def test_a_step_by_hand():
    """One agent, no jitter: it starts at (-0.8, 0), its landmark is (0.8, 0); the zone is |x| < 0.2, |y| < 0.8."""
    env = risky_reach_v0.parallel_env(n_agents=1, zone_prob=1.0, zone_loss=2.0, jitter=0.0)
    obs, infos = env.reset(seed=0)
    # position, landmark - position, distances to the zone's edges x - (-0.2), 0.2 - x, y - (-0.8), 0.8 - y, inside
    assert obs["agent_0"].tolist() == pytest.approx([-0.8, 0.0, 1.6, 0.0, -0.6, 1.0, 0.8, 0.8, 0.0])
    assert infos["agent_0"] == {"zone_steps": 0, "zone_losses": 0}
    env.positions[0] = [-0.25, 0.0]
    obs, rewards, *_, infos = env.step({"agent_0": np.array([1.0, 0.5], np.float32)})  # to (-0.15, 0.05): inside
    distance = np.hypot(0.8 + 0.15, 0.05)
    assert rewards["agent_0"] == pytest.approx(-0.1 * distance - 2.0)  # zone_prob 1: the loss is certain
    assert obs["agent_0"][-1] == 1.0 and infos["agent_0"] == {"zone_steps": 1, "zone_losses": 1}
    obs, rewards, *_, infos = env.step({"agent_0": np.array([0.0, 9.0], np.float32)})  # clipped: to (-0.15, 0.15)
    assert rewards["agent_0"] == pytest.approx(-0.1 * np.hypot(0.95, 0.15) - 2.0)
    safe = risky_reach_v0.parallel_env(n_agents=1, zone_prob=0.0, jitter=0.0)
    safe.reset(seed=0)
    safe.positions[0] = [-0.25, 0.0]
    _, rewards, *_, infos = safe.step({"agent_0": np.array([1.0, 0.5], np.float32)})
    assert rewards["agent_0"] == pytest.approx(-0.1 * distance) and infos["agent_0"] == {"zone_steps": 1, "zone_losses": 0}


def test_the_mean_goes_through_and_the_tail_goes_around():
    """
    500 episodes of each hand-made policy (the docstring's 1 000: -2.733 and -2.957 in the mean, -3.870 and -3.053 in
    CVaR_0.1): through is better in the mean, around in the worst tenth, each by a margin several standard errors wide
    (a team return's standard deviation through is about 0.5, so its 500-episode mean moves by about 0.02).
    """
    through, through_steps = play("risky_reach_v0", lambda obs: hand_made_policy(obs, "through"), 500)
    around, around_steps = play("risky_reach_v0", lambda obs: hand_made_policy(obs, "around"), 500)
    assert around_steps == 0 and through_steps == 500 * 2 * 4  # 4 steps inside an agent: x = -0.2 (rounded), -0.1, 0, 0.1
    assert through.mean() > around.mean() + 0.15
    assert through[:50].mean() < around[:50].mean() - 0.5
    assert np.ptp(around) < 0.5  # around, the only randomness is the lanes' jitter


def test_bad_arguments_are_refused():
    for kwargs, message in [
        (dict(n_agents=0), r"n_agents must be an integer in \[1, 5\]"),
        (dict(zone_prob=1.5), "zone_prob must be a finite number >= 0 and <= 1"),
        (dict(zone_loss=-1.0), "zone_loss must be a finite number >= 0"),
        (dict(max_cycles=0), r"max_cycles must be an integer in \[1, 10000\]"),
        (dict(render_mode="human"), "does not render"),
    ]:
        with pytest.raises(ValueError, match=message):
            risky_reach_v0.parallel_env(**kwargs)
    env = risky_reach_v0.parallel_env()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="no action for"):
        env.step({"agent_0": np.zeros(2)})
    with pytest.raises(ValueError, match="finite"):
        env.step({"agent_0": np.zeros(2), "agent_1": np.array([np.nan, 0.0])})
    assert ZONE == (-0.2, 0.2, -0.8, 0.8)
