#!/usr/bin/env bash
# Tessera's store build against PotreeConverter 2 on the same tiled real LiDAR. See --help.
set -euo pipefail

usage() {
  cat <<'EOF'
Usage: bench/potree_peer.sh --potree-src DIR [--points N] [--rounds R] [--threads T]
                            [--modes LIST] [--tiler PATH] [--out DIR] [--work DIR] [--data DIR]
                            [--tool PATH] [--lock FILE]

Builds PotreeConverter 2 from a source tree you give it (Release, outside the repository,
never a dependency of Tessera's build), tiles Autzen (autzen_trim.las: 110,000 points, LAS 1.2
format 3) side by side into one LAS of N points with bench/tile_las.py, then converts that LAS
R rounds with each tool, alternating (Tessera, Potree, Tessera, Potree, ...), each run into a
fresh output folder, timed by /usr/bin/time -v:

  tessera  default       tessera-lod build IN -o OUT.tlod --threads T --quiet (leaves keep the
                         LAS's own 1 cm integers, as Potree keeps them)
  potree   brotli        PotreeConverter IN -o OUTDIR --encoding BROTLI
                                         --attributes rgb intensity classification
  tessera  lossy         ... --lossy (leaves within a quarter of their spacing)
  potree   uncompressed  PotreeConverter's default encoding (same attributes)

Potree keeps position (always), rgb, intensity and classification, the attributes a Tessera
store keeps (Tessera also keeps an input-source id per point, constant here). PotreeConverter
has no thread option: it starts one thread per online CPU. When T is less than the CPUs here,
both tools run under `taskset -c 0-(T-1)`.

Output (in --out):
  potree_peer.csv   tool, mode, points, seconds_best, seconds_median, mpts_per_s (from the best
                    round), peak_rss_mb (highest of the rounds), bytes (du -sb of the output),
                    bytes_per_point; one row per tool, mode and point count (runs at other
                    point counts into the same --out are kept)
  potree_peer_runs.csv  every round (with user + system CPU seconds)
  potree_peer.png   points/s, peak memory, bytes/point (gnuplot)
  potree_peer_meta.txt  PotreeConverter's commit, compiler, CPU, threads
  logs/             each run's /usr/bin/time -v report and console output

Options:
  --potree-src DIR  a PotreeConverter 2 source tree (required). Get one with
                      git clone https://github.com/potree/PotreeConverter DIR
                    (the commit is read with git; an exported tree may carry it in DIR/COMMIT)
  --points N        points in the tiled LAS (default 10000000; 1e7, 3e7 also work)
  --rounds R        rounds per tool and mode (default 3)
  --threads T       threads for both tools (default 2)
  --modes LIST      the runs, comma-separated TOOL:MODE (default tessera:default,potree:brotli,
                    tessera:lossy,potree:uncompressed; at 10^9 the first two, for the disk)
  --tiler PATH      tile with bench/tile_scan (C++, from a build: PATH to its binary) instead of
                    bench/tile_las.py (pure Python, slow past 10^8)
  --out DIR         results (default build/dev/bench-results/potree_peer)
  --work DIR        PotreeConverter's build, the tiled LAS, the outputs
                    (default OUT/work; kept, so a rerun reuses the build and the LAS)
  --data DIR        the shared data (default: $DATA, else ../shared/data beside the repository)
  --tool PATH       tessera-lod (default: $TESSERA_LOD, else build/dev/lod/tessera-lod)
  --lock FILE       each build, tiling and timed run holds `flock FILE` (default
                    /tmp/tessera-build.lock; `none`: no lock)
  -h, --help        this help

Needs: bash, python3, cmake (3.16+) and a C++20 compiler, TBB (Debian: libtbb-dev),
GNU time at /usr/bin/time (Debian: time), gnuplot (Debian: gnuplot-nox), taskset
(util-linux), flock. PotreeConverter bundles LASzip, Brotli and its JSON library.
Disk: about 34 bytes a point for the LAS, plus the running tool's temporary files and output
(each output is measured, then removed): about 70 GB at 10^9 with PotreeConverter's Brotli.

Exit status: 0 done, 1 a run failed, 2 usage or setup error (no --potree-src: prints how to
get one).
EOF
}

die() { echo "potree_peer: error: $*" >&2; exit 2; }
note() { echo "potree_peer: $*" >&2; }

REPO=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
DATA=${DATA:-$(dirname "$REPO")/shared/data}
TOOL=${TESSERA_LOD:-$REPO/build/dev/lod/tessera-lod}
OUT=$REPO/build/dev/bench-results/potree_peer
WORK=
SRC=
POINTS=10000000
ROUNDS=3
THREADS=2
LOCK=/tmp/tessera-build.lock
MODE_LIST=tessera:default,potree:brotli,tessera:lossy,potree:uncompressed
TILER=

while [ $# -gt 0 ]; do
  case $1 in
    -h|--help) usage; exit 0 ;;
    --potree-src|--points|--rounds|--threads|--out|--work|--data|--tool|--lock|--modes|--tiler)
      [ $# -ge 2 ] || die "$1 needs a value (see --help)"
      case $1 in
        --potree-src) SRC=$2 ;; --points) POINTS=$2 ;; --rounds) ROUNDS=$2 ;;
        --threads) THREADS=$2 ;; --out) OUT=$2 ;; --work) WORK=$2 ;; --data) DATA=$2 ;;
        --tool) TOOL=$2 ;; --lock) LOCK=$2 ;; --modes) MODE_LIST=$2 ;; --tiler) TILER=$2 ;;
      esac
      shift 2 ;;
    *) die "unknown argument '$1' (see --help)" ;;
  esac
done

if [ -z "$SRC" ]; then
  cat >&2 <<'EOF'
potree_peer: no PotreeConverter source tree given (--potree-src DIR).
Get one (outside this repository), then rerun with --potree-src:
  git clone https://github.com/potree/PotreeConverter /path/to/PotreeConverter
  bench/potree_peer.sh --potree-src /path/to/PotreeConverter
It needs TBB to build (Debian: apt-get install libtbb-dev).
EOF
  exit 2
fi

# --- arguments -------------------------------------------------------------------------------
POINTS=$(python3 -c 'import sys
v = float(sys.argv[1])
if v != int(v) or v < 1: raise SystemExit(1)
print(int(v))' "$POINTS" 2>/dev/null) || die "--points must be a positive integer (10000000 or 1e7)"
[[ $ROUNDS =~ ^[1-9][0-9]*$ ]] || die "--rounds must be a positive integer, got '$ROUNDS'"
[[ $THREADS =~ ^[1-9][0-9]*$ ]] || die "--threads must be a positive integer, got '$THREADS'"
[ -f "$SRC/CMakeLists.txt" ] && [ -f "$SRC/Converter/src/main.cpp" ] \
  || die "'$SRC' is not a PotreeConverter 2 source tree (no CMakeLists.txt and Converter/src/main.cpp)"
SRC=$(cd "$SRC" && pwd)
case $SRC/ in "$REPO"/build/*) ;; "$REPO"/*) die "keep the PotreeConverter source outside the repository (or under build/), not in '$SRC'" ;; esac
MODES=()
IFS=, read -r -a mode_items <<<"$MODE_LIST"
for item in "${mode_items[@]}"; do
  case $item in
    tessera:default|tessera:lossy|potree:brotli|potree:uncompressed) MODES+=("${item/:/ }") ;;
    *) die "--modes: '$item' is not one of tessera:default, tessera:lossy, potree:brotli, potree:uncompressed" ;;
  esac
done
[ ${#MODES[@]} -gt 0 ] || die "--modes names no run"
[ -z "$TILER" ] || [ -x "$TILER" ] || die "--tiler: '$TILER' is not an executable (bench/tile_scan from a build)"
[ -x "$TOOL" ] || die "tessera-lod not found at '$TOOL' (build the dev preset, or --tool PATH)"
INPUT=$DATA/lidar/autzen_trim.las
[ -f "$INPUT" ] || die "no $INPUT (set --data DIR or DATA)"

for cmd in python3 cmake gnuplot taskset flock awk du; do
  command -v "$cmd" >/dev/null || die "'$cmd' is missing (see Needs: in --help)"
done
[ -x /usr/bin/time ] || die "GNU time is missing at /usr/bin/time (Debian: apt-get install time)"

mkdir -p "$OUT"
OUT=$(cd "$OUT" && pwd)
WORK=${WORK:-$OUT/work}
mkdir -p "$WORK" "$OUT/logs"
WORK=$(cd "$WORK" && pwd)

NCPU=$(nproc)
PIN=()
if [ "$THREADS" -lt "$NCPU" ]; then PIN=(taskset -c "0-$((THREADS - 1))"); fi

locked() {  # run "$@" holding the shared build lock
  if [ "$LOCK" = none ]; then "$@"; else flock "$LOCK" "$@"; fi
}

# --- PotreeConverter -------------------------------------------------------------------------
PBUILD=$WORK/potree-build
PBIN=$PBUILD/PotreeConverter
if [ ! -x "$PBIN" ] || [ -n "$(find "$SRC/Converter" "$SRC/CMakeLists.txt" -newer "$PBIN" -print -quit)" ]; then
  note "building PotreeConverter (Release, -j$THREADS) in $PBUILD (log: $WORK/potree-build.log)"
  if ! locked sh -c 'cmake -S "$1" -B "$2" -DCMAKE_BUILD_TYPE=Release && cmake --build "$2" -j "$3"' \
       sh "$SRC" "$PBUILD" "$THREADS" >"$WORK/potree-build.log" 2>&1; then
    tail -n 30 "$WORK/potree-build.log" >&2
    die "PotreeConverter did not build (full log: $WORK/potree-build.log)"
  fi
fi
[ -x "$PBIN" ] || die "no PotreeConverter binary at $PBIN after the build"
"$PBIN" --help >"$WORK/potree-help.txt" 2>&1 || true
for opt in encoding attributes; do
  grep -q -- "--$opt" "$WORK/potree-help.txt" || die "this PotreeConverter has no --$opt option (PotreeConverter 2 needed)"
done
PCOMMIT=unknown
if [ "$(git -C "$SRC" rev-parse --show-toplevel 2>/dev/null)" = "$SRC" ]; then
  PCOMMIT=$(git -C "$SRC" rev-parse HEAD)
elif [ -f "$SRC/COMMIT" ]; then
  PCOMMIT=$(head -c 40 "$SRC/COMMIT")
fi

# --- input -----------------------------------------------------------------------------------
LAS=$WORK/autzen_tiled_$POINTS.las
if [ -n "$TILER" ] && [ ! -f "$LAS" ]; then
  note "tiling $INPUT into $POINTS points with $TILER"
  locked "$TILER" "$INPUT" -o "$LAS" -n "$POINTS" --threads "$THREADS" >&2
elif [ ! -f "$LAS" ] || [ "$LAS" -ot "$REPO/bench/tile_las.py" ]; then
  note "tiling $INPUT into $POINTS points"
  locked python3 "$REPO/bench/tile_las.py" "$INPUT" -o "$LAS" --points "$POINTS" >&2
fi
got=$("$TOOL" info "$LAS" | awk '$1 == "points:" { print $2 }')
[ "$got" = "$POINTS" ] || die "tessera-lod info reads $got points in $LAS, expected $POINTS"

# --- runs ------------------------------------------------------------------------------------
RUNS=$OUT/potree_peer_runs.csv
[ -f "$RUNS" ] || echo "tool,mode,points,threads,round,seconds,peak_rss_mb,bytes,cpu_seconds" >"$RUNS"
# rounds of an earlier run at this point count and thread count are replaced
awk -F, -v n="$POINTS" -v t="$THREADS" 'NR == 1 || !($3 == n && $4 == t)' "$RUNS" >"$RUNS.tmp" && mv "$RUNS.tmp" "$RUNS"

run_one() {  # tool mode round
  local tool=$1 mode=$2 round=$3 dest cmd tag
  tag=${tool}_${mode}_${POINTS}_r$round
  dest=$WORK/out_${tool}_$mode
  rm -rf "$dest"
  mkdir -p "$dest"
  if [ "$tool" = tessera ]; then
    cmd=("$TOOL" build "$LAS" -o "$dest/store.tlod" --threads "$THREADS" --quiet)
    [ "$mode" = lossy ] && cmd+=(--lossy)
  else
    rmdir "$dest"   # PotreeConverter makes its own folder
    cmd=("$PBIN" "$LAS" -o "$dest" --attributes rgb intensity classification)
    [ "$mode" = brotli ] && cmd+=(--encoding BROTLI)
  fi
  sync
  if ! locked /usr/bin/time -v -o "$OUT/logs/$tag.time" "${PIN[@]}" "${cmd[@]}" \
       >"$OUT/logs/$tag.log" 2>&1; then
    tail -n 20 "$OUT/logs/$tag.log" >&2
    echo "potree_peer: $tool $mode failed (log: $OUT/logs/$tag.log)" >&2
    exit 1
  fi
  # check the output holds every point
  local n
  if [ "$tool" = tessera ]; then
    n=$("$TOOL" info "$dest/store.tlod" | awk '$1 == "points:" { print $2; exit }')
  else
    n=$(python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))["points"])' "$dest/metadata.json")
  fi
  [ "$n" = "$POINTS" ] || { echo "potree_peer: $tool $mode wrote $n points, not $POINTS" >&2; exit 1; }
  local secs rss bytes cpu
  secs=$(awk -F': ' '/Elapsed \(wall clock\)/ { n = split($2, p, ":"); s = 0
           for (i = 1; i <= n; i++) s = s * 60 + p[i]; print s }' "$OUT/logs/$tag.time")
  rss=$(awk -F': ' '/Maximum resident set size/ { printf "%.1f", $2 / 1024 }' "$OUT/logs/$tag.time")
  bytes=$(du -sb "$dest" | cut -f1)
  cpu=$(awk -F': ' '/User time|System time/ { s += $2 } END { printf "%.2f", s }' "$OUT/logs/$tag.time")
  echo "$tool,$mode,$POINTS,$THREADS,$round,$secs,$rss,$bytes,$cpu" >>"$RUNS"
  rm -rf "$dest"  # measured: its disk goes to the next run
  note "round $round  $tool $mode: ${secs} s (CPU ${cpu} s), ${rss} MB peak, $bytes bytes"
}

note "$POINTS points, $ROUNDS rounds, $THREADS threads${PIN:+ (taskset ${PIN[2]})}, PotreeConverter $PCOMMIT"
for round in $(seq 1 "$ROUNDS"); do
  for m in "${MODES[@]}"; do
    run_one $m "$round"
  done
done

# --- summary ---------------------------------------------------------------------------------
CSV=$OUT/potree_peer.csv
HDR="tool,mode,points,seconds_best,seconds_median,mpts_per_s,peak_rss_mb,bytes,bytes_per_point"
# one row per tool, mode and point count, from this thread count's rounds
awk -F, -v t="$THREADS" 'NR > 1 && $4 == t { k = $1 "," $2 "," $3; s[k] = s[k] " " $6
       if ($7 > r[k]) r[k] = $7; b[k] = $8; if (!(k in seen)) { seen[k] = 1; order[++n] = k } }
     END { for (i = 1; i <= n; i++) { k = order[i]; m = split(substr(s[k], 2), v, " ")
             for (a = 1; a <= m; a++) for (c = a + 1; c <= m; c++) if (v[c] < v[a]) { x = v[a]; v[a] = v[c]; v[c] = x }
             med = (m % 2) ? v[(m + 1) / 2] : (v[m / 2] + v[m / 2 + 1]) / 2
             split(k, f, ","); printf "%s,%.2f,%.2f,%.3f,%.1f,%.0f,%.3f\n", k, v[1], med, f[3] / v[1] / 1e6, r[k], b[k], b[k] / f[3] } }' \
  "$RUNS" | sort -t, -k3,3n -k1,1r -k2,2 >"$CSV.body"
{ echo "$HDR"; cat "$CSV.body"; } >"$CSV"
rm -f "$CSV.body"

cat >"$OUT/potree_peer_meta.txt" <<EOF
PotreeConverter commit: $PCOMMIT (source: $SRC)
PotreeConverter build: $("$(awk -F= '/^CMAKE_CXX_COMPILER:/ { print $2 }' "$PBUILD/CMakeCache.txt")" --version 2>/dev/null | head -1), CMAKE_BUILD_TYPE=$(awk -F= '/^CMAKE_BUILD_TYPE:/ { print $2 }' "$PBUILD/CMakeCache.txt")
tessera-lod: $TOOL
input: $INPUT tiled by ${TILER:-bench/tile_las.py}
threads: $THREADS of $NCPU CPUs${PIN:+ (both tools under taskset ${PIN[2]})}, rounds: $ROUNDS
cpu: $(awk -F': ' '/model name/ { print $2; exit }' /proc/cpuinfo)
date: $(date -u +%Y-%m-%dT%H:%MZ)
EOF

# --- chart -----------------------------------------------------------------------------------
# one row per point count, the four modes as columns, for each panel's clustered bars
DAT=$OUT/potree_peer.dat
awk -F, 'NR > 1 { k = $1 " " $2; v[$3, k] = $6 " " $7 " " $9; if (!($3 in seen)) { seen[$3] = 1; pts[++n] = $3 } }
     END { split("tessera default|tessera lossy|potree brotli|potree uncompressed", ks, "|")
           for (i = 1; i <= n; i++) { p = pts[i]; e = int(log(p) / log(10) + 1e-9); m = p / 10 ^ e
             label = (m == 1) ? sprintf("10^%d", e) : sprintf("%gx10^%d", m, e); line = "\"" label " points\""
             for (a = 1; a <= 3; a++) for (j = 1; j <= 4; j++) {
               if ((p SUBSEP ks[j]) in v) { split(v[p, ks[j]], f, " "); line = line " " f[a] } else line = line " NaN" }
             print p, line } }' "$CSV" | sort -n | cut -d' ' -f2- >"$DAT"

# the modes measured (a run with --modes leaves the others out of the chart)
ALL_MODES=("tessera default" "tessera lossy" "potree brotli" "potree uncompressed")
TITLES=("Tessera (default, exact)" "Tessera --lossy" "Potree BROTLI" "Potree uncompressed (its default)")
COLS=() LEGEND=()
for j in 0 1 2 3; do
  if awk -F, -v k="${ALL_MODES[$j]}" 'NR > 1 && $1 " " $2 == k { f = 1 } END { exit !f }' "$CSV"; then
    COLS+=("$j")
    LEGEND+=("NaN with boxes lt $((j + 1)) title \"${TITLES[$j]}\"")
  fi
done
COL_ARRAY=$(IFS=,; echo "${COLS[*]}")
LEGEND_PLOT=$(IFS=,; echo "${LEGEND[*]}")

# the k bars of a cluster sit at x = cluster + (i - 1 - (k - 1) / 2) / (k + 1) (gap 1); each
# carries its value
gnuplot <<EOF
set terminal pngcairo size 1500,600 font "DejaVu Sans,12"
set output "$OUT/potree_peer.png"
set multiplot title "Tessera against PotreeConverter 2 (${PCOMMIT:0:7}): Autzen tiled, $THREADS threads, best of $ROUNDS rounds" font ",14"
set style data histograms
set style histogram clustered gap 1
set style fill solid 0.85 border -1
set boxwidth 0.9
set grid ytics
set yrange [0:*]
set offsets 0, 0, graph 0.08, 0
set xtics nomirror
set linetype 1 lc rgb "#1b6ca8"
set linetype 2 lc rgb "#7fb3d5"
set linetype 3 lc rgb "#c0392b"
set linetype 4 lc rgb "#f1948a"
unset key
set size 0.333, 0.84
array T[3] = ["Throughput (higher is better)", "Peak memory (lower is better)", "Output size (lower is better)"]
array Y[3] = ["million points / s", "peak RSS, MB", "bytes / point"]
array F[3] = ["%.2f", "%.0f", "%.1f"]
array B[${#COLS[@]}] = [$COL_ARRAY]
k = |B|
do for [p = 1:3] {
  c = 2 + 4 * (p - 1)
  set origin (p - 1) / 3.0, 0.09
  set title T[p]
  set ylabel Y[p]
  plot for [i = 1:k] "$DAT" using (column(c + B[i])):xtic(1) lt (B[i] + 1), \
       for [i = 1:k] "$DAT" using (\$0 + (i - 1 - (k - 1) / 2.0) / (k + 1.0)):(column(c + B[i])):(sprintf(F[p], column(c + B[i]))) \
         with labels offset 0,0.7 font ",9" notitle
}
# the legend, in a strip across the bottom
set origin 0, 0
set size 1, 0.09
unset border; unset tics; unset grid; unset title; unset xlabel; unset ylabel
set offsets 0, 0, 0, 0
set xrange [0:1]; set yrange [0:1]
set key center center horizontal maxrows 1 Left reverse samplen 2 width 2 font ",11"
plot $LEGEND_PLOT
unset multiplot
EOF

column -s, -t "$CSV" >&2
note "wrote $CSV, $RUNS, $OUT/potree_peer.png"
