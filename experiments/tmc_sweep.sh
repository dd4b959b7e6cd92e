#!/usr/bin/env bash
# The N sweep of Liu et al. (TMC 2020) on uav_coverage_tmc_v1 (its setting with v1's rules), through the command line:
#   baselines: random actions, the paper's step greedy (greedy_step) and the greedy static placement for each N,
#              $EPISODES random-start episodes (seeds $EVAL_SEED...), no training;
#   train:     MADDPG (zoo_configs/maddpg.yml's uav_coverage_tmc_v1 entry) for each N and seed, each run evaluated
#              on the same episodes as the baselines (with random actions beside it);
#   table:     the Markdown table of everything under $OUT (experiments/tmc_table.py).
# One training run is 35-60 minutes on one core: the full training sweep is 6 N x 3 seeds.
# Usage: OUT=experiments/results/2026-12-04-tmc CORE=1 bash experiments/tmc_sweep.sh [baselines|train|table|all]
# A quick check of the pipeline: NS=3 SEEDS=0 TIMESTEPS=200 EPISODES=1 OUT=/tmp/tmc bash experiments/tmc_sweep.sh train
# PARAMS overrides entries of the YAML entry as RL Zoo's -params (e.g. the attention critic:
# PARAMS="policy_kwargs:\"dict(n_quantiles=1, critic='attention', features_extractor_kwargs=...)\""); TAG prefixes the
# runs' names, so that runs with other PARAMS can share $OUT. Since 2026-12-07 the entry uses the attention critic; the
# joint critic's rows of docs/results.md: PARAMS="policy_kwargs:\"dict(n_quantiles=1,features_extractor_kwargs=dict(padding=1,coord_channels=True,batch_norm_eps=1e-3,position_channel=1))\"".
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-runs/tmc}
PY=${PY:-.venv/bin/python}
CORE=${CORE:-1}
NICE=${NICE:-10}
NS=${NS:-"3 4 5 6 7 8"}
SEEDS=${SEEDS:-"0 1 2"}
EPISODES=${EPISODES:-20}
EVAL_SEED=${EVAL_SEED:-10000}
BASELINES=${BASELINES:-"random greedy_step greedy_static"}
TIMESTEPS=${TIMESTEPS:-}  # empty: the YAML entry's n_timesteps; a small value checks the pipeline
read -r -a PARAMS <<< "${PARAMS:-}"
SAVE_FREQ=${SAVE_FREQ:--1}  # a checkpoint every SAVE_FREQ timesteps (for the best-of-checkpoints protocol); -1: none
TAG=${TAG:+${TAG}_}
ENV_ID=uav_coverage_tmc_v1
what=${1:-all}
case "$what" in baselines | train | table | all) ;; *) echo "usage: $0 [baselines|train|table|all]" >&2; exit 2 ;; esac
mkdir -p "$OUT"
run() { echo "$(date -u +%H:%M:%S) $*" >&2; nice -n "$NICE" taskset -c "$CORE" "$@"; }

if [ "$what" = baselines ] || [ "$what" = all ]; then
    for n in $NS; do
        # shellcheck disable=SC2086 # BASELINES is a list of names
        run "$PY" -m sb3_maddpg evaluate --baselines-only --env "$ENV_ID" --env-kwargs "n_uavs:$n" \
            --baselines $BASELINES --episodes "$EPISODES" --seed "$EVAL_SEED" --no-gif \
            --out "$OUT/baselines/n$n" >"$OUT/baselines_n$n.log" 2>&1
    done
fi
if [ "$what" = train ] || [ "$what" = all ]; then
    for n in $NS; do
        for seed in $SEEDS; do
            run_name="${TAG}n${n}_s$seed"
            logs="$OUT/logs/$run_name"
            start=$SECONDS
            run "$PY" -m sb3_maddpg train --algo maddpg --env "$ENV_ID" --env-kwargs "n_uavs:$n" --seed "$seed" \
                ${TIMESTEPS:+-n "$TIMESTEPS"} -f "$logs" --eval-freq -1 --save-freq "$SAVE_FREQ" ${PARAMS[@]+-params "${PARAMS[@]}"} \
                >"$OUT/train_$run_name.log" 2>&1
            echo $((SECONDS - start)) >"$OUT/train_$run_name.seconds"  # wall clock of the training run
            # the run's own n_uavs is read from its args.yml
            run "$PY" -m sb3_maddpg evaluate --model "$logs/maddpg/${ENV_ID}_1/$ENV_ID.zip" --baselines random \
                --episodes "$EPISODES" --seed "$EVAL_SEED" --no-gif \
                --out "$OUT/eval/$run_name" >"$OUT/eval_$run_name.log" 2>&1
        done
    done
fi
# every mode ends with the table of all that $OUT holds
"$PY" experiments/tmc_table.py "$OUT" | tee "$OUT/table.md"
