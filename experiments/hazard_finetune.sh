#!/usr/bin/env bash
# The hazardous task from a calm start: a team trained on uav_coverage_cpu_v1 (no hazards) continues on
# uav_coverage_hazard_cpu_v1 with one CVaR level, through the command line's -i (RL Zoo's --trained-agent: the
# hazardous entry's hyperparameters, a fresh replay buffer, the saved noise schedule), then 20 evaluation episodes
# (reset seeds 1000-1019) with the hazard counts (docs/results.md, "A quantile critic that learns as fast ...").
# MEAN_LOSS=squared fits the critics' mean with the squared TD error (MADDPG's mean_loss; default: the entry's, Huber).
# ENV_KWARGS changes the hazards (KEY:VALUE items of --env-kwargs, kept in the run's args.yml, which evaluate reads)
# and TAG names the variant in the file names. ENV_ID picks the task (default uav_coverage_hazard_cpu_v1; e.g.
# uav_coverage_storm_cpu_v1), PARAMS adds -params items (e.g. mean_anchored_quantiles:False for a 1-quantile model,
# whose policy, as every loaded model's, keeps its saved policy_kwargs), EPISODES the evaluation episodes (20).
# Usage: MODEL=runs/q25head/fast_b32_q25_anchor_s0.zip ALPHA=0.5 SEED=0 CORE=1 STEPS=8000 OUT=runs/hzft \
#        [MEAN_LOSS=squared] [ENV_KWARGS="crash_energy:0 crash_ground_steps:20 grounded_penalty:0.5" TAG=ground] \
#        bash experiments/hazard_finetune.sh
set -euo pipefail
cd "$(dirname "$0")/.."
MODEL=${MODEL:?a model trained on uav_coverage_cpu_v1 (.zip)}
ALPHA=${ALPHA:-1.0}
SEED=${SEED:-0}
CORE=${CORE:-0}
STEPS=${STEPS:-8000}
EPISODES=${EPISODES:-20}
OUT=${OUT:-runs/hzft}
PY=${PY:-.venv/bin/python}
ENV_ID=${ENV_ID:-uav_coverage_hazard_cpu_v1}
PARAMS=${PARAMS:-}
MEAN_LOSS=${MEAN_LOSS:-}
ENV_KWARGS=${ENV_KWARGS:-}
TAG="a${ALPHA}${MEAN_LOSS:+_$MEAN_LOSS}${TAG:+_$TAG}_s${SEED}"
mkdir -p "$OUT"
run() { echo "$(date -u +%H:%M:%S) $*" >&2; nice -n 10 taskset -c "$CORE" "$@"; }
run "$PY" -m sb3_maddpg train --algo maddpg --env "$ENV_ID" -i "$MODEL" -n "$STEPS" --seed "$SEED" \
    ${ENV_KWARGS:+--env-kwargs $ENV_KWARGS} -params "cvar_alpha:$ALPHA" ${MEAN_LOSS:+"mean_loss:'$MEAN_LOSS'"} $PARAMS -f "$OUT/logs_$TAG" --eval-freq -1 >"$OUT/train_$TAG.log" 2>&1
run "$PY" -m sb3_maddpg evaluate --model "$OUT/logs_$TAG/maddpg/${ENV_ID}_1/$ENV_ID.zip" --episodes "$EPISODES" \
    --seed 1000 --baselines random --no-gif --out "$OUT/eval_$TAG" >"$OUT/eval_$TAG.log" 2>&1
grep -A3 "^| method" "$OUT/eval_$TAG.log"
