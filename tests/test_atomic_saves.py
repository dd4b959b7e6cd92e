"""Saves are atomic: a save killed part-way leaves the previous file whole (issue: nothing lost after a crash)."""

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from sb3_maddpg import MADDPG
from sb3_maddpg.common.atomic import atomic_open, atomic_path, atomic_save, atomic_write_text, check_writable_folder

# A child process that saves a tiny model and its replay buffer to the same two paths again and again, and prints
# "saved" after the first complete pair.
SAVE_LOOP = textwrap.dedent(
    """
    import signal
    import sys
    # A shell starts background jobs with SIGINT ignored, and a child inherits that: Python then never raises
    # KeyboardInterrupt. Ctrl-C reaches a foreground process, so the child takes Python's own handler back.
    signal.signal(signal.SIGINT, signal.default_int_handler)
    import torch as th
    th.set_num_threads(1)
    from sb3_maddpg import MADDPG, make_multiagent_vec_env
    from sb3_maddpg_envs import uav_coverage_v0

    env = make_multiagent_vec_env(
        uav_coverage_v0.parallel_env, seed=0, env_kwargs=dict(obs_size=16, max_cycles=5, n_uavs=2)
    )
    model = MADDPG("CnnPolicy", env, buffer_size=2000, learning_starts=5, batch_size=4, seed=0, device="cpu",
                   policy_kwargs=dict(n_quantiles=2, net_arch=[8]))
    model.learn(10)
    model.save(sys.argv[1])
    model.save_replay_buffer(sys.argv[2])
    print("saved", flush=True)
    while True:
        model.save(sys.argv[1])
        model.save_replay_buffer(sys.argv[2])
    """
)


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGINT], ids=["SIGKILL", "SIGINT"])
def test_killed_while_saving_in_a_loop_leaves_loadable_files(sig: signal.Signals, tmp_path: Path) -> None:
    model_path, buffer_path = tmp_path / "model.zip", tmp_path / "buffer.pkl"
    rng = np.random.default_rng(int(sig))
    for attempt in range(1):
        child = subprocess.Popen(
            [sys.executable, "-c", SAVE_LOOP, str(model_path), str(buffer_path)],
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
        )
        try:
            assert child.stdout is not None and child.stdout.readline().strip() == "saved"
            # somewhere inside one of the saves that follow (a save of this model takes a few milliseconds)
            time.sleep(0.05 + float(rng.uniform(0.0, 0.3)))
            child.send_signal(sig)
            child.wait(timeout=60)
        finally:
            if child.poll() is None:
                child.kill()
                child.wait()
        model = MADDPG.load(model_path, device="cpu")
        assert model.num_timesteps == 10, attempt
        model.load_replay_buffer(buffer_path)
        assert model.replay_buffer is not None and model.replay_buffer.pos == 10
    if sig == signal.SIGINT:
        # Ctrl-C ends the save through KeyboardInterrupt: its temporary file is removed
        assert sorted(path.name for path in tmp_path.iterdir()) == ["buffer.pkl", "model.zip"]


class Interrupted(Exception):
    pass


def _fail_after_writing(file) -> None:
    file.write(b"partial")
    raise Interrupted


@pytest.mark.parametrize(
    "write",
    [
        lambda path: atomic_save(_fail_after_writing, path),
        lambda path: _fail_inside_atomic_open(path),
        lambda path: atomic_write_text(path, _raise()),
    ],
    ids=["atomic_save", "atomic_open", "atomic_write_text"],
)
def test_a_write_that_fails_keeps_the_previous_file(write, tmp_path: Path) -> None:
    path = tmp_path / "results.json"
    path.write_text("previous")
    with pytest.raises(Interrupted):
        write(path)
    assert path.read_text() == "previous"


def _raise() -> str:
    raise Interrupted


def _fail_inside_atomic_open(path: Path) -> None:
    with atomic_open(path) as file:
        _fail_after_writing(file)


def test_a_failed_write_leaves_no_temporary_file(tmp_path: Path) -> None:
    path = tmp_path / "figure.png"
    with pytest.raises(Interrupted), atomic_path(path) as temporary:
        assert temporary.suffix == ".png" and temporary.parent == tmp_path
        temporary.write_bytes(b"partial")
        raise Interrupted
    assert list(tmp_path.iterdir()) == []


def test_model_save_follows_sb3s_path_rules(tmp_path: Path) -> None:
    from sb3_maddpg import make_multiagent_vec_env
    from sb3_maddpg_envs import uav_coverage_v0

    env = make_multiagent_vec_env(uav_coverage_v0.parallel_env, env_kwargs=dict(obs_size=16, max_cycles=5, n_uavs=2))
    model = MADDPG("CnnPolicy", env, buffer_size=100, device="cpu", policy_kwargs=dict(n_quantiles=2, net_arch=[8]))
    model.save(tmp_path / "sub" / "model")  # parent created, .zip added
    model.save_replay_buffer(tmp_path / "sub" / "buffer")  # .pkl added
    assert sorted(os.listdir(tmp_path / "sub")) == ["buffer.pkl", "model.zip"]
    assert MADDPG.load(tmp_path / "sub" / "model", device="cpu").n_agents == 2


def test_writable_folder_check(tmp_path: Path) -> None:
    check_writable_folder(tmp_path / "new" / "deeper", "--out")
    assert not (tmp_path / "new").exists()  # nothing created
    (tmp_path / "file").write_text("x")
    with pytest.raises(ValueError, match=r"--out: cannot create the folder .* is not a folder"):
        check_writable_folder(tmp_path / "file" / "out", "--out")
    with pytest.raises(ValueError, match="exists and is not a folder"):
        check_writable_folder(tmp_path / "file", "--out")


@pytest.mark.parametrize("save", ["model", "replay_buffer"])
def test_a_save_keeps_the_files_mode_and_writes_through_a_symlink(save: str, tmp_path: Path) -> None:
    from maddpg_test_envs import TargetReachEnv

    from sb3_maddpg import make_multiagent_vec_env

    model = MADDPG("MlpPolicy", make_multiagent_vec_env(lambda **kwargs: TargetReachEnv(), n_envs=1), buffer_size=20)
    write = model.save if save == "model" else model.save_replay_buffer
    target = tmp_path / ("model.zip" if save == "model" else "buffer.pkl")
    write(target)
    target.chmod(0o600)
    write(target)
    assert target.stat().st_mode & 0o777 == 0o600  # not the umask's 644: the file stays private
    link = tmp_path / f"latest{target.suffix}"
    link.symlink_to(target.name)
    write(link)
    assert link.is_symlink() and os.readlink(link) == target.name  # the link stays; its target is written
    assert target.stat().st_mode & 0o777 == 0o600
