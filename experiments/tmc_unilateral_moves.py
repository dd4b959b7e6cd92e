"""
Does v1's per-agent coverage reward itself keep a team moving on the published setting? The greedy static placement
flies to its layout (60 steps); then, for each UAV in turn, with its teammates hovering, its one-step reward for
hovering is compared with that for moves of 0.1, 0.25, 0.5 and 1 l_max at 16 headings. A layout where no UAV gains by
a move is a one-step equilibrium of the reward: a team that keeps moving there does so by what it learned, not because
the reward pays for it.

    python experiments/tmc_unilateral_moves.py --n-uavs 6 --seed 10000 [--energy-coef 0.5]

Each candidate replays the episode from its reset seed (the env cannot be copied: PettingZoo's EzPickle rebuilds it
from its arguments).
"""

import argparse

import numpy as np

from sb3_maddpg_envs import uav_coverage_v1
from sb3_maddpg_envs.uav_coverage.baselines import GreedyStaticController
from sb3_maddpg_envs.uav_coverage.scenarios import TMC2020_KWARGS

DISTANCES = (0.1, 0.25, 0.5, 1.0)  # in l_max
N_HEADINGS = 16
SETTLE_STEPS = 60


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument("--n-uavs", type=int, default=6)
    parser.add_argument("--seed", type=int, default=10000, help="reset seed of the episode (random starts)")
    parser.add_argument("--energy-coef", type=float, default=0.5, help="the coverage reward's energy weight (v1: 0.5)")
    args = parser.parse_args()
    kwargs = {**TMC2020_KWARGS, "n_uavs": args.n_uavs, "energy_coef": args.energy_coef}

    env = uav_coverage_v1.parallel_env(**kwargs)
    observations, _ = env.reset(seed=args.seed)
    controller = GreedyStaticController()
    controller.reset(env, seed=0)
    history = []
    for _ in range(SETTLE_STEPS):
        actions = controller.act(observations, env)
        history.append(actions)
        observations, *_ = env.step(actions)
    hover = {agent: np.full(2, 0.5, dtype=np.float32) for agent in env.agents}

    def reward_of(agent: str, action: np.ndarray) -> float:
        replay = uav_coverage_v1.parallel_env(**kwargs)
        replay.reset(seed=args.seed)
        for actions in history:
            replay.step(actions)
        return float(replay.step({**hover, agent: action})[1][agent])

    print(f"N {args.n_uavs}, reset seed {args.seed}, energy_coef {args.energy_coef}, after {SETTLE_STEPS} greedy steps")
    for agent in env.agents:
        hovering = reward_of(agent, hover[agent])
        best_gain, best_move = 0.0, "none"
        for distance in DISTANCES:
            for heading in range(N_HEADINGS):
                angle = 2 * np.pi * heading / N_HEADINGS
                # Cartesian actions: (dx, dy) = (2a - 1) l_max
                action = np.clip(0.5 + 0.5 * distance * np.array([np.cos(angle), np.sin(angle)]), 0.0, 1.0)
                gain = reward_of(agent, action.astype(np.float32)) - hovering
                if gain > best_gain:
                    best_gain, best_move = gain, f"{distance} l_max at {360 * heading / N_HEADINGS:.1f} deg"
        print(f"{agent}: reward hovering {hovering:+.4f}; best one-step gain of a move {best_gain:+.4f} ({best_move})")


if __name__ == "__main__":
    main()
