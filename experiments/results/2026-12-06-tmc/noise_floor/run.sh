#!/usr/bin/env bash
# run.sh WAIT_PID CORE TAG [-params ...]: after WAIT_PID ends, N 6 seed 0 for 15 000 timesteps, its evaluation, the critic's view
cd /work/main
pid=$1 core=$2 tag=$3; shift 3
while kill -0 "$pid" 2> /dev/null; do sleep 20; done
echo "$(date -u +%H:%M:%S) start $tag"
start=$SECONDS
nice -n 10 taskset -c "$core" .venv/bin/python -m sb3_maddpg train --algo maddpg --env uav_coverage_tmc_v1 --env-kwargs n_uavs:6 \
  --seed 0 -n 15000 -f "runs/tmcnoise/$tag" --eval-freq -1 "$@" > "runs/tmcnoise/train_$tag.log" 2>&1
echo "$((SECONDS - start))" > "runs/tmcnoise/train_$tag.seconds"
model="runs/tmcnoise/$tag/maddpg/uav_coverage_tmc_v1_1/uav_coverage_tmc_v1.zip"
nice -n 10 taskset -c "$core" .venv/bin/python -m sb3_maddpg evaluate --model "$model" --baselines random --episodes 10 \
  --seed 10000 --no-gif --out "runs/tmcnoise/eval_$tag" > "runs/tmcnoise/eval_$tag.log" 2>&1
cd experiments && nice -n 10 taskset -c "$core" ../.venv/bin/python critic_shift_view.py "../$model" --tmc-uavs 6 --episodes 2 \
  --steps 250 --rollout 30 > "../runs/tmcnoise/view_$tag.txt" 2>&1
echo "$(date -u +%H:%M:%S) end $tag"
