#!/usr/bin/env bash
# The docs' screenshots of TensorBoard (docs/figures/tensorboard_images.png, tensorboard_hparams.png): two 600-timestep
# runs on uav_coverage_cpu_v1 (seed 0 with the entry's gamma, seed 1 with gamma 0.95), TensorBoard serving their logs,
# and a headless Chromium from npm taking the pictures (needs node and npm; nothing is installed outside $WORK).
# Usage: bash scripts/tensorboard_screenshots/make.sh [OUT_DIR (default docs/figures)]
set -euo pipefail
cd "$(dirname "$0")/../.."
OUT_DIR=$(realpath "${1:-docs/figures}")
PY=${PY:-.venv/bin/python}
WORK=$(mktemp -d)
trap 'kill "$tb_pid" 2>/dev/null || true; rm -rf "$WORK"' EXIT
for seed in 0 1; do
    params=()
    [ "$seed" = 1 ] && params=(-params gamma:0.95)
    "$PY" -m sb3_maddpg train --algo maddpg --env uav_coverage_cpu_v1 -n 600 --eval-freq 300 --eval-episodes 1 \
        --seed "$seed" ${params[@]+"${params[@]}"} -tb "$WORK/tb" -f "$WORK/logs" >"$WORK/train_$seed.log" 2>&1
done
"$PY" -m tensorboard.main --logdir "$WORK/tb" --port 6006 >"$WORK/tensorboard.log" 2>&1 &
tb_pid=$!
for _ in $(seq 60); do curl -sf http://localhost:6006 >/dev/null && break; sleep 1; done
cp "$(dirname "$0")/screenshots.mjs" "$WORK/"
(cd "$WORK" && npm init -y >/dev/null && npm install --silent @sparticuz/chromium puppeteer-core >/dev/null)
TB_URL=http://localhost:6006 OUT_DIR="$OUT_DIR" node "$WORK/screenshots.mjs"
echo "written: $OUT_DIR/tensorboard_images.png $OUT_DIR/tensorboard_hparams.png"
