"""Bad values that used to pass: each is refused where it enters, with one line naming it and what is accepted."""

import warnings
from pathlib import Path

import numpy as np
import pytest
from cli_testing import fails_with
from maddpg_test_envs import TargetReachEnv
from stable_baselines3.common.noise import NormalActionNoise, VectorizedActionNoise

from sb3_maddpg import MADDPG, make_multiagent_vec_env
from sb3_maddpg.common import host_memory

ROOT = Path(__file__).resolve().parent.parent
CONFIG = str(ROOT / "zoo_configs" / "maddpg.yml")
ENV = "uav_coverage_fast_v0"
TINY = ["--env", ENV, "-conf", CONFIG, "--env-kwargs", "obs_size:16", "max_cycles:10", "n_uavs:2", "--seed", "0"]


def _env(n_envs: int = 1, env_class=TargetReachEnv):
    return make_multiagent_vec_env(lambda **kwargs: env_class(), n_envs=n_envs)


def _model(env=None, **kwargs) -> MADDPG:
    kwargs = {"buffer_size": 100, "learning_starts": 4, "batch_size": 4, "device": "cpu", "seed": 0, **kwargs}
    return MADDPG("MlpPolicy", env if env is not None else _env(), **kwargs)


# ---------------------------------------------------------------------------------------------------------------------
# YAML values, memory and the evaluation env: refused before training, with no run folder left
# ---------------------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("params", "message"),
    [
        (["n_timesteps:-1"], "n_timesteps must be a positive number of timesteps, got -1"),
        (["n_timesteps:0"], "n_timesteps must be a positive number of timesteps, got 0"),
        (["n_envs:0"], "n_envs must be an integer >= 1 (environment copies), got 0"),
        (["learning_rate:'fast'"], "learning_rate must be a number or 'lin_<initial value>'"),
        (["gradient_steps:0"], "gradient_steps must be an integer >= 1, or -1"),
        (["buffer_size:10**13"], "buffer_size=10000000000000: the replay buffer cannot be allocated"),
    ],
    ids=["n_timesteps-negative", "n_timesteps-zero", "n_envs-zero", "learning_rate-word", "gradient_steps-zero", "memory"],
)
def test_a_bad_yaml_value_is_one_line_naming_the_key(params, message, tmp_path: Path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    err = fails_with(["train", *TINY, "-params", *params], capsys)
    assert message in err
    assert not any((tmp_path / "logs" / "maddpg").glob(f"{ENV}_*"))


def test_a_mismatched_evaluation_env_is_refused_before_training(tmp_path: Path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    argv = ["train", *TINY, "-n", "1000", "--eval-freq", "500", "--eval-env-kwargs", "obs_size:16", "n_uavs:3"]
    err = fails_with(argv, capsys)
    assert "--eval-env-kwargs: the evaluation env has 3 agents" in err and "the model trains on 2 agents" in err
    assert not any((tmp_path / "logs" / "maddpg").glob(f"{ENV}_*"))


def test_a_buffer_larger_than_the_free_memory_is_warned_without_psutil(monkeypatch) -> None:
    monkeypatch.setattr(host_memory, "psutil", None)
    monkeypatch.setattr(host_memory, "available_host_memory", lambda: 1000)
    with pytest.warns(UserWarning, match="not have apparently enough memory"):
        _model(buffer_size=10_000)


# ---------------------------------------------------------------------------------------------------------------------
# learn(), action noise
# ---------------------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"total_timesteps": 0}, "total_timesteps must be an integer >= 1, got 0"),
        ({"total_timesteps": -5}, "total_timesteps must be an integer >= 1, got -5"),
        ({"total_timesteps": 1.5}, "total_timesteps must be an integer >= 1, got 1.5"),
        ({"total_timesteps": 10, "log_interval": 0}, r"log_interval \(None: no logging\) must be an integer >= 1, got 0"),
    ],
)
def test_learn_refuses_a_bad_budget_or_log_interval(kwargs, message) -> None:
    with pytest.raises(ValueError, match=message):
        _model().learn(**kwargs)


def test_a_noise_of_another_shape_or_row_count_is_refused() -> None:
    with pytest.raises(ValueError, match=r"action_noise has shape \(1,\), but each agent's action has shape \(2,\)"):
        _model(action_noise=NormalActionNoise(np.zeros(1), np.ones(1)))
    with pytest.raises(ValueError, match=r"action_noise has shape \(3,\)"):
        _model(action_noise=NormalActionNoise(np.zeros(3), np.ones(3)))
    rows = VectorizedActionNoise(NormalActionNoise(np.zeros(2), np.ones(2)), n_envs=3)
    with pytest.raises(ValueError, match="VectorizedActionNoise for 3 rows, but the VecEnv has 4 rows"):
        _model(env=_env(n_envs=2), action_noise=rows)


# ---------------------------------------------------------------------------------------------------------------------
# Non-finite data
# ---------------------------------------------------------------------------------------------------------------------
class NaNRewardEnv(TargetReachEnv):
    """The target-reach task whose second agent gets a NaN reward at its third step."""

    def step(self, actions):
        observations, rewards, terminations, truncations, infos = super().step(actions)
        self._steps = getattr(self, "_steps", 0) + 1
        if self._steps == 3:
            rewards = {**rewards, "agent_1": float("nan")}
        return observations, rewards, terminations, truncations, infos


def test_a_nan_reward_is_refused_where_it_enters_the_buffer_naming_agent_and_step() -> None:
    model = _model(env=_env(env_class=NaNRewardEnv))
    with pytest.raises(ValueError, match=r"non-finite reward \(nan\) for agent 'agent_1' of env copy 0 at timestep 3"):
        model.learn(20)
    assert all(np.isfinite(parameter.detach().numpy()).all() for parameter in model.policy.parameters())


def test_predict_refuses_nan_and_float_images() -> None:
    model = _model()
    observation = np.zeros((2, 4), dtype=np.float32)
    observation[1, 2] = np.nan
    with pytest.raises(ValueError, match=r"predict: the observations hold NaN or infinite values \(nan at index \(1, 2\)\)"):
        model.predict(observation)
    from sb3_maddpg_envs import uav_coverage_v0

    venv = make_multiagent_vec_env(uav_coverage_v0.parallel_env, n_envs=1, env_kwargs=dict(obs_size=16, n_uavs=2))
    images = MADDPG("CnnPolicy", venv, buffer_size=10, device="cpu")
    observations = venv.reset()
    images.predict(observations)
    with pytest.raises(TypeError, match="the observations are float32, but the model's observation space is uint8"):
        images.predict(observations.astype(np.float32) / 255)


# ---------------------------------------------------------------------------------------------------------------------
# plot on a damaged monitor.csv
# ---------------------------------------------------------------------------------------------------------------------
def test_plot_skips_interleaved_monitor_lines_and_says_how_many(tmp_path: Path) -> None:
    from sb3_maddpg.evaluation.figures import load_monitor_series

    monitor = tmp_path / "monitor.csv"
    monitor.write_text('#{"t_start": 0}\nr,l,t\n1.0,5,0.1\n2.0,5,0.21.0,5\n3.0,5,0.3\n4.0,5,#{"t_start": 1}\n')
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        series = load_monitor_series(monitor)
    assert series["r"].tolist() == [1.0, 3.0]
    assert any("skipped 2 malformed line(s) of 4" in str(warning.message) for warning in caught)
