#!/usr/bin/env bash
# Draws the CMake target graph of Tessera's libraries and programs (tests, benchmarks and
# external libraries left out) as build/target-graph.dot and, with Graphviz's dot, .png.
#   ./scripts/target_graph.sh [BUILD_DIR]     default build/graph (configured here, not built)
set -euo pipefail
cd "$(dirname "$0")/.."
case "${1:-}" in -h|--help) sed -n 2,4p "$0" | sed 's/^# \{0,1\}//'; exit 0 ;; esac
out=${1:-build/graph}
mkdir -p "$out"
cat > "$out/CMakeGraphVizOptions.cmake" <<'OPTS'
set(GRAPHVIZ_EXTERNAL_LIBS FALSE)
set(GRAPHVIZ_GENERATE_PER_TARGET FALSE)
set(GRAPHVIZ_GENERATE_DEPENDERS FALSE)
set(GRAPHVIZ_IGNORE_TARGETS "^bench_|_tests$|^tessera_test_|_fuzzer$|_seeds$")
OPTS
cmake -S . -B "$out" -G Ninja -DTESSERA_BUILD_TESTS=OFF -DTESSERA_BUILD_BENCH=OFF \
      --graphviz="$out/targets.dot" >/dev/null
cp "$out/targets.dot" build/target-graph.dot
if command -v dot >/dev/null; then
  dot -Tpng -Grankdir=BT build/target-graph.dot -o build/target-graph.png
  echo "build/target-graph.png"
else
  echo "build/target-graph.dot (apt-get install graphviz to draw it)"
fi
