"""
Where a trained UAV team goes: for a saved MADDPG model on ``uav_coverage_v1`` (``obs_size=16``, 300-step episodes,
random starts), each episode's metrics, each UAV's mean distance flown per step over the last 100 steps, the pairs
of UAVs that end within 3 cells of each other, and each UAV's final position in every episode (does it keep one
place whatever its start?). For each episode it also gives the static coverage of the final positions (the share of
PoIs within R0 of a UAV hovering there) and how far small moves raise it: a coordinate ascent in which one UAV at a
time moves to the best point within 0.75 cells of where it is (a grid of 1/16 cell), until no move gains; a large
gain with small moves means the learned layout is imprecise rather than a poor local optimum.

    python experiments/uav_team_positions.py runs/pos/pos_s0.zip --episodes 4
    python experiments/uav_team_positions.py runs/tm/teammates_s0.zip --env-kwargs '{"teammate_channel": true}'
"""

import argparse
import json

import numpy as np
import torch as th
from uav_learning import reject_removed_variants  # the sibling file, not a package

from sb3_maddpg import MADDPG
from sb3_maddpg_envs import uav_coverage_v1

EVAL_SEED = 10_000  # the first evaluation episode of experiments/uav_learning.py and docs/results.md


def covers(points: np.ndarray, pois: np.ndarray, coverage_range: float) -> np.ndarray:
    """(P, K) bool: PoI k within ``coverage_range`` of point p."""
    return ((pois[None, :, :] - points[:, None, :]) ** 2).sum(axis=-1) <= coverage_range**2


def static_coverage(positions: np.ndarray, pois: np.ndarray, coverage_range: float) -> float:
    """Share of the PoIs within ``coverage_range`` of some position (UAVs hovering at ``positions``)."""
    return float(covers(positions, pois, coverage_range).any(axis=0).mean())


def refine_locally(
    positions: np.ndarray, pois: np.ndarray, coverage_range: float, map_size: float, reach: float = 0.75
) -> np.ndarray:
    """
    Coordinate ascent of the static coverage: one UAV at a time moves to the best point within ``reach`` (max-norm,
    a grid of 1/16 cell, inside the area) of its position, until no move gains.

    :return: the refined positions (N, 2)
    """
    offsets = np.arange(-reach, reach + 1e-9, 1.0 / 16.0)
    grid = np.stack(np.meshgrid(offsets, offsets), axis=-1).reshape(-1, 2)
    refined = positions.copy()
    best = static_coverage(refined, pois, coverage_range)
    improved = True
    while improved:
        improved = False
        for i in range(len(refined)):
            candidates = np.clip(refined[i] + grid, 0.0, np.nextafter(map_size, 0.0))
            covered_by_others = covers(np.delete(refined, i, axis=0), pois, coverage_range).any(axis=0)
            scores = (covers(candidates, pois, coverage_range) | covered_by_others[None]).mean(axis=1)
            j = int(np.argmax(scores))
            if scores[j] > best + 1e-12:
                refined[i], best, improved = candidates[j], float(scores[j]), True
    return refined


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument("model", help="a saved MADDPG model (.zip)")
    parser.add_argument("--env-kwargs", type=json.loads, default={}, help="JSON dict of extra env parameters")
    parser.add_argument("--episodes", type=int, default=4)
    parser.add_argument("--seed", type=int, default=EVAL_SEED, help="seed of the first episode")
    args = parser.parse_args()
    reject_removed_variants(args.env_kwargs)
    th.set_num_threads(1)
    model = MADDPG.load(args.model, device="cpu")
    finals = []
    for episode in range(args.episodes):
        env = uav_coverage_v1.parallel_env(obs_size=16, max_cycles=300, **args.env_kwargs)
        observations, _ = env.reset(seed=args.seed + episode)
        trajectory = [env.core.positions.copy()]
        while env.agents:
            stacked = np.stack([observations[agent] for agent in env.possible_agents])
            actions, _ = model.predict(stacked, deterministic=True)
            observations, *_ = env.step({agent: actions[i] for i, agent in enumerate(env.possible_agents)})
            trajectory.append(env.core.positions.copy())
        path = np.array(trajectory)  # (T + 1, N, 2)
        speed = np.linalg.norm(np.diff(path, axis=0), axis=-1)[-100:].mean(axis=0)
        final = path[-1]
        finals.append(final)
        distances = np.linalg.norm(final[:, None] - final[None], axis=-1)[np.triu_indices(len(final), 1)]
        m = env.core.metrics()
        core = env.core
        refined = refine_locally(final, core.pois, core.coverage_range, core.map_size)
        print(
            f"episode {episode}: c {m['coverage']:.3f} f {m['fairness']:.3f} e {m['energy']:.3f} "
            f"eta {m['energy_efficiency']:.3f} | distance per step, last 100 steps: {speed.round(2).tolist()} | "
            f"pairs within 3 cells: {int((distances < 3).sum())}, closest pair {distances.min():.2f} | "
            f"static coverage {static_coverage(final, core.pois, core.coverage_range):.3f}, "
            f"{static_coverage(refined, core.pois, core.coverage_range):.3f} after local moves "
            f"(largest {np.abs(refined - final).max():.2f} cells)"
        )
    print("final position (x, y) of each UAV in each episode:")
    for i, positions in enumerate(np.array(finals).transpose(1, 0, 2)):
        print(f"  uav_{i}: {positions.round(1).tolist()}")


if __name__ == "__main__":
    main()
