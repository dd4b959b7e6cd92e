"""One meaning of "reward" in each place: the team return where SB3 shows one number, each agent's beside it."""

import numpy as np
from stable_baselines3.common.callbacks import EvalCallback
from stable_baselines3.common.logger import configure

from sb3_maddpg import MADDPG, evaluate_policy, make_multiagent_vec_env
from sb3_maddpg.zoo.monitor import EnjoyVecEnv
from sb3_maddpg_envs import uav_coverage_v1

KWARGS = dict(obs_size=16, n_uavs=3, max_cycles=10)


def venv(n_envs: int = 1):
    return make_multiagent_vec_env(uav_coverage_v1.parallel_env, n_envs=n_envs, seed=0, env_kwargs=KWARGS)


def model(n_envs: int = 1) -> MADDPG:
    return MADDPG("CnnPolicy", venv(n_envs), buffer_size=200, learning_starts=10, batch_size=8, seed=0)


def manual_team_returns(agent: MADDPG, n_episodes: int) -> list[float]:
    env = uav_coverage_v1.parallel_env(**KWARGS)
    returns = []
    for seed in range(n_episodes):
        observations, _ = env.reset(seed=seed)
        total = 0.0
        while env.agents:
            actions, _ = agent.predict(observations, deterministic=True)
            observations, rewards, _, _, _ = env.step(actions)
            total += sum(rewards.values())
        returns.append(total)
    return returns


def test_the_episode_info_holds_the_team_return_and_each_agents() -> None:
    env = venv()
    env.reset()
    for _ in range(KWARGS["max_cycles"]):
        _, rewards, dones, infos = env.step(np.random.default_rng(0).random((3, 2)).astype(np.float32))
    episode = infos[0]["episode"]
    assert dones.all() and episode["l"] == 10 and set(episode["agent_r"]) == {"uav_0", "uav_1", "uav_2"}
    assert np.isclose(sum(episode["agent_r"].values()), episode["r"], atol=1e-4)


def test_evaluate_policy_counts_joint_episodes_and_reports_the_team_return() -> None:
    agent = model(n_envs=2)
    env = venv(n_envs=2)
    returns, lengths = evaluate_policy(agent, env, n_eval_episodes=3, return_episode_rewards=True)
    assert len(returns) == 3 and lengths == [10, 10, 10]
    mean, std = evaluate_policy(agent, venv(), n_eval_episodes=2)
    # deterministic start positions aside, each is a sum of three agents' rewards over 10 steps
    assert np.isfinite(mean) and std >= 0
    one_copy = venv()
    one_copy.seed(0)
    (team,), _ = evaluate_policy(agent, one_copy, n_eval_episodes=1, return_episode_rewards=True)
    assert np.isclose(team, manual_team_returns(agent, 1)[0], atol=1e-3)


def test_eval_callback_logs_the_team_return(tmp_path) -> None:
    agent = model()
    agent.set_logger(configure(str(tmp_path), ["csv"]))
    callback = EvalCallback(venv(), n_eval_episodes=2, eval_freq=20, log_path=str(tmp_path), verbose=0)
    agent.learn(20, callback=callback)
    assert len(callback.evaluations_results[-1]) == 2  # two joint episodes, not one per agent row
    assert callback.evaluations_length[-1] == [10, 10]


def test_learn_logs_each_agents_return_beside_the_team_return(tmp_path) -> None:
    agent = model()
    agent.set_logger(configure(str(tmp_path), ["csv"]))
    agent.learn(40, log_interval=1)
    header = (tmp_path / "progress.csv").read_text().splitlines()[0].split(",")
    assert {"rollout/ep_rew_mean", "rollout/ep_rew_uav_0", "rollout/ep_rew_uav_2"} <= set(header)


def test_enjoy_sees_the_team_reward_in_every_row() -> None:
    env = EnjoyVecEnv(venv(), verbose=0)
    inner = venv()
    env.reset()
    inner.reset()
    actions = np.full((3, 2), 0.5, dtype=np.float32)
    _, team, _, _ = env.step(actions)
    _, rows, _, _ = inner.step(actions)
    assert np.allclose(team, rows.sum())


def test_predict_takes_a_pettingzoo_observation_dict() -> None:
    agent = model()
    env = uav_coverage_v1.parallel_env(**KWARGS)
    observations, _ = env.reset(seed=0)
    actions, state = agent.predict(observations, deterministic=True)
    rows, _ = agent.predict(np.stack([observations[a] for a in env.possible_agents]), deterministic=True)
    assert state is None and list(actions) == ["uav_0", "uav_1", "uav_2"]
    assert np.array_equal(np.stack(list(actions.values())), rows)
    some, _ = agent.predict({"uav_2": observations["uav_2"]}, deterministic=True)
    assert list(some) == ["uav_2"] and np.array_equal(some["uav_2"], rows[2])
    try:
        agent.predict({"uav_9": observations["uav_0"]})
    except ValueError as error:
        assert "uav_9" in str(error)
    else:
        raise AssertionError("an unknown agent must be refused")
