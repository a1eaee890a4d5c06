#!/usr/bin/env bash
# The main job as it stands: build, describe every real data file, virtually scan the bunny.
# Outputs go to out/demo/ (override with TESSERA_DEMO_OUT).
set -uo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
data="${TESSERA_DATA_DIR:-$root/../shared/data}"
out="${TESSERA_DEMO_OUT:-$root/out/demo}"

./scripts/deps.sh || exit 1
cmake --preset release >/dev/null || exit 1
cmake --build --preset release -j"$(nproc)" --target tessera-lod || exit 1
lod="$root/build/release/lod/tessera-lod"
mkdir -p "$out"

echo "== tessera-lod info on every file in $data"
mapfile -t files < <(find "$data" -type f \( -name '*.ply' -o -name '*.las' -o -name '*.laz' -o -name '*.conf' \
                       -o -name '*.xyz' -o -name '*.pts' -o -name '*.obj' \) | sort)
"$lod" info "${files[@]}" | tee "$out/info.txt"
"$lod" info --json --quiet "${files[@]}" > "$out/info.json" 2>/dev/null
echo "(files that could not be read are reported above with the reason; that is expected for the .laz)"

echo "== virtual scanner: the bunny reconstruction, 12 scanners, 0.2 mm noise"
"$lod" --config configs/scans/bunny-demo.toml scan "$data/stanford-bunny/reconstruction/bun_zipper.ply" \
  -o "$out/bunny-virtual-scans" || exit 1
"$lod" info "$out/bunny-virtual-scans/scans.conf" | tee "$out/bunny-virtual-scans.txt" | head -12

echo
echo "Outputs:"
echo "  $out/info.txt                      description of every data file"
echo "  $out/info.json                     the same as JSON"
echo "  $out/bunny-virtual-scans/          virtual range scans (Stanford format) + scans.conf"
echo "  $out/bunny-virtual-scans.txt       their description"
