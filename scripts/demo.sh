#!/usr/bin/env bash
# The main job as it stands: build, describe every real data file, virtually scan the bunny,
# build and verify point LOD stores of the real scans.
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

echo "== point LOD stores: the registered bunny scans and the Autzen LiDAR, built and verified"
mkdir -p "$out/stores"
"$lod" build "$data/stanford-bunny/scans/bun.conf" -o "$out/stores/bunny.tlod" || exit 1
"$lod" verify "$out/stores/bunny.tlod" "$data/stanford-bunny/scans/bun.conf" --quiet || exit 1
"$lod" build "$data/lidar/autzen_trim.las" -o "$out/stores/autzen.tlod" || exit 1
"$lod" verify "$out/stores/autzen.tlod" "$data/lidar/autzen_trim.las" --quiet || exit 1
"$lod" info "$out/stores/bunny.tlod" "$out/stores/autzen.tlod" | tee "$out/stores.txt"

echo
echo "Outputs:"
echo "  $out/info.txt                      description of every data file"
echo "  $out/info.json                     the same as JSON"
echo "  $out/bunny-virtual-scans/          virtual range scans (Stanford format) + scans.conf"
echo "  $out/bunny-virtual-scans.txt       their description"
echo "  $out/stores/bunny.tlod, autzen.tlod   point LOD stores (the renderer's input)"
echo "  $out/stores.txt                    their description"
