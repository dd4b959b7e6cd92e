#!/usr/bin/env bash
# MADDPG (or MATD3) on one of MPE2's tasks through the command line and its zoo_configs entry, three seeds, then the
# team return (and, with competing teams, each team's) of each model and of uniformly random actions on 20 episodes
# (experiments/team_return.py, reset seeds 1000-1019).
# Usage: ENV_ID=simple_speaker_listener_discrete_v4 OUT=runs/mpe CORE=1 STEPS=25000 bash experiments/mpe_task.sh
# ENV_ID: a registered MPE2 id (default simple_spread_discrete_v3); PARAMS (e.g. "actor_reg:0.001 groups:'teams'")
# overrides entries of the YAML config, as RL Zoo's -params; ENV_KWARGS (e.g. "N:20") env arguments, for training and
# evaluation alike; TAG names the run's files (default: the env id).
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
read -r -a ENV_KWARGS <<< "${ENV_KWARGS:-}"
TAG=${TAG:-$ENV_ID}
mkdir -p "$OUT"
run() { echo "$(date -u +%H:%M:%S) $*" >&2; nice -n 10 taskset -c "$CORE" "$@"; }
# The evaluation's env arguments: the registered action mode, 25-step episodes and ENV_KWARGS, as JSON
eval_kwargs=$("$PY" - "$ENV_ID" ${ENV_KWARGS[@]+"${ENV_KWARGS[@]}"} <<'PY'
import json, sys

from sb3_maddpg.zoo.command_line import parse_key_values
from sb3_maddpg.zoo.registry import MULTIAGENT_ENVS

kwargs = {"continuous_actions": MULTIAGENT_ENVS[sys.argv[1]].kwargs["continuous_actions"], "max_cycles": 25}
print(json.dumps({**kwargs, **(parse_key_values(sys.argv[2:], "ENV_KWARGS") or {})}))
PY
)

for seed in $SEEDS; do
    start=$(date +%s)
    run "$PY" -m sb3_maddpg train --algo "$ALGO" --env "$ENV_ID" --seed "$seed" -n "$STEPS" -f "$OUT/logs_$TAG" \
        -tb "$OUT/tensorboard" --eval-freq -1 ${PARAMS[@]+-params "${PARAMS[@]}"} \
        ${ENV_KWARGS[@]+--env-kwargs "${ENV_KWARGS[@]}"} >"$OUT/train_${ALGO}_${TAG}_s$seed.log" 2>&1
    echo "seed $seed: $(($(date +%s) - start)) s" >&2
done
run "$PY" experiments/team_return.py --env "$ENV_ID" --env-kwargs "$eval_kwargs" \
    --episodes 20 --seed 1000 "$OUT/logs_$TAG/$ALGO/${ENV_ID}"_*/"$ENV_ID".zip >"$OUT/team_returns_${TAG}.jsonl"
cat "$OUT/team_returns_${TAG}.jsonl"
