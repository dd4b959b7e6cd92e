"""A model refuses a team other than its own, and a file that is not an intact MADDPG model says so."""

import io
import zipfile
from pathlib import Path

import numpy as np
import pytest
from stable_baselines3.common.evaluation import evaluate_policy

from sb3_maddpg import MADDPG, make_multiagent_vec_env
from sb3_maddpg_envs import uav_coverage_v0

ENV_KWARGS = dict(obs_size=16, max_cycles=5)


def uav_env(n_uavs: int, n_envs: int = 1):
    return make_multiagent_vec_env(
        uav_coverage_v0.parallel_env, n_envs=n_envs, seed=0, env_kwargs=dict(ENV_KWARGS, n_uavs=n_uavs)
    )


def tiny_model(env) -> MADDPG:
    return MADDPG("CnnPolicy", env, buffer_size=100, device="cpu", policy_kwargs=dict(n_quantiles=2, net_arch=[8]))


@pytest.fixture(scope="module")
def two_agent_model_path(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("team") / "two_uavs.zip"
    tiny_model(uav_env(2)).save(path)
    return path


TEAM_MESSAGE = r"acts for a team of 2 agents \(uav_0, uav_1\).*team of 4 agents \(uav_0, uav_1, uav_2, uav_3\)"


def test_predict_refuses_observations_of_another_team(two_agent_model_path: Path) -> None:
    model = MADDPG.load(two_agent_model_path, device="cpu")
    four = uav_env(4)
    with pytest.raises(ValueError, match=TEAM_MESSAGE):
        model.predict(four.reset(), deterministic=True)
    # the model's own team, in one copy or two, still works; so do plain arrays (nothing to check)
    actions, _ = model.predict(uav_env(2, n_envs=2).reset(), deterministic=True)
    assert actions.shape == (4, 2)
    assert model.predict(np.zeros((4, 3, 16, 16), np.uint8))[0].shape == (4, 2)


def test_evaluate_policy_refuses_another_team(two_agent_model_path: Path) -> None:
    model = MADDPG.load(two_agent_model_path, device="cpu")
    with pytest.raises(ValueError, match=TEAM_MESSAGE):
        evaluate_policy(model, uav_env(4), n_eval_episodes=1, warn=False)
    mean_reward, _ = evaluate_policy(model, uav_env(2), n_eval_episodes=1, warn=False)
    assert np.isfinite(mean_reward)


def test_load_and_set_env_refuse_another_team(two_agent_model_path: Path) -> None:
    with pytest.raises(ValueError, match=TEAM_MESSAGE):
        MADDPG.load(two_agent_model_path, env=uav_env(4), device="cpu")
    model = MADDPG.load(two_agent_model_path, env=uav_env(2), device="cpu")
    with pytest.raises(ValueError, match=TEAM_MESSAGE):
        model.set_env(uav_env(4))


def test_another_team_with_the_same_number_of_agents_is_refused(two_agent_model_path: Path) -> None:
    from maddpg_test_envs import TargetReachEnv

    model = MADDPG.load(two_agent_model_path, device="cpu")
    other = make_multiagent_vec_env(TargetReachEnv, env_kwargs=dict(n_agents=2))
    with pytest.raises(ValueError, match=r"team of 2 agents \(uav_0, uav_1\).*team of 2 agents \(agent_0, agent_1\)"):
        model.predict(other.reset())


def test_enjoy_refuses_a_model_on_another_team(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys) -> None:
    """RL Zoo's enjoy loop gets the one-line message (from the command's check, or from predict)."""
    from sb3_maddpg.__main__ import main

    run = tmp_path / "logs" / "maddpg" / "uav_coverage_fast_v0_1"
    run.mkdir(parents=True)
    tiny_model(uav_env(2)).save(run / "uav_coverage_fast_v0.zip")
    monkeypatch.chdir(tmp_path)
    for kwargs, expected in (
        (["n_uavs:4"], ("trained with 2 agents", "has 4 agents")),
        (["n_uavs:2", "obs_size:32"], ("observations Box(0, 255, (3, 16, 16), uint8)", "Box(0, 255, (3, 32, 32), uint8)")),
    ):
        with pytest.raises(SystemExit) as exit_info:
            main(["enjoy", "--env", "uav_coverage_fast_v0", "-n", "5", "--no-render", "--env-kwargs", "max_cycles:5", *kwargs])
        assert exit_info.value.code == 2
        err = capsys.readouterr().err
        assert err.startswith("sb3_maddpg enjoy: error:") and all(part in err for part in expected)
        assert "Traceback" not in err and len(err.strip().splitlines()) == 1


# ---------------------------------------------------------------------------------------------------------------------
# Files that are not MADDPG models, or are damaged
# ---------------------------------------------------------------------------------------------------------------------
def test_load_of_another_algorithms_zip_says_so(tmp_path: Path) -> None:
    import gymnasium as gym
    from stable_baselines3 import TD3

    TD3("MlpPolicy", gym.make("Pendulum-v1"), buffer_size=10, device="cpu").save(tmp_path / "td3.zip")
    with pytest.raises(ValueError, match=r"td3.zip is not a MADDPG model: it was saved by another algorithm .*TD3Policy"):
        MADDPG.load(tmp_path / "td3.zip")


def _rewrite_member(source: Path, target: Path, member: str, change) -> None:
    with zipfile.ZipFile(source) as archive:
        members = {name: archive.read(name) for name in archive.namelist()}
    members[member] = change(members[member])
    with zipfile.ZipFile(target, "w") as archive:
        for name, content in members.items():
            archive.writestr(name, content)


def _flip_bytes_inside(source: Path, target: Path, member: str) -> None:
    """Corrupt a member's stored bytes in place (its CRC no longer matches), as a disk or transfer error would."""
    raw = bytearray(source.read_bytes())
    with zipfile.ZipFile(source) as archive:
        info = archive.getinfo(member)
    # the local header's own name and extra-field lengths (its extra field can differ from the central directory's)
    name_length = int.from_bytes(raw[info.header_offset + 26 : info.header_offset + 28], "little")
    extra_length = int.from_bytes(raw[info.header_offset + 28 : info.header_offset + 30], "little")
    start = info.header_offset + 30 + name_length + extra_length
    for offset in range(start + 10, start + 20):
        raw[offset] ^= 0xFF
    target.write_bytes(bytes(raw))


@pytest.mark.parametrize(
    ("damage", "message"),
    [
        (lambda src, dst: _flip_bytes_inside(src, dst, "policy.pth"), r"is damaged: its member 'policy.pth' fails"),
        (lambda src, dst: _flip_bytes_inside(src, dst, "data"), r"is damaged: its member 'data' fails"),
        (lambda src, dst: _rewrite_member(src, dst, "data", lambda b: b[: len(b) // 2]), r"'data' member is not valid JSON"),
        (lambda src, dst: _rewrite_member(src, dst, "policy.pth", lambda b: b[:100]), r"is damaged or was saved by"),
        (lambda src, dst: dst.write_bytes(src.read_bytes()[:3000]), r"is damaged: it is a truncated or corrupted zip"),
        (lambda src, dst: dst.write_bytes(b"not a zip at all"), r"is not a MADDPG model: it is not a zip file"),
    ],
    ids=["member-crc", "data-crc", "data-json", "policy-truncated", "file-truncated", "not-a-zip"],
)
def test_load_of_a_damaged_zip_says_which(damage, message: str, two_agent_model_path: Path, tmp_path: Path) -> None:
    damaged = tmp_path / "damaged.zip"
    damage(two_agent_model_path, damaged)
    with pytest.raises(ValueError, match=f"damaged.zip {message}" if message.startswith("is") else message):
        MADDPG.load(damaged, device="cpu")


def test_load_from_an_open_file_is_checked_and_works(two_agent_model_path: Path) -> None:
    with open(two_agent_model_path, "rb") as file:
        assert MADDPG.load(file, device="cpu").n_agents == 2
    with pytest.raises(ValueError, match="not a MADDPG model"):
        MADDPG.load(io.BytesIO(b"nothing"), device="cpu")
