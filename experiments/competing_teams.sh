#!/usr/bin/env bash
# Competing teams on one of MPE2's tasks (simple_tag, simple_adversary, simple_push): train three seeds through the
# command line and the task's zoo_configs entry, then for each model, EPISODES episodes each (default 100, reset seeds
# from 1000):
#   evaluate --team ADVERSARY --opponent random   the trained adversaries against random good agents, beside random
#                                                 adversaries against the same random good agents;
#   evaluate --team GOOD --opponent MODEL         the trained good agents against the trained adversaries, beside
#                                                 random good agents against the same trained adversaries.
# Usage: ENV_ID=simple_tag_discrete_v3 OUT=runs/teams CORE=1 STEPS=50000 bash experiments/competing_teams.sh
# ADVERSARY and GOOD name the two teams (default: adversary and agent, MPE2's names).
set -euo pipefail
cd "$(dirname "$0")/.."
ENV_ID=${ENV_ID:-simple_tag_discrete_v3}
OUT=${OUT:-runs/teams}
PY=${PY:-.venv/bin/python}
CORE=${CORE:-0}
SEEDS=${SEEDS:-"0 1 2"}
STEPS=${STEPS:-50000}
EPISODES=${EPISODES:-100}
ADVERSARY=${ADVERSARY:-adversary}
GOOD=${GOOD:-agent}
mkdir -p "$OUT"
run() { echo "$(date -u +%H:%M:%S) $*" >&2; nice -n 10 taskset -c "$CORE" "$@"; }

for seed in $SEEDS; do
    run "$PY" -m sb3_maddpg train --algo maddpg --env "$ENV_ID" --seed "$seed" -n "$STEPS" -f "$OUT/logs" \
        --eval-freq -1 >"$OUT/train_${ENV_ID}_s$seed.log" 2>&1
done
for model in "$OUT"/logs/maddpg/"$ENV_ID"_*/"$ENV_ID".zip; do
    run_name=$(basename "$(dirname "$model")")
    run "$PY" -m sb3_maddpg evaluate --model "$model" --team "$ADVERSARY" --opponent random --episodes "$EPISODES" --seed 1000 \
        --no-gif --out "$OUT/eval/${run_name}_${ADVERSARY}_vs_random" >"$OUT/eval_${run_name}_${ADVERSARY}.log" 2>&1
    run "$PY" -m sb3_maddpg evaluate --model "$model" --team "$GOOD" --opponent "$model" --episodes "$EPISODES" --seed 1000 \
        --no-gif --out "$OUT/eval/${run_name}_${GOOD}_vs_trained" >"$OUT/eval_${run_name}_${GOOD}.log" 2>&1
done
"$PY" - "$OUT" "$ADVERSARY" "$GOOD" <<'PY'
import json, sys
from pathlib import Path

out, adversary, good = Path(sys.argv[1]), sys.argv[2], sys.argv[3]
for results in sorted((out / "eval").glob("*/results.json")):
    for row in json.loads(results.read_text())["summary"]:
        teams = {key[len("return_team_"):-len("_mean")]: round(value, 2) for key, value in row.items()
                 if key.startswith("return_team_") and key.endswith("_mean")}
        print(json.dumps({"evaluation": results.parent.name, "method": row["method"], **teams}))
PY
