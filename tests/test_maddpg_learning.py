"""MADDPG learns: it beats a random policy by a clear margin within a CI-sized budget (fixed seeds, honest baselines)."""

import numpy as np
import pytest
from maddpg_test_envs import DiscreteTargetReachEnv, TargetReachEnv

from sb3_maddpg import MADDPG, MATD3, make_multiagent_vec_env
from sb3_maddpg.common.noise import DecayingGaussianNoise


def mean_episode_return(venv, act, n_episodes: int = 20) -> float:
    """Mean team return (SB3 episode statistics, once per joint episode) over the first n_episodes episodes."""
    obs = venv.reset()
    returns: list[float] = []
    while len(returns) < n_episodes:
        obs, _, _, infos = venv.step(act(obs))
        returns += [info["episode"]["r"] for info in infos if "episode" in info]
    return float(np.mean(returns[:n_episodes]))


# The small coverage task of the CNN learning tests: an 8x8 map seen as 16x16 images, 2 UAVs starting in the middle,
# 4 PoIs in the top-right corner, 20-step episodes.
UAV_SMALL = dict(
    map_size=8,
    obs_size=16,
    n_uavs=2,
    max_cycles=20,
    pois=np.array([[6.0, 6.0], [6.5, 6.0], [6.0, 6.5], [7.0, 7.0]]),
    start=np.array([[4.0, 4.0], [4.5, 4.0]]),
    coverage_range=1.5,
)


def episode_end_coverage(env_fn, env_kwargs: dict, act, n_episodes: int = 8) -> float:
    """Mean episode-end coverage c_T of the first n_episodes joint episodes of 4 copies (seed 100) under ``act``."""
    venv = make_multiagent_vec_env(env_fn, n_envs=4, seed=100, env_kwargs=env_kwargs)
    n_agents = venv.n_agents
    obs, coverage = venv.reset(), []
    while len(coverage) < n_episodes:
        obs, _, dones, infos = venv.step(act(obs))
        coverage += [infos[row]["coverage"] for row in range(0, len(infos), n_agents) if dones[row]]
    return float(np.mean(coverage[:n_episodes]))


def returns_against_random(
    algorithm, env_cls, seed: int, random_actions, critic: str = "joint", **model_kwargs
) -> tuple[float, float]:
    """
    Train on ``env_cls`` (2 agents, 2 copies) for 2 000 timesteps, then the mean team returns of random actions and of
    the trained model on the same 20 evaluation episodes.

    :param random_actions: (generator, number of rows) -> the random actions of the rows
    :param critic: the policy's critic design
    :return: the random and the trained team return
    """
    kwargs = dict(n_agents=2)
    venv = make_multiagent_vec_env(env_cls, n_envs=2, seed=seed, env_kwargs=kwargs)
    model = algorithm(
        "MlpPolicy",
        venv,
        learning_starts=500,
        batch_size=64,
        buffer_size=20_000,
        gamma=0.9,
        policy_kwargs=dict(n_quantiles=10, critic=critic),
        seed=seed,
        **model_kwargs,
    )
    model.learn(2_000)

    rng = np.random.default_rng(seed)
    eval_seed = 100 * (seed + 1)
    eval_env = make_multiagent_vec_env(env_cls, n_envs=4, seed=eval_seed, env_kwargs=kwargs)
    random_return = mean_episode_return(eval_env, lambda obs: random_actions(rng, len(obs)))
    eval_env = make_multiagent_vec_env(env_cls, n_envs=4, seed=eval_seed, env_kwargs=kwargs)
    trained_return = mean_episode_return(eval_env, lambda obs: model.predict(obs, deterministic=True)[0])
    return random_return, trained_return


@pytest.mark.parametrize(
    ("algorithm", "cvar_alpha", "seed", "critic"),
    [
        (MADDPG, 1.0, 0, "joint"),
        (MADDPG, 0.25, 1, "joint"),
        (MATD3, 1.0, 0, "joint"),
        (MADDPG, 1.0, 0, "attention"),
        (MADDPG, 0.25, 1, "attention"),
        (MATD3, 1.0, 2, "attention"),
    ],
)
def test_mlp_policy_beats_random_on_cooperative_target_reaching(algorithm, cvar_alpha, seed, critic):
    """
    Risk-neutral (alpha = 1) and risk-averse (alpha = 0.25) critics both learn the cooperative task; MATD3 too; the
    joint critic and the attention critic alike.
    """
    random_return, trained_return = returns_against_random(
        algorithm,
        TargetReachEnv,
        seed,
        lambda rng, rows: rng.uniform(-1, 1, (rows, 2)).astype(np.float32),
        critic=critic,
        cvar_alpha=cvar_alpha,
        action_noise=DecayingGaussianNoise(np.zeros(2), sigma=0.5, final_sigma=0.1, decay=0.999),
    )
    name = algorithm.__name__
    print(f"\n{name} {critic} CVaR_{cvar_alpha}: 20 episodes: random {random_return:.2f}, trained {trained_return:.2f}")
    # Returns are negative distances: the random policy ends about 9 below zero; a clear margin is half of that
    assert trained_return > random_return + 0.5 * abs(random_return)


@pytest.mark.parametrize(("algorithm", "seed"), [(MADDPG, 0), (MATD3, 1)])
def test_discrete_actors_beat_random_on_target_reaching(algorithm, seed):
    """
    The same task with Discrete(5) moves: the straight-through Gumbel-softmax actors, exploring by sampling their
    logits, beat uniformly random moves (MATD3's target smoothing does not apply to one-hot actions).
    """
    random_return, trained_return = returns_against_random(
        algorithm, DiscreteTargetReachEnv, seed, lambda rng, rows: rng.integers(0, 5, rows)
    )
    name = algorithm.__name__
    print(f"\n{name} discrete: team return over 20 episodes: random {random_return:.2f}, {name} {trained_return:.2f}")
    # Measured: random about -9.3, trained about -4.3; a clear margin is a third of the random return
    assert trained_return > random_return + abs(random_return) / 3


@pytest.mark.xfail(
    reason="v0's rules learn only by chance (docs/results.md: v0 rules reach c_T 0.000 on seeds 0, 1 and 2 of this "
    "task); this seed stopped reaching the PoIs when the noise schedule came to count timesteps and the encoder's "
    "convolutions changed memory layout. The v1 test below is the learning test of the image pipeline.",
    strict=False,
)
def test_cnn_policy_raises_uav_coverage_over_random():
    """
    A small uav_coverage_v0: 8x8 map seen as 16x16 images, 2 UAVs starting in the middle, 4 PoIs in the top-right
    corner, 20-step episodes. Wall and link penalties and the entropy bonus are lowered or off and rewards scaled
    by 10, so that reaching and hovering over the PoIs is what pays; episode-end coverage c_T measures it.

    This shows that the image pipeline (CNN, centralised quantile critics, joint buffer) can learn within a CI budget;
    it does not show that it does so reliably: with seeds 1 and 2 (and also with lr 3e-4, gamma 0.9, more noise, a
    small last-layer initialisation or no BatchNorm) the actors saturated at "hover" (distance 0) and coverage stayed
    at 0 within 6000 timesteps.
    """
    uav_coverage_v0 = pytest.importorskip("sb3_maddpg_envs.uav_coverage_v0")
    env_kwargs = dict(
        **UAV_SMALL,
        wall_penalty=0.5,
        comm_penalty=0.0,
        entropy_coef=0.0,
        reward_scale=10.0,
    )

    venv = make_multiagent_vec_env(uav_coverage_v0.parallel_env, n_envs=2, seed=0, env_kwargs=env_kwargs)
    model = MADDPG(
        "CnnPolicy",
        venv,
        learning_starts=500,
        batch_size=64,
        buffer_size=20_000,
        # 0.9995 per VecEnv step of 2 copies, as before the schedule counted timesteps
        action_noise=DecayingGaussianNoise(np.zeros(2), sigma=0.5, final_sigma=0.2, decay=0.99975),
        policy_kwargs=dict(n_quantiles=10),
        seed=0,
    )
    model.learn(4_000)

    rng = np.random.default_rng(0)
    random_coverage = episode_end_coverage(
        uav_coverage_v0.parallel_env, env_kwargs, lambda obs: rng.uniform(0, 1, (len(obs), 2)).astype(np.float32)
    )
    trained_coverage = episode_end_coverage(
        uav_coverage_v0.parallel_env, env_kwargs, lambda obs: model.predict(obs, deterministic=True)[0]
    )
    print(f"\nepisode-end coverage over 8 episodes: random {random_coverage:.3f}, MADDPG {trained_coverage:.3f}")
    assert trained_coverage > random_coverage + 0.2


UAV_V1_SMALL = dict(**UAV_SMALL, fairness_coef=0.0)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_cnn_policy_learns_small_uav_coverage_v1_with_every_seed(seed):
    """
    The same small coverage task as above on ``uav_coverage_v1`` (Cartesian actions, clipped walls, per-agent
    coverage reward) with the stabilisers of ``zoo_configs/maddpg.yml``'s v1 entries (critic warm-up, policy delay,
    a slower actor, target policy smoothing, padded encoder with coordinate channels): with each of three seeds
    chosen before the run, the team ends its episodes covering clearly more than random actions.

    6 000 timesteps: a seed's run depends on the CPU's floating-point kernels, and at 4 000 seed 1 ended at 0.287
    (random 0.108) on an AVX-512 Intel machine where an AVX2 AMD machine passed; at 6 000 every seed covers 0.60 or
    more on the Intel machine (seeds 0, 1, 2: 0.988, 0.600, 1.000).
    """
    uav_coverage_v1 = pytest.importorskip("sb3_maddpg_envs.uav_coverage_v1")

    venv = make_multiagent_vec_env(uav_coverage_v1.parallel_env, n_envs=2, seed=seed, env_kwargs=UAV_V1_SMALL)
    model = MADDPG(
        "CnnPolicy",
        venv,
        learning_starts=500,
        batch_size=64,
        buffer_size=20_000,
        gamma=0.9,
        actor_learning_rate=3e-4,
        critic_warmup_steps=250,
        policy_delay=2,
        target_policy_noise=0.2,
        actor_reg=1e-3,
        action_noise=DecayingGaussianNoise(np.zeros(2), sigma=0.5, final_sigma=0.1, decay=0.9995),
        policy_kwargs=dict(n_quantiles=10, features_extractor_kwargs=dict(padding=1, coord_channels=True)),
        seed=seed,
    )
    model.learn(6_000)

    rng = np.random.default_rng(seed)
    random_coverage = episode_end_coverage(
        uav_coverage_v1.parallel_env, UAV_V1_SMALL, lambda obs: rng.uniform(0, 1, (len(obs), 2)).astype(np.float32)
    )
    trained_coverage = episode_end_coverage(
        uav_coverage_v1.parallel_env, UAV_V1_SMALL, lambda obs: model.predict(obs, deterministic=True)[0]
    )
    print(f"\nseed {seed}: episode-end coverage over 8 episodes: random {random_coverage:.3f}, MADDPG {trained_coverage:.3f}")
    assert trained_coverage > random_coverage + 0.2
