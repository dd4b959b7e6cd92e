"""Every entry of every YAML file in zoo_configs/ builds its model through RL Zoo's experiment manager."""

import argparse
from pathlib import Path

import pytest
import yaml

from sb3_maddpg.zoo import register_with_rl_zoo
from sb3_maddpg.zoo.exp_manager import MultiAgentExperimentManager
from sb3_maddpg.zoo.registry import UsageError

CONFIG_DIR = Path(__file__).resolve().parent.parent / "zoo_configs"
ENTRIES = [
    (path, env_id)
    for path in sorted(CONFIG_DIR.glob("*.yml"))
    for env_id in (yaml.safe_load(path.read_text()) or {})
    if env_id != "default"
]
# Small observations and episodes: building the model is what is tested, not the report's sizes.
SMALL_ENV_KWARGS = {
    "uav_coverage_v0": dict(obs_size=16, max_cycles=10, n_uavs=2),
    "uav_coverage_fast_v0": dict(max_cycles=10, n_uavs=2),
    "simple_spread_v3": dict(continuous_actions=True, max_cycles=10),
    "simple_spread_discrete_v3": dict(max_cycles=10),
    # obs_size stays the registered 20: the CNN must fit the paper setting's images
    "uav_coverage_tmc_v1": dict(max_cycles=10, n_uavs=2),
}


def make_manager(path: Path, env_id: str, tmp_path: Path, **kwargs) -> MultiAgentExperimentManager:
    register_with_rl_zoo()
    return MultiAgentExperimentManager(
        argparse.Namespace(),
        path.stem,  # the file name is the algorithm, as in RL Zoo's hyperparams folder
        env_id,
        str(tmp_path / "logs"),
        eval_freq=-1,
        seed=0,
        verbose=0,
        device="cpu",
        config=str(path),
        **kwargs,
    )


def test_configs_exist() -> None:
    assert ("maddpg.yml", "uav_coverage_v0") in [(path.name, env_id) for path, env_id in ENTRIES]
    assert {env_id for _, env_id in ENTRIES} >= {"uav_coverage_v0", "uav_coverage_fast_v0", "simple_spread_v3"}


@pytest.mark.parametrize(("path", "env_id"), ENTRIES, ids=[f"{path.name}:{env_id}" for path, env_id in ENTRIES])
def test_every_entry_builds_its_model(path: Path, env_id: str, tmp_path: Path) -> None:
    manager = make_manager(
        path,
        env_id,
        tmp_path,
        # keep every other setting; a small buffer so that building does not reserve gigabytes
        hyperparams={"buffer_size": 100},
        env_kwargs=SMALL_ENV_KWARGS.get(env_id),
    )
    model, saved = manager.setup_experiment()
    entry = yaml.safe_load(path.read_text())[env_id]
    assert type(model).__name__.lower() == path.stem
    assert model.gamma == pytest.approx(entry.get("gamma", model.gamma))
    assert model.batch_size == entry.get("batch_size", model.batch_size)
    assert saved["policy"] == entry["policy"]
    model.predict(model.env.reset(), deterministic=True)
    model.env.close()


def test_report_settings() -> None:
    entry = yaml.safe_load((CONFIG_DIR / "maddpg.yml").read_text())["uav_coverage_v0"]
    assert entry["gamma"] == 0.83
    assert entry["tau"] == 0.01
    assert entry["learning_rate"] == 1e-3
    assert entry["batch_size"] == 32
    assert entry["train_freq"] == 5 and entry["gradient_steps"] == 1
    assert entry["cvar_alpha"] == 0.5
    assert "n_quantiles=50" in entry["policy_kwargs"]
    assert entry["policy"] == "CnnPolicy"
    assert (entry["noise_type"], entry["noise_std"], entry["noise_final_std"]) == ("decaying-normal", 1.0, 0.1)
    fast = yaml.safe_load((CONFIG_DIR / "maddpg.yml").read_text())["uav_coverage_fast_v0"]
    assert fast["env_kwargs"]["obs_size"] == 16


def test_report_entry_uses_the_decaying_noise(tmp_path: Path) -> None:
    from sb3_maddpg.common.noise import DecayingGaussianNoise

    manager = make_manager(
        CONFIG_DIR / "maddpg.yml",
        "uav_coverage_v0",
        tmp_path,
        hyperparams={"buffer_size": 100},
        env_kwargs=SMALL_ENV_KWARGS["uav_coverage_v0"],
    )
    model, _ = manager.setup_experiment()
    assert isinstance(model.action_noise, DecayingGaussianNoise)
    model.env.close()


def test_unknown_yaml_key_is_a_usage_error(tmp_path: Path) -> None:
    config = tmp_path / "maddpg.yml"
    config.write_text("uav_coverage_fast_v0:\n  n_timesteps: 10\n  policy: 'CnnPolicy'\n  not_a_setting: 3\n")
    manager = make_manager(config, "uav_coverage_fast_v0", tmp_path)
    with pytest.raises(UsageError, match="not_a_setting"):
        manager.setup_experiment()
