"""
How much a team stays in the storm zone: for saved MADDPG models on ``uav_coverage_storm_cpu_v1`` (or ``--env``, e.g.
the redesigned ``uav_coverage_storm_cpu_v2``), the share of the
active UAV-steps spent inside the zone (the exposure a risk-averse policy should cut), the strikes, the wall hits and
the team return per episode, over the same random-start episodes (reset seeds ``--seed`` + e), deterministic actions.
Strikes are few (about 4 an episode inside the zone), so their count is a noisy measure of exposure; the occupancy is
not.

    python experiments/storm_occupancy.py runs/stsc/st_a1_s0.zip runs/stsc/st_a05_s0.zip --episodes 20
    python experiments/storm_occupancy.py --env uav_coverage_storm_cpu_v2 --episodes 20 \
        runs/storm2/logs/a1_s0/maddpg/uav_coverage_storm_cpu_v2_1/uav_coverage_storm_cpu_v2.zip
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
import torch as th

from sb3_maddpg import MADDPG
from sb3_maddpg.evaluation.baselines import ModelController
from sb3_maddpg.zoo.registry import make_multiagent_env
from sb3_maddpg_envs.uav_coverage.hazards import in_zone

ENV_ID = "uav_coverage_storm_cpu_v1"
EVAL_SEED = 10_000  # the first evaluation episode of experiments/uav_learning.py


def occupancy(model: MADDPG, n_episodes: int, seed: int = EVAL_SEED, env_id: str = ENV_ID) -> dict[str, float]:
    """
    Play ``n_episodes`` deterministic episodes and measure the exposure to the storm.

    :param model: a team trained on (or for) the storm task
    :param n_episodes: episodes, reset seeds ``seed``, ``seed + 1``, ...
    :param seed: the first reset seed
    :param env_id: a storm task's env id
    :return: ``inside`` (share of active UAV-steps inside the zone), ``inside_per_uav`` (per UAV), ``strikes``,
        ``wall_hits`` and ``return`` (team, per episode)
    """
    env = make_multiagent_env(env_id)
    core, controller = env.core, ModelController(model)
    inside_steps, active_steps = np.zeros(core.n_uavs), np.zeros(core.n_uavs)
    strikes, wall_hits, returns = [], [], []
    for episode in range(n_episodes):
        observations, _ = env.reset(seed=seed + episode)
        total = 0.0
        infos: dict = {}
        while env.agents:
            observations, rewards, _, _, infos = env.step(controller.act(observations, env))
            total += sum(rewards.values())
            # where each UAV that flew this step ended it (a grounded UAV is not active and not counted)
            inside_steps += core.active & in_zone(core.positions, core.storm_zone)
            active_steps += core.active
        strikes.append(sum(info["crashes"] for info in infos.values()))
        wall_hits.append(sum(info["wall_hits"] for info in infos.values()))
        returns.append(total)
    inside = inside_steps / np.maximum(active_steps, 1)
    return {
        "inside": float(inside_steps.sum() / max(active_steps.sum(), 1)),
        "inside_per_uav": inside.round(2).tolist(),
        "strikes": float(np.mean(strikes)),
        "wall_hits": float(np.mean(wall_hits)),
        "return": float(np.mean(returns)),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("models", nargs="+", help="saved MADDPG models (.zip)")
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--seed", type=int, default=EVAL_SEED, help="seed of the first episode")
    parser.add_argument("--env", default=ENV_ID, help="the storm task's env id (default: %(default)s)")
    args = parser.parse_args(argv)
    th.set_num_threads(1)
    print("| model | share of UAV-steps inside the zone | per UAV | strikes / episode | wall hits / episode | team return |")
    print("|---|---|---|---|---|---|")
    for path in args.models:
        row = occupancy(MADDPG.load(path, device="cpu"), args.episodes, args.seed, args.env)
        print(
            f"| {path} | {row['inside']:.3f} | {row['inside_per_uav']} | {row['strikes']:.2f} | "
            f"{row['wall_hits']:.1f} | {row['return']:.1f} |"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
