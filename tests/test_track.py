"""
``train --track``: RL Zoo's Weights & Biases tracking works with this library's algorithms, checked offline
(``WANDB_MODE=offline``: the run is written to disk, to be uploaded later with ``wandb sync``).
"""

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
ENV = "uav_coverage_fast_v0"


def test_train_track_records_the_run_and_its_scalars_offline(tmp_path: Path) -> None:
    if os.environ.get("CI", "").lower() == "true":
        import wandb  # noqa: F401 (CI installs the track extra: there this test runs)
    else:
        pytest.importorskip("wandb", reason='the track extra is not installed: pip install -e ".[track]"')
    # A fresh process: wandb patches TensorBoard's writers and Gymnasium's video recorder for the rest of the process
    env = {**os.environ, "WANDB_MODE": "offline", "WANDB_SILENT": "true", "PYTHONPATH": str(ROOT)}
    env.update({name: str(tmp_path / "wandb_home") for name in ("WANDB_CONFIG_DIR", "WANDB_CACHE_DIR", "WANDB_DATA_DIR")})
    env["WANDB_DIR"] = str(tmp_path)
    tiny = ["--env-kwargs", "obs_size:16", "max_cycles:20", "n_uavs:2", "-params", "learning_starts:100", "buffer_size:100"]
    command = [sys.executable, "-m", "sb3_maddpg", "train", "--env", ENV, *tiny, "-n", "60", "--seed", "0"]
    command += ["--num-threads", "1", "--track", "--wandb-project-name", "sb3_maddpg-test", "-tags", "offline-test"]
    result = subprocess.run(command, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-3000:]

    (run_file,) = tmp_path.glob("wandb/offline-run-*/run-*.wandb")
    record = run_file.read_bytes()
    # The run's config (RL Zoo's arguments) and the TensorBoard scalars W&B copies from SB3's logger, ours included
    for text in ("sb3_maddpg-test", "maddpg", ENV, "offline-test", "rollout/ep_rew_uav_0", "rollout/coverage"):
        assert text.encode() in record, text
    # RL Zoo points TensorBoard at runs/<run name>, which W&B reads
    assert list(tmp_path.glob(f"runs/{ENV}__maddpg__0__*/**/events.out.tfevents.*"))
    assert (tmp_path / "logs" / "maddpg" / f"{ENV}_1" / f"{ENV}.zip").is_file()
