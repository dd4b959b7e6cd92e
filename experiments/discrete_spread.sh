#!/usr/bin/env bash
# MADDPG with discrete actions (Gumbel-softmax actors) on MPE2's simple_spread_v3 (Discrete(5) moves): three seeds
# through the command line and the zoo_configs entry simple_spread_discrete_v3, then the team return of each model and
# of uniformly random actions on 20 episodes. experiments/mpe_task.sh with ENV_ID=simple_spread_discrete_v3.
# Usage: OUT=runs/discrete CORE=1 STEPS=25000 bash experiments/discrete_spread.sh
exec env ENV_ID=simple_spread_discrete_v3 OUT="${OUT:-runs/discrete}" bash "$(dirname "$0")/mpe_task.sh"
