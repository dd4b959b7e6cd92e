"""
Why is the quantile critic's lower tail too shallow on ``risky_reach_v0``? Policy evaluation with a fixed policy: critic
learning alone, without actor learning.

Both agents follow ``hand_made_policy(obs, "through")``. The actors are fitted to it by behaviour cloning (and copied to
the actor targets) and never updated again, so the target policy is fixed; the replay buffer is filled with transitions
of the hand-made policy plus Gaussian exploration noise (std 0.1, clipped to [-1, 1]); then only the critics learn, with
the library's ``critic_loss``, the critic optimizer and SB3's polyak target update at ``tau``. At checkpoints, critic
i's tail depth (mean minus CVaR_alpha of its quantiles for the team's actual joint action) is read along deterministic
episodes before, inside and after the zone, beside

- the truth: the path is deterministic and the losses Bernoulli, so the loss part of the return has an exact
  distribution (a Monte Carlo over the draws, ``risky_reach_critic_view.true_tail_depth``);
- the fixed point of the loss itself: the same distributional Bellman backup run exactly along the path, each state's
  quantiles the minimiser of the expected loss (quantile Huber, kappa 1, or its mean-anchored form) against the exact
  mixture of next-state atoms. What a tabular critic with infinitely many updates reaches: where the network matches
  it and both miss the truth, the loss is the cause; where the network misses it, the learning is.

The one-step check: at the agent-steps inside the zone of the first episode, the critic's lowest quantiles beside those
of the one-step target distribution (the step's reward, with and without the loss, plus gamma times the target critic's
quantiles at the next state and the target actors' action) and that target's loss minimiser.

Variants (``VARIANTS``): the YAML entry's mean-anchored critic and the plain QR loss, 25 or 100 quantiles, the zone's
loss 1 or 5, and the Huber threshold kappa 0.1 or 0.01 instead of 1 (the library's ``quantile_kappa``). The other
settings are the zoo_configs/maddpg.yml entry's: lr 1e-3, batch 256, tau 0.01, gamma 0.95, net_arch [64, 64]. One
update takes about 7 ms on one (shared) CPU core with 25 quantiles, 17 ms with 100.

    python experiments/quantile_tail_evaluation.py --variants anchored plain plain_kappa0.01 --checkpoints 5000 15000 30000
    python experiments/quantile_tail_evaluation.py --tabular-only --variants anchored plain_q100 plain_kappa0.1  # seconds
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Sequence

import numpy as np
import torch as th
from risky_reach_critic_view import EVAL_SEED, choice_steps, true_tail_depth
from stable_baselines3.common.utils import polyak_update

from sb3_maddpg import MADDPG, make_multiagent_vec_env
from sb3_maddpg.common.distributional import cvar, quantile_midpoints
from sb3_maddpg_envs.risky_reach_v0 import DISTANCE_COST, hand_made_policy, in_zone, parallel_env

# name: (mean_anchored_quantiles, n_quantiles, env kwargs, kappa). kappa None: the library's critic_loss (Huber kappa 1);
# a number: ``quantile_kappa`` with that Huber threshold, for the mean-anchored form
# with the squared mean (the mean of the targets; a Huber mean with a small kappa would be a median)
VARIANTS: dict[str, tuple[bool, int, dict, float | None]] = {
    "anchored": (True, 25, {}, None),
    "plain": (False, 25, {}, None),
    "anchored_q100": (True, 100, {}, None),
    "plain_q100": (False, 100, {}, None),
    "anchored_loss5": (True, 25, {"zone_loss": 5.0}, None),
    "plain_loss5": (False, 25, {"zone_loss": 5.0}, None),
    "plain_kappa0.1": (False, 25, {}, 0.1),
    "plain_kappa0.01": (False, 25, {}, 0.01),
    "anchored_sq_kappa0.01": (True, 25, {}, 0.01),
}
# The zoo_configs/maddpg.yml entry risky_reach_v0
YAML = dict(learning_rate=1e-3, batch_size=256, tau=0.01, gamma=0.95, net_arch=[64, 64])
NOISE_STD = 0.1
PHASES = ("before", "inside", "after")


def hand_made_actions(observations: np.ndarray) -> np.ndarray:
    """The "through" policy for every row of (..., obs_dim) observations, (..., 2)."""
    flat = observations.reshape(-1, observations.shape[-1])
    return np.stack([hand_made_policy(o, "through") for o in flat]).reshape(*observations.shape[:-1], 2)


def make_model(variant: str, seed: int, buffer_size: int) -> MADDPG:
    """A MADDPG team on risky_reach_v0 with the YAML entry's settings and the variant's critic."""
    anchored, n_quantiles, env_kwargs, _ = VARIANTS[variant]
    venv = make_multiagent_vec_env(parallel_env, n_envs=1, seed=seed, env_kwargs=env_kwargs)
    return MADDPG(
        "MlpPolicy",
        venv,
        learning_rate=YAML["learning_rate"],
        buffer_size=buffer_size,
        batch_size=YAML["batch_size"],
        tau=YAML["tau"],
        gamma=YAML["gamma"],
        mean_anchored_quantiles=anchored,
        policy_kwargs=dict(n_quantiles=n_quantiles, net_arch=YAML["net_arch"]),
        seed=seed,
        device="cpu",
    )


def collect(model: MADDPG, n_steps: int, env_kwargs: dict, seed: int) -> np.ndarray:
    """
    Fill the replay buffer with ``n_steps`` joint steps of the noisy hand-made policy (the rows as SB3's loop adds them).

    :return: the joint observations seen, (n_steps, N, obs_dim)
    """
    rng = np.random.default_rng(seed)
    env = parallel_env(**env_kwargs)
    agents = env.possible_agents
    seen, episode = [], 0
    while len(seen) < n_steps:
        observations, _ = env.reset(seed=seed * 1_000_000 + episode)
        episode += 1
        while env.agents and len(seen) < n_steps:
            obs = np.stack([observations[a] for a in agents])
            actions = np.clip(hand_made_actions(obs) + rng.normal(0.0, NOISE_STD, (len(agents), 2)), -1.0, 1.0)
            observations, rewards, _, truncations, _ = env.step({a: actions[i] for i, a in enumerate(agents)})
            next_obs = np.stack([observations[a] for a in agents])
            truncated = any(truncations.values())
            model.replay_buffer.add(
                obs,
                next_obs,
                actions.astype(np.float32),
                np.array([rewards[a] for a in agents], np.float32),
                np.full(len(agents), truncated),
                [{"TimeLimit.truncated": truncated} for _ in agents],
            )
            seen.append(obs)
    return np.stack(seen).astype(np.float32)


def hand_made_episodes(n_episodes: int, env_kwargs: dict, seed: int = EVAL_SEED) -> tuple[np.ndarray, list[int]]:
    """
    The noise-free hand-made paths (reset seeds ``seed``, ...): their joint observations (T, N, obs_dim) and the
    team's zone steps per episode.
    """
    seen, counts = [], []
    for episode in range(n_episodes):
        env = parallel_env(**env_kwargs)
        observations, _ = env.reset(seed=seed + episode)
        while env.agents:
            obs = np.stack([observations[a] for a in env.possible_agents])
            seen.append(obs)
            actions = hand_made_actions(obs)
            observations, _, _, _, infos = env.step({a: actions[i] for i, a in enumerate(env.possible_agents)})
        counts.append(sum(info["zone_steps"] for info in infos.values()))
    return np.stack(seen).astype(np.float32), counts


def clone_policy(model: MADDPG, observations: np.ndarray, max_steps: int = 4_000, target_mse: float = 2e-5) -> float:
    """
    Fit the actors to the hand-made policy on joint observations (M, N, obs_dim) by behaviour cloning, then copy them
    to the actor targets; the actors are not updated again.

    :return: the final mean squared error of the actions
    """
    obs = th.as_tensor(observations)
    targets = th.as_tensor(hand_made_actions(observations), dtype=th.float32)
    optimizer = th.optim.Adam(model.actor.parameters(), lr=1e-3)
    generator = th.Generator().manual_seed(0)
    mse = float("inf")
    for step in range(max_steps):
        batch = th.randint(0, len(obs), (512,), generator=generator)
        loss = (model.actor(obs[batch]) - targets[batch]).square().mean()
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        if step % 500 == 499:
            with th.no_grad():
                mse = float((model.actor(obs) - targets).square().mean())
            if mse < target_mse:
                break
    model.actor_target.load_state_dict(model.actor.state_dict())
    return mse


def train_critic(model: MADDPG, n_updates: int, kappa: float | None = None) -> None:
    """
    Critic updates only: the library's critic loss (with ``kappa``: ``quantile_kappa`` kappa, and for the
    mean-anchored form the squared mean, ``mean_loss="squared"``), the critic optimizer, SB3's polyak update of the
    critic targets.
    """
    if kappa is not None:
        model.quantile_kappa = kappa
        if model.mean_anchored_quantiles:
            model.mean_loss = "squared"  # a Huber mean with a small kappa would be a median
    model.policy.set_training_mode(True)
    critic, optimizer = model.critic, model.critic.optimizer
    online, target = list(critic.parameters()), list(model.critic_target.parameters())
    for _ in range(n_updates):
        replay_data = model.replay_buffer.sample(model.batch_size)
        loss, _, _ = model.critic_loss(replay_data)
        optimizer.zero_grad(set_to_none=True)
        loss.sum().backward()
        optimizer.step()
        polyak_update(online, target, model.tau)
    model.policy.set_training_mode(False)


# --- The fixed point of the loss along the path (tabular) --------------------------------------------------------------


def _loss_gradient(z: np.ndarray, taus: np.ndarray, atoms: np.ndarray, weights: np.ndarray, kappa: float) -> np.ndarray:
    """
    d/dz_j of sum_k w_k |tau_j - 1{t_k < z_j}| huber_kappa(t_k - z_j) / kappa for z (..., n), (..., n); nondecreasing in
    each z_j.
    """
    delta = atoms - z[..., None]
    asymmetry = np.where(delta < 0, 1.0 - taus[:, None], taus[:, None])
    return -(weights * asymmetry * np.clip(delta, -kappa, kappa)).sum(axis=-1) / kappa


def _solve(taus: np.ndarray, atoms: np.ndarray, weights: np.ndarray, kappa: float, levels: np.ndarray) -> np.ndarray:
    """Each z_j whose gradient is each of ``levels`` (L,), (L, n), by bisection (level 0: the loss's minimiser)."""
    # wide enough for a quantile that the mean-anchored loss pushes beyond every atom (``loss_fixed_point``)
    spread = len(taus) * (atoms.max() - atoms.min()) + 2.0 * kappa + 1.0
    low = np.full((len(levels), len(taus)), atoms.min() - spread)
    high = np.full((len(levels), len(taus)), atoms.max() + spread)
    for _ in range(56):
        middle = 0.5 * (low + high)
        above = _loss_gradient(middle, taus, atoms, weights, kappa) > levels[:, None]
        high, low = np.where(above, middle, high), np.where(above, low, middle)
    return 0.5 * (low + high)


def loss_fixed_point(
    outcomes: np.ndarray, probabilities: np.ndarray, anchored: bool, kappa: float = 1.0, squared_mean: bool = False
) -> np.ndarray:
    """
    The n quantiles that minimise the expected loss against a target distribution that is, with each probability, one
    row of n target quantiles (one outcome of the reward, plus gamma times the next state's quantiles): the quantile
    Huber loss (plain), or the mean-anchored loss: the mean the Huber M-estimate of the rows' means (with
    ``squared_mean`` their mean), the quantiles the minimiser of the quantile Huber loss with that mean (its gradient
    reaches the quantiles less its mean, so at the minimiser every quantile has the same gradient,
    ``mean_anchored_quantile_loss``). NaN where the mean-anchored loss has no single stationary point.

    :param outcomes: (K, n) target quantiles of each outcome
    :param probabilities: (K,)
    :return: (n,)
    """
    n_quantiles = outcomes.shape[1]
    taus = quantile_midpoints(n_quantiles).double().numpy()
    atoms, weights = outcomes.ravel(), np.repeat(probabilities / n_quantiles, n_quantiles)
    if not anchored:
        return _solve(taus, atoms, weights, kappa, np.zeros(1))[0]
    row_means = outcomes.mean(axis=1)
    if squared_mean:
        mean = float(probabilities @ row_means / probabilities.sum())
    else:
        # sum_k p_k clip(mean_k - m, -kappa, kappa) = 0
        low, high = row_means.min(), row_means.max()
        for _ in range(60):
            middle = 0.5 * (low + high)
            low, high = (
                (middle, high) if (probabilities * np.clip(row_means - middle, -kappa, kappa)).sum() > 0 else (low, middle)
            )
        mean = 0.5 * (low + high)
    # The common gradient lies in (-tau_1, 1 - tau_n), and the quantiles' mean grows with it: bisection
    low_level, high_level = -taus[0], 1.0 - taus[-1]
    for _ in range(40):
        level = 0.5 * (low_level + high_level)
        if _solve(taus, atoms, weights, kappa, np.array([level]))[0].mean() > mean:
            high_level = level
        else:
            low_level = level
    # Where a quantile's loss is linear (no atom within kappa of it), its z_j jumps at the common gradient: the one
    # quantile on such a flat stretch takes what the mean needs (it can be the top one, pushed beyond every target
    # atom: the quantile Huber loss's mean differs from the targets' mean, and the anchor makes up the difference).
    # With several on flat stretches the stationary points are a continuum, and there is no one fixed point: NaN
    z_low, z_high = _solve(taus, atoms, weights, kappa, np.array([low_level, high_level]))
    jumps = np.flatnonzero(z_high - z_low > 1e-6)
    if len(jumps) > 1:
        return np.full(n_quantiles, np.nan)
    z = z_low.copy()
    if len(jumps) == 1:
        z[jumps[0]] = n_quantiles * mean - np.delete(z_low, jumps[0]).sum()
    z = z - z.mean() + mean
    gradients = _loss_gradient(z, taus, atoms, weights, kappa)
    flat = np.abs(atoms[None, :] - z[:, None]).min(axis=1) > kappa - 1e-9  # with a flat stretch of loss at z_j
    return z if np.ptp(gradients) < 1e-6 and flat.sum() <= 1 else np.full(n_quantiles, np.nan)


class FixedPoint:
    """
    The tail depths of a tabular critic at the loss's fixed point along a path: the backup
    Z_t = argmin E loss(z, r_t + gamma Z_{t+1}) from Z = 0 after the last step, with r_t = -loss w.p. ``p`` where the
    step ends inside, else 0 (the deterministic rewards shift every quantile alike and leave the depth unchanged).
    Each path suffix's quantiles are computed once.

    :param kappa: as in ``VARIANTS`` (None: the library's loss, kappa 1 and a Huber mean)
    """

    def __init__(
        self, gamma: float, n_quantiles: int, anchored: bool, p: float, loss: float, kappa: float | None = None
    ) -> None:
        self.gamma, self.n_quantiles, self.anchored, self.p, self.loss = gamma, n_quantiles, anchored, p, loss
        self.kappa = 1.0 if kappa is None else kappa
        self.squared_mean = kappa is not None
        self.cache: dict[bytes, np.ndarray] = {}

    def quantiles(self, inside_ahead: np.ndarray) -> np.ndarray:
        """Z at the first step of ``inside_ahead`` (H,) booleans, (n,)."""
        n, z = self.n_quantiles, np.zeros(self.n_quantiles)
        inside_ahead = np.asarray(inside_ahead, dtype=bool)
        for t in range(len(inside_ahead) - 1, -1, -1):
            key = inside_ahead[t:].tobytes()
            if not inside_ahead[t:].any():
                z = np.zeros(n)
            elif key in self.cache:
                z = self.cache[key]
            else:
                if inside_ahead[t]:
                    outcomes, probabilities = (
                        np.stack([self.gamma * z, self.gamma * z - self.loss]),
                        np.array([1 - self.p, self.p]),
                    )
                else:
                    outcomes, probabilities = self.gamma * z[None], np.ones(1)
                z = loss_fixed_point(outcomes, probabilities, self.anchored, self.kappa, self.squared_mean)
                self.cache[key] = z
        return z

    def depths(self, inside_ahead: np.ndarray, alphas: Sequence[float]) -> list[float]:
        """Mean minus CVaR_alpha of ``quantiles(inside_ahead)`` for each alpha."""
        quantiles = th.as_tensor(self.quantiles(inside_ahead))
        return [float(quantiles.mean() - cvar(quantiles, alpha)) for alpha in alphas]


# --- Reading the critic along deterministic episodes ---------------------------------------------------------------


class Truths:
    """The truth's and the tabular fixed point's tail depths, cached by the path ahead (the same for every checkpoint)."""

    def __init__(self, gamma: float, alphas: Sequence[float], variant: str, p: float, loss: float) -> None:
        self.gamma, self.alphas, self.p, self.loss = gamma, alphas, p, loss
        self.anchored, n_quantiles, _, self.kappa = VARIANTS[variant]
        self.fixed_point = FixedPoint(gamma, n_quantiles, self.anchored, p, loss, self.kappa)
        self.cache: dict[bytes, tuple[list[float], list[float]]] = {}

    def __call__(self, inside_ahead: np.ndarray) -> tuple[list[float], list[float]]:
        key = np.asarray(inside_ahead, dtype=bool).tobytes()
        if key not in self.cache:
            inside = np.asarray(inside_ahead, dtype=bool)
            chances, costs = self.p * inside, np.full(len(inside), self.loss)
            truth = [true_tail_depth(chances, costs, self.gamma, a) for a in self.alphas]
            fixed = self.fixed_point.depths(inside_ahead, self.alphas)
            self.cache[key] = (truth, fixed)
        return self.cache[key]


def read_critic(model: MADDPG, env_kwargs: dict, n_episodes: int, truths: Truths) -> dict:
    """
    Critic i's tail depth at every agent-step of deterministic episodes (reset seeds EVAL_SEED, ...), with the phase
    (0 before the zone, 1 the step ends inside, 2 elsewhere: as ``risky_reach_critic_view.critic_view``), the truth's and
    the tabular fixed point's depths, the team's zone steps per episode, and the one-step check of the first episode.
    """
    policy = model.policy
    phases, depths, true_depths, fixed_depths, zone_steps, one_step = [], [], [], [], [], []
    for episode in range(n_episodes):
        env = parallel_env(**env_kwargs)
        observations, _ = env.reset(seed=EVAL_SEED + episode)
        n_agents = len(env.possible_agents)
        episode_depths, episode_phases, inside_after, quantile_rows, steps = [], [], [], [], []
        while env.agents:
            stacked = np.stack([observations[a] for a in env.possible_agents])
            actions, _ = model.predict(stacked, deterministic=True)
            with th.no_grad():
                obs = th.as_tensor(stacked).view(1, n_agents, -1)
                joint = th.as_tensor(policy.scale_action(actions), dtype=th.float32).view(1, n_agents, -1)
                quantiles = policy.critic.quantiles_from_features(policy.critic.encode(obs), joint)[0]  # (N, n_q)
            episode_depths.append([(quantiles.mean(dim=-1) - cvar(quantiles, a)).numpy() for a in truths.alphas])
            before, _ = choice_steps(env)
            observations, *_ = env.step({a: actions[i] for i, a in enumerate(env.possible_agents)})
            inside = in_zone(env.positions)
            inside_after.append(inside)
            episode_phases.append(np.where(before, 0, np.where(inside, 1, 2)))
            if episode == 0:
                quantile_rows.append(quantiles.numpy())
                distances = np.linalg.norm(env.landmarks - env.positions, axis=1)
                steps.append((np.stack([observations[a] for a in env.possible_agents]), -DISTANCE_COST * distances, inside))
        zone_steps.append(int(np.sum(inside_after)))
        inside_after = np.array(inside_after)
        for t, (depth, phase) in enumerate(zip(episode_depths, episode_phases, strict=True)):
            for i in range(n_agents):
                truth, fixed = truths(inside_after[t:, i])
                phases.append(int(phase[i]))
                depths.append([float(d[i]) for d in depth])
                true_depths.append(truth)
                fixed_depths.append(fixed)
        if episode == 0:
            one_step = one_step_check(model, quantile_rows, steps, truths)
    return {
        "phase": np.array(phases),
        "depth": np.array(depths),
        "true_depth": np.array(true_depths),
        "fixed_depth": np.array(fixed_depths),
        "zone_steps": zone_steps,
        "one_step": one_step,
    }


def one_step_check(model: MADDPG, quantile_rows: list, steps: list, truths: Truths, n_lowest: int = 4) -> list[dict]:
    """
    At agent 0's steps that end inside the zone: its critic's lowest quantiles, those of the one-step target
    distribution (reward with and without the loss + gamma times the target critic at the next state, target actors'
    action), and that target's loss minimiser (``loss_fixed_point``); the tail depth at the first alpha of each.
    """
    policy, gamma, rows = model.policy, float(model.gamma), []
    for t, (next_stacked, reward, inside) in enumerate(steps):
        if not inside[0]:
            continue
        with th.no_grad():
            next_obs = th.as_tensor(next_stacked).view(1, len(reward), -1)
            next_features = policy.critic_target.encode(next_obs)
            next_actions = policy.actor_target(next_obs)
            next_quantiles = policy.critic_target.quantiles_from_features(next_features, next_actions)[0, 0].double().numpy()
        n = len(next_quantiles)
        base = reward[0] + gamma * next_quantiles
        outcomes, probabilities = np.stack([base, base - truths.loss]), np.array([1 - truths.p, truths.p])
        atoms, weights = outcomes.ravel(), np.repeat(probabilities / n, n)
        order = np.argsort(atoms)
        cdf = np.cumsum(weights[order])
        taus = quantile_midpoints(n).double().numpy()
        exact = atoms[order][np.minimum(np.searchsorted(cdf, taus - 1e-12), len(atoms) - 1)]
        point = truths.fixed_point
        fixed = np.sort(loss_fixed_point(outcomes, probabilities, point.anchored, point.kappa, point.squared_mean))
        critic = np.sort(quantile_rows[t][0].astype(np.float64))
        alpha = truths.alphas[0]
        depths = [float(q.mean() - cvar(th.as_tensor(q), alpha)) for q in (critic, exact, fixed)]
        rows.append(
            {
                "t": t,
                "critic": critic[:n_lowest].round(3).tolist(),
                "target": exact[:n_lowest].round(3).tolist(),
                "target_loss_fit": fixed[:n_lowest].round(3).tolist(),
                "critic_median": round(float(np.median(critic)), 3),
                "target_median": round(float(exact[n // 2]), 3),
                "depth": [round(d, 3) for d in depths],
            }
        )
    return rows


def summary(view: dict, alphas: Sequence[float]) -> dict:
    """Mean depths per phase: {phase: {alpha: (critic, fixed point, truth)}}."""
    result = {}
    for phase_id, phase in enumerate(PHASES):
        mask = view["phase"] == phase_id
        result[phase] = {
            a: tuple(
                float(view[key][mask, k].mean()) if mask.any() else float("nan")
                for key in ("depth", "fixed_depth", "true_depth")
            )
            for k, a in enumerate(alphas)
        }
    return result


def run(variant: str, seed: int, buffer_steps: int, checkpoints: Sequence[int], alphas: Sequence[float], n_episodes: int, log):
    """One variant and seed: build, clone, fill the buffer, then critic updates with a reading at each checkpoint."""
    env_kwargs, kappa = VARIANTS[variant][2:]
    start = time.perf_counter()
    model = make_model(variant, seed, buffer_steps)
    seen = collect(model, buffer_steps, env_kwargs, seed)
    # the noisy data's observations and those of the noise-free paths (the readings' first 20 episodes among them)
    mse = clone_policy(model, np.concatenate([seen, hand_made_episodes(20, env_kwargs)[0]]))
    probe = parallel_env(**env_kwargs)
    truths = Truths(float(model.gamma), alphas, variant, probe.zone_prob, probe.zone_loss)
    hand = hand_made_episodes(n_episodes, env_kwargs)[1]
    view = read_critic(model, env_kwargs, n_episodes, truths)
    print(
        f"# {variant} seed {seed}: behaviour cloning MSE {mse:.1e}; team zone steps per episode, cloned actor "
        f"{view['zone_steps']}, hand-made {hand}; setup {time.perf_counter() - start:.0f} s",
        flush=True,
    )
    done, train_time = 0, 0.0
    for checkpoint in checkpoints:
        tic = time.perf_counter()
        train_critic(model, checkpoint - done, kappa)
        train_time += time.perf_counter() - tic
        done = checkpoint
        view = read_critic(model, env_kwargs, n_episodes, truths)
        record = {
            "variant": variant,
            "seed": seed,
            "updates": checkpoint,
            "train_s": round(train_time, 1),
            "depths": {phase: {str(a): v for a, v in by_alpha.items()} for phase, by_alpha in summary(view, alphas).items()},
            "one_step": view["one_step"],
        }
        print_row(record, alphas)
        if log is not None:
            log.write(json.dumps(record) + "\n")
            log.flush()


def tabular_only(variant: str, alphas: Sequence[float], n_episodes: int) -> dict:
    """
    The truth's and the loss's tabular fixed point's tail depths along the noise-free hand-made paths, without a critic
    (no training): the phases as in ``read_critic``, the critic's depths NaN.
    """
    env_kwargs = VARIANTS[variant][2]
    probe = parallel_env(**env_kwargs)
    truths = Truths(YAML["gamma"], alphas, variant, probe.zone_prob, probe.zone_loss)
    phases, true_depths, fixed_depths = [], [], []
    for episode in range(n_episodes):
        env = parallel_env(**env_kwargs)
        observations, _ = env.reset(seed=EVAL_SEED + episode)
        episode_phases, inside_after = [], []
        while env.agents:
            obs = np.stack([observations[a] for a in env.possible_agents])
            before, _ = choice_steps(env)
            actions = hand_made_actions(obs)
            observations, *_ = env.step({a: actions[i] for i, a in enumerate(env.possible_agents)})
            inside = in_zone(env.positions)
            inside_after.append(inside)
            episode_phases.append(np.where(before, 0, np.where(inside, 1, 2)))
        inside_after = np.array(inside_after)
        for t, phase in enumerate(episode_phases):
            for i in range(len(phase)):
                truth, fixed = truths(inside_after[t:, i])
                phases.append(int(phase[i]))
                true_depths.append(truth)
                fixed_depths.append(fixed)
    view = {"phase": np.array(phases), "true_depth": np.array(true_depths), "fixed_depth": np.array(fixed_depths)}
    view["depth"] = np.full_like(view["true_depth"], np.nan)
    return view


def print_row(record: dict, alphas: Sequence[float]) -> None:
    cells = []
    for a in alphas:
        for phase in PHASES:
            critic, fixed, truth = record["depths"][phase][str(a)]
            cells.append(" / ".join("-" if np.isnan(value) else f"{value:.3f}" for value in (critic, fixed, truth)))
    print(
        f"| {record['variant']} | {record['seed']} | {record['updates']} | "
        + " | ".join(cells)
        + (" | - |" if np.isnan(record["train_s"]) else f" | {record['train_s']:.0f} |")
    )
    for row in record["one_step"]:
        print(
            f"#   one step, agent 0, t={row['t']}: lowest quantiles critic {row['critic']}, target {row['target']}, "
            f"the target's loss minimiser {row['target_loss_fit']}; median critic {row['critic_median']}, "
            f"target {row['target_median']}; depth at α={alphas[0]} critic / target / minimiser {row['depth']}"
        )
    sys.stdout.flush()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--variants", nargs="+", choices=sorted(VARIANTS), default=["anchored", "plain"])
    parser.add_argument("--seeds", nargs="+", type=int, default=[0])
    parser.add_argument("--buffer-steps", type=int, default=30_000, help="joint steps of the noisy hand-made policy")
    parser.add_argument("--checkpoints", nargs="+", type=int, default=[30_000, 100_000], help="critic updates at readings")
    parser.add_argument("--alphas", nargs="+", type=float, default=[0.25, 0.1])
    parser.add_argument("--episodes", type=int, default=10, help="deterministic episodes per reading")
    parser.add_argument("--log", help="append one JSON line per reading to this file")
    parser.add_argument(
        "--tabular-only", action="store_true", help="only the truth and the loss's tabular fixed point (no training)"
    )
    args = parser.parse_args(argv)
    th.set_num_threads(1)
    header = " | ".join(f"{phase} α={a}" for a in args.alphas for phase in PHASES)
    print("tail depth (mean - CVaR_α): critic / the loss's tabular fixed point / truth")
    print(f"| variant | seed | critic updates | {header} | training s |")
    print("|---" * (4 + 3 * len(args.alphas)) + "|")
    if args.tabular_only:
        for variant in args.variants:
            depths = summary(tabular_only(variant, args.alphas, args.episodes), args.alphas)
            record = {"variant": variant, "seed": "-", "updates": "-", "train_s": float("nan"), "one_step": []}
            record["depths"] = {phase: {str(a): v for a, v in by_alpha.items()} for phase, by_alpha in depths.items()}
            print_row(record, args.alphas)
        return 0
    log = open(args.log, "a", encoding="utf-8") if args.log else None
    try:
        for seed in args.seeds:
            for variant in args.variants:
                run(variant, seed, args.buffer_steps, sorted(args.checkpoints), args.alphas, args.episodes, log)
    finally:
        if log is not None:
            log.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
