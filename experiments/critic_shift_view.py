"""
Whose is the cell that a trained UAV team's places are off by, the critics' or the actors'? For a saved MADDPG model
on ``uav_coverage_v1`` (``obs_size=16``, 300-step episodes, random starts), the team flies its deterministic policy;
at the chosen steps, for each UAV i, 26 candidate moves are scored: the actor's own move, the same move shifted by
-1, -0.5, 0, 0.5 or 1 cell on each axis (shortened to l_max, kept inside the area), and hovering, with the teammates'
moves the actors'. Each candidate gets

- the critic's score: the mean of critic i's quantiles (its first network) on the joint observation with UAV i's
  action replaced by the candidate (``quantiles_with_own_actions``, as the actor update scores it);
- the truth that matters for the layout: the number of PoIs that the team covers after the step (static coverage of
  the next positions), with UAV i at the candidate's end point.

With ``--rollout H`` each candidate also gets UAV i's own discounted return over the next H steps when it makes
that move and the team then flies its policy (from a snapshot of the episode's state, ``env.snapshot()``: H steps a
candidate), the quantity critic i estimates, truncated at H (γ^H of the tail left
out), and the best-coverage spot once more held: UAV i hovers there after the move while its teammates fly on (a
policy that keeps the better spot rather than a one-step deviation from the learned one).

Per UAV and step it prints the gain in covered PoIs that the best candidate offers over the actor's move, whether the
critic ranks that candidate above the actor's move, and Spearman's rank correlation of the critic's scores with the
covered PoIs. A critic that ranks the better spot higher while the actor does not go there points at the actor
(its gradient ascent on the critic); a critic that prefers the actor's move points at the critic (it cannot see
the better spot). Energy is left out of the truth: a shift of a cell costs one step's extra flight, the PoIs it
gains count at every later step.

    python experiments/critic_shift_view.py runs/p3/exact_tpn005_g09_mates_s0.zip --episodes 3 --steps 150 299
    python experiments/critic_shift_view.py MODEL --episodes 2 --steps 150 --rollout 30
    python experiments/critic_shift_view.py runs/tmc/logs/n8_s0/maddpg/uav_coverage_tmc_v1_1/uav_coverage_tmc_v1.zip \
        --tmc-uavs 8 --episodes 2 --steps 250 --rollout 30

``--tmc-uavs N`` scores a model trained on ``uav_coverage_tmc_v1`` with N UAVs (its geometry, 500-step episodes).
"""

import argparse
import json

import numpy as np
import torch as th
from uav_learning import reject_removed_variants  # the sibling files, not a package
from uav_team_positions import covers

from sb3_maddpg import MADDPG
from sb3_maddpg_envs import uav_coverage_v1
from sb3_maddpg_envs.uav_coverage.dynamics import commanded_move, step_energy
from sb3_maddpg_envs.uav_coverage.rewards import energy_cost
from sb3_maddpg_envs.uav_coverage.scenarios import TMC2020_KWARGS

EVAL_SEED = 10_000  # the first evaluation episode of experiments/uav_learning.py and docs/results.md
SHIFTS = np.array([(dx, dy) for dx in (-1.0, -0.5, 0.0, 0.5, 1.0) for dy in (-1.0, -0.5, 0.0, 0.5, 1.0)])
ACTOR = int(np.argmin(np.abs(SHIFTS).sum(axis=1)))  # the unshifted candidate: the actor's own move
HOVER = len(SHIFTS)  # the last candidate: no move


def covered_pois(positions: np.ndarray, pois: np.ndarray, coverage_range: float) -> int:
    """How many PoIs lie within ``coverage_range`` of some position."""
    return int(covers(positions, pois, coverage_range).any(axis=0).sum())


def spearman(x: np.ndarray, y: np.ndarray) -> float:
    """Spearman's rank correlation (average ranks for ties); NaN when either side is constant."""

    def ranks(v: np.ndarray) -> np.ndarray:
        order = np.argsort(v, kind="stable")
        r = np.empty(len(v))
        r[order] = np.arange(len(v), dtype=float)
        for value in np.unique(v):  # ties share their mean rank
            r[v == value] = r[v == value].mean()
        return r

    rx, ry = ranks(x), ranks(y)
    if rx.std() == 0 or ry.std() == 0:
        return float("nan")
    return float(np.corrcoef(rx, ry)[0, 1])


def as_actions(moves: np.ndarray, max_distance: float) -> np.ndarray:
    """v1's Cartesian actions in [0, 1]^2 that command the displacements ``moves`` (each at most l_max long)."""
    return (moves / max_distance + 1.0) / 2.0


def candidate_moves(
    position: np.ndarray, own_move: np.ndarray, max_distance: float, map_size: float
) -> tuple[np.ndarray, np.ndarray]:
    """
    The 26 candidates: ``own_move`` shifted by SHIFTS, kept inside the area and shortened to l_max as the env shortens
    a command (``commanded_move``), and hovering (the last, index HOVER).

    :return: displacements (26, 2) and their distance ratios rho (26,)
    """
    ends = np.clip(position + own_move + SHIFTS, 0.0, np.nextafter(map_size, 0.0))
    moves, rho = commanded_move(as_actions(ends - position, max_distance), max_distance, "cartesian")
    return np.concatenate([moves, np.zeros((1, 2))]), np.append(rho, 0.0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument("model", help="a saved MADDPG model (.zip) trained on uav_coverage_cpu_v1")
    parser.add_argument("--env-kwargs", type=json.loads, default={}, help="JSON dict of extra env parameters")
    parser.add_argument("--episodes", type=int, default=3)
    parser.add_argument("--seed", type=int, default=EVAL_SEED, help="seed of the first episode")
    parser.add_argument("--steps", type=int, nargs="+", default=[150, 299], help="steps at which moves are scored")
    parser.add_argument("--rollout", type=int, default=0, help="H > 0: each candidate's H-step return (slow)")
    parser.add_argument("--tmc-uavs", type=int, default=0, help="N > 0: uav_coverage_tmc_v1 with N UAVs instead")
    args = parser.parse_args()
    reject_removed_variants(args.env_kwargs)
    if args.tmc_uavs > 0:
        env_kwargs = {**TMC2020_KWARGS, "n_uavs": args.tmc_uavs, **args.env_kwargs}
    else:
        env_kwargs = {"obs_size": 16, "max_cycles": 300, **args.env_kwargs}
    th.set_num_threads(1)
    model = MADDPG.load(args.model, device="cpu")
    policy = model.policy
    policy.set_training_mode(False)
    rows = []
    for episode in range(args.episodes):
        env = uav_coverage_v1.parallel_env(**env_kwargs)
        observations, _ = env.reset(seed=args.seed + episode)
        core = env.core
        if core.action_mode != "cartesian":
            raise ValueError("the candidates are Cartesian moves: use v1's action_mode='cartesian'")
        scratch = uav_coverage_v1.parallel_env(**env_kwargs)  # where the candidates' rollouts run
        step = 0
        while env.agents:
            stacked = np.stack([observations[agent] for agent in env.possible_agents])
            actions, _ = model.predict(stacked, deterministic=True)  # env actions in [0, 1]
            if step in args.steps:
                scored = score_moves(model, core, stacked, actions, episode, step)
                if args.rollout > 0:
                    replay = (scratch, env.snapshot())
                    for row in scored:
                        row.update(rollout_truth(model, replay, actions, row, args.rollout))
                rows.extend(scored)
            observations, *_ = env.step({agent: actions[i] for i, agent in enumerate(env.possible_agents)})
            step += 1
    summarise(rows, args.rollout)


def share(rows: list[dict], key: str) -> float:
    """The fraction of ``rows`` whose ``key`` is true (NaN for none)."""
    return float(np.mean([r[key] for r in rows])) if rows else float("nan")


def spread(values: list[float]) -> str:
    """Median and quartiles, finite values only."""
    v = np.array([x for x in values if np.isfinite(x)])
    return f"median {np.median(v):+.3f} (quartiles {np.quantile(v, 0.25):+.3f}, {np.quantile(v, 0.75):+.3f})"


def summarise(rows: list[dict], rollout: int) -> None:
    """Print what the module's docstring lists."""
    better = [r for r in rows if r["gain"] > 0]
    clear = [r for r in rows if r["gain"] >= 2]
    print(
        f"{len(rows)} UAV-steps: a spot within a cell covers more PoIs in {len(better)} (mean gain "
        f"{np.mean([r['gain'] for r in rows]):.2f} PoIs, largest {int(max(r['gain'] for r in rows))}); where there "
        f"is one, the critic scores it above the actor's move in {share(better, 'critic_prefers_best'):.2f}; the "
        f"actor's move is the critic's best of the 26 in {share(rows, 'own_is_critic_argmax'):.2f}; Spearman's rho "
        f"of the critic's scores with the covered PoIs: {spread([r['rho'] for r in rows])}; the critic's score range "
        f"over the 26 moves: {spread([r['q_range'] for r in rows])}"
    )
    if clear:
        print(
            f"{len(clear)} UAV-steps with a spot 2 or more PoIs better: the critic scores it above the actor's move in "
            f"{share(clear, 'critic_prefers_best'):.2f}; critic's score, that spot minus the actor's move: "
            f"{spread([r['q_gap'] for r in clear])}; the gain held for 1 / (1 - gamma) steps at the mean PoI worth: "
            f"{spread([r['value_of_gain'] for r in clear])}; the spot's extra energy this step: "
            f"{spread([r['extra_energy'] for r in clear])}"
        )
    moving = [r for r in rows if r["actor_distance"] > 0.25]
    print(
        f"the actor's move: {spread([r['actor_distance'] for r in rows])} of l_max; {len(moving)} UAV-steps move more "
        f"than a quarter of l_max, and in {share(moving, 'critic_prefers_hover'):.2f} of them the critic scores "
        f"hovering above the actor's move"
    )
    if rollout > 0:
        improvable = [r for r in rows if r["return_gain"] > 0]
        print(
            f"against UAV i's {rollout}-step return after each move (the team on its policy after it): Spearman's "
            f"rho of the critic's scores {spread([r['rho_return'] for r in rows])}; the best move's return minus "
            f"the actor's: {spread([r['return_gain'] for r in rows])}; the critic scores that move above the actor's "
            f"in {share(improvable, 'critic_prefers_best_return'):.2f} of the {len(improvable)} UAV-steps where it "
            f"is better; the best-coverage move's return minus the actor's: "
            f"{spread([r['return_of_best_coverage'] for r in rows])}; the best-coverage spot held (UAV i hovers "
            f"there after the move) minus the actor's move and policy: "
            f"{spread([r['return_of_best_coverage_held'] for r in rows])}"
        )
        if moving:
            print(
                f"where the actor moves more than a quarter of l_max: hovering this step (then the policy) minus the "
                f"actor's move: {spread([r['return_of_hover'] for r in moving])}; hovering on for the whole horizon: "
                f"{spread([r['return_of_hovering_on'] for r in moving])}"
            )


def rollout_truth(model: MADDPG, replay: tuple, actions: np.ndarray, row: dict, horizon: int) -> dict:
    """UAV ``row["uav"]``'s discounted return over ``horizon`` steps for each of its candidate moves (docstring)."""
    i, returns = row["uav"], []
    for move in row["moves"]:
        returns.append(candidate_return(model, replay, actions, i, move, horizon, hold=False))
    returns = np.array(returns)
    actor, best = row["actor_index"], int(np.argmax(returns))
    # The best-coverage spot held: UAV i hovers there for the rest of the horizon, its teammates on their policy
    held = candidate_return(model, replay, actions, i, row["moves"][row["best_index"]], horizon, hold=True)
    hovering = candidate_return(model, replay, actions, i, np.zeros(2), horizon, hold=True)
    return dict(
        rho_return=spearman(row["scores"], returns),
        return_gain=float(returns[best] - returns[actor]),
        critic_prefers_best_return=bool(row["scores"][best] > row["scores"][actor]),
        return_of_best_coverage=float(returns[row["best_index"]] - returns[actor]),
        return_of_best_coverage_held=float(held - returns[actor]),
        return_of_hover=float(returns[HOVER] - returns[actor]),
        return_of_hovering_on=float(hovering - returns[actor]),
    )


def candidate_return(
    model: MADDPG, replay: tuple, actions: np.ndarray, i: int, move: np.ndarray, horizon: int, hold: bool
) -> float:
    """
    UAV i's discounted return over ``horizon`` steps when it makes ``move`` now and then follows its policy, or
    hovers with ``hold``; its teammates follow their policy.
    """
    env, snapshot = replay
    env.restore(snapshot)
    joint = actions.copy()
    joint[i] = np.clip(as_actions(move, env.core.max_distance), 0.0, 1.0)
    total, discount = 0.0, 1.0
    for _ in range(horizon):
        if not env.agents:
            break
        observations, rewards, *_ = env.step({agent: joint[j] for j, agent in enumerate(env.possible_agents)})
        total += discount * rewards[env.possible_agents[i]]
        discount *= model.gamma
        if env.agents:
            stacked = np.stack([observations[agent] for agent in env.possible_agents])
            joint, _ = model.predict(stacked, deterministic=True)
            if hold:
                joint[i] = 0.5  # v1's Cartesian action for no move
    return total


def score_moves(model: MADDPG, core, stacked: np.ndarray, actions: np.ndarray, episode: int, step: int) -> list[dict]:
    """The candidates of every active UAV at this step (see the module's docstring)."""
    policy = model.policy
    max_distance, n_agents = core.max_distance, len(actions)
    # A PoI that UAV i alone covers is worth (N / K) (1 - phi c(k)) a step in its reward (v1's coverage reward)
    poi_worth = n_agents / len(core.pois) * (1.0 - core.fairness_coef * float(core.coverage_scores.mean()))
    own_moves = commanded_move(actions, max_distance, core.action_mode)[0]
    positions = core.positions.copy()
    next_positions = np.clip(positions + own_moves, 0.0, np.nextafter(core.map_size, 0.0))
    with th.no_grad():
        obs = policy.obs_to_tensor(stacked)[0].view(1, n_agents, *stacked.shape[1:])
        features = policy.critic.encode(obs)
        joint = th.as_tensor(policy.scale_action(actions), dtype=th.float32).view(1, n_agents, -1)
    rows = []
    for i in range(n_agents):
        if not core.active[i]:
            continue
        moves, rho = candidate_moves(positions[i], own_moves[i], max_distance, core.map_size)
        candidate_actions = policy.scale_action(np.clip(as_actions(moves, max_distance), 0.0, 1.0))
        with th.no_grad():
            own = joint.repeat(len(moves), 1, 1)
            own[:, i] = th.as_tensor(candidate_actions, dtype=th.float32)
            scores = (
                policy.critic.quantiles_with_own_actions(
                    features.expand(len(moves), -1, -1), joint.expand(len(moves), -1, -1), own
                )[:, i]
                .mean(dim=-1)
                .numpy()
            )
        covered = np.empty(len(moves))
        for c, move in enumerate(moves):
            layout = next_positions.copy()
            layout[i] = positions[i] + move
            covered[c] = covered_pois(layout, core.pois, core.coverage_range)
        actor, best = ACTOR, int(np.argmax(covered))
        # each candidate's energy this step (never short of battery here) and its weight in UAV i's reward
        energy = step_energy(
            rho,
            np.ones(len(rho), dtype=bool),
            np.full(len(rho), np.inf),
            max_distance=max_distance,
            move_energy=core.move_energy,
            hover_energy=core.hover_energy,
        )
        energy_term = energy_cost(energy, core.energy_coef, core.move_energy, max_distance)
        rows.append(
            dict(
                episode=episode,
                step=step,
                uav=i,
                gain=covered[best] - covered[actor],
                critic_prefers_best=bool(scores[best] > scores[actor]),
                own_is_critic_argmax=bool(np.argmax(scores) == actor),
                actor_distance=float(rho[actor]),
                critic_prefers_hover=bool(scores[HOVER] > scores[actor]),
                rho=spearman(scores, covered),
                q_range=float(scores.max() - scores.min()),
                q_gap=float(scores[best] - scores[actor]),
                value_of_gain=float((covered[best] - covered[actor]) * poi_worth / (1.0 - model.gamma)),
                extra_energy=float(energy_term[best] - energy_term[actor]),
                moves=moves,
                scores=scores,
                actor_index=actor,
                best_index=best,
            )
        )
    return rows


if __name__ == "__main__":
    main()
