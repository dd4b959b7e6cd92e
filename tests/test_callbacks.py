"""EpisodeMetricsCallback: once per joint episode, team sums of per-agent counts, TensorBoard scalars of a real run."""

import glob

import numpy as np
import pytest
from stable_baselines3.common.logger import Logger

from sb3_maddpg.common.callbacks import EpisodeMetricsCallback, declared_episode_metrics, joint_episode_metrics

UAV_KEYS = ("coverage", "fairness", "energy", "energy_efficiency", "wall_hits", "disconnections")
UAV_PER_AGENT_KEYS = ("wall_hits", "disconnections")


def agent_info(coverage: float, wall_hits: int = 0, disconnections: int = 0) -> dict:
    return {
        "coverage": coverage,
        "fairness": 0.5,
        "energy": 0.25,
        "energy_efficiency": 1.0,
        "wall_hits": wall_hits,
        "disconnections": disconnections,
    }


class FakeEnv:
    """An env that declares the UAV task's metrics, as the UAV envs' metadata does."""

    metadata = {"episode_metrics": UAV_KEYS, "per_agent_episode_metrics": UAV_PER_AGENT_KEYS}


class FakeModel:
    """What the callback touches: the logger, the timestep counter, n_agents and the env."""

    def __init__(self, n_agents: int, env: object = None) -> None:
        self.n_agents = n_agents
        self.num_timesteps = 0
        self.logger = Logger(folder=None, output_formats=[])
        self.env = env

    def get_env(self) -> object:
        return self.env


def make_callback(n_agents: int, env: object = FakeEnv()) -> tuple[EpisodeMetricsCallback, FakeModel]:
    model = FakeModel(n_agents, env)
    callback = EpisodeMetricsCallback()
    callback.init_callback(model)  # type: ignore[arg-type]
    return callback, model


def step(callback: EpisodeMetricsCallback, dones: list[bool], infos: list[dict]) -> None:
    callback.update_locals({"dones": np.array(dones), "infos": infos})
    assert callback.on_step()


def test_joint_episode_metrics_sums_per_agent_counts() -> None:
    infos = [agent_info(0.3, 1, 0), agent_info(0.3, 2, 5), agent_info(0.9, 7, 7), agent_info(0.9, 0, 1)]
    metrics = joint_episode_metrics(infos, first_row=0, n_agents=2, keys=UAV_KEYS, per_agent_keys=UAV_PER_AGENT_KEYS)
    assert metrics["coverage"] == pytest.approx(0.3)
    assert metrics["wall_hits"] == 3
    assert metrics["disconnections"] == 5
    assert joint_episode_metrics([{}, {}], 0, 2, UAV_KEYS, UAV_PER_AGENT_KEYS) == {}


def test_logs_once_per_joint_episode_and_averages_between_dumps() -> None:
    callback, model = make_callback(n_agents=3)
    # two copies of 3 agents; copy 0 ends (coverage 0.2), then copy 1 ends (coverage 0.6)
    rows = [agent_info(0.2, 1)] * 3 + [agent_info(0.6, 0)] * 3
    step(callback, [False] * 6, rows)
    assert callback.n_episodes == 0
    step(callback, [True] * 3 + [False] * 3, rows)
    assert callback.n_episodes == 1
    assert model.logger.name_to_value["rollout/coverage"] == pytest.approx(0.2)
    assert model.logger.name_to_value["rollout/wall_hits"] == 3
    step(callback, [False] * 3 + [True] * 3, rows)
    assert callback.n_episodes == 2
    assert model.logger.name_to_value["rollout/coverage"] == pytest.approx(0.4)
    assert model.logger.name_to_value["rollout/fairness"] == pytest.approx(0.5)


def test_envs_without_metrics_log_nothing() -> None:
    callback, model = make_callback(n_agents=2)
    step(callback, [True, True], [{"terminal_observation": np.zeros(3)}, {}])
    assert callback.n_episodes == 0
    assert not any(key.startswith("rollout/") for key in model.logger.name_to_value)


def test_metrics_an_env_does_not_declare_are_not_logged() -> None:
    # the same infos as above, from an env whose metadata declares no metrics (the MPE tasks)
    callback, model = make_callback(n_agents=3, env=None)
    step(callback, [True] * 3, [agent_info(0.2, 1)] * 3)
    assert callback.n_episodes == 0
    assert "rollout/coverage" not in model.logger.name_to_value


@pytest.mark.parametrize(
    ("env_id", "keys", "per_agent_keys"),
    [
        ("uav_coverage_cpu_v1", UAV_KEYS, UAV_PER_AGENT_KEYS),
        ("uav_coverage_v0", UAV_KEYS, UAV_PER_AGENT_KEYS),
        ("risky_reach_v0", ("zone_steps", "zone_losses"), ("zone_steps", "zone_losses")),
        ("simple_spread_v3", (), ()),
    ],
)
def test_the_env_declares_its_episode_metrics_through_the_vec_env(env_id, keys, per_agent_keys) -> None:
    import functools

    from sb3_maddpg import make_multiagent_vec_env
    from sb3_maddpg.zoo.registry import make_multiagent_env

    venv = make_multiagent_vec_env(functools.partial(make_multiagent_env, env_id), n_envs=1, seed=0)
    assert declared_episode_metrics(venv) == (keys, per_agent_keys)
    venv.close()


class BadDeclaration:
    def __init__(self, **metadata) -> None:
        self.metadata = metadata


@pytest.mark.parametrize(
    ("metadata", "message"),
    [
        (dict(episode_metrics="coverage"), "must be a list of info keys"),
        (dict(episode_metrics=["coverage", 3]), "must be a list of info keys"),
        (dict(episode_metrics=["coverage"], per_agent_episode_metrics=["wall_hits"]), "not among its"),
    ],
)
def test_a_malformed_declaration_is_refused_naming_it(metadata, message) -> None:
    with pytest.raises(TypeError, match=message):
        declared_episode_metrics(BadDeclaration(**metadata))


def test_short_run_writes_coverage_and_fairness_to_tensorboard(tmp_path) -> None:
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    from sb3_maddpg import MADDPG, make_multiagent_vec_env
    from sb3_maddpg_envs import uav_coverage_v0

    env_kwargs = dict(n_uavs=2, obs_size=16, max_cycles=10)
    venv = make_multiagent_vec_env(uav_coverage_v0.parallel_env, n_envs=1, seed=0, env_kwargs=env_kwargs)
    model = MADDPG(
        "CnnPolicy",
        venv,
        buffer_size=200,
        learning_starts=40,
        batch_size=8,
        train_freq=10,
        policy_kwargs=dict(n_quantiles=5, net_arch=[16]),
        tensorboard_log=str(tmp_path),
        seed=0,
    )
    # No callback given: MADDPG.learn logs the episode metrics in every run
    model.learn(60)

    events = glob.glob(str(tmp_path / "**" / "events.out.tfevents.*"), recursive=True)
    assert events
    accumulator = EventAccumulator(events[0])
    accumulator.Reload()
    tags = accumulator.Tags()["scalars"]
    for tag in ("rollout/coverage", "rollout/fairness", "rollout/energy", "rollout/energy_efficiency"):
        assert tag in tags
    coverage = [event.value for event in accumulator.Scalars("rollout/coverage")]
    fairness = [event.value for event in accumulator.Scalars("rollout/fairness")]
    # Two UAVs covering a 16 x 16 lattice for 10 steps cover something: the episode-end values, not the reset ones.
    assert all(0.0 < value <= 1.0 for value in coverage)
    assert all(0.0 < value <= 1.0 for value in fairness)

    # `plot` falls back on these scalars when a run has no monitor.csv (runs started from Python)
    from sb3_maddpg.evaluation import plot_training_logs

    paths = plot_training_logs(tmp_path, tmp_path / "figures")
    assert all(path.stat().st_size > 0 for path in paths)


def test_maddpg_adds_the_metrics_callback_once() -> None:
    from stable_baselines3.common.callbacks import CallbackList

    from sb3_maddpg import MADDPG, make_multiagent_vec_env
    from sb3_maddpg.common.callbacks import contains_callback
    from sb3_maddpg_envs import uav_coverage_v0

    venv = make_multiagent_vec_env(uav_coverage_v0.parallel_env, n_envs=1, seed=0, env_kwargs=dict(n_uavs=2, obs_size=16))
    model = MADDPG("CnnPolicy", venv, buffer_size=10, policy_kwargs=dict(n_quantiles=2, net_arch=[8]))

    def count(callback) -> int:
        if isinstance(callback, CallbackList):
            return sum(count(c) for c in callback.callbacks)
        return int(isinstance(callback, EpisodeMetricsCallback))

    assert count(model._init_callback(None)) == 1
    given = EpisodeMetricsCallback()
    assert count(model._init_callback([given])) == 1
    assert contains_callback(model._init_callback(given), EpisodeMetricsCallback)
