"""HParamsCallback: the run's hyperparameters and metric names read back from the TensorBoard event file."""

import glob
from pathlib import Path
from typing import Any

import pytest
from stable_baselines3.common.logger import configure
from tensorboard_testing import read_hparams

from sb3_maddpg import MADDPG, make_multiagent_vec_env
from sb3_maddpg.common.hparams import HParamsCallback, flat_hparams, hparam_value
from sb3_maddpg_envs import uav_coverage_v1

KWARGS = dict(obs_size=16, n_uavs=2, max_cycles=5)


def run(folder: Path, callback: HParamsCallback, tensorboard: bool = True) -> MADDPG:
    env = make_multiagent_vec_env(uav_coverage_v1.parallel_env, seed=0, env_kwargs=KWARGS)
    model = MADDPG("CnnPolicy", env, buffer_size=50, learning_starts=100, batch_size=4, gamma=0.9, seed=0)
    model.set_logger(configure(str(folder), ["tensorboard"] if tensorboard else ["csv"]))
    model.learn(5, callback=callback)
    return model


def test_given_hyperparameters_are_written_with_the_metric_names(tmp_path: Path) -> None:
    given = {"algo": "maddpg", "gamma": 0.9, "env_kwargs": {"n_uavs": 2, "start": "random"}, "policy_kwargs": None}
    run(tmp_path, HParamsCallback(given, metrics=("eval/mean_reward", "eval/coverage")))
    hparams, metrics = read_hparams(tmp_path)
    assert hparams == {
        "algo": "maddpg",
        "gamma": 0.9,
        "env_kwargs/n_uavs": 2.0,
        "env_kwargs/start": "random",
        "policy_kwargs": "None",
    }
    assert metrics == ["eval/mean_reward", "eval/coverage"]


def test_the_models_own_hyperparameters_by_default(tmp_path: Path) -> None:
    run(tmp_path, HParamsCallback())
    hparams, metrics = read_hparams(tmp_path)
    assert hparams["algo"] == "MADDPG"
    assert hparams["gamma"] == 0.9
    assert hparams["batch_size"] == 4.0
    assert hparams["seed"] == 0.0
    assert hparams["train_freq"] == "1 step"
    # SB3's evaluation scalars, the episode-end values the UAV env declares, the training return
    assert metrics == [
        "eval/mean_reward",
        "eval/mean_ep_length",
        "eval/coverage",
        "eval/fairness",
        "eval/energy",
        "eval/energy_efficiency",
        "rollout/ep_rew_mean",
    ]


def test_nothing_without_tensorboard(tmp_path: Path) -> None:
    run(tmp_path, HParamsCallback(), tensorboard=False)
    assert not glob.glob(str(tmp_path / "**" / "events.out.tfevents.*"), recursive=True)


def test_values_as_the_tab_stores_them() -> None:
    assert hparam_value(True) == "True"
    assert hparam_value(None) == "None"
    assert hparam_value(3) == 3 and hparam_value(0.5) == 0.5
    assert hparam_value([64, 64]) == "[64, 64]"
    assert len(hparam_value("x" * 1000)) == 200
    assert flat_hparams({"b": 1, "a": {"k": 2}}) == {"a/k": 2, "b": 1}


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: HParamsCallback(["gamma", 0.9]), "mapping"),  # type: ignore[arg-type]
        (lambda: HParamsCallback({1: 2}), "names must be strings"),  # type: ignore[dict-item]
        (lambda: HParamsCallback(metrics="eval/mean_reward"), "sequence of scalar tags"),
        (lambda: HParamsCallback(metrics=()), "sequence of scalar tags"),
    ],
)
def test_bad_input_says_what_is_accepted(call: Any, message: str) -> None:
    with pytest.raises(TypeError, match=message):
        call()
