"""Hand-made teams played on the small risky tasks (risky_reach_v0, risky_hover_v0), for their tests."""

from collections.abc import Callable

import numpy as np

from sb3_maddpg.zoo.registry import make_multiagent_env


def play(env_id: str, act: Callable[[np.ndarray], np.ndarray], n_episodes: int) -> tuple[np.ndarray, int]:
    """
    Every agent acting with ``act`` (its own observation -> its action) for ``n_episodes`` episodes (reset seeds 0, 1,
    ...) of the registered task ``env_id``.

    :return: the sorted team returns, and the zone steps of all agents and episodes together
    """
    env = make_multiagent_env(env_id)
    returns, zone_steps = [], 0
    for episode in range(n_episodes):
        observations, _ = env.reset(seed=episode)
        total = 0.0
        while env.agents:
            observations, rewards, _, _, infos = env.step({agent: act(obs) for agent, obs in observations.items()})
            total += sum(rewards.values())
        returns.append(total)
        zone_steps += sum(info["zone_steps"] for info in infos.values())
    return np.sort(returns), zone_steps
