"""Flushing denormal floats while a model learns: the mode is on during learn() only, and restored as found."""

import pytest
import torch as th
from maddpg_test_envs import TargetReachEnv
from stable_baselines3.common.callbacks import BaseCallback

from sb3_maddpg import MADDPG, MATD3, make_multiagent_vec_env
from sb3_maddpg.common.denormals import flush_denormal_enabled, flushed_denormals


def _cpu_can_flush() -> bool:
    supported = th.set_flush_denormal(True)
    th.set_flush_denormal(False)
    return supported


pytestmark = pytest.mark.skipif(not _cpu_can_flush(), reason="this CPU cannot flush denormal floats")


@pytest.fixture(autouse=True)
def _mode_off_around_each_test():
    th.set_flush_denormal(False)
    yield
    th.set_flush_denormal(False)


class RecordFlushMode(BaseCallback):
    def __init__(self) -> None:
        super().__init__()
        self.modes: list[bool] = []

    def _on_step(self) -> bool:
        self.modes.append(flush_denormal_enabled())
        return True


def make_model(algorithm: type[MADDPG] = MADDPG, **kwargs) -> MADDPG:
    venv = make_multiagent_vec_env(TargetReachEnv, n_envs=1, seed=0, env_kwargs=dict(n_agents=2))
    return algorithm(
        "MlpPolicy", venv, buffer_size=100, learning_starts=4, batch_size=4, seed=0,
        policy_kwargs=dict(net_arch=[8]), **kwargs,
    )  # fmt: skip


def test_probe_reads_the_mode_by_hand():
    # 2e-38 is a normal float32 (the smallest is about 1.18e-38); 2e-38 * 0.05 = 1e-39 is not: kept as a denormal
    # number normally, 0 once the CPU flushes them
    assert not flush_denormal_enabled()
    assert th.tensor([2e-38]).mul_(0.05).item() == pytest.approx(1e-39, rel=1e-3)
    th.set_flush_denormal(True)
    assert flush_denormal_enabled()
    assert th.tensor([2e-38]).mul_(0.05).item() == 0.0


def test_context_turns_the_mode_on_and_restores_it():
    with flushed_denormals():
        assert flush_denormal_enabled()
    assert not flush_denormal_enabled()
    with flushed_denormals(enabled=False):
        assert not flush_denormal_enabled()
    # A mode that was on stays on, also after an error in the block
    th.set_flush_denormal(True)
    with pytest.raises(RuntimeError, match="inside"), flushed_denormals():
        raise RuntimeError("inside")
    assert flush_denormal_enabled()


def test_context_restores_the_mode_after_an_error():
    with pytest.raises(RuntimeError, match="inside"), flushed_denormals():
        raise RuntimeError("inside")
    assert not flush_denormal_enabled()


@pytest.mark.parametrize("algorithm", [MADDPG, MATD3])
def test_learn_flushes_denormals_by_default_and_restores_the_mode(algorithm):
    model = make_model(algorithm)
    assert model.flush_denormals is True
    record = RecordFlushMode()
    model.learn(12, callback=record)
    assert len(record.modes) == 12 and all(record.modes)
    assert not flush_denormal_enabled()


def test_learn_leaves_the_mode_alone_when_turned_off(tmp_path):
    model = make_model(flush_denormals=False)
    record = RecordFlushMode()
    model.learn(8, callback=record)
    assert record.modes == [False] * 8
    # A mode the user set stays on through learn()
    th.set_flush_denormal(True)
    record = RecordFlushMode()
    model.learn(4, callback=record, reset_num_timesteps=False)
    assert all(record.modes) and flush_denormal_enabled()
    # The choice is saved with the model
    model.save(tmp_path / "model.zip")
    assert MADDPG.load(tmp_path / "model.zip").flush_denormals is False


def test_flush_denormals_must_be_a_bool():
    with pytest.raises(TypeError, match="flush_denormals must be True or False, got 1"):
        make_model(flush_denormals=1)
