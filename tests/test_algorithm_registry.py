"""One list of the library's algorithms, read by the command line, the RL Zoo integration and evaluation; the keys a
saved model must have belong to its algorithm."""

import json
import zipfile
from pathlib import Path

import pytest
from maddpg_test_envs import TargetReachEnv

from sb3_maddpg import MADDPG, MATD3, make_multiagent_vec_env
from sb3_maddpg.algorithms import ALGORITHM_NAMES, algorithm_class
from sb3_maddpg.common.model_files import read_maddpg_data
from sb3_maddpg.common.off_policy_algorithm import MultiAgentOffPolicyAlgorithm

ZOO_CONFIGS = Path(__file__).resolve().parent.parent / "zoo_configs"


def test_every_algorithm_has_a_class_and_a_zoo_config() -> None:
    assert ALGORITHM_NAMES == ("maddpg", "matd3")
    assert algorithm_class("maddpg") is MADDPG and algorithm_class("matd3") is MATD3
    for name in ALGORITHM_NAMES:
        assert issubclass(algorithm_class(name), MultiAgentOffPolicyAlgorithm)
        assert (ZOO_CONFIGS / f"{name}.yml").is_file(), name


def test_an_unknown_algorithm_is_named_with_the_choices() -> None:
    with pytest.raises(ValueError, match=r"unknown algorithm 'ppo': the library's algorithms are maddpg, matd3"):
        algorithm_class("ppo")


def test_the_command_line_and_rl_zoo_read_the_registry() -> None:
    pytest.importorskip("rl_zoo3")
    import rl_zoo3.utils

    from sb3_maddpg.zoo.command_line import MULTIAGENT_ALGOS
    from sb3_maddpg.zoo.integration import register_with_rl_zoo

    register_with_rl_zoo()
    assert MULTIAGENT_ALGOS == ALGORITHM_NAMES
    assert all(rl_zoo3.utils.ALGOS[name] is algorithm_class(name) for name in ALGORITHM_NAMES)


def _without(source: Path, target: Path, key: str) -> Path:
    """A copy of the model zip without the class parameter ``key``."""
    with zipfile.ZipFile(source) as archive:
        members = {name: archive.read(name) for name in archive.namelist()}
    raw = json.loads(members["data"])
    del raw[key]
    members["data"] = json.dumps(raw).encode()
    with zipfile.ZipFile(target, "w") as archive:
        for name, content in members.items():
            archive.writestr(name, content)
    return target


def test_the_keys_a_model_must_have_are_its_algorithms(tmp_path: Path) -> None:
    assert MultiAgentOffPolicyAlgorithm.saved_model_keys == ("n_agents",)
    assert MADDPG.saved_model_keys == MATD3.saved_model_keys == ("n_agents", "cvar_alpha")
    env = make_multiagent_vec_env(lambda **kwargs: TargetReachEnv(), n_envs=1)
    saved = tmp_path / "model.zip"
    MADDPG("MlpPolicy", env, buffer_size=50, learning_starts=5, batch_size=4, device="cpu").save(saved)
    no_alpha = _without(saved, tmp_path / "no_alpha.zip", "cvar_alpha")
    # An algorithm without a risk level would need only n_agents: the file is a model of the library for it ...
    assert read_maddpg_data(no_alpha, ("n_agents",), required_keys=("n_agents",)) == {"n_agents": 2}
    # ... and not for MADDPG, whose models all save cvar_alpha
    with pytest.raises(ValueError, match="no_alpha.zip is not a MADDPG model"):
        MADDPG.load(no_alpha)
    no_agents = _without(saved, tmp_path / "no_agents.zip", "n_agents")
    with pytest.raises(ValueError, match="is not a MADDPG model"):
        read_maddpg_data(no_agents, required_keys=MultiAgentOffPolicyAlgorithm.saved_model_keys)
