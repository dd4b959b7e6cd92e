#!/usr/bin/env bash
# MADDPG (or MATD3) on one of MPE2's tasks through the command line and its zoo_configs entry, three seeds, then the
# team return (and, with competing teams, each team's) of each model and of uniformly random actions on 20 episodes
# (experiments/team_return.py, reset seeds 1000-1019).
# Usage: ENV_ID=simple_speaker_listener_discrete_v4 OUT=runs/mpe CORE=1 STEPS=25000 bash experiments/mpe_task.sh
# ENV_ID: a registered MPE2 id (default simple_spread_discrete_v3); PARAMS (e.g. "actor_reg:0.001") overrides entries
# of the YAML config, as RL Zoo's -params.
set -euo pipefail
cd "$(dirname "$0")/.."
ENV_ID=${ENV_ID:-simple_spread_discrete_v3}
OUT=${OUT:-runs/mpe}
PY=${PY:-.venv/bin/python}
CORE=${CORE:-0}
SEEDS=${SEEDS:-"0 1 2"}
STEPS=${STEPS:-25000}
ALGO=${ALGO:-maddpg}
read -r -a PARAMS <<< "${PARAMS:-}"
mkdir -p "$OUT"
run() { echo "$(date -u +%H:%M:%S) $*" >&2; nice -n 10 taskset -c "$CORE" "$@"; }
continuous=$("$PY" -c "from sb3_maddpg.zoo.registry import MULTIAGENT_ENVS as E; print(str(E['$ENV_ID'].kwargs['continuous_actions']).lower())")

for seed in $SEEDS; do
    start=$(date +%s)
    run "$PY" -m sb3_maddpg train --algo "$ALGO" --env "$ENV_ID" --seed "$seed" -n "$STEPS" \
        -f "$OUT/logs" -tb "$OUT/tensorboard" --eval-freq -1 ${PARAMS[@]+-params "${PARAMS[@]}"} >"$OUT/train_${ALGO}_${ENV_ID}_s$seed.log" 2>&1
    echo "seed $seed: $(($(date +%s) - start)) s" >&2
done
run "$PY" experiments/team_return.py --env "$ENV_ID" --env-kwargs "{\"continuous_actions\": $continuous, \"max_cycles\": 25}" \
    --episodes 20 --seed 1000 "$OUT"/logs/"$ALGO"/"$ENV_ID"_*/"$ENV_ID".zip >"$OUT/team_returns_${ENV_ID}.jsonl"
cat "$OUT/team_returns_${ENV_ID}.jsonl"
