#!/usr/bin/env bash
# The test command: install dependencies, configure, build, run every test.
# Exits non-zero on any failure; prints ctest's summary.
#   ./scripts/test.sh            full run (optimised build with asserts, then the sanitizer pass)
#   TESSERA_SKIP_ASAN=1 ./scripts/test.sh   skip the AddressSanitizer/UBSan pass over the readers
set -euo pipefail
cd "$(dirname "$0")/.."

./scripts/deps.sh
jobs=$(nproc)

echo "== configure + build (dev: optimised, asserts on)"
cmake --preset dev >/dev/null
cmake --build --preset dev -j"$jobs"

echo "== tests"
ctest --preset dev -j"$jobs" --timeout 600

if [ "${TESSERA_SKIP_ASAN:-0}" != 1 ]; then
  # Decoders of outside bytes also run under AddressSanitizer and UBSan.
  # The scene draw list too: a loader decoding into a closed store would be a use-after-free.
  # Voice: packets and WAV files from outside, the jitter buffer and libopus behind them.
  # Annotation: JSON imports and database files from outside.
  echo "== sanitizer pass (asan: readers, decoders, the sync schema, the scene draw list, voice, video, annotation)"
  cmake --preset asan >/dev/null
  cmake --build --preset asan -j"$jobs" --target tessera_lod_tests tessera_sync_tests tessera_scene_tests \
    tessera_site_unit_tests tessera_voice_tests tessera_video_tests tessera_annotation_tests \
    tessera_annotation_scene_tests
  ctest --preset asan -j"$jobs" --timeout 900 -L "lod|sync|scene|voice|video|annotation"
fi
