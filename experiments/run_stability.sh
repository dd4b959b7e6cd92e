#!/usr/bin/env bash
# Issue 7's stability runs: the uav_coverage_cpu_v1 settings (experiments/run_results.sh) for 32 000 timesteps,
# with one change at a time, on one core each.
#   bash experiments/run_stability.sh NAME SEED CORE 'ALGO_JSON_EXTRA' 'ENCODER_JSON_EXTRA'
# e.g. bash experiments/run_stability.sh bn_eps 0 0 '' '"batch_norm_eps": 0.001'
# ENV_EXTRA adds env parameters (e.g. ENV_EXTRA='"position_mark": "exact"'), TIMESTEPS sets the budget,
# N_QUANTILES the critic's quantiles (default 25; 1 with cvar_alpha 1 is classic MADDPG), NOISE the exploration
# noise's DecayingGaussianNoise arguments (e.g. NOISE='"final_sigma": 0.2, "decay": 0.9999'), POLICY_EXTRA more policy
# kwargs (e.g. POLICY_EXTRA='"net_arch": {"pi": [64, 64], "qf": [256, 256]}').
set -euo pipefail
cd "$(dirname "$0")/.."
py="${PYTHON:-.venv/bin/python}"
out="${OUT:-runs/results32k}"
name=$1 seed=$2 core=$3 algo_extra=${4:-} encoder_extra=${5:-}
mkdir -p "$out"
v1_algo='"learning_starts": 2000, "train_freq": 1, "gamma": 0.95, "tau": 0.01, "learning_rate": 0.001,
  "actor_learning_rate": 0.0001, "critic_warmup_steps": 2000, "policy_delay": 2, "target_policy_noise": 0.2,
  "actor_reg": 0.001, "buffer_size": 100000, "batch_size": 64, "cvar_alpha": 1.0'
encoder='"padding": 1, "coord_channels": true'
[ -n "$algo_extra" ] && v1_algo="$v1_algo, $algo_extra"
[ -n "$encoder_extra" ] && encoder="$encoder, $encoder_extra"
env_kwargs='"max_cycles": 300'
[ -n "${ENV_EXTRA:-}" ] && env_kwargs="$env_kwargs, $ENV_EXTRA"
taskset -c "$core" "$py" experiments/uav_learning.py --env uav_coverage_cpu_v1 --env-kwargs "{$env_kwargs}" \
  --algo-kwargs "{$v1_algo}" --policy-kwargs "{\"n_quantiles\": ${N_QUANTILES:-25}, \"features_extractor_kwargs\": {$encoder}${POLICY_EXTRA:+, $POLICY_EXTRA}}" \
  ${NOISE:+--noise-kwargs "{$NOISE}"} --timesteps "${TIMESTEPS:-32000}" --eval-every 4000 --seed "$seed" --save "$out/${name}_s${seed}.zip" \
  --out "$out/${name}_s${seed}.jsonl" --tensorboard-log "$out/tb_${name}_s${seed}" > "$out/${name}_s${seed}.log" 2>&1
