"""The one-run GPU check (benchmarks/gpu_check.sh) works end to end as a CPU dry run, so it is ready for a GPU."""

import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def test_gpu_check_dry_run_on_cpu(tmp_path):
    env = dict(os.environ, PYTHON=sys.executable, OUT=str(tmp_path))
    result = subprocess.run(
        ["bash", str(REPO / "benchmarks" / "gpu_check.sh"), "--device", "cpu"],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    report = (tmp_path / "report.md").read_text()
    for needed in ("per-agent reference", "| cpu | eager |", "graph (code path, not recorded)", "timesteps_per_s", "passed"):
        assert needed in report, needed
    assert "failed" not in report.split("## CUDA tests")[1]
    assert any((tmp_path / "tensorboard").rglob("events.out.tfevents.*"))
