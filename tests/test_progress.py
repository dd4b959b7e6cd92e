"""The progress bar of evaluate and select-checkpoint: drawn on a terminal, never with --quiet or without a terminal."""

import io
import os
import subprocess
import sys
from pathlib import Path

import pytest

from sb3_maddpg import MADDPG, make_multiagent_vec_env
from sb3_maddpg.__main__ import main
from sb3_maddpg.evaluation.checkpoints import select_checkpoint
from sb3_maddpg.evaluation.progress import episode_progress, wants_progress_bar
from sb3_maddpg_envs import uav_coverage_v0

ENV = "uav_coverage_fast_v0"
KWARGS = {"obs_size": 16, "max_cycles": 5, "n_uavs": 2}
# Two baselines (random, greedy_static), two episodes each
EVALUATE = ["evaluate", "--baselines-only", "--env", ENV, "--env-kwargs", *(f"{k}:{v}" for k, v in KWARGS.items())]
EVALUATE += ["--episodes", "2", "--no-gif", "--verbose", "0"]


class Terminal(io.StringIO):
    """A stderr that says it is a terminal."""

    def isatty(self) -> bool:
        return True


def test_wants_a_bar_on_a_terminal_only_and_not_when_quiet() -> None:
    assert wants_progress_bar(stream=Terminal())
    assert not wants_progress_bar(quiet=True, stream=Terminal())
    assert not wants_progress_bar(stream=io.StringIO())


@pytest.mark.parametrize(
    ("stderr", "quiet", "shown"), [(Terminal, False, True), (Terminal, True, False), (io.StringIO, False, False)]
)
def test_evaluate(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, stderr: type, quiet: bool, shown: bool) -> None:
    stream = stderr()
    monkeypatch.setattr(sys, "stderr", stream)
    main([*EVALUATE, "--out", str(tmp_path), *(["--quiet"] if quiet else [])])
    text = stream.getvalue()
    assert ("evaluate: 100%" in text and "4/4" in text) is shown
    assert ("episode" in text) is shown


def test_a_real_terminal_gets_the_bar_with_the_time_left(tmp_path: Path) -> None:
    import fcntl
    import struct
    import termios

    leader, follower = os.openpty()
    # A terminal 100 columns wide (a new pseudo-terminal has 0, where tqdm has no room to draw)
    fcntl.ioctl(follower, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))
    try:
        process = subprocess.Popen(
            [sys.executable, "-m", "sb3_maddpg", *EVALUATE, "--out", str(tmp_path)],
            stdout=subprocess.DEVNULL,
            stderr=follower,
        )
        os.close(follower)
        chunks = []
        while True:
            try:
                chunk = os.read(leader, 4096)
            except OSError:  # the terminal closed with the process
                break
            if not chunk:
                break
            chunks.append(chunk)
        assert process.wait(timeout=120) == 0
    finally:
        os.close(leader)
    text = b"".join(chunks).decode(errors="replace")
    assert "evaluate: 100%" in text and "4/4" in text
    # tqdm's elapsed<remaining
    assert "<00:00" in text


def test_select_checkpoint_counts_every_episode(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    env = make_multiagent_vec_env(uav_coverage_v0.parallel_env, seed=0, env_kwargs=KWARGS)
    model = MADDPG("CnnPolicy", env, buffer_size=20, learning_starts=50, batch_size=4, seed=0)
    paths = [tmp_path / "rl_model_5_steps.zip", tmp_path / f"{ENV}.zip"]
    for path in paths:
        model.save(path)
    stream = Terminal()
    monkeypatch.setattr(sys, "stderr", stream)
    select_checkpoint(paths, validation_episodes=2, test_episodes=1, env_id=ENV, env_kwargs=KWARGS, progress=True)
    # 2 models x 2 validation episodes, then the final and the chosen model on 1 test episode each
    assert "select-checkpoint: 100%" in stream.getvalue() and "6/6" in stream.getvalue()


def test_a_bar_needs_a_positive_number_of_episodes() -> None:
    with pytest.raises(ValueError, match="positive number of episodes"), episode_progress(0, "evaluate", True):
        pass
