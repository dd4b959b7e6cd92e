#!/usr/bin/env bash
# Every GPU measurement of docs/benchmarks.md in one run (under 5 minutes on one GPU), printed as one report:
#   1. the update benchmark at the report's configuration (6 agents, batch 32, 50 quantiles, 3x80x80) and at 4 agents
#      with batch 256: the per-agent reference, eager (host buffer), eager with the buffer on the GPU, CUDA graph,
#      CUDA graph + bf16, with the ratio reference / ours in the same run;
#   2. a 2-minute training run of the report's configuration (CUDA graph, buffer on the GPU) with TensorBoard logs,
#      and the time 500 episodes (150,000 timesteps) would take at its rate;
#   3. the CUDA tests (graph = eager on the GPU, the device buffer).
# It installs nothing: run it with a Python that has the project's requirements (torch with CUDA included).
#
#   bash benchmarks/gpu_check.sh                 # on a GPU machine
#   bash benchmarks/gpu_check.sh --device cpu    # dry run on a CPU: tiny sizes, a few seconds per step
#
# OUT (default runs/gpu_check) receives the logs, the TensorBoard folder and report.md.
set -euo pipefail
cd "$(dirname "$0")/.."
device=cuda
if [ "${1:-}" = "--device" ]; then device="${2:?--device cpu|cuda}"; fi
py="${PYTHON:-python3}"
out="${OUT:-runs/gpu_check}"
mkdir -p "$out"
export PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}" PYTHONUNBUFFERED=1

if [ "$device" = cuda ]; then
  updates=50; image=80; seconds=120; obs=80; graph=(--cuda-graph --storage-device cuda)
  variants=eager,eager+device-buffer,graph,graph+bf16
else
  updates=2; image=32; seconds=15; obs=16; graph=()
  variants=eager,graph,bf16
fi

{
  echo "# GPU check, $(date -u +%F) ($device)"
  "$py" -c "import torch; print('torch', torch.__version__, '| CUDA', torch.cuda.is_available(), '|', torch.cuda.get_device_name(0) if torch.cuda.is_available() else 'no GPU')"
  echo
  echo "## Update benchmark"
  "$py" benchmarks/update_speed.py --device "$device" --updates "$updates" --image-size "$image" --variants "$variants"
  echo
  echo "## Training run ($seconds s, report's configuration, obs $obs)"
  "$py" benchmarks/training_speed.py --device "$device" --seconds "$seconds" --obs-size "$obs" "${graph[@]}" \
    --tensorboard-log "$out/tensorboard"
  echo
  echo "## CUDA tests"
  "$py" -m pytest -q -p no:cacheprovider tests/test_graphed_update.py tests/test_device_buffer.py 2>&1 | tail -3
} 2>&1 | tee "$out/report.md"
