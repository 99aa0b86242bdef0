#!/usr/bin/env bash
# Builds the one-folder app into packaging/dist/sketchmesh and prints its size.
# Needs: pip install pyinstaller (in the environment that has the app installed, without
# the training extra being required: torch is excluded from the bundle either way).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
cd "$here/.."
command -v pyinstaller >/dev/null || { echo "build.sh: pyinstaller not found: pip install pyinstaller" >&2; exit 2; }
pyinstaller --noconfirm --log-level WARN --distpath packaging/dist --workpath packaging/build packaging/sketchmesh.spec
out=packaging/dist/sketchmesh
if [ -d "$out/_internal/torch" ] || [ -d "$out/_internal/training" ]; then
  echo "build.sh: torch or training leaked into the bundle" >&2; exit 1
fi
echo "built $out: $(du -sh "$out" | cut -f1) in $(find "$out" -type f | wc -l) files"
# sed, not head: head exits early, sort dies of SIGPIPE and pipefail failed the build (rc 141)
echo "largest parts:"; du -sh "$out"/_internal/* 2>/dev/null | sort -rh | sed -n 1,8p
