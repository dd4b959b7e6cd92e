"""
A task package registers its env ids through the entry-point group ``sb3_maddpg.envs`` of its distribution: the
registry finds a package installed on the path (a ``*.dist-info`` folder, as pip writes it) when an id is first looked
up, skips a broken one with a warning, and lets an id registered afterwards (``--gym-packages``) replace it; this
repository's setup.cfg declares its own task package so.
"""

import configparser
import importlib
from collections.abc import Iterator
from pathlib import Path

import gymnasium as gym
import pytest

from sb3_maddpg.zoo import registry
from sb3_maddpg.zoo.registry import ENV_ENTRY_POINT_GROUP, MULTIAGENT_ENVS, make_multiagent_env, register_multiagent_env

ROOT = Path(__file__).resolve().parent.parent
IDS = ("my_reach_v0", "my_reach_long_v0")


def install(site: Path, name: str, entry_points: str) -> None:
    """A distribution's metadata as pip installs it: ``<name>-1.0.dist-info/`` with METADATA and entry_points.txt."""
    info = site / f"{name}-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text(entry_points)


@pytest.fixture
def site(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """A folder on the path holding a task package and its metadata; the registry reads the entry points anew."""
    (tmp_path / "my_tasks.py").write_text(
        "def register_envs(register):\n"
        "    register('my_reach_v0', 'maddpg_test_envs:TargetReachEnv', {'max_cycles': 3})\n"
        "    register('my_reach_long_v0', 'maddpg_test_envs:TargetReachEnv', {'max_cycles': 7})\n"
    )
    install(tmp_path, "my_tasks", f"[{ENV_ENTRY_POINT_GROUP}]\nmy_tasks = my_tasks:register_envs\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(registry, "_env_packages_loaded", False)
    yield tmp_path
    for env_id in IDS:
        MULTIAGENT_ENVS.specs.pop(env_id, None)
        gym.registry.pop(env_id, None)


def test_an_installed_task_package_registers_its_ids_when_one_is_looked_up(site: Path) -> None:
    assert "my_reach_v0" not in MULTIAGENT_ENVS.specs  # nothing read before the first lookup
    assert "my_reach_v0" in MULTIAGENT_ENVS
    assert MULTIAGENT_ENVS["my_reach_long_v0"].kwargs == {"max_cycles": 7}
    assert make_multiagent_env("my_reach_v0").max_cycles == 3
    # RL Zoo checks --env in Gymnasium's registry: the placeholder is there
    assert "my_reach_v0" in gym.registry
    # the library's own ids stay
    assert "simple_spread_v3" in MULTIAGENT_ENVS


def test_an_id_registered_afterwards_replaces_the_packages(site: Path) -> None:
    # a module imported with --gym-packages, before any lookup: the packages register first, it wins
    register_multiagent_env("my_reach_v0", "maddpg_test_envs:TargetReachEnv", {"max_cycles": 5})
    assert MULTIAGENT_ENVS["my_reach_v0"].kwargs == {"max_cycles": 5}
    assert "my_reach_long_v0" in MULTIAGENT_ENVS


def test_a_broken_task_package_is_skipped_with_a_warning(site: Path) -> None:
    install(site, "broken_tasks", f"[{ENV_ENTRY_POINT_GROUP}]\nbroken = no_such_module_here:register_envs\n")
    importlib.invalidate_caches()
    with pytest.warns(UserWarning, match=r"the task package 'broken' \(no_such_module_here:register_envs.*ModuleNotFound"):
        assert "my_reach_v0" in MULTIAGENT_ENVS


def test_this_repository_declares_its_task_package() -> None:
    # What the wheel's and the editable install's entry_points.txt hold (pip writes them from setup.cfg)
    config = configparser.ConfigParser()
    config.read(ROOT / "setup.cfg")
    entries = dict(
        line.replace(" ", "").split("=", 1)
        for line in config["options.entry_points"][ENV_ENTRY_POINT_GROUP].split("\n")
        if line
    )
    assert entries == {"sb3_maddpg_envs": "sb3_maddpg_envs.registration:register_envs"}
    module, _, function = entries["sb3_maddpg_envs"].partition(":")
    registered: dict[str, tuple] = {}
    getattr(importlib.import_module(module), function)(lambda *args: registered.setdefault(args[0], args[1:]))
    assert "uav_coverage_cpu_v1" in registered and "risky_reach_v0" in registered
    for env_id, (entry_point, kwargs) in registered.items():
        assert MULTIAGENT_ENVS[env_id].entry_point == entry_point and MULTIAGENT_ENVS[env_id].kwargs == kwargs
