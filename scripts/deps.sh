#!/usr/bin/env bash
# Installs exactly the Debian 12 packages Tessera needs to build, test, benchmark and run.
# Idempotent: packages already present are not reinstalled and apt is not touched at all.
# Works as root or through sudo.
set -euo pipefail

PACKAGES=(
  # toolchain
  build-essential cmake ninja-build pkg-config git clang libclang-rt-14-dev
  # cluster transport (inside the cluster) and collaboration transport (across sites)
  libopenmpi-dev openmpi-bin libzmq3-dev cppzmq-dev
  # windows, maths, OpenGL 4.5 through EGL on Mesa (llvmpipe when there is no GPU)
  libglfw3-dev libglm-dev libegl-dev libgl-dev libopengl-dev libegl1-mesa-dev
  libgl1-mesa-dri libegl-mesa0
  # a virtual X server: windowed GL (GLFW + GLX) tested headless
  xvfb xauth xdotool
  # video insets and audio for remote sites
  libavcodec-dev libavformat-dev libswscale-dev libavutil-dev libopus-dev
  # voice: microphones and speakers through ALSA
  libasound2-dev
  # video insets: V4L2 cameras through FFmpeg's video4linux2 input
  libavdevice-dev
  # voice: the spoken test sentence (tests and bench/voice; skipped without it)
  espeak-ng
  # one schema for configs, wire and snapshots
  libprotobuf-dev protobuf-compiler
  # tests and benchmarks
  libgtest-dev libgmock-dev libbenchmark-dev gnuplot-nox
  # the target graph (scripts/target_graph.sh)
  graphviz
  # annotations database, mesh LOD, console UI, command line, logging
  libsqlite3-dev libmeshoptimizer-dev libmetis-dev libimgui-dev libcli11-dev libspdlog-dev
  # GeoJSON exports in longitude and latitude from a projected CRS
  libproj-dev proj-data
  # virtual scanner ray casting, point chunk entropy coding, images, E57 scans' XML
  libembree-dev libzstd-dev libpng-dev libpugixml-dev
  # projector calibrations: MPCDI files are zips
  libzip-dev
  # the overlay's text: shaping, glyphs, fonts for every script (render/src/text_shaper.h):
  # DejaVu (Latin, Greek, Cyrillic, Hebrew, Arabic), Noto Sans CJK, Symbola (emoji, symbols)
  libharfbuzz-dev libfreetype-dev libfontconfig-dev fonts-dejavu-core fonts-noto-cjk fonts-symbola
)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "deps.sh: all ${#PACKAGES[@]} packages present"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  if command -v sudo >/dev/null 2>&1; then
    SUDO="sudo"
  else
    echo "deps.sh: not root and no sudo; install these packages: ${missing[*]}" >&2
    exit 1
  fi
fi

echo "deps.sh: installing ${#missing[@]} packages: ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
echo "deps.sh: done"
