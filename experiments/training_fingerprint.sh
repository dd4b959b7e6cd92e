#!/usr/bin/env bash
# SHA-256 of every tensor of the models (networks and optimizer states) after short CLI training runs: equal before and
# after a refactoring of the algorithm means the refactoring changed nothing in training.
#   bash experiments/training_fingerprint.sh REPO OUT [ALGO]
# REPO: a checkout (e.g. `git worktree add /tmp/ref COMMIT`); OUT: a scratch folder; the python of $PY runs the
# checkout's sb3_maddpg (python -m puts the working directory first on the path).
set -euo pipefail
repo=$1; out=$2; algo=${3:-maddpg}
py=${PY:-$(pwd)/.venv/bin/python}
rm -rf "$out"; mkdir -p "$out"
cd "$repo"
# 1200 timesteps of the quick start's env with updates from timestep 300, actor updates from update 200; and 2000 of MPE
taskset -c "${CORE:-0}" "$py" -m sb3_maddpg train --algo "$algo" --env uav_coverage_cpu_v1 -n 1200 --seed 0 -f "$out/logs" \
    --eval-freq -1 -params learning_starts:300 critic_warmup_steps:200 >"$out/uav.log" 2>&1
taskset -c "${CORE:-0}" "$py" -m sb3_maddpg train --algo "$algo" --env simple_spread_v3 -n 2000 --seed 0 -f "$out/logs" \
    --eval-freq -1 -params learning_starts:500 >"$out/spread.log" 2>&1
"$py" - "$out" <<'PY'
import glob, hashlib, io, sys, zipfile

import torch


def walk(digest, value, prefix=""):
    if isinstance(value, torch.Tensor):
        digest.update(prefix.encode())
        digest.update(value.detach().contiguous().numpy().tobytes())
    elif isinstance(value, dict):
        for key in sorted(value, key=str):
            walk(digest, value[key], f"{prefix}/{key}")
    elif isinstance(value, (list, tuple)):
        for i, item in enumerate(value):
            walk(digest, item, f"{prefix}[{i}]")
    else:
        digest.update(f"{prefix}{value!r}".encode())


for path in sorted(glob.glob(sys.argv[1] + "/logs/*/*/*.zip")):
    if "rl_model" in path or "best_model" in path:
        continue
    digest = hashlib.sha256()
    with zipfile.ZipFile(path) as archive:
        for name in sorted(n for n in archive.namelist() if n.endswith(".pth")):
            walk(digest, torch.load(io.BytesIO(archive.read(name)), map_location="cpu", weights_only=False), name)
    print(path.split("/logs/")[1], digest.hexdigest()[:16])
PY
