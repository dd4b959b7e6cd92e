"""
Ablation on the small UAV task of ``tests/test_maddpg_learning.py`` (8 x 8 map seen as 16 x 16 images, 2 UAVs, 4 PoIs in
a corner, 20-step episodes): which of v1's env rules and MADDPG's stabilisers make the difference, with seeds 0, 1, 2.

    python experiments/small_task_ablation.py            # prints one line per (variant, seed): random vs trained c_T
"""

import sys
from pathlib import Path

import numpy as np
import torch as th

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from test_maddpg_learning import UAV_V1_SMALL, episode_end_coverage  # noqa: E402

from sb3_maddpg import MADDPG, make_multiagent_vec_env  # noqa: E402
from sb3_maddpg.common.noise import DecayingGaussianNoise  # noqa: E402
from sb3_maddpg_envs import uav_coverage_v1  # noqa: E402

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
