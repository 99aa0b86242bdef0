#!/usr/bin/env bash
# Smoke test of the built app (run by hand or in a slow CI job, not in the default tests):
# the frozen app starts, opens a sample sketch, writes a window screenshot, and exports a GLB.
# Usage: packaging/smoke.sh [MODELS_DIR]   (default: the bundled assets/models)
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
cd "$here/.."
app=packaging/dist/sketchmesh/sketchmesh
[ -x "$app" ] || bash packaging/build.sh
models_args=()
[ $# -ge 1 ] && models_args=(--models "$1")
sample=$(ls assets/samples/*.png 2>/dev/null | head -1 || true)
[ -n "$sample" ] || { echo "smoke: no sample sketch in assets/samples" >&2; exit 1; }
out=$(mktemp -d)
run() { if [ -n "${DISPLAY:-}" ]; then "$@"; else xvfb-run -a -s "-screen 0 1600x1000x24" "$@"; fi; }
run "$app" "${models_args[@]}" --open "$sample" --screenshot "$out/window.png"
"$app" infer "$sample" -o "$out/mesh.glb" "${models_args[@]}"
for f in window.png mesh.glb; do
  [ -s "$out/$f" ] || { echo "smoke: $f was not written" >&2; exit 1; }
done
echo "smoke: ok ($out/window.png, $out/mesh.glb)"
