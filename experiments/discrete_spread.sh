#!/usr/bin/env bash
# MADDPG with discrete actions (Gumbel-softmax actors) on MPE2's simple_spread_v3 (Discrete(5) moves), three seeds
# through the command line and the zoo_configs entry simple_spread_discrete_v3, then the team return of each model and
# of uniformly random actions on 20 episodes (experiments/team_return.py, reset seeds 1000-1019).
# Usage: OUT=runs/discrete CORE=1 STEPS=25000 bash experiments/discrete_spread.sh
# PARAMS (e.g. "actor_reg:0.001") overrides entries of the YAML config, as RL Zoo's -params.
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-runs/discrete}
PY=${PY:-.venv/bin/python}
CORE=${CORE:-0}
SEEDS=${SEEDS:-"0 1 2"}
STEPS=${STEPS:-25000}
ALGO=${ALGO:-maddpg}
read -r -a PARAMS <<< "${PARAMS:-}"
mkdir -p "$OUT"
run() { echo "$(date -u +%H:%M:%S) $*" >&2; nice -n 10 taskset -c "$CORE" "$@"; }

for seed in $SEEDS; do
    start=$(date +%s)
    run "$PY" -m sb3_maddpg train --algo "$ALGO" --env simple_spread_discrete_v3 --seed "$seed" -n "$STEPS" \
        -f "$OUT/logs" -tb "$OUT/tensorboard" --eval-freq -1 ${PARAMS[@]+-params "${PARAMS[@]}"} >"$OUT/train_${ALGO}_s$seed.log" 2>&1
    echo "seed $seed: $(($(date +%s) - start)) s" >&2
done
run "$PY" experiments/team_return.py --env simple_spread_discrete_v3 --env-kwargs '{"max_cycles": 25}' --episodes 20 \
    --seed 1000 "$OUT"/logs/"$ALGO"/simple_spread_discrete_v3_*/simple_spread_discrete_v3.zip >"$OUT/team_returns.jsonl"
cat "$OUT/team_returns.jsonl"
