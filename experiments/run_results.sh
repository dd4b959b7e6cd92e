#!/usr/bin/env bash
# The runs behind docs/results.md's table: each configuration with seeds 0, 1 and 2 (chosen before the runs) on
# uav_coverage_cpu_v1 with 300-step episodes, two runs at a time, each pinned to one core with one torch thread.
#   bash experiments/run_results.sh [CONFIG ...]     (default: every configuration below)
#   python experiments/results_table.py runs/results/*.jsonl --figure docs/figures/learning_curves_v1.png
# SEEDS (default "0 1 2"), EVAL_EPISODES (final evaluation episodes; default 20, 100 for the hazard configs), TIMESTEPS (default: 28000 for the config exact_tpn005_g09_mates, 24000 for the others),
# OUT (default runs/results) and CORES (default "0 1", one run at a time on each) override the defaults.
set -euo pipefail
cd "$(dirname "$0")/.."
py="${PYTHON:-.venv/bin/python}"
out="${OUT:-runs/results}"
timesteps="${TIMESTEPS:-}"
eval_episodes="${EVAL_EPISODES:-}"
read -r -a seeds <<< "${SEEDS:-0 1 2}"
read -r -a cores <<< "${CORES:-0 1}"
mkdir -p "$out"

# The settings of zoo_configs/maddpg.yml's uav_coverage_cpu_v1 entry but the discount, the actor learning rate, the
# target policy smoothing, the critic's quantiles, the position mark and the teammate channel (the entry: γ 0.9, actor
# learning rate 3e-4, smoothing 0.05, one quantile, the exact mark, the teammate channel, 28 000 timesteps, i.e.
# exact_tpn005_g09_mates below; before that, on 2026-12-04, exact_tpn005_g09 with 24 000 timesteps, and before
# 2026-12-04 classic_actor3e4).
# experiments/run_stability.sh with max_grad_norm 1 and position_channel 1 passes the same as alpha1.
v1_common='"learning_starts": 2000, "train_freq": 1, "gamma": 0.95, "tau": 0.01, "learning_rate": 0.001,
  "critic_warmup_steps": 2000, "policy_delay": 2,
  "actor_reg": 0.001, "buffer_size": 100000, "batch_size": 64, "max_grad_norm": 1.0'
v1_algo="$v1_common, \"target_policy_noise\": 0.2, \"actor_learning_rate\": 0.0001"
fast_actor="$v1_common, \"target_policy_noise\": 0.2, \"actor_learning_rate\": 0.0003"
# Research log run 54: the faster actor with less target policy smoothing (0.05 instead of 0.2)
fast_actor_tpn005="$v1_common, \"target_policy_noise\": 0.05, \"actor_learning_rate\": 0.0003"
encoder='"features_extractor_kwargs": {"padding": 1, "coord_channels": true, "batch_norm_eps": 0.001, "position_channel": 1}'

declare -A ENV ALGO POLICY ENV_KWARGS STEPS NENVS EPISODES
# v1 draws each UAV at its exact position (position_mark="exact") and shows the linked teammates in a fourth channel
# (teammate_channel=True) since 2026-12-04; the configurations measured before that keep the mark and the channels
# they were measured with.
cell='"position_mark": "cell", "teammate_channel": false'
exact_no_mates='"position_mark": "exact", "teammate_channel": false'
ENV[alpha05]=uav_coverage_cpu_v1; ALGO[alpha05]="{$v1_algo, \"cvar_alpha\": 0.5}"; POLICY[alpha05]="{\"n_quantiles\": 25, $encoder}"; ENV_KWARGS[alpha05]="$cell"
ENV[alpha1]=uav_coverage_cpu_v1;  ALGO[alpha1]="{$v1_algo, \"cvar_alpha\": 1.0}";  POLICY[alpha1]="{\"n_quantiles\": 25, $encoder}"; ENV_KWARGS[alpha1]="$cell"
ENV[alpha01]=uav_coverage_cpu_v1; ALGO[alpha01]="{$v1_algo, \"cvar_alpha\": 0.1}"; POLICY[alpha01]="{\"n_quantiles\": 25, $encoder}"; ENV_KWARGS[alpha01]="$cell"
ENV[classic]=uav_coverage_cpu_v1; ALGO[classic]="{$v1_algo, \"cvar_alpha\": 1.0}"; POLICY[classic]="{\"n_quantiles\": 1, $encoder}"; ENV_KWARGS[classic]="$cell"
# The same with a faster actor (actor learning rate 3e-4 instead of 1e-4: zoo_configs/maddpg.yml's v1 entries)
ENV[classic_actor3e4]=uav_coverage_cpu_v1; ALGO[classic_actor3e4]="{$fast_actor, \"cvar_alpha\": 1.0}"; POLICY[classic_actor3e4]="{\"n_quantiles\": 1, $encoder}"; ENV_KWARGS[classic_actor3e4]="$cell"
ENV[alpha05_actor3e4]=uav_coverage_cpu_v1; ALGO[alpha05_actor3e4]="{$fast_actor, \"cvar_alpha\": 0.5}"; POLICY[alpha05_actor3e4]="{\"n_quantiles\": 25, $encoder}"; ENV_KWARGS[alpha05_actor3e4]="$cell"
ENV[alpha01_actor3e4]=uav_coverage_cpu_v1; ALGO[alpha01_actor3e4]="{$fast_actor, \"cvar_alpha\": 0.1}"; POLICY[alpha01_actor3e4]="{\"n_quantiles\": 25, $encoder}"; ENV_KWARGS[alpha01_actor3e4]="$cell"
# The faster actor's settings on v1 with the exact position mark (position_mark="exact": each UAV drawn at its exact
# position instead of on its cell's block)
ENV[exact_mark]=uav_coverage_cpu_v1; ALGO[exact_mark]="{$fast_actor, \"cvar_alpha\": 1.0}"; POLICY[exact_mark]="{\"n_quantiles\": 1, $encoder}"
ENV_KWARGS[exact_mark]="$exact_no_mates"
# The same with less target policy smoothing (0.05 instead of 0.2): research log run 54
ENV[exact_tpn005]=uav_coverage_cpu_v1; ALGO[exact_tpn005]="{$fast_actor_tpn005, \"cvar_alpha\": 1.0}"; POLICY[exact_tpn005]="{\"n_quantiles\": 1, $encoder}"
ENV_KWARGS[exact_tpn005]="$exact_no_mates"
# The same with the discount 0.9 instead of 0.95 (research log run 56): the config on 2026-12-04 until the next one
ENV[exact_tpn005_g09]=uav_coverage_cpu_v1; ALGO[exact_tpn005_g09]="{$fast_actor_tpn005, \"gamma\": 0.9, \"cvar_alpha\": 1.0}"; POLICY[exact_tpn005_g09]="{\"n_quantiles\": 1, $encoder}"
ENV_KWARGS[exact_tpn005_g09]="$exact_no_mates"
# The same with the teammate channel (teammate_channel=True: the teammates within radio range drawn in their own
# channel; research log run 59) and 28 000 timesteps: the config since 2026-12-04
ENV[exact_tpn005_g09_mates]=uav_coverage_cpu_v1; ALGO[exact_tpn005_g09_mates]="${ALGO[exact_tpn005_g09]}"; POLICY[exact_tpn005_g09_mates]="${POLICY[exact_tpn005_g09]}"
ENV_KWARGS[exact_tpn005_g09_mates]='"position_mark": "exact", "teammate_channel": true'; STEPS[exact_tpn005_g09_mates]=28000
# The config with the actors reading the critics' encoders (share_features_extractor) and an encoder sized for
# 16 x 16 inputs (channels 8, 16, 32 instead of the report's 16, 32, 64); with two env copies per step (one update per
# two timesteps) or one: the training-speed measurements of docs/benchmarks.md
small_encoder='"features_extractor_kwargs": {"padding": 1, "coord_channels": true, "batch_norm_eps": 0.001, "position_channel": 1, "channels": [8, 16, 32]}'
for config in fast_shared_small fast_shared_small_envs2; do
  ENV[$config]=uav_coverage_cpu_v1; ALGO[$config]="${ALGO[exact_tpn005_g09]}"; ENV_KWARGS[$config]="${ENV_KWARGS[exact_tpn005_g09_mates]}"
  POLICY[$config]="{\"n_quantiles\": 1, \"share_features_extractor\": true, $small_encoder}"; STEPS[$config]=28000
done
NENVS[fast_shared_small_envs2]=2
# The same with batch 32 (the report's) instead of 64
ENV[fast_shared_small_b32]=uav_coverage_cpu_v1; ENV_KWARGS[fast_shared_small_b32]="${ENV_KWARGS[exact_tpn005_g09_mates]}"
ALGO[fast_shared_small_b32]="${ALGO[exact_tpn005_g09]/\"batch_size\": 64/\"batch_size\": 32}"
POLICY[fast_shared_small_b32]="${POLICY[fast_shared_small]}"; STEPS[fast_shared_small_b32]=28000
# The small encoder without the sharing (actors with encoders of their own), batch 64 or 32
for config in fast_small fast_small_b32; do
  ENV[$config]=uav_coverage_cpu_v1; ENV_KWARGS[$config]="${ENV_KWARGS[exact_tpn005_g09_mates]}"; STEPS[$config]=28000
  POLICY[$config]="{\"n_quantiles\": 1, $small_encoder}"
done
ALGO[fast_small]="${ALGO[exact_tpn005_g09]}"; ALGO[fast_small_b32]="${ALGO[fast_shared_small_b32]}"
# The sharing with the report's encoder and batch 32
ENV[fast_shared_b32]=uav_coverage_cpu_v1; ENV_KWARGS[fast_shared_b32]="${ENV_KWARGS[exact_tpn005_g09_mates]}"; STEPS[fast_shared_b32]=28000
ALGO[fast_shared_b32]="${ALGO[fast_shared_small_b32]}"; POLICY[fast_shared_b32]="{\"n_quantiles\": 1, \"share_features_extractor\": true, $encoder}"
# The report's encoder with batch 32, no sharing
ENV[fast_b32]=uav_coverage_cpu_v1; ENV_KWARGS[fast_b32]="${ENV_KWARGS[exact_tpn005_g09_mates]}"; STEPS[fast_b32]=28000
ALGO[fast_b32]="${ALGO[fast_shared_small_b32]}"; POLICY[fast_b32]="${POLICY[exact_tpn005_g09]}"
# Cheaper and longer (issue: the published table, part 3): batch 32 for 40 000 timesteps, about the CPU time of the
# config's batch 64 for 28 000 (an update at batch 32 costs 1 / 1.57 of one at 64: docs/benchmarks.md)
ENV[fast_b32_40k]=uav_coverage_cpu_v1; ENV_KWARGS[fast_b32_40k]="${ENV_KWARGS[fast_b32]}"; STEPS[fast_b32_40k]=40000
ALGO[fast_b32_40k]="${ALGO[fast_b32]}"; POLICY[fast_b32_40k]="${POLICY[fast_b32]}"
# The quick start's config (fast_b32_40k) with the encoder sized for 16 x 16 inputs (issue: training speed): does the
# longer budget give back the fairness that channels (8, 16, 32) lost at 28 000 timesteps?
ENV[fast_small_b32_40k]=uav_coverage_cpu_v1; ENV_KWARGS[fast_small_b32_40k]="${ENV_KWARGS[fast_b32]}"; STEPS[fast_small_b32_40k]=40000
ALGO[fast_small_b32_40k]="${ALGO[fast_b32]}"; POLICY[fast_small_b32_40k]="${POLICY[fast_small_b32]}"
# Between the two: channels (12, 24, 48), about half the report's arithmetic
mid_encoder='"features_extractor_kwargs": {"padding": 1, "coord_channels": true, "batch_norm_eps": 0.001, "position_channel": 1, "channels": [12, 24, 48]}'
ENV[fast_mid_b32_40k]=uav_coverage_cpu_v1; ENV_KWARGS[fast_mid_b32_40k]="${ENV_KWARGS[fast_b32]}"; STEPS[fast_mid_b32_40k]=40000
ALGO[fast_mid_b32_40k]="${ALGO[fast_b32]}"; POLICY[fast_mid_b32_40k]="{\"n_quantiles\": 1, $mid_encoder}"
# The config with a 25-quantile critic at alpha 1: does the quantile critic learn as fast as the scalar one?
ENV[mates_q25]=uav_coverage_cpu_v1; ALGO[mates_q25]="${ALGO[exact_tpn005_g09]}"; ENV_KWARGS[mates_q25]="${ENV_KWARGS[exact_tpn005_g09_mates]}"
POLICY[mates_q25]="{\"n_quantiles\": 25, $encoder}"; STEPS[mates_q25]=28000
# The same at batch 32 (fast_b32 with 25 quantiles): the scalar against the quantile critic at equal settings
ENV[fast_b32_q25]=uav_coverage_cpu_v1; ALGO[fast_b32_q25]="${ALGO[fast_b32]}"; ENV_KWARGS[fast_b32_q25]="${ENV_KWARGS[fast_b32]}"
POLICY[fast_b32_q25]="{\"n_quantiles\": 25, $encoder}"; STEPS[fast_b32_q25]=28000
# Screens of the quantile critic's lag (research log, 2026-12-05): fewer quantiles; a slower critic
ENV[fast_b32_q5]=uav_coverage_cpu_v1; ALGO[fast_b32_q5]="${ALGO[fast_b32]}"; ENV_KWARGS[fast_b32_q5]="${ENV_KWARGS[fast_b32]}"
POLICY[fast_b32_q5]="{\"n_quantiles\": 5, $encoder}"; STEPS[fast_b32_q5]=28000
ENV[fast_b32_q25_clr3e4]=uav_coverage_cpu_v1; ALGO[fast_b32_q25_clr3e4]="${ALGO[fast_b32]%\}}, \"learning_rate\": 0.0003}"
ENV_KWARGS[fast_b32_q25_clr3e4]="${ENV_KWARGS[fast_b32]}"; POLICY[fast_b32_q25_clr3e4]="${POLICY[fast_b32_q25]}"; STEPS[fast_b32_q25_clr3e4]=28000
# The 25-quantile critic with the mean-anchored loss (mean_anchored_quantiles: the mean learns with the scalar TD loss)
ENV[fast_b32_q25_anchor]=uav_coverage_cpu_v1; ALGO[fast_b32_q25_anchor]="${ALGO[fast_b32]%\}}, \"mean_anchored_quantiles\": true}"
ENV_KWARGS[fast_b32_q25_anchor]="${ENV_KWARGS[fast_b32]}"; POLICY[fast_b32_q25_anchor]="${POLICY[fast_b32_q25]}"; STEPS[fast_b32_q25_anchor]=28000
# The alpha sweep on the hazardous task (issue: risk that CVaR can see): fast_b32's settings on
# uav_coverage_hazard_cpu_v1, the classic critic and 25 quantiles at alpha 1, 0.5, 0.25, 0.1; 100 evaluation episodes
for config in hz_classic hz_a1 hz_a05 hz_a025 hz_a01; do
  ENV[$config]=uav_coverage_hazard_cpu_v1; ENV_KWARGS[$config]="${ENV_KWARGS[fast_b32]}"; STEPS[$config]=28000; EPISODES[$config]=100
done
# (the 25-quantile critics mean-anchored: fast_b32_q25_anchor's, which learns as fast as the scalar one at alpha 1)
ALGO[hz_classic]="${ALGO[fast_b32]}"; POLICY[hz_classic]="${POLICY[fast_b32]}"
for alpha in 05 025 01; do  # hz_a05: cvar_alpha 0.5, ...
  ALGO[hz_a$alpha]="${ALGO[fast_b32_q25_anchor]%\}}, \"cvar_alpha\": 0.${alpha#0}}"
done
ALGO[hz_a1]="${ALGO[fast_b32_q25_anchor]}"
for config in hz_a1 hz_a05 hz_a025 hz_a01; do POLICY[$config]="${POLICY[fast_b32_q25]}"; done
# The alpha sweep on the storm task (uav_coverage_storm_cpu_v1: a storm over the middle of the map grounds the UAVs it
# strikes; no gusts): the same five configurations, trained from scratch (hazards that never move a UAV do not crash
# the early random actions' UAVs out of the episode), 100 evaluation episodes
for config in classic a1 a05 a025 a01; do
  ENV[st_$config]=uav_coverage_storm_cpu_v1; ENV_KWARGS[st_$config]="${ENV_KWARGS[hz_$config]}"; STEPS[st_$config]=28000
  EPISODES[st_$config]=100; ALGO[st_$config]="${ALGO[hz_$config]}"; POLICY[st_$config]="${POLICY[hz_$config]}"
done
# The storm task with the grounded UAV's countdown in its own observation (show_grounded: a grounded UAV's return is
# then a function of what its critic sees; without it the 20 grounded steps look alike)
for config in a1 a05; do
  ENV[st_${config}_vis]=uav_coverage_storm_cpu_v1; ENV_KWARGS[st_${config}_vis]="${ENV_KWARGS[st_$config]}, \"show_grounded\": true"
  STEPS[st_${config}_vis]=28000; EPISODES[st_${config}_vis]=100; ALGO[st_${config}_vis]="${ALGO[st_$config]}"; POLICY[st_${config}_vis]="${POLICY[st_$config]}"
done
# The same five with the critics' mean fitted by the squared TD error (mean_loss "squared"): a crash's reward of about
# -100 counts in full, where the Huber loss (kappa 1) weighs it as about -1
for config in hz_classic hz_a1 hz_a05 hz_a025 hz_a01; do
  ENV[${config}_sq]=uav_coverage_hazard_cpu_v1; ENV_KWARGS[${config}_sq]="${ENV_KWARGS[$config]}"; STEPS[${config}_sq]=28000
  EPISODES[${config}_sq]=100; POLICY[${config}_sq]="${POLICY[$config]}"; ALGO[${config}_sq]="${ALGO[$config]%\}}, \"mean_loss\": \"squared\"}"
done
# The classic critic with the squared mean loss and a critic-only warm-up of 8 000 updates instead of 2 000: do the
# actors still saturate when they start from a critic that has seen four times more crashes?
ENV[hz_classic_sq_warm8k]=uav_coverage_hazard_cpu_v1; ENV_KWARGS[hz_classic_sq_warm8k]="${ENV_KWARGS[hz_classic]}"
STEPS[hz_classic_sq_warm8k]=28000; EPISODES[hz_classic_sq_warm8k]=100; POLICY[hz_classic_sq_warm8k]="${POLICY[hz_classic]}"
ALGO[hz_classic_sq_warm8k]="${ALGO[hz_classic_sq]/\"critic_warmup_steps\": 2000/\"critic_warmup_steps\": 8000}"
# The classic critic on the hazardous task with rewards scaled by 0.1 (a crash's energy, 200, is a reward of -20
# instead of -200): does the critic learn where hz_classic diverged?
ENV[hz_classic_r01]=uav_coverage_hazard_cpu_v1; ENV_KWARGS[hz_classic_r01]="${ENV_KWARGS[fast_b32]}, \"reward_scale\": 0.1"
ALGO[hz_classic_r01]="${ALGO[fast_b32]}"; POLICY[hz_classic_r01]="${POLICY[fast_b32]}"; STEPS[hz_classic_r01]=28000; EPISODES[hz_classic_r01]=100
# Screens of the hazardous task's learning failure: gusts at a quarter of the steps instead of 3 in 4; crashes that
# cost 50 energy instead of 200
for config in hz_classic_g025 hz_classic_c50; do
  ENV[$config]=uav_coverage_hazard_cpu_v1; ALGO[$config]="${ALGO[fast_b32]}"; POLICY[$config]="${POLICY[fast_b32]}"
  STEPS[$config]=28000; EPISODES[$config]=100
done
ENV_KWARGS[hz_classic_g025]="${ENV_KWARGS[fast_b32]}, \"gust_prob\": 0.25"
ENV_KWARGS[hz_classic_c50]="${ENV_KWARGS[fast_b32]}, \"crash_energy\": 50.0"
ENV[fast_shared]=uav_coverage_cpu_v1; ALGO[fast_shared]="${ALGO[exact_tpn005_g09]}"; ENV_KWARGS[fast_shared]="${ENV_KWARGS[exact_tpn005_g09_mates]}"
POLICY[fast_shared]="{\"n_quantiles\": 1, \"share_features_extractor\": true, $encoder}"; STEPS[fast_shared]=28000
ENV[fast_shared_envs2]=uav_coverage_cpu_v1; ALGO[fast_shared_envs2]="${ALGO[exact_tpn005_g09]}"; ENV_KWARGS[fast_shared_envs2]="${ENV_KWARGS[exact_tpn005_g09_mates]}"
POLICY[fast_shared_envs2]="{\"n_quantiles\": 1, \"share_features_extractor\": true, $encoder}"; STEPS[fast_shared_envs2]=28000; NENVS[fast_shared_envs2]=2

# v0 (the report's task at 1 pixel per cell: polar actions, refused walls, the report's reward) with the same settings
ENV[v0_classic]=uav_coverage_fast_v0; ALGO[v0_classic]="{$v1_algo, \"cvar_alpha\": 1.0}"; POLICY[v0_classic]="{\"n_quantiles\": 1, $encoder}"

configs=("$@")
[ ${#configs[@]} -gt 0 ] || configs=(classic_actor3e4 classic alpha1 alpha05 alpha01 alpha05_actor3e4 alpha01_actor3e4 exact_mark exact_tpn005 exact_tpn005_g09 exact_tpn005_g09_mates v0_classic)

jobs=()
for config in "${configs[@]}"; do
  [ -n "${ENV[$config]:-}" ] || { echo "unknown configuration $config (known: ${!ENV[*]})" >&2; exit 2; }
  for seed in "${seeds[@]}"; do jobs+=("$config $seed"); done
done

run() {  # run CONFIG SEED CORE
  local config=$1 seed=$2 core=$3
  taskset -c "$core" "$py" experiments/uav_learning.py --env "${ENV[$config]}" --env-kwargs "{\"max_cycles\": 300${ENV_KWARGS[$config]:+, ${ENV_KWARGS[$config]}}}" \
    --algo-kwargs "${ALGO[$config]}" --policy-kwargs "${POLICY[$config]}" --timesteps "${timesteps:-${STEPS[$config]:-24000}}" \
    --n-envs "${NENVS[$config]:-1}" \
    --eval-every 4000 --eval-episodes "${eval_episodes:-${EPISODES[$config]:-20}}" --seed "$seed" --save "$out/${config}_s${seed}.zip" --out "$out/${config}_s${seed}.jsonl" \
    > "$out/${config}_s${seed}.log" 2>&1
}

# One queue per core, so that a fast run does not wait for a slow one.
queue() {  # queue INDEX: the jobs INDEX, INDEX + number of cores, ... on core cores[INDEX]
  local index=$1 i config seed
  for ((i = index; i < ${#jobs[@]}; i += ${#cores[@]})); do
    read -r config seed <<< "${jobs[i]}"
    run "$config" "$seed" "${cores[index]}"
  done
}
for ((q = 0; q < ${#cores[@]}; q++)); do queue "$q" & done
wait
"$py" experiments/results_table.py "$out"/*.jsonl
