#!/usr/bin/env bash
# The runs behind docs/results.md: each configuration with seeds 0, 1 and 2 (chosen before the runs) on
# uav_coverage_cpu_v1 with 300-step episodes, two runs at a time, each pinned to one core with one torch thread.
#   bash benchmarks/run_results.sh [CONFIG ...]     (default: every configuration below)
#   python benchmarks/results_table.py runs/results/*.jsonl --figure docs/figures/learning_curves_v1.png
set -euo pipefail
cd "$(dirname "$0")/.."
py="${PYTHON:-.venv/bin/python}"
out="${OUT:-runs/results}"
timesteps="${TIMESTEPS:-16000}"
mkdir -p "$out"

# The hyperparameters of zoo_configs/maddpg.yml's uav_coverage_cpu_v1 entry when the table was measured (the entry has
# batch_norm_eps=1e-3 in its encoder since: benchmarks/run_stability.sh has the runs with it).
v1_algo='"learning_starts": 2000, "train_freq": 1, "gamma": 0.95, "tau": 0.01, "learning_rate": 0.001,
  "actor_learning_rate": 0.0001, "critic_warmup_steps": 2000, "policy_delay": 2, "target_policy_noise": 0.2,
  "actor_reg": 0.001, "buffer_size": 100000, "batch_size": 64'
encoder='"features_extractor_kwargs": {"padding": 1, "coord_channels": true}'

declare -A ENV ALGO POLICY
ENV[alpha05]=uav_coverage_cpu_v1; ALGO[alpha05]="{$v1_algo, \"cvar_alpha\": 0.5}"; POLICY[alpha05]="{\"n_quantiles\": 25, $encoder}"
ENV[alpha1]=uav_coverage_cpu_v1;  ALGO[alpha1]="{$v1_algo, \"cvar_alpha\": 1.0}";  POLICY[alpha1]="{\"n_quantiles\": 25, $encoder}"
ENV[alpha01]=uav_coverage_cpu_v1; ALGO[alpha01]="{$v1_algo, \"cvar_alpha\": 0.1}"; POLICY[alpha01]="{\"n_quantiles\": 25, $encoder}"
ENV[classic]=uav_coverage_cpu_v1; ALGO[classic]="{$v1_algo, \"cvar_alpha\": 1.0}"; POLICY[classic]="{\"n_quantiles\": 1, $encoder}"
# v0 (the report's task at 1 pixel per cell) with the same algorithm settings
ENV[v0_alpha05]=uav_coverage_fast_v0; ALGO[v0_alpha05]="{$v1_algo, \"cvar_alpha\": 0.5}"; POLICY[v0_alpha05]="{\"n_quantiles\": 25, $encoder}"

configs=("$@")
[ ${#configs[@]} -gt 0 ] || configs=(alpha05 alpha1 alpha01 classic v0_alpha05)

jobs=()
for config in "${configs[@]}"; do
  for seed in 0 1 2; do jobs+=("$config $seed"); done
done

run() {  # run CONFIG SEED CORE
  local config=$1 seed=$2 core=$3
  taskset -c "$core" "$py" benchmarks/uav_learning.py --env "${ENV[$config]}" --env-kwargs '{"max_cycles": 300}' \
    --algo-kwargs "${ALGO[$config]}" --policy-kwargs "${POLICY[$config]}" --timesteps "$timesteps" \
    --eval-every 4000 --seed "$seed" --save "$out/${config}_s${seed}.zip" --out "$out/${config}_s${seed}.jsonl" \
    > "$out/${config}_s${seed}.log" 2>&1
}

for ((i = 0; i < ${#jobs[@]}; i += 2)); do
  read -r c0 s0 <<< "${jobs[i]}"
  run "$c0" "$s0" 0 &
  if ((i + 1 < ${#jobs[@]})); then
    read -r c1 s1 <<< "${jobs[i + 1]}"
    run "$c1" "$s1" 1 &
  fi
  wait
done
"$py" benchmarks/results_table.py "$out"/*.jsonl
