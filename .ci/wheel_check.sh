#!/usr/bin/env bash
# CI: what a user who installs the wheel meets. Builds the wheel, installs it with the zoo extra into a fresh virtual
# environment outside the checkout, and from there runs a 500-timestep `train` (no -conf: the packaged
# zoo_configs/maddpg.yml), `record-video`, `enjoy`, `evaluate` and `plot` on a small uav_coverage_cpu_v1.
set -euo pipefail
cd "$(dirname "$0")/.."
python="${PYTHON:-.venv/bin/python}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

"$python" -m pip wheel -q --no-deps . -w "$work/dist"
python3 -m venv "$work/venv"
"$work/venv/bin/python" -m pip install -q --upgrade pip
"$work/venv/bin/python" -m pip install -q "torch==2.13.0"
wheel="$(ls "$work"/dist/sb3_maddpg-*.whl)"
"$work/venv/bin/python" -m pip install -q "${wheel}[zoo]"

cd "$work"
cli="$work/venv/bin/sb3_maddpg"
env_kwargs=(--env-kwargs obs_size:16 n_uavs:3 max_cycles:100)
"$cli" --version
"$cli" train --env uav_coverage_cpu_v1 -n 500 -f logs --seed 0 -P "${env_kwargs[@]}" \
    -params learning_starts:200 buffer_size:1000 batch_size:16 critic_warmup_steps:100
run=logs/maddpg/uav_coverage_cpu_v1_1
"$cli" record-video --env uav_coverage_cpu_v1 -f logs -n 100 -o videos
"$cli" enjoy --env uav_coverage_cpu_v1 -f logs -n 100 --no-render
"$cli" evaluate --model "$run/uav_coverage_cpu_v1.zip" --episodes 2 --out evaluation
"$cli" plot --log "$run" --out figures
ls videos/*.mp4 evaluation/results.md evaluation/figures/returns_vs_episode.png figures/train_returns_vs_episode.png
echo ".ci/wheel_check.sh: the wheel trains, records, evaluates and plots"
