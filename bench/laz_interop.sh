#!/usr/bin/env bash
# LAZ written by Tessera, read by LAZperf: an independent check that the LAZ files tessera-lod
# export writes decode, in another LAZ reader, to the records Tessera means. See --help.
set -euo pipefail

usage() {
  cat <<'EOF'
Usage: bench/laz_interop.sh [--out DIR] [--data DIR] [--tool PATH] [--cache DIR] [--work DIR]

Writes LAZ files with `tessera-lod export` from the real data, decodes every point of each with
LAZperf (the npm package laz-perf, a WebAssembly build of Hobu's LAZperf, installed at run time
into a cache folder outside the repository) and compares each record byte for byte with the
uncompressed LAS that tessera-lod writes from the same LAZ. The other way round, the LASzip-
written autzen_trim.laz is decoded by LAZperf and by tessera-lod and the records compared.

Files (all exported by tessera-lod):
  LAS 1.2 format 3 (pointwise items v2)  autzen_trim.las, 1.2-with-color.las (records copied)
  LAS 1.4 formats 6, 7 (layered items v3) bunnyDouble.e57, ColouredCubeFloat.e57 (converted),
                                          a .tlod store of Autzen (its leaves, converted)
  LAS formats 0-3, 6-8, extra bytes       tessera-lod makes these from LAS input only (scans and
                                          stores become 6 or 7 with GPS time 0), so the script
                                          derives LAS inputs from Autzen's records (real returns,
                                          GPS times and colour; in formats 6-8 four scanner
                                          channels and a made-up NIR) and has tessera-lod copy
                                          them into LAZ

Options:
  --out DIR    where laz_interop.csv goes (default: build/dev/bench-results/laz_interop)
  --data DIR   the shared data (default: $DATA, else ../shared/data beside the repository)
  --tool PATH  tessera-lod (default: $TESSERA_LOD, else build/dev/lod/tessera-lod)
  --cache DIR  where laz-perf is installed (default: ${XDG_CACHE_HOME:-~/.cache}/tessera-bench/laz-perf)
  --work DIR   keep the LAZ and LAS files there (default: a temporary folder, removed at exit)
  -h, --help   this help

Environment: LAZPERF_VERSION (default 0.0.7) picks the laz-perf release.
Exit status: 0 when every record of every file matches, 1 when any differs, 2 for a usage or
setup error, 3 when npm cannot install laz-perf.
EOF
}

die() { echo "laz_interop: error: $*" >&2; exit 2; }

REPO=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
DATA=${DATA:-$(dirname "$REPO")/shared/data}
TOOL=${TESSERA_LOD:-$REPO/build/dev/lod/tessera-lod}
OUT=$REPO/build/dev/bench-results/laz_interop
CACHE=${XDG_CACHE_HOME:-$HOME/.cache}/tessera-bench/laz-perf
LAZPERF_VERSION=${LAZPERF_VERSION:-0.0.7}
WORK=

while [ $# -gt 0 ]; do
  case $1 in
    -h|--help) usage; exit 0 ;;
    --out|--data|--tool|--cache|--work)
      [ $# -ge 2 ] || die "$1 needs a value (see --help)"
      case $1 in
        --out) OUT=$2 ;; --data) DATA=$2 ;; --tool) TOOL=$2 ;; --cache) CACHE=$2 ;; --work) WORK=$2 ;;
      esac
      shift 2 ;;
    *) die "unknown argument '$1' (see --help)" ;;
  esac
done

SCRIPT=$REPO/bench/laz_interop.mjs
[ -f "$SCRIPT" ] || die "$SCRIPT is missing"
[ -x "$TOOL" ] || die "tessera-lod not found at $TOOL (build it, or give --tool PATH)"
for f in lidar/autzen_trim.las lidar/autzen_trim.laz lidar/1.2-with-color.las \
         e57/bunnyDouble.e57 e57/ColouredCubeFloat.e57; do
  [ -f "$DATA/$f" ] || die "$DATA/$f is missing (give the shared data with --data DIR)"
done
command -v node >/dev/null || die "node is not on PATH (LAZperf runs in node)"
command -v npm >/dev/null || die "npm is not on PATH (it installs laz-perf)"

# ---- laz-perf, installed outside the repository --------------------------------------------
installed=$(node -e 'try { console.log(require(process.argv[1]).version) } catch { }' \
  "$CACHE/node_modules/laz-perf/package.json" 2>/dev/null || true)
if [ "$installed" != "$LAZPERF_VERSION" ]; then
  echo "installing laz-perf@$LAZPERF_VERSION into $CACHE (npm)"
  mkdir -p "$CACHE"
  if ! npm install --prefix "$CACHE" --no-audit --no-fund --no-save --loglevel=error \
       "laz-perf@$LAZPERF_VERSION" >"$CACHE/npm-install.log" 2>&1; then
    echo "laz_interop: error: npm could not install laz-perf@$LAZPERF_VERSION from" \
         "$(npm config get registry 2>/dev/null || echo 'its registry'); is the registry reachable?" >&2
    tail -n 15 "$CACHE/npm-install.log" >&2
    exit 3
  fi
else
  echo "laz-perf $installed already in $CACHE"
fi

# ---- the files -----------------------------------------------------------------------------
if [ -n "$WORK" ]; then
  mkdir -p "$WORK"
else
  WORK=$(mktemp -d "${TMPDIR:-/tmp}/laz_interop.XXXXXX")
  trap 'rm -rf "$WORK"' EXIT
fi
WORK=$(cd "$WORK" && pwd)
mkdir -p "$OUT"
OUT=$(cd "$OUT" && pwd)

run() {  # run a command quietly; on failure show what it printed and stop
  if ! "$@" >"$WORK/last.log" 2>&1; then
    echo "laz_interop: error: failed: $*" >&2
    cat "$WORK/last.log" >&2
    exit 2
  fi
}
export_to() { run "$TOOL" export "$1" -o "$2" --quiet; }

PAIRS=()
# tessera-lod writes NAME.laz from IN, then NAME.las from NAME.laz (records copied exactly)
tessera_laz() {
  local name=$1 in=$2
  export_to "$in" "$WORK/$name.laz"
  export_to "$WORK/$name.laz" "$WORK/$name.las"
  PAIRS+=(--pair "$name.laz" tessera-lod "$WORK/$name.laz" "$WORK/$name.las")
}
derived_laz() {  # NAME from a LAS input in FORMAT (+ EXTRA bytes) derived from SRC
  local name=$1 src=$2 format=$3 extra=${4:-0}
  run node "$SCRIPT" derive "$src" "$WORK/$name.in.las" "$format" "$extra"
  tessera_laz "$name" "$WORK/$name.in.las"
}

echo "writing LAZ with $TOOL into $WORK"
tessera_laz autzen_fmt3 "$DATA/lidar/autzen_trim.las"
tessera_laz color_fmt3 "$DATA/lidar/1.2-with-color.las"
tessera_laz bunny_fmt6 "$DATA/e57/bunnyDouble.e57"
tessera_laz cube_fmt7 "$DATA/e57/ColouredCubeFloat.e57"
run "$TOOL" build "$DATA/lidar/autzen_trim.las" -o "$WORK/autzen.tlod" --quiet
tessera_laz autzen_store_fmt7 "$WORK/autzen.tlod"
echo "formats 0-3 and 6-8 with real returns and GPS times, and extra bytes: tessera-lod exports them" \
     "only from LAS input (scans and stores become format 6 or 7), so LAS inputs are derived from Autzen's records"
A=$WORK/autzen_fmt3.las
derived_laz autzen_fmt0 "$A" 0
derived_laz autzen_fmt1 "$A" 1
derived_laz autzen_fmt2 "$A" 2
derived_laz autzen_fmt3_eb3 "$A" 3 3
derived_laz autzen_fmt6 "$A" 6
derived_laz autzen_fmt7 "$A" 7
derived_laz autzen_fmt8 "$A" 8
derived_laz autzen_fmt8_eb4 "$A" 8 4

# LASzip's own LAZ: LAZperf against tessera-lod's decoding, and against the LAS twin
export_to "$DATA/lidar/autzen_trim.laz" "$WORK/laszip_autzen.las"
PAIRS+=(--pair "autzen_trim.laz" LASzip "$DATA/lidar/autzen_trim.laz" "$WORK/laszip_autzen.las")
PAIRS+=(--pair "autzen_trim.laz" LASzip "$DATA/lidar/autzen_trim.laz" "$DATA/lidar/autzen_trim.las")

# ---- decode with LAZperf and compare -------------------------------------------------------
CSV=$OUT/laz_interop.csv
echo "file,point_format,points,laz_perf_equal,writer,reference,first_difference" >"$CSV"
status=0
node "$SCRIPT" compare --lazperf "$CACHE" --csv "$CSV" "${PAIRS[@]}" || status=$?
if [ "$status" -ge 2 ]; then
  echo "laz_interop: error: the comparison stopped (status $status)" >&2
  exit 2
fi
rows=$(($(wc -l <"$CSV") - 1))
equal=$(grep -c ',yes,' "$CSV" || true)
echo "summary: $equal of $rows comparisons equal record for record; CSV: $CSV"
echo "reproduce: bench/laz_interop.sh --out $OUT --data $DATA --tool $TOOL"
if [ "$status" -ne 0 ] || [ "$equal" -ne "$rows" ]; then
  echo "laz_interop: LAZperf disagrees on $((rows - equal)) file(s); see first_difference in the CSV" >&2
  exit 1
fi
