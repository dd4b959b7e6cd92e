#!/usr/bin/env bash
# MATD3 against MADDPG, three seeds each, through the command line and the zoo_configs entries:
#   - uav_coverage_cpu_v1: MATD3 (zoo_configs/matd3.yml: MADDPG's config with twin critics), 28 000 timesteps,
#     evaluated on 20 random-start episodes (seeds 10 000-10 019, the episodes of docs/results.md's MADDPG rows);
#   - simple_spread_v3: both algorithms, $SPREAD_STEPS timesteps, team return on 20 episodes (experiments/team_return.py).
# Usage: OUT=runs/matd3 CORE=0 bash experiments/matd3_vs_maddpg.sh [uav|spread|all]
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-runs/matd3}
PY=${PY:-.venv/bin/python}
CORE=${CORE:-0}
SEEDS=${SEEDS:-"0 1 2"}
SPREAD_STEPS=${SPREAD_STEPS:-50000}
what=${1:-all}
mkdir -p "$OUT"
run() { echo "$(date -u +%H:%M:%S) $*" >&2; taskset -c "$CORE" "$@"; }

if [ "$what" = spread ] || [ "$what" = all ]; then
    for seed in $SEEDS; do
        for algo in maddpg matd3; do
            run "$PY" -m sb3_maddpg train --algo "$algo" --env simple_spread_v3 --seed "$seed" -n "$SPREAD_STEPS" \
                -f "$OUT/logs" -tb "$OUT/tensorboard" --eval-freq -1 >"$OUT/spread_${algo}_s$seed.log" 2>&1
        done
    done
    run "$PY" experiments/team_return.py --env simple_spread_v3 --episodes 20 --seed 1000 \
        "$OUT"/logs/*/simple_spread_v3_*/simple_spread_v3.zip >"$OUT/spread_team_returns.jsonl"
fi
if [ "$what" = uav ] || [ "$what" = all ]; then
    for seed in $SEEDS; do
        run "$PY" -m sb3_maddpg train --algo matd3 --env uav_coverage_cpu_v1 --seed "$seed" \
            -f "$OUT/logs" -tb "$OUT/tensorboard" --eval-freq -1 >"$OUT/uav_matd3_s$seed.log" 2>&1
    done
    for run_dir in "$OUT"/logs/matd3/uav_coverage_cpu_v1_*; do
        run "$PY" -m sb3_maddpg evaluate --model "$run_dir/uav_coverage_cpu_v1.zip" --episodes 20 --seed 10000 \
            --no-gif --out "$OUT/eval/$(basename "$run_dir")" >"$OUT/eval_$(basename "$run_dir").log" 2>&1
    done
fi
