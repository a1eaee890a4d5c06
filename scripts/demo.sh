#!/usr/bin/env bash
# The main job as it stands: build, describe every real data file, virtually scan the bunny,
# build and verify point LOD stores of the real scans, render them headless (one view, a 2x2 wall),
# then run the wall as a cluster: tessera-master + 4 tessera-nodes (mpirun) on the 2x2 wall along
# the bunny orbit, writing the wall pictures and per-frame statistics.
# Outputs go to out/demo/ (override with TESSERA_DEMO_OUT).
set -uo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
data="${TESSERA_DATA_DIR:-$root/../shared/data}"
out="${TESSERA_DEMO_OUT:-$root/out/demo}"

./scripts/deps.sh || exit 1
cmake --preset release >/dev/null || exit 1
cmake --build --preset release -j"$(nproc)" --target tessera-lod tessera-render tessera-master tessera-node tessera-site || exit 1
lod="$root/build/release/lod/tessera-lod"
render="$root/build/release/render/tessera-render"
master="$root/build/release/master/tessera-master"
node="$root/build/release/render_node/tessera-node"
site="$root/build/release/collab/tessera-site"
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

echo "== pictures: headless renders of the stores (compute-shader points, eye-dome lighting)"
export EGL_PLATFORM=surfaceless
"$render" --model "$out/stores/bunny.tlod" --edl --size 1280x960 --background 0.05,0.05,0.08 \
  --stats "$out/render-stats.csv" -o "$out/bunny.png" || exit 1
"$render" --model "$out/stores/autzen.tlod" --size 1280x720 --stats "$out/render-stats.csv" -o "$out/autzen.png" || exit 1
"$render" --model "$out/stores/bunny.tlod" --edl --wall configs/walls/2x2.json --mosaic \
  --camera "eye=-0.03,0.12,0.42;target=-0.026,0.1,0;up=0,1,0" --background 0.05,0.05,0.08 \
  --stats "$out/render-stats.csv" -o "$out/wall-2x2.png" || exit 1

echo "== meshes: the bunny reconstruction as a patch hierarchy (.tmesh), verified, drawn beside the"
echo "   scans in one picture (points and triangles hide each other), one view and the 2x2 wall"
"$lod" build "$data/stanford-bunny/reconstruction/bun_zipper.ply" -o "$out/stores/bunny.tmesh" || exit 1
"$lod" verify "$out/stores/bunny.tmesh" "$data/stanford-bunny/reconstruction/bun_zipper.ply" --quiet \
  | tee "$out/stores/bunny-tmesh-verify.txt" || exit 1
"$render" --scene configs/scenes/bunny-mesh.json --size 1280x720 --stats "$out/render-stats.csv" \
  -o "$out/mesh-and-points.png" || exit 1
"$render" --scene configs/scenes/bunny-mesh.json --wall configs/walls/2x2.json --mosaic \
  --stats "$out/render-stats.csv" -o "$out/mesh-and-points-wall-2x2.png" || exit 1
# The same mesh see-through (opacity 0.45): points sampled on its triangles, through SPBR.
"$render" --scene configs/scenes/bunny-mesh-see-through.json --size 1280x720 --spbr-L 64 \
  --stats "$out/render-stats.csv" -o "$out/mesh-see-through.png" || exit 1

echo "== see-through (stochastic point-based rendering): the bunny's ten scans in two groups,"
echo "   fused at two opacities, and a photo fused with the scans"
scans="$data/stanford-bunny/scans"
awk -v d="$scans" '$1=="bmesh" && ($2=="bun000.ply"||$2=="bun045.ply"||$2=="bun315.ply"||$2=="chin.ply"||$2=="top2.ply") {$2=d"/"$2; print}' \
  "$scans/bun.conf" > "$out/stores/bunny-front.conf"
awk -v d="$scans" '$1=="bmesh" && ($2=="bun090.ply"||$2=="bun180.ply"||$2=="bun270.ply"||$2=="top3.ply"||$2=="ear_back.ply") {$2=d"/"$2; print}' \
  "$scans/bun.conf" > "$out/stores/bunny-back.conf"
"$lod" build "$out/stores/bunny-front.conf" -o "$out/stores/bunny-front.tlod" --quiet || exit 1
"$lod" build "$out/stores/bunny-back.conf" -o "$out/stores/bunny-back.tlod" --quiet || exit 1
"$render" --scene configs/scenes/bunny-fused.json --size 1280x960 --spbr-L 64 \
  --stats "$out/render-stats.csv" -o "$out/see-through-bunny.png" || exit 1
# An aerial view of Autzen as a photo standing behind the bunny (section 4.5 of the SPBR paper).
"$render" --model "$out/stores/autzen.tlod" --size 1280x720 --fovy 30 --background 0.92,0.9,0.85 \
  --camera "eye=636590,848900,1400;target=636590,849216,440;up=0,0,1" -o "$out/autzen-photo.png" || exit 1
"$lod" photo "$out/autzen-photo.png" --corner -0.13,0.03,-0.08 --u 0.2,0,0 --v 0,0.1125,0 \
  -o "$out/stores/photo.tlod" --quiet || exit 1
"$render" --model "$out/stores/bunny.tlod:0.4" --model "$out/stores/photo.tlod:0.7" --size 1280x960 \
  --camera "eye=0.05,0.14,0.3;target=-0.03,0.09,0;up=0,1,0" --spbr-L 64 \
  --stats "$out/render-stats.csv" -o "$out/see-through-photo.png" || exit 1

echo "== the wall as a cluster: master + 4 render nodes (mpirun, oversubscribed on $(nproc) cores),"
echo "   2x2 wall, headless, along configs/paths/bunny-fused-orbit.json over the fused scans, opacities"
echo "   changing on the way (12 s path sampled at 5 frames/s, deterministic)"
mpi=(mpirun --oversubscribe)
[ "$(id -u)" -eq 0 ] && mpi+=(--allow-run-as-root)
# configs/scenes/bunny-fused.json names the stores this script built (out/demo/stores/); the
# path's own screenshots (half-way and at the end of the turn) land in out/demo/cluster/.
mkdir -p "$out/cluster"
"${mpi[@]}" -np 1 "$master" --wall configs/walls/2x2.json --scene configs/scenes/bunny-fused.json \
  --script configs/paths/bunny-fused-orbit.json --frames "${TESSERA_DEMO_FRAMES:-61}" --fps 5 \
  --out-dir "$out/cluster" --screenshot "$out/cluster/wall-2x2-cluster.png" \
  --stats "$out/cluster/stats.csv" : -np 4 "$node" --headless | tee "$out/cluster/master.txt" || exit 1
# The same wall with the mesh scene: every node streams the patches its own tile needs.
"${mpi[@]}" -np 1 "$master" --wall configs/walls/2x2.json --scene configs/scenes/bunny-mesh.json \
  --frames "${TESSERA_DEMO_MESH_FRAMES:-5}" --fps 5 --out-dir "$out/cluster" \
  --screenshot "$out/cluster/wall-2x2-mesh-cluster.png" --stats "$out/cluster/mesh-stats.csv" \
  : -np 4 "$node" --headless | tee "$out/cluster/mesh-master.txt" || exit 1

echo
echo "== the same wall over ZeroMQ: nodes join on their own, one is killed (kill -9) on the way and"
echo "   restarted; the wall goes on with the lost tile striped red, then the node rejoins from a"
echo "   snapshot and its tile is exact again"
mkdir -p "$out/zmq"
rm -f "$out/zmq/"*.log "$out/zmq/stats.csv"
"$master" --transport zmq --listen tcp://127.0.0.1:7400 --wall configs/walls/2x2.json \
  --scene configs/scenes/bunny-fused.json --script configs/paths/bunny-fused-orbit.json \
  --frames "${TESSERA_DEMO_FRAMES:-61}" --fps 5 --max-fps 4 --node-timeout 3000 \
  --out-dir "$out/zmq" --screenshot "$out/zmq/wall-2x2-zmq.png" \
  --stats "$out/zmq/stats.csv" >"$out/zmq/master.log" 2>&1 &
master_pid=$!
node_pids=()
for tile in tile-0-0 tile-1-0 tile-0-1 tile-1-1; do
  "$node" --master tcp://127.0.0.1:7400 --headless --tile "$tile" >"$out/zmq/node-$tile.log" 2>&1 &
  node_pids+=($!)
done
wait_in() {  # wait_in FILE PATTERN SECONDS: until FILE has PATTERN (or the master ended)
  local end=$((SECONDS + $3))
  until grep -q "$2" "$1" 2>/dev/null; do
    if ((SECONDS > end)) || ! kill -0 "$master_pid" 2>/dev/null; then return 1; fi
    sleep 0.2
  done
}
wait_for() { wait_in "$out/zmq/master.log" "$1" "$2"; }  # wait_for PATTERN SECONDS: the master's log
t0=$(date +%s.%N)
stamp() { awk -v a="$(date +%s.%N)" -v b="$t0" -v m="$1" 'BEGIN { printf "  %6.2f s  %s\n", a - b, m }'; }
frames_done() {  # the last frame in the master's stats
  awk -F, 'NR > 1 && $1 > f { f = $1 } END { print f + 0 }' "$out/zmq/stats.csv" 2>/dev/null || echo 0
}
end=$((SECONDS + 300))
until (($(frames_done) >= 15)) || ((SECONDS > end)) || ! kill -0 "$master_pid" 2>/dev/null; do sleep 0.2; done
if kill -0 "$master_pid" 2>/dev/null; then
  stamp "frame $(frames_done): kill -9 tile-1-0 (pid ${node_pids[1]})"
  kill -9 "${node_pids[1]}"
  wait_for "tile-1-0 .* dropped" 30 && stamp "$(grep -m1 'tile-1-0 .* dropped' "$out/zmq/master.log")"
  sleep 2
  stamp "restart tile-1-0"
  "$node" --master tcp://127.0.0.1:7400 --headless --tile tile-1-0 >"$out/zmq/node-tile-1-0-restarted.log" 2>&1 &
  node_pids[1]=$!
  wait_for "tile-1-0 .* rejoined" 30 && stamp "$(grep -m1 'tile-1-0 .* rejoined' "$out/zmq/master.log")"
fi
wait "$master_pid" || { echo "the ZeroMQ wall failed: $out/zmq/master.log"; exit 1; }
for p in "${node_pids[@]}"; do wait "$p" 2>/dev/null || true; done
stamp "the session ended: $(tail -1 "$out/zmq/master.log")"
awk -F, '$4 == "master" && NR > 1 { n++; s += $10; if ($10 > m) m = $10 }
  END { if (n) printf "  %d frames, mean %.0f ms, slowest %.0f ms\n", n, s / n, m }' "$out/zmq/stats.csv"

echo
echo "== two remote sites join the wall over encrypted ZeroMQ (CURVE keys, an allow list): Kyoto"
echo "   draws a stroke on the bunny and leads the view, Leiden follows it, then both go their own"
echo "   way; their avatars and the sketch are on every tile, and each sends a test-pattern video"
echo "   (H.264, 320x240, 300 kbit/s) that the wall shows as an inset beside its avatar; each says a"
echo "   sentence (espeak-ng, Opus over the link) and the master mixes what the wall room hears"
sd="$out/sites"
rm -rf "$sd" && mkdir -p "$sd/kyoto" "$sd/leiden" && chmod 700 "$sd"
kyoto_voice=() leiden_voice=()
if command -v espeak-ng >/dev/null 2>&1 &&
  espeak-ng -w "$sd/kyoto-says.wav" "Hello from Kyoto. Look at the ear of the bunny, I am drawing on it." &&
  espeak-ng -s 150 -v en-us -w "$sd/leiden-says.wav" "Leiden here. We follow your view, Kyoto."; then
  kyoto_voice=(--audio-in "$sd/kyoto-says.wav")
  leiden_voice=(--audio-in "$sd/leiden-says.wav")
else
  echo "   (espeak-ng not installed: the sites say nothing)"
fi
"$site" keygen -o "$sd/master.key" >"$sd/master.pub" 2>/dev/null
"$site" keygen -o "$sd/kyoto.key" >"$sd/kyoto.pub" 2>/dev/null
"$site" keygen -o "$sd/leiden.key" >"$sd/leiden.pub" 2>/dev/null
{ echo "$(cat "$sd/kyoto.pub")  Kyoto lab"; echo "$(cat "$sd/leiden.pub")  Leiden museum"; } >"$sd/allow.txt"
chmod 600 "$sd/allow.txt"
"$master" --transport zmq --listen tcp://127.0.0.1:7410 --wall configs/walls/2x2.json \
  --scene configs/scenes/bunny.json --script configs/paths/bunny-sites.json --max-fps 15 \
  --sites tcp://127.0.0.1:7411 --site-key "$sd/master.key" --allow "$sd/allow.txt" \
  --voice --audio-out "$sd/wall-room.wav" \
  --screenshot "$sd/wall-with-sites.png" --stats "$sd/stats.csv" >"$sd/master.log" 2>&1 &
master_pid=$!
node_pids=()
for tile in tile-0-0 tile-1-0 tile-0-1 tile-1-1; do
  "$node" --master tcp://127.0.0.1:7410 --headless --tile "$tile" >"$sd/node-$tile.log" 2>&1 &
  node_pids+=($!)
done
wait_in "$sd/master.log" "4 of 4 tiles have a node" 120
"$site" --master tcp://127.0.0.1:7411 --master-key "$(cat "$sd/master.pub")" --name "Kyoto lab" \
  --key "$sd/kyoto.key" --headless -o "$sd/kyoto" --script configs/sites/kyoto.json \
  --video test --video-size 320x240 --video-kbps 300 "${kyoto_voice[@]}" >"$sd/kyoto.log" 2>&1 &
kyoto_pid=$!
wait_in "$sd/kyoto.log" "leads the view" 120
"$site" --master tcp://127.0.0.1:7411 --master-key "$(cat "$sd/master.pub")" --name "Leiden museum" \
  --key "$sd/leiden.key" --headless -o "$sd/leiden" --script configs/sites/leiden.json \
  --video test --video-size 320x240 --video-kbps 300 "${leiden_voice[@]}" >"$sd/leiden.log" 2>&1 &
leiden_pid=$!
wait "$master_pid" || { echo "the wall with sites failed: $sd/master.log"; exit 1; }
for p in "${node_pids[@]}" "$kyoto_pid" "$leiden_pid"; do wait "$p" 2>/dev/null || true; done
grep "sites:" "$sd/master.log" | sed 's/^/  /'
cat "$sd/kyoto.log" "$sd/leiden.log" | sed 's/^/  /'

echo
echo "Outputs:"
echo "  $out/info.txt                      description of every data file"
echo "  $out/info.json                     the same as JSON"
echo "  $out/bunny-virtual-scans/          virtual range scans (Stanford format) + scans.conf"
echo "  $out/bunny-virtual-scans.txt       their description"
echo "  $out/stores/bunny.tlod, autzen.tlod   point LOD stores (the renderer's input)"
echo "  $out/stores.txt                    their description"
echo "  $out/bunny.png, autzen.png          renders of the stores"
echo "  $out/wall-2x2.png                   the 2x2 wall (configs/walls/2x2.json), tiles assembled with bezels"
echo "  $out/render-stats.csv               per-view render statistics"
echo "  $out/cluster/wall-2x2-cluster.png   the cluster's wall picture (master + 4 nodes), last frame"
echo "  $out/see-through-bunny.png         the two groups of bunny scans fused at opacities 0.3 (orange) and 0.6 (blue)"
echo "  $out/see-through-photo.png         a photo fused with the scans (tessera-lod photo)"
echo "  $out/cluster/bunny-fused-half.png, bunny-fused.png   the path's own screenshots"
echo "  $out/cluster/stats.csv              per frame and node: sync, render, barrier ms, points, resident bytes"
echo "  $out/cluster/master.txt             the master's log (each screenshot's camera, for tessera-render --camera)"
echo "  $out/zmq/                           the ZeroMQ wall: master.log (joins, the drop, the rejoin), stats.csv,"
echo "                                      the path's screenshots (the lost tile striped red), node logs"
echo "  $out/sites/wall-with-sites.png      the wall with two remote sites: their avatars (head, view frustum,"
echo "                                      name), their video insets beside them and Kyoto's sketch on the"
echo "                                      bunny; master.log (joins, lead, video, voice)"
echo "  $out/sites/wall-room.wav            what the wall room's speakers played: both sites' sentences,"
echo "                                      mixed by the master (kyoto-says.wav, leiden-says.wav: what they said)"
echo "  $out/sites/kyoto/, leiden/          the sites' own views, Leiden's while following Kyoto, strokes.csv"
