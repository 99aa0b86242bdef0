#!/usr/bin/env bash
# Issue 16 on a lent GPU (the `device` tool), in ONE call of at most 10 minutes: continue a bundled
# predictor on true normal images at large batches, then bring slim checkpoints back. It fits the
# 15 minutes of device time a session is now lent (the machine's start included), so it rebuilds only
# what the predictor reads: the data-v2 shapes, cameras and 64x64 targets (`data --size 64`, whose
# normals64 / silhouette64 / cameras equal the 256 build's exactly: tests/test_data_render.py), not the
# 256x256 sketches (86.9 s on the H200 machine's 16 cores). The generator's images cannot be made
# there in time, so the runs read true normal images (the `ceiling-v2` recipe of the fourth pair);
# back here the predictor is fine-tuned on the generated images (reproduce_models.sh predictor-v10).
# What a call buys (model card, "What the table lacks among other shapes"): the overfit check stands the table on
# legs among 13 shapes only after about 17,000 samples of it (overfit-long-v32), and the twenty-first's GPU stage (two
# calls) gave each category about 42,000 spread over 600 shapes (the paper: 1.28 M a category), so the legged
# categories need many calls resumed one after another; look at the legs (gallery) after each, not only the mean,
# against what the sphere reaches on the same test shapes (reproduce_models.sh ceiling-v57: the direct fit stands 5 of the
# 8 standing test chairs on their own legs, the bundle 0.09 of their drawings).
# Which batch: for the same samples the overfit check ends far behind at batch 512 (gap 0.203, the table a box; 0.183 at
# four times the rate), between at 256 (0.112) and close to batch 32 at 128 (0.089 against 0.080; from the start on
# this CPU, reproduce_models.sh compare-overfit-v33; at 128 the 40-minute run's samples pass the check with the table
# on legs, overfit-b128-long-v33): train at 128 (SPECS="NAME 128 LR") unless the calibration shows its steps cost
# nearly as much as 512's here; every stage so far ran at 512.
#
#   bash training/gpu_predictor.sh INIT_RUN       on the GPU machine: INIT_RUN holds the predictor to
#                                                 continue (a slim copy travels in gpucarry/, which
#                                                 .gitignore ignores: reproduce_models.sh gpucarry-v10;
#                                                 carry it and .whl)
#   DEVICE=cpu SHAPES=2 CAL=8 END=150 bash training/gpu_predictor.sh INIT_RUN    a dry run on any machine
#   ARCH="--predictor-channels 64 --predictor-hidden 1024" bash training/gpu_predictor.sh fresh
#                                                 a predictor of another size trained from the start (INIT_RUN
#                                                 "fresh"); a later session continues it with the same ARCH and
#                                                 INIT_RUN its slim copy: a larger predictor trained over several
#                                                 lent GPUs, each call's run resumable from what came back (that
#                                                 size: 7.1 M parameters, a 28 MB slim checkpoint, which travels
#                                                 out with .whl under carry's 64 MiB and comes back in 15 MiB
#                                                 parts; adding --predictor-blocks 1 makes 13.8 M and 55 MB, over
#                                                 the app's 40 MB of ONNX beside the generator; dry-run on this
#                                                 CPU: DEVICE=cpu SHAPES=2 CAL=8 END=170 WORKERS=0
#                                                 SPECS="big 8 6e-4" ARCH=... then fetch-gpu-v12)
#   INPUTS=generated ARCH="--predictor-channels 64 --predictor-hidden 1024" SPECS="gen12 512 4e-4" \
#     bash training/gpu_predictor.sh gpucarry/v12_more2
#                                                 that predictor fine-tuned on the generator's images as the app feeds
#                                                 it, at GPU speed (reproduce_models.sh gpucarry-v12; carry .whl,
#                                                 gpucarry/v12_more2 and gpucarry/models_fifth: 44 MB); dry-run on this
#                                                 CPU: DEVICE=cpu SHAPES=2 CAL=8 END=420 WORKERS=0 SPECS="gen 8 3e-4"
#                                                 INPUTS=generated DATA=/tmp/g256 ARCH=... (data 42 s, each generated
#                                                 set 35 s for 1,056 views on two busy cores: about 33 ms per view and
#                                                 core, so about 105 s per set on 16 cores for the 49,920 training views)
#   EXTRA="--mirror-consistency 50" (with either call above): more `train mesh` flags; this one keeps the
#                                                 larger predictor's vertex placement mirror-consistent, which the
#                                                 app's mirror averaging needs (model card, "Mirror averaging":
#                                                 predictor-v13-big); the eleventh pair's predictor:
#                                                 INPUTS=generated ARCH=... EXTRA="--mirror-consistency 50"
#                                                 SPECS="gen15 512 4e-4" bash training/gpu_predictor.sh
#                                                 gpucarry/v15_control (reproduce_models.sh gpucarry-v15)
#
# Runs: RUNS/NAME for each "NAME BATCH LR" of SPECS (';' between runs), side by side with the machine's
# cores split between them. A short concurrent calibration run of each (CAL iterations) sets its cosine
# schedule to end when the call must (END seconds after the start, default 555), measured, not guessed;
# CAL=0 skips it and trains ITERS iterations (WARMUP warm-up steps [100]). A second call on the same warm
# machine reuses the data it built. What comes back under $OUT: NAME.pt (the newest checkpoint without
# optimiser state) and logs.tgz; `GPU_FILES=DIR bash training/reproduce_models.sh fetch-gpu-v10` places
# them as runs.
#
# The eighth predictor's GPU stage (issue 16, 2026-11-26, H200) was two calls from the seventh (a slim
# copy of runs/v9/v9_mirror in gpucarry/v9_mirror):
#   SPECS="g10_b128 128 4e-4;g10_b512 512 8e-4" WORKERS=0 bash training/gpu_predictor.sh gpucarry/v9_mirror
#     (then without the thread split: the two processes took 16 threads each and ran at 0.4 it/s
#     side by side against 3.3 alone, so g10_b512 stopped at 189 of its 889 iterations)
#   SPECS="g10_b512b 512 6e-4" CAL=0 ITERS=520 WARMUP=20 END=190 WORKERS=0 bash training/gpu_predictor.sh runs/gpu10/g10_b512
#     (typed as the train command this script runs; 520 iterations in 156 s alone: 3.4 it/s, 1,770 samples/s against about 110 on this project's 2-core CPU)
# The tenth predictor's GPU stage (2026-11-26, H200, one warm machine, 13 minutes of device time held) was two calls from
# the ninth (reproduce_models.sh gpucarry-v11 writes gpucarry/v10_more):
#   SPECS="g11_b512 512 6e-4" bash training/gpu_predictor.sh gpucarry/v10_more
#     (data 94 s; calibration 6.8 it/s with 4 loader workers, twice the rate without them; 2,418 iterations in 356 s)
#   SPECS="g11_b512b 512 3e-4" CAL=0 ITERS=1500 WARMUP=20 END=265 bash training/gpu_predictor.sh runs/gpu10/g11_b512
#     (the data of the first call reused; 1,500 iterations in 206 s: 3,900 at batch 512 in all, about 2.0 M samples)
# The larger predictor (64 channels, hidden 1024: 7.1 M parameters, a 28 MB checkpoint, within the 40 MB of ONNX the app
# allows beside the 9.3 MB generator) from the start (2026-11-26, H100, one warm machine, 13 minutes of device time held):
#   ARCH="--predictor-channels 64 --predictor-hidden 1024" SPECS="big12 512 1e-3" END=530 bash training/gpu_predictor.sh fresh
#     (data 65 s; calibration 8.8 it/s; 2,900 iterations in 400 s)
#   ARCH="--predictor-channels 64 --predictor-hidden 1024" SPECS="big12b 512 5e-4" CAL=0 ITERS=1400 WARMUP=20 END=245 \
#     bash training/gpu_predictor.sh runs/gpu10/big12
#     (1,400 iterations in 188 s: 4,300 at batch 512, about 2.2 M samples; reproduce_models.sh fetch-gpu-v12, val-gpu-v12)
# The fourteenth candidate's GPU stage (2026-11-27, H100, 14 minutes of device time held): the thirteenth predictor (a slim
# copy of runs/v18/v18_more, reproduce_models.sh gpucarry-v19) on the generator's images, in two calls on one machine
# (carry .whl and gpucarry/v18_more; GEN_MODELS=assets/models, the same generator file as the fifth's, so the carry
# stays under 64 MiB):
#   INPUTS=generated ARCH="--predictor-channels 64 --predictor-hidden 1024 --predictor-aligned 128" \
#     EXTRA="--mirror-consistency 50" SPECS="g19 512 3e-4" END=560 GEN_MODELS=assets/models \
#     bash training/gpu_predictor.sh gpucarry/v18_more
#     (ran out of its 600 s building the 256-pixel data and the two generated sets, before any training: on the H100
#     they take about ten minutes, not the five estimated above, so a first INPUTS=generated call only builds)
#   the same with CAL=0 ITERS=600 WARMUP=20 END=190
#     (the data reused, the last 3,984 mirrored views generated in 18 s; 600 iterations at batch 512 in 122 s,
#     4.9 it/s: 307,000 samples, about twice what the thirteenth's 59 CPU minutes saw; reproduce_models.sh fetch-gpu-v19)
# INIT may also be an exported models folder (its mesh_predictor.onnx; e.g. assets/models, which travels with the
# tree): with INPUTS=generated the predictor is imported there (`import-models --only predictor`, batch norms
# calibrated on the generated set just built), so a session needs no local run, data or carry beyond .whl:
#   INPUTS=generated ARCH="--predictor-channels 64 --predictor-hidden 1024 --predictor-aligned 128" \
#     EXTRA="--mirror-consistency 50" SPECS="g20 512 3e-4" GEN_MODELS=assets/models bash training/gpu_predictor.sh assets/models
# Since then the generated sets run the generator in torch on the GPU (`data generated --torch-device cuda`; the
# workers only draw the sketches), so a first call should leave most of its ten minutes to training (not yet run
# on a GPU; on the CPU its rows equal ONNX Runtime's within float16, tests/test_generated_inputs.py).
# The fifteenth pair's predictor was trained on twice the shapes on the CPU (reproduce_models.sh data-v20 predictor-v20:
# 200 per category, ahead of its equal-sample control on the validation split in every case), so a lent GPU should
# train on them too: SHAPES=200 builds them there (twice the 1,300 shapes' rendering and generated views, so the
# first call mostly builds and a second call on the warm machine trains), from the bundled fifteenth pair:
#   SHAPES=200 INPUTS=generated ARCH="--predictor-channels 64 --predictor-hidden 1024 --predictor-aligned 128" \
#     EXTRA="--mirror-consistency 50" SPECS="g21 512 3e-4" GEN_MODELS=assets/models bash training/gpu_predictor.sh assets/models
# The seventeenth candidate's GPU stage (2026-11-27, H100, two calls on one warm machine, 14 minutes of device time held),
# from the bundled sixteenth pair (nothing carried but .whl): DATA20's shapes at half the views,
#   SHAPES=200 VIEWS=8 ELEVATIONS="0 20 40" INPUTS=generated ARCH="--predictor-channels 64 --predictor-hidden 1024 \
#     --predictor-aligned 128" EXTRA="--mirror-consistency 50" SPECS="g22 512 3e-4" END=565 GEN_MODELS=assets/models \
#     bash training/gpu_predictor.sh assets/models
#     (only built: 2,600 shapes at 24 views in 263 s, split md5 31f869fe... as DATA20's; the generator on the GPU made
#     each generated set of 50,088 views in 91 s, a quarter of ONNX Runtime's time on the 16 cores; no time left to train)
#   the same with CAL=0 ITERS=900 WARMUP=20 END=255
#     (900 iterations at batch 512 in 200 s, 4.5 it/s: 461,000 samples, about three of the CPU's 5,000-iteration
#     passes at batch 32; reproduce_models.sh fetch-gpu-v22, val-*-v22-gpu)
#   It came back far worse on the validation split (mirror averaged 0.500 / 0.466 / 0.467 against the sixteenth's
#   0.580 / 0.536 / 0.520): the predictor is specific to the views it trains at, and these were off the CPU data's grid
#   (12 azimuths 30 degrees apart at 0 / 15 / 30 / 45). On the same validation shapes (reproduce_models.sh views-v22) the
#   sixteenth scores 0.609 at grid views and 0.540 at views off it, g22 0.526 and 0.600: 900 iterations moved it to
#   its new views. So a GPU stage must train at the views it will be measured and used at: all 48 (SHAPES=100, the
#   fourteenth's data: 62,400 views like this call's, so at its rates about 263 s of data and 2 x 91 s of generated
#   sets, 7.5 minutes: a first call builds and a second call on the warm machine trains), or a data option that
#   draws each shape's views from the grid (not written yet).
# The nineteenth candidate's GPU stage (2026-11-27, H100, one call, 10 minutes of device time held), from the bundled
# eighteenth pair with nothing carried but .whl: twice DATA30's shapes at a twelfth of the views, each shape at 4 of the
# 48 grid views (one azimuth drawn at each elevation, `data --views-per-shape`):
#   SHAPES=600 VIEWS_PER_SHAPE=4 INPUTS=generated ARCH="--predictor-channels 64 --predictor-hidden 1024 \
#     --predictor-aligned 128" EXTRA="--mirror-consistency 50" SPECS="g25 512 3e-4" END=568 GEN_MODELS=assets/models \
#     bash training/gpu_predictor.sh assets/models
#     (7,800 shapes / 31,200 views in 144 s, split md5 751cbb43...; generated sets of 24,952 views in 67 s and 69 s;
#     import done at 325 s; 905 iterations at batch 512 in 189 s, 5.0 it/s: 463,000 samples; done at 561 s.) Lost: the
#     device tool could not copy the two 15 MiB parts back because this machine's disk was full (old CI clones in
#     /tmp), and the machine was handed back idle before a second call. Check `df -h .` here before a GPU call.
#     Rerun as is on the next lent GPU, then GPU_FILES=<files_at> bash training/reproduce_models.sh fetch-gpu-v25
#     val-v25-gpu val-strong-v25-gpu val-side-v25-gpu (against the eighteenth, out/v25).
#   Rerun (2026-11-27, H100, two calls on one warm machine, 13.5 minutes of device time held) from the bundled twentieth
#   pair, nothing carried but .whl: the call above as is (g25: the same split md5; 7,800 shapes in 186 s, the generated
#   sets in 76 s each, import at 381 s, calibration 4.5 it/s, 519 iterations at batch 512 in 116 s), then on the warm
#   machine from its end, the data reused (g25b: 560 iterations in 137 s; 1,079 in all, 552,000 samples):
#     SHAPES=600 VIEWS_PER_SHAPE=4 INPUTS=generated ARCH=... EXTRA="--mirror-consistency 50" SPECS="g25b 512 2e-4" CAL=0 \
#       ITERS=560 WARMUP=20 END=215 GEN_MODELS=assets/models bash training/gpu_predictor.sh runs/gpu10/g25
#   then fetch-gpu-v25 with each call's files, val-*-v25-gpu (against the twentieth). It was ahead on validation by
#   +0.012 / +0.005 / +0.018 mirror averaged, more than any CPU pass, and became the twenty-first pair (all-v26).
# The next lent GPU: the same two calls from the bundled twenty-first (assets/models), with SHAPES=800 (2,600 shapes
#   none of the stages has seen: more shapes is what paid; about 250 s of rendering and 2 x 100 s of generated sets,
#   so the first call trains about a minute and the second, on the warm machine, the rest), into RUNS g27 / g27b, at
#   batch 128 (header, "Which batch"; SPECS="g27 128 2e-4", between the CPU recipe's 1e-4 at 32 and g25's 3e-4 at 512).
#   Choose between it and the twenty-first on more than the validation split's 156 sketches: on them a pair's mean
#   carries about +-0.016 and a paired difference +-0.001 to 0.003 (sketchmesh eval prints both since 2026-11-28), and
#   last session's CPU passes looked 0.005-0.015 behind there but were within 0.003 on DATA72's 520 (reproduce_models.sh
#   check-*-v27, whose runs a later step can extend with the new one).
# The next lent GPU (prepared 2026-12-01; the CPU rounds of the legged specialist are spent: the model card's "A third
#   more samples a CPU minute"): the bundled legged specialist (PREDICTOR=mesh_predictor_legged.onnx) at batch 128 on
#   bench, chair and table shapes no stage has seen (ids 6000-7499, train split, 4 grid views each), nothing carried
#   but .whl (reproduce_models.sh whl-gpu), in one call of the device tool (carry [".whl"], timeout_s 600):
#     SHAPES=1500 FIRST_SHAPE=6000 CATEGORIES="bench chair table" SPLITS=train VIEWS_PER_SHAPE=4 INPUTS=generated \
#       PREDICTOR=mesh_predictor_legged.onnx GEN_MODELS=assets/models DATA=data/g256legs END=560 \
#       ARCH="--predictor-channels 64 --predictor-hidden 1024 --predictor-aligned 128" EXTRA="--mirror-consistency 50" \
#       SPECS="legs12 128 2e-4" bash training/gpu_predictor.sh assets/models
#   then here GPU_FILES=<files_at> bash training/reproduce_models.sh fetch-gpu-v59 check-legs-v59 (its choice set beside
#   the bundled specialist, as the CPU rounds were chosen), and when it is ahead gpulegs12-route-v59 (every test sketch,
#   routed as the bundle runs it) and ship-compact19-v59. Read its legs ("how the meshes stand") against ceiling-v57.
#   Dry run on this CPU (4.5 min, 894 iterations at batch 8; a 30 MB slim checkpoint in two parts): the same with
#   DEVICE=cpu SHAPES=3 CAL=8 END=400 WORKERS=0 SPECS="legs12 8 2e-4" DATA=/tmp/gdry RUNS=/tmp/gdry_runs OUT=/tmp/gdry_out
set -uo pipefail

INIT=${1:?usage: gpu_predictor.sh INIT_RUN|MODELS_DIR|fresh}
# INPUTS [true]: what the predictor reads. "true": the true normal images (the 64x64 data only). "generated": the
# generator's images of the training sketches and of their flipped drawings, as the app feeds it (the seventh's recipe,
# reproduce_models.sh train7: --input-normals normals16 --mirror-inputs normals16_mirror --no-normal-edges), built here
# from the 256x256 data and the generator file in GEN_MODELS [gpucarry/models_fifth] (reproduce_models.sh
# gpucarry-v12 puts it there; carry it): the 1.4 GB sets cannot travel, so the first call spends about five minutes
# of its ten on them (an estimate from this CPU's 34 ms per view and core) and a second call on the warm machine reuses them
INPUTS=${INPUTS:-true}
case "$INPUTS" in
  true) DATA=${DATA:-data/g64}; SIZE=(--size 64) ;;
  generated) DATA=${DATA:-data/g256}; SIZE=() ;;
  *) echo "INPUTS must be true or generated, got '$INPUTS'" >&2; exit 2 ;;
esac
GEN_MODELS=${GEN_MODELS:-gpucarry/models_fifth}
RUNS=${RUNS:-runs/gpu10}
DEVICE=${DEVICE:-cuda}
SHAPES=${SHAPES:-100}
# VIEWS azimuths at each of ELEVATIONS [12; 0 15 30 45: the 48 views of the CPU data]. Fewer views per shape build
# faster on the lent machine, but the predictor learns the views it is trained at and forgets others (the seventeenth
# candidate's stage below): keep the 48 unless the run is meant to move to other views
VIEWS=${VIEWS:-12}
ELEVATIONS=${ELEVATIONS:-"0 15 30 45"}
# VIEWS_PER_SHAPE K [every view]: render K of those grid views per shape (`data --views-per-shape`, as many at each
# elevation when K is a multiple of them): more shapes for the same rendering, still at the views the app is measured at
VIEWS_PER_SHAPE=${VIEWS_PER_SHAPE:-}
SUBSET=(); [ -n "$VIEWS_PER_SHAPE" ] && SUBSET=(--views-per-shape "$VIEWS_PER_SHAPE")
# CATEGORIES [all 13], FIRST_SHAPE [0] and SPLITS [all]: which procedural shapes the data holds (`data --categories
# --first-shape --splits`); a specialist trains on its categories' shapes that no stage has seen, all in the train split
# (e.g. CATEGORIES="bench chair table" FIRST_SHAPE=6000 SPLITS=train: the CPU rounds used ids up to 5749)
CATEGORIES=${CATEGORIES:-}
FIRST_SHAPE=${FIRST_SHAPE:-0}
SPLITS=${SPLITS:-}
PICK=(--first-shape "$FIRST_SHAPE")
# shellcheck disable=SC2206
[ -n "$CATEGORIES" ] && PICK+=(--categories $CATEGORIES)
# shellcheck disable=SC2206
[ -n "$SPLITS" ] && PICK+=(--splits $SPLITS)
# PREDICTOR [mesh_predictor.onnx]: which predictor file of an INIT models folder is imported and trained on (e.g.
# mesh_predictor_legged.onnx, the bundled specialist for bench, chair and table)
PREDICTOR=${PREDICTOR:-mesh_predictor.onnx}
CAL=${CAL:-60}
END=${END:-555}
SPECS=${SPECS:-"g10_b512 512 8e-4"}
ITERS=${ITERS:-0}
WARMUP=${WARMUP:-100}
T0=$(date +%s)
export PYTHONUNBUFFERED=1 PYTHONPATH="/tmp/site:$PWD"
SM=(python3 -m sketchmesh)
IFS=';' read -r -a RUNSPECS <<< "$SPECS"
NAMES=(); for s in "${RUNSPECS[@]}"; do read -r n _ <<< "$s"; NAMES+=("$n"); done
THREADS=$(( $(nproc) / ${#NAMES[@]} > 0 ? $(nproc) / ${#NAMES[@]} : 1 ))
[ "$CAL" -gt 0 ] || [ "$ITERS" -gt 0 ] || { echo "CAL=0 needs ITERS" >&2; exit 2; }
elapsed() { echo $(($(date +%s) - T0)); }

# Loader processes per run (WORKERS [4]): the eighth's calls ran with none, and gathering plus collating a batch of
# 512 views and their 1,536 extra views costs 0.2 to 0.8 s on this project's 2-core CPU, in series with the GPU's step
# there; with workers it overlaps the step: 6.8 it/s at batch 512 on the H200 against 3.4 without (the tenth's calls).
WORKERS=${WORKERS:-4}
ARCH=${ARCH:-}  # predictor size flags of `train mesh` (the same in every call that continues the run)
EXTRA=${EXTRA:-}  # further `train mesh` flags (e.g. --mirror-consistency 50)
INIT_ARGS=(--init-mesh "$INIT"); [ "$INIT" = fresh ] && INIT_ARGS=()
# the calls on true normal images (eighth to tenth pairs) ran with the paper's edge gradient on the normal image, then
# train mesh's default; it is pinned so they rerun as recorded (the default is off since 2026-11-28)
INPUT_ARGS=(--normal-edges); [ "$INPUTS" = generated ] && INPUT_ARGS=(--input-normals normals16 --mirror-inputs normals16_mirror --no-normal-edges)
train_args() {  # NAME BATCH LR -> the training command (the seventh predictor's recipe on INPUTS)
  # shellcheck disable=SC2086
  echo train mesh --data "$DATA" --device "$DEVICE" --quiet "${INIT_ARGS[@]}" "${INPUT_ARGS[@]}" $ARCH $EXTRA --batch "$2" --lr-mesh "$3" \
    --mirror 0.5 --num-workers "$WORKERS" --val-every 0 --plot-every 0 --threads "$THREADS"
}

if [ "$DEVICE" = cuda ]; then
  python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl \
    || exit 1
  nvidia-smi -L
fi
python3 -c "import torch, trimesh, manifold3d, cv2, onnxruntime; print('torch', torch.__version__, torch.cuda.is_available())" \
  || exit 1
echo "== data $(elapsed) s"
if [ -f "$DATA/manifest.json" ] && [ -f "$DATA/.cache/mesh_arrays.bin" ]; then
  echo "$DATA: already built"
else
  # shellcheck disable=SC2086
  "${SM[@]}" data --source procedural --shapes-per-category "$SHAPES" --views "$VIEWS" --elevations $ELEVATIONS "${SUBSET[@]}" "${PICK[@]}" "${SIZE[@]}" \
    --workers "$(nproc)" --no-progress --out "$DATA" || exit 1
  python3 -c "
import hashlib, json
m = json.load(open('$DATA/manifest.json'))
print('split md5', hashlib.md5(json.dumps([(s['shape_id'], s['split']) for s in m['shapes']]).encode()).hexdigest())
from training.data.mesh_cache import open_mesh_cache; open_mesh_cache('$DATA', None, 'disk'); print('mesh cache built')" || exit 1
fi
if [ "$INPUTS" = generated ]; then
  [ -f "$GEN_MODELS/generator.onnx" ] || { echo "INPUTS=generated needs $GEN_MODELS/generator.onnx (carry it)" >&2; exit 1; }
  for set in normals16 normals16_mirror; do
    echo "== generated $set $(elapsed) s (resumes: a second call finds it built)"
    flags=(); [ "$set" = normals16_mirror ] && flags=(--mirror)
    # the generator in torch on the GPU (data generated --torch-device): ONNX Runtime on the 16 cores took about 220 s a set
    [ "$DEVICE" = cuda ] && flags+=(--torch-device cuda)
    "${SM[@]}" data generated "$DATA" --models "$GEN_MODELS" --name "$set" "${flags[@]}" --workers "$(nproc)" --no-progress \
      || exit 1
  done
fi
if [ -f "$INIT/$PREDICTOR" ]; then  # INIT an exported models folder (e.g. assets/models): import its PREDICTOR here
  [ "$INPUTS" = generated ] || { echo "importing $INIT needs INPUTS=generated (its batch norms are calibrated on the generator's images)" >&2; exit 1; }
  echo "== import $INIT/$PREDICTOR $(elapsed) s"
  rm -rf /tmp/imported /tmp/init_models; mkdir -p /tmp/init_models
  cp "$INIT/$PREDICTOR" /tmp/init_models/mesh_predictor.onnx || exit 1  # import-models reads a folder's mesh_predictor.onnx
  "${SM[@]}" import-models /tmp/init_models --out /tmp/imported --only predictor --data "$DATA" --threads "$(nproc)" || exit 1
  INIT_ARGS=(--init-mesh /tmp/imported/predictor)
fi
if [ "$CAL" -gt 0 ]; then
  echo "== calibrate $(elapsed) s"
  rm -rf /tmp/cal; mkdir -p /tmp/cal
  for s in "${RUNSPECS[@]}"; do
    read -r n b lr <<< "$s"
    # shellcheck disable=SC2046
    "${SM[@]}" $(train_args "$n" "$b" "$lr") --out "/tmp/cal/$n" --iters "$CAL" --log-every $((CAL / 6)) \
      --ckpt-every 0 --lr-warmup 0 > "/tmp/cal/$n.log" 2>&1 &
  done
  wait
fi
LEFT=$((END - $(elapsed) - 25))  # 25 s: start-up of the runs and the last checkpoint
[ "$LEFT" -gt 30 ] || { echo "no time left to train ($LEFT s)"; exit 1; }
mkdir -p "$RUNS"
PIDS=()
echo "== launch $(elapsed) s, $LEFT s to train"
for s in "${RUNSPECS[@]}"; do
  read -r n b lr <<< "$s"
  if [ "$CAL" -eq 0 ]; then
    iters=$ITERS; echo "$n: batch $b, lr $lr: $iters iterations"
  else
    rate=$(python3 -c "
import csv; r = {int(x['iteration']): float(x['wall_s']) for x in csv.DictReader(open('/tmp/cal/$n/log.csv'))}
a = sorted(r)[len(r) // 3]; z = max(r); print((z - a) / (r[z] - r[a]))") || { tail -n 20 "/tmp/cal/$n.log"; exit 1; }
    iters=$(python3 -c "print(max(20, int($rate * $LEFT * 0.92)))")
    echo "$n: batch $b, lr $lr: $rate it/s side by side -> $iters iterations"
  fi
  # shellcheck disable=SC2046
  setsid nohup "${SM[@]}" $(train_args "$n" "$b" "$lr") --out "$RUNS/$n" --iters "$iters" --lr-warmup "$WARMUP" --log-every 20 \
    --ckpt-every 200 --max-minutes "$(python3 -c "print(round($LEFT / 60, 2))")" > "$RUNS/$n.out" 2>&1 < /dev/null &
  PIDS+=($!)
done
running() { for p in "${PIDS[@]}"; do kill -0 "$p" 2> /dev/null && return 0; done; return 1; }
while running && [ "$(elapsed)" -lt "$END" ]; do sleep 2; done
for n in "${NAMES[@]}"; do printf '%-10s ' "$n"; tail -n 1 "$RUNS/$n/log.csv" | cut -c1-160; tail -n 2 "$RUNS/$n.out"; done
[ "$DEVICE" != cuda ] || nvidia-smi --query-gpu=utilization.gpu,memory.used --format=csv,noheader
[ -n "${OUT:-}" ] || exit 0
for n in "${NAMES[@]}"; do  # the newest checkpoint of each run without optimiser state
  python3 -c "from training.loop.checkpoint import save_slim_copy as c; print('$n: iteration', c('$RUNS/$n', '$OUT/$n.pt'))"
  # the device tool brings back files of at most 16 MiB: a larger predictor's checkpoint comes back in parts
  # (NAME.pt.part-aa, -ab, ...), which fetch-gpu joins
  if [ "$(stat -c %s "$OUT/$n.pt")" -gt $((15 * 1024 * 1024)) ]; then
    split -b 15M "$OUT/$n.pt" "$OUT/$n.pt.part-" && rm "$OUT/$n.pt"
  fi
done
tar czf "$OUT/logs.tgz" --exclude='checkpoints' "$RUNS" 2>/dev/null  # RUNS/NAME/...: fetch-gpu's layout
ls -la "$OUT"; echo "done at $(elapsed) s"
