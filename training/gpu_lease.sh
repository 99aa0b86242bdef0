#!/usr/bin/env bash
# Issue 16's long trainings on a lent GPU machine (the `device` tool; H100, 16 cores, nothing reachable
# from it): the data-v2 dataset is rebuilt there (same seed and settings as `reproduce_models.sh data-v2`,
# 16 workers), then the generator at widths 16 and 8 (the error-against-run-time table) and three
# predictors (silhouette-only; the full loss at the paper's normal weight 0.002 and at 0.0005) train
# side by side on the one GPU, each with the recipe of its v2 step and as many iterations as the lease holds (measured, not guessed: a short concurrent run
# of all five sets each one's cosine schedule length).
#
#   bash training/gpu_lease.sh start MINUTES     set up, build the data, calibrate, launch the five runs
#                                                (in the background, ending MINUTES after launch), then
#                                                wait until this call has used WAIT seconds [540]
#   bash training/gpu_lease.sh wait SECONDS      wait, print progress, copy slim checkpoints to $OUT
#   bash training/gpu_lease.sh finish            wait for the runs to end, copy slim checkpoints to $OUT
#   bash training/gpu_lease.sh basis             save the predictor basis this machine computes ($OUT/basis.npy):
#                                                only for checkpoints written before the basis was stored in
#                                                them (the issue-16 runs; fetch-gpu's GPU_BASIS)
#
# What comes back under $OUT: each run's newest checkpoint without optimiser state (RUN.pt, loadable by
# `sketchmesh export` / `eval` once placed as runs/gpu/RUN/checkpoints/ckpt_N.pt; see
# training/reproduce_models.sh fetch-gpu) and logs.tgz (each run's log.csv, curves, config, events).
# Python packages the machine lacks (trimesh, manifold3d) travel as wheels in .whl/ (carry it), fetched
# here for its Python 3.12: pip download --no-deps --only-binary=:all: --python-version 3.12
#   --implementation cp --platform manylinux_2_28_x86_64 --platform manylinux_2_17_x86_64 -d .whl
#   trimesh==5.2.0 manifold3d==3.5.4
set -uo pipefail

DATA=${DATA:-data/proc100e4}
RUNS=${RUNS:-runs/gpu}
WAIT=${WAIT:-540}
DEVICE=${DEVICE:-cuda}     # cpu: a dry run of this script on any machine (with SHAPES=2 CAL=16)
SHAPES=${SHAPES:-100}      # shapes per category (data-v2: 100)
CAL=${CAL:-160}            # calibration iterations (the rate is measured over the last three quarters)
T0=$(date +%s)
export PYTHONUNBUFFERED=1 PYTHONPATH="/tmp/site:$PWD"
SM=(python3 -m sketchmesh)
NAMES=(normals16 normals8 mesh_silhouette mesh_full mesh_n5e-4)

run_args() {  # the training command of one run (the v2 recipes; GPU, data loader workers)
  local common=(--data "$DATA" --device "$DEVICE" --quiet --plot-every 500)
  local edges=(--normal-edges)  # the v2 mesh runs' normal term kept the paper's edge gradient (the default until 2026-11-28)
  case "$1" in
    normals16) echo train normals "${common[@]}" --base-channels 16 --batch 4 --num-workers 6 --ckpt-every 500 --val-every 0 ;;
    normals8) echo train normals "${common[@]}" --base-channels 8 --batch 4 --num-workers 4 --ckpt-every 500 --val-every 0 ;;
    mesh_silhouette) echo train mesh "${common[@]}" "${edges[@]}" --lambda-n 0 --num-workers 2 --ckpt-every 500 --val-every 0 ;;
    mesh_full) echo train mesh "${common[@]}" "${edges[@]}" --num-workers 2 --ckpt-every 500 --val-every 0 ;;
    mesh_n5e-4) echo train mesh "${common[@]}" "${edges[@]}" --lambda-n 0.0005 --num-workers 2 --ckpt-every 500 --val-every 0 ;;
  esac
}

snapshot() {  # slim copies of the newest checkpoints (no optimiser state) and the logs, into $OUT
  [ -n "${OUT:-}" ] || return 0
  for n in "${NAMES[@]}"; do  # the newest checkpoint of each run without optimiser state
    python3 -c "from training.loop.checkpoint import save_slim_copy as c; print('$n: iteration', c('$RUNS/$n', '$OUT/$n.pt'))"
  done
  tar czf "$OUT/logs.tgz" --exclude='checkpoints' --exclude='val' "$RUNS" 2>/dev/null
  ls -la "$OUT"
}

progress() {
  for n in "${NAMES[@]}"; do
    printf '%-16s ' "$n"; tail -n 1 "$RUNS/$n/log.csv" 2>/dev/null | cut -c1-150 || echo "-"
  done
  [ "$DEVICE" != cuda ] || nvidia-smi --query-gpu=utilization.gpu,memory.used --format=csv,noheader
}

case "${1:-}" in
  start)
    MINUTES=${2:?usage: start MINUTES}
    if [ "$DEVICE" = cuda ]; then
      python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl || exit 1
      nvidia-smi -L
    fi
    python3 -c "import torch, trimesh, manifold3d, cv2, onnxruntime; print('torch', torch.__version__, torch.cuda.is_available())" || exit 1
    echo "== data $(date +%T)"
    "${SM[@]}" data --source procedural --shapes-per-category "$SHAPES" --views 12 --elevations 0 15 30 45 \
      --workers 16 --out "$DATA" 2>&1 | tr '\r' '\n' | grep -v '^$' | tail -n 3 || exit 1
    python3 -c "
import hashlib, numpy as np
z = np.load('$DATA/shapes/chair/chair_00000.npz'); print('data check', {k: hashlib.md5(z[k].tobytes()).hexdigest()[:10] for k in ('normals64', 'cameras')})
from training.data.mesh_cache import open_mesh_cache; open_mesh_cache('$DATA', None, 'disk'); print('mesh cache built')" || exit 1
    echo "== calibrate $(date +%T)"
    rm -rf /tmp/cal; mkdir -p /tmp/cal
    for n in "${NAMES[@]}"; do
      # shellcheck disable=SC2046
      "${SM[@]}" $(run_args "$n") --out "/tmp/cal/$n" --iters "$CAL" --log-every $((CAL / 8)) --ckpt-every 0 --lr-warmup 0 \
        > "/tmp/cal/$n.log" 2>&1 &
    done
    wait
    declare -A ITERS
    LEFT=$((MINUTES * 60))
    for n in "${NAMES[@]}"; do
      rate=$(python3 -c "
import csv; r = {int(x['iteration']): float(x['wall_s']) for x in csv.DictReader(open('/tmp/cal/$n/log.csv'))}
a = $CAL // 4; print(($CAL - a) / (r[$CAL] - r[a]))") || { tail -n 20 "/tmp/cal/$n.log"; exit 1; }
      ITERS[$n]=$(python3 -c "print(max(100, int($rate * $LEFT * 0.9) // 100 * 100))")
      echo "$n: $rate it/s side by side -> ${ITERS[$n]} iterations in $MINUTES min"
    done
    echo "== launch $(date +%T)"
    mkdir -p "$RUNS"
    for n in "${NAMES[@]}"; do
      # shellcheck disable=SC2046
      setsid nohup "${SM[@]}" $(run_args "$n") --out "$RUNS/$n" --iters "${ITERS[$n]}" --max-minutes "$((MINUTES + 1))" \
        > "$RUNS/$n.out" 2>&1 < /dev/null &
    done
    sleep $((WAIT - ($(date +%s) - T0) > 0 ? WAIT - ($(date +%s) - T0) : 0))
    progress; snapshot ;;
  wait)
    sleep "${2:?usage: wait SECONDS}"; progress; snapshot ;;
  finish)
    while pgrep -f "sketchmesh train" > /dev/null; do sleep 5; [ $(($(date +%s) - T0)) -lt 560 ] || break; done
    progress; for n in "${NAMES[@]}"; do tail -n 2 "$RUNS/$n.out" | tr '\r' '\n' | tail -n 2; done; snapshot ;;
  basis)
    python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl || exit 1
    python3 -c "
import sys, numpy as np; from training.loop.trainer import build_models; from training.loop.config import TrainConfig
m = build_models(TrainConfig(mode='mesh', data_dir='x', out_dir='y'))['predictor']; np.save('$OUT/basis.npy', m.basis.numpy())" ;;
  *) echo "usage: $0 start MINUTES | wait SECONDS | finish | basis" >&2; exit 2 ;;
esac
