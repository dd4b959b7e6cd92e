"""
Ablation on the small UAV task of ``tests/test_maddpg_learning.py`` (8 x 8 map seen as 16 x 16 images, 2 UAVs, 4 PoIs in
a corner, 20-step episodes): which of v1's env rules and MADDPG's stabilisers make the difference, with seeds 0, 1, 2.

    python experiments/small_task_ablation.py            # prints one line per (variant, seed): random vs trained c_T
"""

import numpy as np
import torch as th

from sb3_maddpg import MADDPG, make_multiagent_vec_env
from sb3_maddpg.common.noise import DecayingGaussianNoise
from sb3_maddpg_envs import uav_coverage_v1

# The small task of tests/test_maddpg_learning.py (its UAV_V1_SMALL): an 8x8 map seen as 16x16 images, 2 UAVs starting
# in the middle, 4 PoIs in the top-right corner, 20-step episodes, no fairness term. A copy: the ablation keeps the
# task it measured should the test's change.
UAV_V1_SMALL = dict(
    map_size=8,
    obs_size=16,
    n_uavs=2,
    max_cycles=20,
    pois=np.array([[6.0, 6.0], [6.5, 6.0], [6.0, 6.5], [7.0, 7.0]]),
    start=np.array([[4.0, 4.0], [4.5, 4.0]]),
    coverage_range=1.5,
    fairness_coef=0.0,
)

STABILISERS = dict(
    gamma=0.9,
    actor_learning_rate=3e-4,
    critic_warmup_steps=250,
    policy_delay=2,
    target_policy_noise=0.2,
    actor_reg=1e-3,
)
ENCODER = dict(padding=1, coord_channels=True)
V0_RULES = dict(
    action_mode="polar",
    wall_mode="refuse",
    reward_mode="report",
    wall_penalty=0.5,
    comm_penalty=0.0,
    entropy_coef=0.0,
    reward_scale=10.0,
)
VARIANTS = {
    "v1 rules + stabilisers + encoder (the test)": (dict(), STABILISERS, ENCODER),
    "v1 rules, no stabilisers, report encoder": (dict(), dict(gamma=0.9), dict()),
    "v1 rules + stabilisers, report encoder": (dict(), STABILISERS, dict()),
    "v0 rules (as the v0 test) + stabilisers + encoder": (V0_RULES, STABILISERS, ENCODER),
}


def episode_end_coverage(env_fn, env_kwargs: dict, act, n_episodes: int = 8) -> float:
    """Mean episode-end coverage c_T of the first n_episodes joint episodes of 4 copies (seed 100) under ``act``."""
    venv = make_multiagent_vec_env(env_fn, n_envs=4, seed=100, env_kwargs=env_kwargs)
    obs, coverage = venv.reset(), []
    while len(coverage) < n_episodes:
        obs, _, dones, infos = venv.step(act(obs))
        coverage += [infos[row]["coverage"] for row in range(0, len(infos), venv.n_agents) if dones[row]]
    return float(np.mean(coverage[:n_episodes]))


def main() -> None:
    th.set_num_threads(1)
    for name, (env_rules, algo, encoder) in VARIANTS.items():
        env_kwargs = {**UAV_V1_SMALL, **env_rules}
        for seed in (0, 1, 2):
            venv = make_multiagent_vec_env(uav_coverage_v1.parallel_env, n_envs=2, seed=seed, env_kwargs=env_kwargs)
            model = MADDPG(
                "CnnPolicy",
                venv,
                learning_starts=500,
                batch_size=64,
                buffer_size=20_000,
                seed=seed,
                action_noise=DecayingGaussianNoise(np.zeros(2), sigma=0.5, final_sigma=0.1, decay=0.9995),
                policy_kwargs=dict(n_quantiles=10, features_extractor_kwargs=encoder),
                **algo,
            )
            model.learn(4_000)
            rng = np.random.default_rng(seed)
            random = episode_end_coverage(
                uav_coverage_v1.parallel_env,
                env_kwargs,
                lambda obs, rng=rng: rng.uniform(0, 1, (len(obs), 2)).astype(np.float32),
            )
            trained = episode_end_coverage(
                uav_coverage_v1.parallel_env, env_kwargs, lambda obs, model=model: model.predict(obs, deterministic=True)[0]
            )
            print(f"{name} | seed {seed} | random {random:.3f} | MADDPG {trained:.3f}", flush=True)


if __name__ == "__main__":
    main()
