"""
MPE2's ``simple_speaker_listener_v4`` measured as the MADDPG paper (Lowe et al., 2017) reports it: the listener's
distance to its goal landmark at the end of each 25-step episode, and how often it ends on the landmark; beside the
team return of docs/results.md. One JSON line per model and one for uniformly random actions.

    python experiments/speaker_listener.py --episodes 100 --seed 1000 \
        runs/mpe/logs_simple_speaker_listener_discrete_v4/maddpg/*/simple_speaker_listener_discrete_v4.zip

Episode e of every method is reset with seed ``--seed + e`` on the PettingZoo parallel env itself (no wrapper of
this library in between), so models of other libraries are measured on the same episodes
(experiments/peer_speaker_listener.py imports :func:`speaker_listener_episodes`). "On the landmark" means the
listener's disc touches the goal landmark's (distance below the sum of their sizes, 0.075 + 0.04).
"""

import argparse
import json
from collections.abc import Callable

import numpy as np

Act = Callable[[dict[str, np.ndarray]], dict[str, np.ndarray | int]]


def speaker_listener_episodes(act: Act, episodes: int, seed: int, continuous_actions: bool) -> dict[str, float]:
    """
    Run ``episodes`` episodes of ``simple_speaker_listener_v4`` (25 steps each), episode e reset with ``seed + e``.

    :param act: maps the env's observation dict to an action dict (the env's own action types)
    :param episodes: number of episodes
    :param seed: reset seed of the first episode
    :param continuous_actions: the env's action mode
    :return: mean and std of the team return (sum over agents and steps), mean final distance of the listener to its
        goal landmark, and the fraction of episodes that end with the listener on it
    """
    from mpe2 import simple_speaker_listener_v4

    returns, distances, touching = [], [], []
    for episode in range(episodes):
        env = simple_speaker_listener_v4.parallel_env(max_cycles=25, continuous_actions=continuous_actions)
        observations, _ = env.reset(seed=seed + episode)
        total = 0.0
        while env.agents:
            observations, rewards, _, _, _ = env.step(act(observations))
            total += float(sum(rewards.values()))
        speaker = env.unwrapped.world.agents[0]  # MPE2 keeps the goal on the speaker: goal_a the listener, goal_b its landmark
        listener, landmark = speaker.goal_a, speaker.goal_b
        distance = float(np.linalg.norm(listener.state.p_pos - landmark.state.p_pos))
        returns.append(total)
        distances.append(distance)
        touching.append(distance < listener.size + landmark.size)
        env.close()
    return dict(mean=float(np.mean(returns)), std=float(np.std(returns)), final_distance=float(np.mean(distances)),
                on_landmark=float(np.mean(touching)))  # fmt: skip


def random_actions(continuous_actions: bool, seed: int) -> Act:
    """Uniformly random actions, each agent in its own action space (seeded)."""
    from mpe2 import simple_speaker_listener_v4

    env = simple_speaker_listener_v4.parallel_env(continuous_actions=continuous_actions)
    spaces = {agent: env.action_space(agent) for agent in env.possible_agents}
    for offset, space in enumerate(spaces.values()):
        space.seed(seed + offset)
    return lambda observations: {agent: spaces[agent].sample() for agent in observations}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument("models", nargs="*", help="saved models (.zip) of this library")
    parser.add_argument("--continuous", action="store_true", help="Box actions (default: Discrete, MPE2's default)")
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--seed", type=int, default=1000)
    args = parser.parse_args()
    from sb3_maddpg import MADDPG

    controllers = {"random": random_actions(args.continuous, args.seed)}
    for path in args.models:
        model = MADDPG.load(path, device="cpu")
        controllers[path] = lambda observations, model=model: model.predict(observations, deterministic=True)[0]
    for name, act in controllers.items():
        result = speaker_listener_episodes(act, args.episodes, args.seed, args.continuous)
        print(json.dumps(dict(model=name, continuous_actions=args.continuous, episodes=args.episodes, **result)))


if __name__ == "__main__":
    main()
