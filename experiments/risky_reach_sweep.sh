#!/usr/bin/env bash
# The risk level sweep on risky_reach_v0 (envs/risky_reach_v0.py; issue "CVaR that pays"), or on ENV_ID (e.g.
# risky_hover_v0, envs/risky_hover_v0.py): MADDPG with the YAML
# entry's settings and one CVaR level per variant, each seed trained and then evaluated on $EPISODES episodes (reset
# seeds $EVAL_SEED...) with random actions beside it; experiments/alpha_sweep_table.py draws the table and the figure.
# Variants (VARIANTS, in this order by default):
#   a1       cvar_alpha 1 (the mean; the schedule is then a no-op)
#   a05      cvar_alpha 0.5, annealed from 1 over the entry's cvar_alpha_anneal_steps
#   a025     cvar_alpha 0.25, annealed (the YAML entry as shipped)
#   a01      cvar_alpha 0.1, annealed
#   a025flat cvar_alpha 0.25 from the first update (cvar_alpha_anneal_steps 0)
# EXTRA: more -params for every variant (e.g. EXTRA="quantile_kappa:0.01"); TAG prefixes the runs' names so that runs
# with other EXTRA can share $OUT.
# Usage: OUT=runs/risky CORE=0 SEEDS="0 1 2" VARIANTS="a1 a025" bash experiments/risky_reach_sweep.sh
#        python experiments/alpha_sweep_table.py runs/risky --variants a1 a05 a025 a01 a025flat --figure F.png
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-runs/risky}
PY=${PY:-.venv/bin/python}
CORE=${CORE:-0}
SEEDS=${SEEDS:-"0 1 2 3 4"}
VARIANTS=${VARIANTS:-"a1 a05 a025 a01 a025flat"}
EPISODES=${EPISODES:-100}
EVAL_SEED=${EVAL_SEED:-10000}
TIMESTEPS=${TIMESTEPS:-}  # empty: the entry's n_timesteps; a small value checks the pipeline
read -r -a EXTRA <<< "${EXTRA:-}"
TAG=${TAG:+${TAG}_}
ENV_ID=${ENV_ID:-risky_reach_v0}
mkdir -p "$OUT"
run() { echo "$(date -u +%H:%M:%S) $*" >&2; taskset -c "$CORE" "$@"; }
params_of() {
    case "$1" in
        a1) echo "cvar_alpha:1.0" ;;
        a05) echo "cvar_alpha:0.5" ;;
        a025) echo "cvar_alpha:0.25" ;;
        a01) echo "cvar_alpha:0.1" ;;
        a025flat) echo "cvar_alpha:0.25 cvar_alpha_anneal_steps:0" ;;
        *) echo "unknown variant $1 (a1, a05, a025, a01, a025flat)" >&2; exit 2 ;;
    esac
}
for variant in $VARIANTS; do
    read -r -a params <<< "$(params_of "$variant")"
    for seed in $SEEDS; do
        name="${TAG}${variant}_s$seed"
        [ -s "$OUT/eval_$name/results.json" ] && continue  # done before: the sweep can be resumed
        start=$SECONDS
        run "$PY" -m sb3_maddpg train --algo maddpg --env "$ENV_ID" --seed "$seed" ${TIMESTEPS:+-n "$TIMESTEPS"} \
            -f "$OUT/logs/$name" --eval-freq -1 -params "${params[@]}" ${EXTRA[@]+"${EXTRA[@]}"} >"$OUT/train_$name.log" 2>&1
        echo $((SECONDS - start)) >"$OUT/train_$name.seconds"
        run "$PY" -m sb3_maddpg evaluate --model "$OUT/logs/$name/maddpg/${ENV_ID}_1/$ENV_ID.zip" --baselines random \
            --episodes "$EPISODES" --seed "$EVAL_SEED" --no-gif --out "$OUT/eval_$name" >"$OUT/eval_$name.log" 2>&1
    done
done
