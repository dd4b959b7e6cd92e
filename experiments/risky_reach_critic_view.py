"""
Does the quantile critic see a small risky task's hazard, and where does the CVaR actor's gradient pull? For saved
MADDPG models with a quantile critic on ``risky_reach_v0`` or ``risky_hover_v0``, play deterministic episodes and, at
every agent-step, read critic i's quantiles of agent i's return for the team's actual joint action, beside the truth
it should learn.

The truth is exact here: the tasks' losses do not move the agents and no observation shows them, so a deterministic
team flies the same path whatever the draws, and the loss part of agent i's return from step t is
``-sum_k gamma^k c_{t+k} B_{t+k}`` with ``B_k`` Bernoulli(the loss chance at the position step k ends at: ``zone_prob``
inside risky_reach_v0's zone, ``gust_prob`` on risky_hover_v0) and ``c_k`` the loss's cost there (``zone_loss``; a
gust's cost graded with the depth). Its tail depth (mean minus CVaR_alpha) is what the
critic's tail depth should be; the rest of the return is deterministic and adds nothing to the depth.

For the agent-steps where the risky choice is made, it also reads where the actor's objective pulls: the gradient of
critic i's mean and of its CVaR_alpha with respect to agent i's own action, and the share of those steps where its y
component points to safety. On risky_reach_v0 these are the steps before the zone (left of it, inside its band of
y), and safety is around it (towards the nearer of its top and bottom edges); on risky_hover_v0 the steps within 0.2
of the hazard's edge, and safety is down, out of the hazard.

    python experiments/risky_reach_critic_view.py runs/risky/logs/a025_s0/maddpg/risky_reach_v0_1/risky_reach_v0.zip
    python experiments/risky_reach_critic_view.py runs/hover/logs/a025_s0/maddpg/risky_hover_v0_1/risky_hover_v0.zip
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
import torch as th

from sb3_maddpg import MADDPG
from sb3_maddpg.common.diagnostics import own_action_gradients
from sb3_maddpg.common.distributional import cvar
from sb3_maddpg_envs import risky_hover_v0, risky_reach_v0
from sb3_maddpg_envs.risky_reach_v0 import ZONE, RiskyReachEnv

EVAL_SEED = 10_000  # the first evaluation episode of experiments/risky_reach_sweep.sh
N_DRAWS = 20_000  # Monte Carlo draws of the losses for the truth's tail
HOLD_FROM = 15  # risky_hover_v0: the steps from which a team holds its depth (it reaches the landmark in about 13)


def true_tail_depth(probabilities_ahead: np.ndarray, costs_ahead: np.ndarray, gamma: float, alpha: float) -> float:
    """
    Mean minus CVaR_alpha of the loss part of a return whose steps end with a loss with ``probabilities_ahead``.

    :param probabilities_ahead: (H,) the loss chance of each step, the step of the read value first
    :param costs_ahead: (H,) what a loss costs at each step
    :param gamma: the discount
    :param alpha: the CVaR level
    :return: the tail depth (>= 0)
    """
    if not (probabilities_ahead * costs_ahead).any():
        return 0.0
    rng = np.random.default_rng(0)
    draws = rng.random((N_DRAWS, len(probabilities_ahead))) < probabilities_ahead
    losses = -(draws * costs_ahead) @ (gamma ** np.arange(len(probabilities_ahead)))
    worst = np.sort(losses)[: max(1, int(round(alpha * N_DRAWS)))]
    return float(losses.mean() - worst.mean())


def choice_steps(env: RiskyReachEnv) -> tuple[np.ndarray, np.ndarray]:
    """
    Where each agent makes the task's risky choice (before risky_reach_v0's zone, near risky_hover_v0's edge), (N,)
    booleans, and the sign of the y move towards safety there, (N,).
    """
    if isinstance(env, risky_hover_v0.RiskyHoverEnv):
        return np.abs(env.positions[:, 1] - env.edge) <= 0.2, -np.ones(len(env.positions))
    x_min, _, y_min, y_max = ZONE
    x, y = env.positions[:, 0], env.positions[:, 1]
    return (x <= x_min) & (y > y_min) & (y < y_max), np.where(y >= 0.0, 1.0, -1.0)  # around: the nearer edge's side


TASKS = {"risky_reach_v0": risky_reach_v0, "risky_hover_v0": risky_hover_v0}


def critic_view(
    model: MADDPG, n_episodes: int, alpha: float, seed: int = EVAL_SEED, env_id: str = "risky_reach_v0"
) -> dict[str, np.ndarray]:
    """
    Critic i's tail depth and the truth at every agent-step; the own-action gradients' pull before the zone.

    :param model: a trained team on ``risky_reach_v0`` or ``risky_hover_v0`` whose policy has ``n_quantiles > 1``
    :param n_episodes: deterministic episodes, reset seeds ``seed``, ``seed + 1``, ...
    :param alpha: the CVaR level read
    :param seed: the first reset seed
    :param env_id: the task, one of :data:`TASKS`
    :return: per agent-step ``phase`` (0 at a choice step, 1 inside the zone, 2 elsewhere), ``depth`` and
        ``true_depth``; per choice step ``around_mean`` and ``around_cvar`` (whether the gradient's y component points
        to safety); on risky_hover_v0, ``hold_depth``: each agent's mean depth from step ``HOLD_FROM`` on
    """
    policy = model.policy
    if policy.n_quantiles < 2:
        raise ValueError(f"{type(model).__name__} has {policy.n_quantiles} quantile: there is no tail to read")
    gamma = float(model.gamma)
    phases, depths, true_depths, around_mean, around_cvar, holds = [], [], [], [], [], []
    task = TASKS[env_id]
    for episode in range(n_episodes):
        env = task.parallel_env()
        observations, _ = env.reset(seed=seed + episode)
        n_agents = len(env.possible_agents)
        episode_depths, episode_phases, probabilities_after, costs_after = [], [], [], []
        while env.agents:
            stacked = np.stack([observations[agent] for agent in env.possible_agents])
            actions, _ = model.predict(stacked, deterministic=True)
            with th.no_grad():
                obs = policy.obs_to_tensor(stacked)[0].view(1, n_agents, *stacked.shape[1:])
                joint = th.as_tensor(policy.scale_action(actions), dtype=th.float32).view(1, n_agents, -1)
                features = policy.critic.encode(obs)
                quantiles = policy.critic.quantiles_from_features(features, joint)[0]  # (N, n_q)
            episode_depths.append((quantiles.mean(dim=-1) - cvar(quantiles, alpha)).numpy())
            before, around = choice_steps(env)
            if before.any():
                objectives = (lambda q: q.mean(dim=-1), lambda q: cvar(q, alpha))
                gradients = [g[0].numpy() for g in own_action_gradients(policy.critic, features, joint, objectives)]
                for i in np.flatnonzero(before):
                    around_mean.append(bool(gradients[0][i, 1] * around[i] > 0))
                    around_cvar.append(bool(gradients[1][i, 1] * around[i] > 0))
            observations, *_ = env.step({a: actions[i] for i, a in enumerate(env.possible_agents)})
            if isinstance(env, risky_hover_v0.RiskyHoverEnv) and env.t >= HOLD_FROM:
                holds.append(env.positions[:, 1] - env.edge)
            probabilities_after.append(env.loss_probabilities())
            costs_after.append(env.loss_costs())
            episode_phases.append(np.where(before, 0, np.where(env.inside_zone(), 1, 2)))
        probabilities_after, costs_after = np.array(probabilities_after), np.array(costs_after)  # (T, N)
        for t, (depth, phase) in enumerate(zip(episode_depths, episode_phases, strict=True)):
            for i in range(n_agents):
                phases.append(int(phase[i]))
                depths.append(float(depth[i]))
                true_depths.append(true_tail_depth(probabilities_after[t:, i], costs_after[t:, i], gamma, alpha))
    return {
        "phase": np.array(phases),
        "depth": np.array(depths),
        "true_depth": np.array(true_depths),
        "around_mean": np.array(around_mean),
        "around_cvar": np.array(around_cvar),
        "hold_depth": np.array(holds).reshape(-1, n_agents).mean(axis=0) if holds else np.zeros(0),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("models", nargs="+", help="saved MADDPG models (.zip) on a small risky task with quantile critics")
    parser.add_argument("--env", choices=sorted(TASKS), default=None, help="the task (default: the id in the path)")
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--alpha", type=float, default=0.25, help="the CVaR level read")
    parser.add_argument("--seed", type=int, default=EVAL_SEED, help="seed of the first episode")
    args = parser.parse_args(argv)
    th.set_num_threads(1)
    a = args.alpha
    print(
        f"| model | choice steps / steps inside the zone | tail depth (mean - CVaR_{a}) at a choice: critic / truth | "
        f"inside: critic / truth | elsewhere: critic / truth | at a choice: the mean's / CVaR_{a}'s gradient "
        "points to safety | hold depth by agent (risky_hover_v0) |"
    )
    print("|---|---|---|---|---|---|---|")
    for path in args.models:
        env_id = args.env or next((env_id for env_id in TASKS if env_id in path), None)
        if env_id is None:
            parser.error(f"no task id in {path}: give --env")
        view = critic_view(MADDPG.load(path, device="cpu"), args.episodes, args.alpha, args.seed, env_id)
        before, inside, elsewhere = (view["phase"] == phase for phase in (0, 1, 2))
        cells = [
            f"{view[key][mask].mean():.3f}" if mask.any() else "-"
            for mask in (before, inside, elsewhere)
            for key in ("depth", "true_depth")
        ]
        pulls = " / ".join(f"{view[key].mean():.2f}" if view[key].size else "-" for key in ("around_mean", "around_cvar"))
        counts = f"{int(before.sum())} / {int(inside.sum())}"
        hold = ", ".join(f"{depth:.3f}" for depth in view["hold_depth"]) or "-"
        row = f"| {path} | {counts} | {cells[0]} / {cells[1]} | {cells[2]} / {cells[3]} | {cells[4]} / {cells[5]} | {pulls} |"
        print(f"{row} {hold} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
