"""
Can a quantile critic see the storm? For saved MADDPG models with a quantile critic on ``uav_coverage_storm_cpu_v1``
(or ``--env``, e.g. the redesigned ``uav_coverage_storm_cpu_v2``, where p_s is 0.07 and a strike costs 0.9 at once),
play deterministic episodes and, at every step, read critic i's quantiles of UAV i's return for the team's actual
joint action; then compare the UAV-steps that end inside the storm zone with those outside: the quantiles' mean, their
CVaR at 0.1 (``sb3_maddpg.common.distributional.cvar``) and the tail depth (mean minus CVaR), beside the truth the
critic should learn: how often a UAV inside is struck within the critic's horizon. For the UAV-steps inside, it
also reads where the actor's objective pulls: the gradient of critic i's mean and of its CVaR at 0.1 with respect to
UAV i's own action (v1's actions are displacements), and the share of the UAV-steps where it points out of the zone
(positive dot product with the direction to the nearest edge of the zone).

A UAV hovering inside the zone is struck at a step with p_s = 0.005, so within 10 steps (about a γ 0.9 horizon) with
about 5 %: a critic that sees the storm has a deeper lower tail inside than outside (CVaR at 0.1 lowered by about half
the discounted cost of a strike, 20 grounded steps at -0.75). No difference in tail depth means an actor maximising
CVaR has nothing to climb away from.

    python experiments/storm_critic_tail.py runs/stsc/st_a05_s0.zip runs/stsc/st_a1_s0.zip --episodes 5
    python experiments/storm_critic_tail.py --env uav_coverage_storm_cpu_v2 --episodes 3 MODEL.zip
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
import torch as th

from sb3_maddpg import MADDPG
from sb3_maddpg.common.diagnostics import own_action_gradients
from sb3_maddpg.common.distributional import cvar
from sb3_maddpg.zoo.registry import make_multiagent_env
from sb3_maddpg_envs.uav_coverage.hazards import in_zone

ENV_ID = "uav_coverage_storm_cpu_v1"
EVAL_SEED = 10_000  # the first evaluation episode of experiments/uav_learning.py
ALPHA = 0.1


def critic_tails(
    model: MADDPG, n_episodes: int, seed: int = EVAL_SEED, alpha: float = ALPHA, env_id: str = ENV_ID
) -> dict[str, np.ndarray]:
    """
    Critic i's mean and CVaR_alpha of UAV i's return at every active UAV-step, and whether the UAV ended it inside.

    :param model: a trained team whose policy has ``n_quantiles > 1``
    :param n_episodes: deterministic episodes, reset seeds ``seed``, ``seed + 1``, ...
    :param seed: the first reset seed
    :param alpha: the CVaR level read
    :param env_id: a storm task's env id
    :return: ``inside`` (bool), ``mean`` and ``cvar`` (float), one entry per active UAV-step; ``out_mean`` and
        ``out_cvar`` (bool), one entry per active UAV-step inside the zone: whether the gradient of the mean (of
        CVaR_alpha) with respect to the UAV's own action points out of the zone
    """
    policy = model.policy
    if policy.n_quantiles < 2:
        raise ValueError(f"{type(model).__name__} has {policy.n_quantiles} quantile: there is no tail to read")
    inside, means, cvars, out_mean, out_cvar = [], [], [], [], []
    for episode in range(n_episodes):
        env = make_multiagent_env(env_id)
        observations, _ = env.reset(seed=seed + episode)
        core = env.core
        while env.agents:
            stacked = np.stack([observations[agent] for agent in env.possible_agents])
            actions, _ = model.predict(stacked, deterministic=True)
            n_agents = len(actions)
            with th.no_grad():
                obs = policy.obs_to_tensor(stacked)[0].view(1, n_agents, *stacked.shape[1:])
                joint = th.as_tensor(policy.scale_action(actions), dtype=th.float32).view(1, n_agents, -1)
                features = policy.critic.encode(obs)
                quantiles = policy.critic.quantiles_from_features(features, joint)[0]  # (N, n_q)
            # d(critic i's mean or CVaR)/d(UAV i's own action), all UAVs at once: critic i reads own[:, i] only
            objectives = (lambda q: q.mean(dim=-1), lambda q: cvar(q, alpha))
            gradients = [g[0].numpy() for g in own_action_gradients(policy.critic, features, joint, objectives)]
            exits = exit_directions(core.positions, core.storm_zone)
            observations, *_ = env.step({a: actions[i] for i, a in enumerate(env.possible_agents)})
            active = core.active.copy()
            zone = in_zone(core.positions, core.storm_zone)
            for i in np.flatnonzero(active):
                inside.append(bool(zone[i]))
                means.append(float(quantiles[i].mean()))
                cvars.append(float(cvar(quantiles[i : i + 1], alpha)[0]))
                if zone[i]:
                    out_mean.append(bool(gradients[0][i] @ exits[i] > 0))
                    out_cvar.append(bool(gradients[1][i] @ exits[i] > 0))
    return {
        "inside": np.array(inside),
        "mean": np.array(means),
        "cvar": np.array(cvars),
        "out_mean": np.array(out_mean),
        "out_cvar": np.array(out_cvar),
    }


def exit_directions(positions: np.ndarray, zone: tuple[float, float, float, float]) -> np.ndarray:
    """
    The unit vector from each position towards the nearest edge of the zone (for a position inside it).

    :param positions: (N, 2)
    :param zone: (x0, y0, x1, y1)
    :return: (N, 2)
    """
    x0, y0, x1, y1 = zone
    x, y = positions[:, 0], positions[:, 1]
    distances = np.stack([x - x0, x1 - x, y - y0, y1 - y], axis=1)  # west, east, south, north
    units = np.array([[-1.0, 0.0], [1.0, 0.0], [0.0, -1.0], [0.0, 1.0]])
    return units[np.argmin(distances, axis=1)]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("models", nargs="+", help="saved MADDPG models (.zip) with quantile critics")
    parser.add_argument("--episodes", type=int, default=5)
    parser.add_argument("--seed", type=int, default=EVAL_SEED, help="seed of the first episode")
    parser.add_argument("--env", default=ENV_ID, help="the storm task's env id (default: %(default)s)")
    args = parser.parse_args(argv)
    th.set_num_threads(1)
    print(
        f"| model | UAV-steps inside / outside | mean inside / outside | CVaR_{ALPHA} inside / outside | "
        f"tail depth (mean - CVaR) inside / outside | inside: the mean's / CVaR_{ALPHA}'s gradient points out |"
    )
    print("|---|---|---|---|---|---|")
    for path in args.models:
        tails = critic_tails(MADDPG.load(path, device="cpu"), args.episodes, args.seed, env_id=args.env)
        inside = tails["inside"]
        depth = tails["mean"] - tails["cvar"]

        print(
            f"| {path} | {int(inside.sum())} / {int((~inside).sum())} | {pair(tails['mean'], inside)} | "
            f"{pair(tails['cvar'], inside)} | {pair(depth, inside)} | "
            f"{tails['out_mean'].mean():.2f} / {tails['out_cvar'].mean():.2f} |"
        )
    return 0


def pair(values: np.ndarray, inside: np.ndarray) -> str:
    """The mean of ``values`` over the UAV-steps inside the zone and over those outside."""
    return " / ".join(f"{values[mask].mean():+.3f}" if mask.any() else "-" for mask in (inside, ~inside))


if __name__ == "__main__":
    sys.exit(main())
