#!/usr/bin/env bash
# README command (1): install, then train MADDPG on the CPU variant of the UAV coverage task (uav_coverage_cpu_v1:
# version 1 of the task with 16 x 16 observations, 300-step episodes) with RL Zoo, evaluate it against the two
# baselines and draw the report's figures. About 20 minutes on one CPU core; -P shows a progress bar in timesteps
# with the time left.
# Everything is written under runs/quickstart/ (override with OUT=...):
#   logs/maddpg/uav_coverage_cpu_v1_1/   the model, checkpoints, monitor.csv, the run's config
#   tensorboard/                          TensorBoard logs: tensorboard --logdir runs/quickstart/tensorboard
#   evaluation/                           results.csv, results.json, episodes.csv, results.md and figures/
#   training_figures/                     fairness vs coverage / energy efficiency and metrics vs episode
set -euo pipefail
cd "$(dirname "$0")/.."
venv="${VENV:-.venv}"
out="${OUT:-runs/quickstart}"
seed="${SEED:-0}"

bash scripts/install.sh "$venv"
py="$venv/bin/python"

rm -rf "$out"
mkdir -p "$out"
"$py" -m sb3_maddpg train --algo maddpg --env uav_coverage_cpu_v1 -conf zoo_configs/maddpg.yml \
    -f "$out/logs" -tb "$out/tensorboard" --seed "$seed" --eval-freq 4000 --eval-episodes 2 --save-freq 4000 --num-threads 2 -P
run="$out/logs/maddpg/uav_coverage_cpu_v1_1"
"$py" -m sb3_maddpg evaluate --model "$run/uav_coverage_cpu_v1.zip" --episodes 10 --out "$out/evaluation"
"$py" -m sb3_maddpg plot --log "$run" --out "$out/training_figures"

echo
echo "Model:       $run/uav_coverage_cpu_v1.zip"
echo "TensorBoard: $venv/bin/tensorboard --logdir $out/tensorboard"
echo "Results:     $out/evaluation/results.md (CSV and JSON beside it), figures in $out/evaluation/figures"
