#!/usr/bin/env bash
# What grows how with the input size: real LiDAR tiled to 10^7, 10^8 and 10^9 points, end to end.
# See --help.
set -euo pipefail

usage() {
  cat <<'EOF'
Usage: bench/scale.sh [--sizes 1e7,1e8,1e9] [--work DIR] [--out DIR] [--build DIR]
                      [--memory-mb M] [--threads T] [--rebuild] [--rounds R] [--wall-rounds W]
                      [--drop-caches] [--skip-wall] [--skip-site] [--chart-only]

Tiles Autzen (autzen_trim.laz: 110,000 real airborne LiDAR points) side by side into one LAZ of
each size (bench/tile_scan; 10^9 points are 5.5 GB as LAZ, 34 GB as LAS), then for each:

  build     tessera-lod build IN.laz -o S.tlod --threads T --memory-mb M, timed by /usr/bin/time -v
            (wall time, peak RSS), store bytes a point
  verify    tessera-lod verify S.tlod IN.laz: every input point found in the store
  store     bench/scale: open, first picture, settled full view (1920x1080, the defaults
            without the pixel budget: every level the pixels ask for), a frame resident so and
            with a budget of 10^6 points, a lasso over the middle half of the view, a distance
            between two full-resolution picks; each the median of --rounds rounds
  wall      the 2x2 wall (configs/walls/2x2.json, 1920x1080 in all) over ZeroMQ: tessera-master
            and four tessera-nodes on this machine flying configs/paths/autzen-flyover.json in
            real time (20 s) over the store's first copy of Autzen; frame times from --stats,
            the median over --wall-rounds runs of each run's median and 95th percentile
  site      bench/site_join --store S.tlod --rates 20 --join-only: a remote site without the
            store joins over a link of 20 Mbit/s and settles its view

Inputs and stores go to --work (default /tmp/tessera-scale; about 40 GB at 10^9: the LAZ, the
build's temporary files and the store), kept for the next run (--rebuild builds again).
Results in --out (default BUILD/bench-results/scale):
  scale_build.csv  size, points, build_s, build_mpts, build_peak_mb, store_bytes,
                   bytes_per_point, verify_s, verify_peak_mb, verified
  scale_store.csv  bench/scale's figures per store (open_ms ... measure_ms)
  scale_wall.csv   size, frames, median and 95th percentile frame ms, median points a tile
                   (medians over the runs; scale_wall_rounds.csv: every run)
  scale_site.csv   size, joined_s, first_image_s, settled_s, fetched_bytes
  scale.png        the figures against the input size (gnuplot)
  logs/            every run's output

Options:
  --sizes LIST      point counts (default 1e7,1e8,1e9)
  --work DIR        inputs and stores (default /tmp/tessera-scale)
  --out DIR         results (default BUILD/bench-results/scale)
  --build DIR       the build tree with the tools and benches (default build/release, else
                    build/dev)
  --memory-mb M     the builds' memory budget (default 8192)
  --threads T       build threads (default 2)
  --rebuild         build the stores again even when they are there
  --rounds R        bench/scale rounds over the stores (default 5)
  --wall-rounds W   wall runs per store (default 3)
  --drop-caches     bench/scale drops the OS page cache before the view, the lasso and the
                    measurement (root only): cold from the disk, not only from a fresh store
  --skip-wall       no wall runs
  --skip-site       no site runs
  --chart-only      redraw scale.png from the CSVs already in --out, measuring nothing
EOF
}

die() { echo "scale.sh: error: $*" >&2; exit 1; }

repo=$(cd "$(dirname "$0")/.." && pwd)
sizes=1e7,1e8,1e9
work=/tmp/tessera-scale
out=
build=
memory=8192
threads=2
rebuild=0
rounds=5
wall_rounds=3
skip_wall=0
skip_site=0
chart_only=0
drop_caches=()
while [ $# -gt 0 ]; do
  case "$1" in
    -h|--help) usage; exit 0 ;;
    --sizes) sizes=${2:?--sizes needs a value}; shift 2 ;;
    --work) work=${2:?--work needs a value}; shift 2 ;;
    --out) out=${2:?--out needs a value}; shift 2 ;;
    --build) build=${2:?--build needs a value}; shift 2 ;;
    --memory-mb) memory=${2:?--memory-mb needs a value}; shift 2 ;;
    --threads) threads=${2:?--threads needs a value}; shift 2 ;;
    --rebuild) rebuild=1; shift ;;
    --rounds) rounds=${2:?--rounds needs a value}; shift 2 ;;
    --wall-rounds) wall_rounds=${2:?--wall-rounds needs a value}; shift 2 ;;
    --skip-wall) skip_wall=1; shift ;;
    --skip-site) skip_site=1; shift ;;
    --chart-only) chart_only=1; shift ;;
    --drop-caches) drop_caches=(--drop-caches); shift ;;
    *) die "unknown option '$1' (--help lists them)" ;;
  esac
done
if [ -z "$build" ]; then
  build=$repo/build/release
  [ -x "$build/lod/tessera-lod" ] || build=$repo/build/dev
fi
build=$(cd "$build" && pwd) || die "no build tree at $build"
out=${out:-$build/bench-results/scale}
[[ "$memory" =~ ^[0-9]+$ ]] || die "--memory-mb must be a whole number, got '$memory'"
[[ "$threads" =~ ^[0-9]+$ ]] || die "--threads must be a whole number, got '$threads'"
[[ "$rounds" =~ ^[1-9][0-9]*$ ]] || die "--rounds must be a whole number above 0, got '$rounds'"
[[ "$wall_rounds" =~ ^[1-9][0-9]*$ ]] ||
  die "--wall-rounds must be a whole number above 0, got '$wall_rounds'"
lod=$build/lod/tessera-lod
command -v gnuplot >/dev/null || die "gnuplot is not installed"

# "Maximum resident set size (kbytes): N" and "Elapsed (wall clock) time (h:mm:ss or m:ss): T"
peak_mb() { awk -F': ' '/Maximum resident set size/ {printf "%.0f", $2 / 1024}' "$1"; }
wall_s() {
  awk -F': ' '/Elapsed \(wall clock\)/ {n = split($2, t, ":"); s = 0;
              for (i = 1; i <= n; i++) s = s * 60 + t[i]; printf "%.2f", s}' "$1"
}

# The chart of OUT's CSVs: scale.png.
draw_chart() {
  echo "== chart" >&2
  join_col() {  # file, column name -> "points value" lines
    python3 - "$1" "$2" "$3" <<'PY'
import csv, sys
path, x, y = sys.argv[1:]
try:
    with open(path) as f:
        for row in csv.DictReader(f):
            print(float(row[x]) if x != "size" else float(row["size"]), row[y])
except FileNotFoundError:
    pass
PY
  }
  join_col "$out/scale_build.csv" points build_s > "$out/g_build_s.dat"
  join_col "$out/scale_build.csv" points verify_s > "$out/g_verify_s.dat"
  join_col "$out/scale_build.csv" points build_mpts > "$out/g_build_mpts.dat"
  join_col "$out/scale_build.csv" points build_peak_mb > "$out/g_build_peak.dat"
  join_col "$out/scale_build.csv" points bytes_per_point > "$out/g_bpp.dat"
  join_col "$out/scale_store.csv" points first_ms > "$out/g_first.dat"
  join_col "$out/scale_store.csv" points settle_ms > "$out/g_settle.dat"
  join_col "$out/scale_store.csv" points frame_ms > "$out/g_frame.dat"
  join_col "$out/scale_store.csv" points budget_frame_ms > "$out/g_budget.dat"
  join_col "$out/scale_store.csv" points lasso_ms > "$out/g_lasso.dat"
  join_col "$out/scale_store.csv" points measure_ms > "$out/g_measure.dat"
  [ -f "$out/scale_wall.csv" ] && join_col "$out/scale_wall.csv" size median_frame_ms > "$out/g_wall.dat"
  [ -f "$out/scale_site.csv" ] && python3 - "$out/scale_site.csv" > "$out/g_site.dat" <<'PY'
import csv, sys
for row in csv.DictReader(open(sys.argv[1])):
    print(float(row["size"]), float(row["settled_s"]) * 1000)
PY
  touch "$out/g_wall.dat" "$out/g_site.dat"
  # Room above the largest peak RSS, for the key.
  local rss_top
  rss_top=$(awk -F, 'NR > 1 && $5 > m {m = $5} END {printf "%.0f", 1.25 * m + 1}' \
    "$out/scale_build.csv" 2>/dev/null || echo 1)
  gnuplot <<EOF
set terminal pngcairo size 1200,480 font 'DejaVu Sans,10' noenhanced
set output '$out/scale.png'
set multiplot layout 1,3 title 'Tiled Autzen LiDAR from 10^7 to 10^9 points, 2 shared cores, llvmpipe'
set logscale x
set format x '10^%L'
set xrange [5e6:2e9]
set grid
set key top left
set title 'build and verification (grow with the input)'
set xlabel 'input points'
set ylabel 's (log)'
set logscale y
set y2label 'peak RSS, MB'
set y2tics
set yrange [1:3000]
set y2range [0:$rss_top]
plot '$out/g_build_s.dat' using 1:2 with linespoints pt 7 title 'build time, s', \
     '$out/g_verify_s.dat' using 1:2 with linespoints pt 9 title 'verify time, s', \
     '$out/g_build_peak.dat' using 1:2 axes x1y2 with linespoints pt 5 title 'build peak RSS, MB'
unset y2tics
unset y2label
unset logscale y
set title 'build rate and store size'
set ylabel 'M points/s, bytes a point'
set yrange [0:7]
set key bottom right
plot '$out/g_build_mpts.dat' using 1:2 with linespoints pt 7 title 'build, M points/s', \
     '$out/g_bpp.dat' using 1:2 with linespoints pt 5 title 'store bytes a point'
set title 'what a user waits for'
set ylabel 'ms'
set logscale y
set yrange [1:1e5]
set key top left font ',8'
plot '$out/g_first.dat' using 1:2 with linespoints pt 7 title 'first picture (cold)', \
     '$out/g_settle.dat' using 1:2 with linespoints pt 5 title 'settled view (cold)', \
     '$out/g_frame.dat' using 1:2 with linespoints pt 9 title 'frame, every level', \
     '$out/g_budget.dat' using 1:2 with linespoints pt 11 title 'frame, budget 10^6', \
     '$out/g_lasso.dat' using 1:2 with linespoints pt 13 title 'lasso, middle half', \
     '$out/g_measure.dat' using 1:2 with linespoints pt 3 title 'measure (2 picks)', \
     '$out/g_wall.dat' using 1:2 with linespoints pt 4 title '2x2 wall frame (median)', \
     '$out/g_site.dat' using 1:2 with linespoints pt 6 title 'site settled at 20 Mbit/s'
unset multiplot
EOF
  rm -f "$out"/g_*.dat
}

if [ "$chart_only" = 1 ]; then
  draw_chart
  echo "scale.sh: $out/scale.png redrawn" >&2
  exit 0
fi
for tool in "$lod" "$build/bench/tile_scan" "$build/bench/scale" "$build/master/tessera-master" \
            "$build/render_node/tessera-node" "$build/bench/site_join"; do
  [ -x "$tool" ] || die "$tool is missing: build it first (cmake --build $build --target ...)"
done
data=$repo/../shared/data/lidar/autzen_trim.laz
[ -f "$data" ] || die "no $data"
mkdir -p "$work" "$out/logs"

IFS=, read -r -a size_list <<< "$sizes"
build_csv=$out/scale_build.csv
echo "size,points,build_s,build_mpts,build_peak_mb,store_bytes,bytes_per_point,verify_s,verify_peak_mb,verified" > "$build_csv"
stores=()
for size in "${size_list[@]}"; do
  n=$(python3 -c "import sys; v = float(sys.argv[1]); print(int(v) if v == int(v) and v >= 1 else '')" "$size" 2>/dev/null) || true
  [ -n "$n" ] || die "--sizes: '$size' is not a whole number of points"
  in=$work/autzen-$size.laz
  store=$work/autzen-$size.tlod
  if [ ! -f "$in" ]; then
    echo "== tiling $size points into $in" >&2
    "$build/bench/tile_scan" "$data" -o "$in" -n "$n" --threads "$threads"
  fi
  if [ "$rebuild" = 1 ] || [ ! -f "$store" ] || [ ! -f "$out/logs/build-$size.txt" ]; then
    echo "== building $store" >&2
    rm -f "$store"
    /usr/bin/time -v "$lod" build "$in" -o "$store" --threads "$threads" --memory-mb "$memory" \
      > "$out/logs/build-$size.txt" 2>&1 || die "the build failed: $out/logs/build-$size.txt"
    echo "== verifying $store" >&2
    /usr/bin/time -v "$lod" verify "$store" "$in" --memory-mb "$memory" \
      > "$out/logs/verify-$size.txt" 2>&1 || true
  fi
  b=$out/logs/build-$size.txt
  v=$out/logs/verify-$size.txt
  bytes=$(stat -c %s "$store")
  bs=$(wall_s "$b")
  ok=0
  grep -q "^OK:" "$v" && ok=1
  python3 - "$size" "$n" "$bs" "$(peak_mb "$b")" "$bytes" "$(wall_s "$v")" "$(peak_mb "$v")" "$ok" >> "$build_csv" <<'PY'
import sys
size, n, bs, peak, nbytes, vs, vpeak, ok = sys.argv[1:]
n = int(n); bs = float(bs); nbytes = int(nbytes)
print(f"{size},{n},{bs:.1f},{n / bs / 1e6:.2f},{peak},{nbytes},{nbytes / n:.3f},{vs},{vpeak},{ok}")
PY
  stores+=("$size=$store")
done
cat "$build_csv"

echo "== store figures" >&2
"$build/bench/scale" "${stores[@]}" --out "$out" --rounds "$rounds" "${drop_caches[@]}" \
  2> "$out/logs/scale.txt"

if [ "$skip_wall" = 0 ]; then
  wall_csv=$out/scale_wall.csv
  wall_rounds_csv=$out/scale_wall_rounds.csv
  echo "round,size,frames,median_frame_ms,p95_frame_ms,median_tile_points" > "$wall_rounds_csv"
  # Round after round over the stores, so load from other work hits each size alike.
  for round in $(seq 1 "$wall_rounds"); do
    for spec in "${stores[@]}"; do
      size=${spec%%=*}
      store=${spec#*=}
      dir=$out/wall-$size-$round
      mkdir -p "$dir"
      sed -E "s|\"store\"[[:space:]]*:[[:space:]]*\"[^\"]*\"|\"store\": \"$store\"|" \
        "$repo/configs/scenes/autzen.json" > "$dir/scene.json"
      rm -f "$dir/stats.csv"
      echo "== wall over ZeroMQ, $size, run $round of $wall_rounds" >&2
      # The path's screenshot step writes beside the master: into this run's folder.
      pushd "$dir" > /dev/null
      "$build/master/tessera-master" --transport zmq --listen "tcp://127.0.0.1:*" \
        --wall "$repo/configs/walls/2x2.json" --scene "$dir/scene.json" \
        --script "$repo/configs/paths/autzen-flyover.json" --join-wait 120 \
        --stats "$dir/stats.csv" > "$dir/master.txt" 2>&1 &
      master=$!
      endpoint=
      for _ in $(seq 1 300); do
        endpoint=$(grep -o -m1 'listening on tcp://[^ ]*' "$dir/master.txt" 2>/dev/null | cut -d' ' -f3) || true
        [ -n "$endpoint" ] && break
        kill -0 "$master" 2>/dev/null || break
        sleep 0.1
      done
      popd > /dev/null
      if [ -z "$endpoint" ]; then
        kill "$master" 2>/dev/null || true
        die "tessera-master did not listen; see $dir/master.txt"
      fi
      nodes=()
      for t in tile-0-0 tile-1-0 tile-0-1 tile-1-1; do
        "$build/render_node/tessera-node" --master "$endpoint" --headless --tile "$t" \
          > "$dir/node-$t.txt" 2>&1 &
        nodes+=($!)
      done
      status=0
      wait "$master" || status=$?
      for p in "${nodes[@]}"; do
        for _ in $(seq 1 100); do kill -0 "$p" 2>/dev/null || break; sleep 0.1; done
        kill "$p" 2>/dev/null || true
        wait "$p" 2>/dev/null || true
      done
      [ "$status" = 0 ] || die "the wall run failed ($status); see $dir/master.txt"
      python3 - "$round" "$size" "$dir/stats.csv" >> "$wall_rounds_csv" <<'PY'
import csv, statistics, sys
rnd, size, path = sys.argv[1:]
frames = {}
points = []
with open(path) as f:
    for row in csv.DictReader(f):
        if row["tile"] == "master":
            frames[row["frame"]] = float(row["frame_ms"])
        elif row["state"] == "live":
            points.append(float(row["points"]))
ms = sorted(frames.values())
p95 = ms[min(len(ms) - 1, int(round(0.95 * (len(ms) - 1))))]
pts = statistics.median(points) if points else 0
print(f"{rnd},{size},{len(ms)},{statistics.median(ms):.1f},{p95:.1f},{pts:.0f}")
PY
    done
  done
  # Per size, the median over the runs of each column.
  python3 - "$wall_rounds_csv" > "$wall_csv" <<'PY'
import csv, statistics, sys
runs = {}
with open(sys.argv[1]) as f:
    for row in csv.DictReader(f):
        runs.setdefault(row["size"], []).append(row)
print("size,frames,median_frame_ms,p95_frame_ms,median_tile_points")
for size, rows in runs.items():
    med = lambda k: statistics.median(float(r[k]) for r in rows)
    print(f"{size},{med('frames'):.0f},{med('median_frame_ms'):.1f},{med('p95_frame_ms'):.1f},"
          f"{med('median_tile_points'):.0f}")
PY
  cat "$wall_rounds_csv" "$wall_csv"
fi

if [ "$skip_site" = 0 ]; then
  site_csv=$out/scale_site.csv
  echo "size,joined_s,first_image_s,settled_s,fetched_bytes" > "$site_csv"
  for spec in "${stores[@]}"; do
    size=${spec%%=*}
    store=${spec#*=}
    echo "== a site joins at 20 Mbit/s, $size" >&2
    "$build/bench/site_join" --store "$store" --rates 20 --runs 1 --join-only \
      --out "$out/site-$size" > "$out/logs/site-$size.txt" 2>&1 ||
      die "site_join failed; see $out/logs/site-$size.txt"
    python3 - "$size" "$out/site-$size/site_join_summary.csv" >> "$site_csv" <<'PY'
import csv, sys
size, path = sys.argv[1:]
with open(path) as f:
    for row in csv.DictReader(f):
        if row["case"].startswith("chunks"):
            print(f"{size},{row['joined_s']},{row['first_image_s']},{row['settled_s']},{row['fetched_bytes']}")
PY
  done
  cat "$site_csv"
fi

draw_chart
echo "scale.sh: results in $out (scale.png)" >&2
