"""The UAV env's config, its scenarios and its hazard hook: the config's checks, each registered task's scenario
equal to the registry's entry, and a calm task's core without a hazard hook."""

import pickle

import numpy as np
import pytest

from sb3_maddpg.zoo.registry import MULTIAGENT_ENVS, make_multiagent_env
from sb3_maddpg_envs import registration, uav_coverage_v0, uav_coverage_v1
from sb3_maddpg_envs.uav_coverage import SCENARIOS, UAVCoverageConfig, UAVCoverageCore, scenarios
from sb3_maddpg_envs.uav_coverage.hazards import HazardHook

#: registered id -> (its scenario, what the registry sets over the scenario)
REGISTERED = {
    "uav_coverage_v0": (scenarios.V0, {}),
    "uav_coverage_fast_v0": (scenarios.V0, {"obs_size": 16}),
    "uav_coverage_v1": (scenarios.V1, {}),
    "uav_coverage_cpu_v1": (scenarios.V1, {"obs_size": 16}),
    "uav_coverage_tmc_v1": (scenarios.TMC2020, {}),
    "uav_coverage_hazard_cpu_v1": (scenarios.HAZARD, {"obs_size": 16}),
    "uav_coverage_storm_cpu_v1": (scenarios.STORM_TASK, {"obs_size": 16}),
    "uav_coverage_storm_cpu_v2": (scenarios.STORM_V2_TASK, {"obs_size": 16}),
}


def test_every_registered_uav_task_has_its_scenario():
    assert {env_id for env_id in MULTIAGENT_ENVS if env_id.startswith("uav_coverage")} == set(REGISTERED)
    assert set(SCENARIOS.values()) == {scenario for scenario, _ in REGISTERED.values()}


@pytest.mark.parametrize("env_id", sorted(REGISTERED))
def test_scenario_defaults_equal_the_registry_entry(env_id: str):
    scenario, over = REGISTERED[env_id]
    env = make_multiagent_env(env_id)
    assert env.core.config.kwargs() == scenario.make_config(**over).kwargs()
    assert env.metadata["name"] == scenario.name
    assert scenario.parallel_env(**over).core.config.kwargs() == env.core.config.kwargs()


def test_scenario_tables_are_the_versioned_modules_and_the_registry():
    assert registration.ENVS["uav_coverage_tmc_v1"][1] is scenarios.TMC2020_KWARGS
    assert uav_coverage_v1.V1_DEFAULTS is scenarios.V1_DEFAULTS
    assert uav_coverage_v1.HAZARDS is scenarios.HAZARDS and uav_coverage_v1.STORM is scenarios.STORM
    assert scenarios.V1.defaults == uav_coverage_v1.V1_DEFAULTS
    assert scenarios.HAZARD.defaults == {**uav_coverage_v1.V1_DEFAULTS, **uav_coverage_v1.HAZARDS}
    assert scenarios.STORM_TASK.defaults == {**uav_coverage_v1.V1_DEFAULTS, **uav_coverage_v1.STORM}
    assert uav_coverage_v1.STORM_V2 is scenarios.STORM_V2
    assert scenarios.STORM_V2_TASK.defaults == {**uav_coverage_v1.V1_DEFAULTS, **uav_coverage_v1.STORM_V2}
    assert scenarios.V0.defaults == {} and uav_coverage_v0.parallel_env(obs_size=16).metadata["name"] == "uav_coverage_v0"


@pytest.mark.parametrize("env_id", ["uav_coverage_v0", "uav_coverage_cpu_v1", "uav_coverage_tmc_v1"])
def test_a_calm_task_has_no_hazard_hook(env_id: str):
    env = make_multiagent_env(env_id, obs_size=20 if "tmc" in env_id else 16)
    assert env.core.hazard_hook is None and not env.core.hazards


@pytest.mark.parametrize("env_id", ["uav_coverage_hazard_cpu_v1", "uav_coverage_storm_cpu_v1", "uav_coverage_storm_cpu_v2"])
def test_a_hazardous_task_has_a_hazard_hook(env_id: str):
    core = make_multiagent_env(env_id).core
    assert isinstance(core.hazard_hook, HazardHook) and core.hazard_hook.config is core.config


def test_a_calm_step_calls_no_hazard_code(monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("a calm task's step ran hazard code")

    for name in ("ground", "perturb", "charge", "fail_links", "penalize", "charge_grounded", "finish"):
        monkeypatch.setattr(HazardHook, name, refuse)
    env = make_multiagent_env("uav_coverage_cpu_v1", max_cycles=5)
    env.reset(seed=0)
    while env.agents:
        env.step({agent: np.array([0.9, 0.2], np.float32) for agent in env.agents})


def test_config_checks_each_parameter_where_it_is_set():
    with pytest.warns(UserWarning, match="storm_zone has no effect"):
        config = UAVCoverageConfig(obs_size=16, coverage_range=2, storm_zone=[1, 1, 4, 4])
    assert config.coverage_range == 2.0 and isinstance(config.coverage_range, float)
    assert config.storm_zone == (1.0, 1.0, 4.0, 4.0)
    with pytest.raises(ValueError, match="max_cycles must be an integer"):
        config.max_cycles = 0
    config.max_cycles = 7
    assert config.max_cycles == 7
    with pytest.raises(ValueError, match="map_size must be an integer"):
        UAVCoverageConfig(map_size=0)
    with pytest.raises(ValueError, match=r"coverage_range must be <= comm_range \(R0 <= R\)"):
        UAVCoverageConfig(coverage_range=7.0)
    with pytest.raises(ValueError, match="obs_size must be a positive multiple of map_size=16"):
        UAVCoverageConfig(obs_size=20)
    with pytest.raises(TypeError, match="teammate_channel must be a bool"):
        UAVCoverageConfig(teammate_channel=1)
    with pytest.raises(ValueError, match="n_pois is only used with pois='uniform'"):
        UAVCoverageConfig(obs_size=16, n_pois=3)


def test_config_reads_pois_and_start():
    grid = UAVCoverageConfig(map_size=4, obs_size=4)
    assert grid.pois_mode == "grid" and grid.poi_points.shape == (16, 2) and grid.n_pois is None
    uniform = UAVCoverageConfig(map_size=4, obs_size=4, pois="uniform")
    assert uniform.pois_mode == "uniform" and uniform.poi_points is None and uniform.n_pois == 16
    given = UAVCoverageConfig(map_size=4, obs_size=4, n_uavs=2, start=[[1, 1], [2, 3]])
    assert given.start_mode == "array" and given.start_points.tolist() == [[1.0, 1.0], [2.0, 3.0]]


def test_core_from_a_config_equals_the_core_from_its_keywords():
    kwargs = {**scenarios.STORM, "obs_size": 16, "gust_prob": 0.3, "n_uavs": 3}
    config = UAVCoverageConfig(**kwargs)
    cores = [UAVCoverageCore(config), UAVCoverageCore(**kwargs), pickle.loads(pickle.dumps(UAVCoverageCore(config)))]
    assert cores[0].config is not config  # max_cycles can be set on a core: each has its own
    outputs = []
    for core in cores:
        core.reset(seed=4)
        steps = [core.step(np.random.default_rng(i).uniform(0, 1, (3, 2))) for i in range(20)]
        outputs.append([np.concatenate([obs.ravel(), rewards]) for obs, rewards, *_ in steps])
    for other in outputs[1:]:
        np.testing.assert_array_equal(np.array(outputs[0]), np.array(other))
    assert cores[0].map_size == 16 and cores[0].storm_prob == config.storm_prob and cores[0].pois_mode == "grid"
