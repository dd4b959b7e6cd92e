#!/usr/bin/env bash
# The calm teams of the redesigned storm task (issue "CVaR that pays"): the uav_coverage_storm_cpu_v2 entry at alpha 1
# trained without strikes (storm_prob 0: the zone is drawn in the observations as on the storm task, nothing strikes),
# then evaluated with the task's strikes (storm_prob 0.07) on $EPISODES episodes from reset seed $EVAL_SEED, with random
# actions beside it. Their folders (eval_calm_s<seed>) sit beside experiments/risky_reach_sweep.sh's, so that
# experiments/alpha_sweep_table.py puts the calm teams in the same table as the storm-trained ones.
# Usage: OUT=runs/storm2 CORE=1 SEEDS="0 1 2" bash experiments/storm_calm_teams.sh
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-runs/storm2}
PY=${PY:-.venv/bin/python}
CORE=${CORE:-0}
SEEDS=${SEEDS:-"0 1 2"}
EPISODES=${EPISODES:-100}
EVAL_SEED=${EVAL_SEED:-10000}
ENV_ID=uav_coverage_storm_cpu_v2
mkdir -p "$OUT"
run() { echo "$(date -u +%H:%M:%S) $*" >&2; taskset -c "$CORE" "$@"; }
for seed in $SEEDS; do
    name=calm_s$seed
    [ -s "$OUT/eval_$name/results.json" ] && continue  # done before: the runs can be resumed
    start=$SECONDS
    run "$PY" -m sb3_maddpg train --algo maddpg --env "$ENV_ID" --seed "$seed" -f "$OUT/logs/$name" --eval-freq -1 \
        --env-kwargs storm_prob:0 -params cvar_alpha:1.0 >"$OUT/train_$name.log" 2>&1
    echo $((SECONDS - start)) >"$OUT/train_$name.seconds"
    run "$PY" -m sb3_maddpg evaluate --model "$OUT/logs/$name/maddpg/${ENV_ID}_1/$ENV_ID.zip" --env-kwargs storm_prob:0.07 \
        --baselines random --episodes "$EPISODES" --seed "$EVAL_SEED" --no-gif --out "$OUT/eval_$name" >"$OUT/eval_$name.log" 2>&1
done
