#!/usr/bin/env bash
# Builds the reader and frame fuzz targets (preset `fuzz`, -j1), seeds a corpus per target in
# build/fuzz/corpus/<target>/ from small real files and hand-made inputs, then runs each fuzzer
# for SECONDS (default 300), one at a time. Crashing inputs land in fuzz/regressions/<target>/,
# which is also replayed first, so a regression that comes back fails at once.
# Usage: fuzz/run.sh [SECONDS] [TARGET...]
#   (targets: ply las laz e57 text obj conf tlod chunk tmesh frame link site chunk_request voice
#    wav video selection annotation picture pfm scan_sample; default all)
set -euo pipefail

cd "$(dirname "$0")/.."
SECONDS_PER_TARGET=${1:-300}
shift || true
TARGETS=("${@:-ply las laz e57 text obj conf tlod chunk tmesh frame link site chunk_request voice wav video selection annotation picture pfm scan_sample}")
read -r -a TARGETS <<<"${TARGETS[*]}"
DATA=${TESSERA_DATA_DIR:-$(cd .. && pwd)/shared/data}
BUILD=build/fuzz

cmake --preset fuzz >/dev/null
# tessera-lod (same build) writes the seed stores of the tlod and chunk targets.
TOOLS=()
if [[ " ${TARGETS[*]} " =~ \ (tlod|chunk|tmesh|laz|scan_sample)\  ]]; then TOOLS=(tessera-lod); fi
if [[ " ${TARGETS[*]} " == *" video "* ]]; then TOOLS+=(video_seeds); fi
cmake --build "$BUILD" -j1 --target "${TARGETS[@]/%/_fuzzer}" "${TOOLS[@]}"
LOD_TOOL=$(pwd)/$BUILD/lod/tessera-lod

# poke FILE OFFSET WIDTH VALUE: writes VALUE as a WIDTH-byte little-endian integer at OFFSET.
poke() {
  local hex="" i
  for ((i = 0; i < $3; i++)); do hex+=$(printf '\\x%02x' $((($4 >> (8 * i)) & 255))); done
  printf "$hex" | dd of="$1" bs=1 seek="$2" conv=notrunc status=none
}

seed_ply() {
  local bunny="$DATA/stanford-bunny/scans/bun000.ply" i
  head -c 4096 "$bunny" >bunny-head.ply
  # The same header cut down to an 8x8 grid over the first 60 vertices.
  { head -24 "$bunny" | sed -e 's/num_cols 512/num_cols 8/;s/num_rows 400/num_rows 8/' \
      -e 's/vertex 40256/vertex 60/;s/range_grid 204800/range_grid 64/'
    sed -n '25,84p;84q' "$bunny"
    for ((i = 0; i < 64; i++)); do if ((i % 16 < 15)); then echo "1 $((i - i / 16))"; else echo 0; fi; done
  } >bunny-small.ply
  printf 'ply\nformat ascii 1.0\ncomment colours and a quad\nelement vertex 4\nproperty float x
property float y\nproperty float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue
element face 2\nproperty list uchar int vertex_indices\nend_header\n0 0 0 255 0 0\n1 0 0 0 255 0
1 1 0 0 0 255\nnan 1 0 9 9 9\n3 0 1 2\n4 0 1 2 3\n' >ascii-faces.ply
  printf 'ply\r\nformat ascii 1.0\r\nobj_info num_cols 2\r\nobj_info num_rows 2\r\nelement vertex 3
property double x\nproperty double y\nproperty double z\nproperty float confidence
property float intensity\nelement range_grid 4\nproperty list uchar int vertex_indices\nend_header
0 0 0 0.5 1\n1 0 0 0.5 1\n0 1 0 0.5 1\n1 0\n1 1\n0\n1 2\n' >ascii-grid.ply
  # Big-endian floats 0 and 1, normals, ushort colours, a skipped element and a face.
  { printf 'ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y
property float z\nproperty float nx\nproperty float ny\nproperty float nz\nproperty ushort red
property ushort green\nproperty ushort blue\nelement extra 2\nproperty int16 a\nproperty int8 b
element face 1\nproperty list uchar uint vertex_indices\nproperty uchar flags\nend_header\n'
    for v in 0 1 2; do
      printf '\x3f\x80\x00\x00\x00\x00\x00\x00\x3f\x80\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00'
      printf '\x3f\x80\x00\x00\xff\xff\x80\x00\x00'"\\x0$v"
    done
    printf '\x00\x01\x02\xff\xfe\x03'
    printf '\x03\x00\x00\x00\x00\x00\x00\x00\x01\x00\x00\x00\x02\x07'; } >binary-be.ply
  # Little-endian range grid with a vertex the grid leaves out.
  { printf 'ply\nformat binary_little_endian 1.0\nobj_info num_cols 2\nobj_info num_rows 2
element vertex 3\nproperty float x\nproperty float y\nproperty float z\nproperty uchar alpha
element range_grid 4\nproperty list uchar int vertex_indices\nend_header\n'
    printf '\x00\x00\x00\x00\x00\x00\x80\x3f\x00\x00\x00\x00\x80'
    printf '\x00\x00\x80\x3f\x00\x00\x00\x00\x00\x00\x80\x3f\x40'
    printf '\x00\x00\xc0\x7f\x00\x00\x00\x00\x00\x00\x00\x00\xff'
    printf '\x01\x00\x00\x00\x00\x00\x01\x01\x00\x00\x00\x00\x01\x02\x00\x00\x00'; } >binary-le-grid.ply
}

seed_las() {
  local src="$DATA/lidar/1.2-with-color.las"
  # (dd, not `tail | head`: under pipefail the SIGPIPE tail may get would end the script)
  records() { dd if="$src" iflag=skip_bytes,count_bytes skip=229 count="$1" status=none; }
  # LAS 1.2 format 3: the header, 2 pad bytes and the records that fit in 4 KiB.
  head -c 4096 "$src" >color-1.2.las
  poke color-1.2.las 107 4 $(((4096 - 229) / 34))
  # LAS 1.0 format 0 and LAS 1.4 format 7 (375-byte header, 64-bit count), records reused.
  { head -c 227 "$src"; records 400; } >format0-1.0.las
  poke format0-1.0.las 25 1 0; poke format0-1.0.las 96 4 227; poke format0-1.0.las 100 4 0
  poke format0-1.0.las 104 1 0; poke format0-1.0.las 105 2 20; poke format0-1.0.las 107 4 20
  { head -c 227 "$src"; head -c 148 /dev/zero; records 720; } >format7-1.4.las
  poke format7-1.4.las 25 1 4; poke format7-1.4.las 94 2 375; poke format7-1.4.las 96 4 375
  poke format7-1.4.las 100 4 0; poke format7-1.4.las 104 1 7; poke format7-1.4.las 105 2 36
  poke format7-1.4.las 107 4 0; poke format7-1.4.las 247 8 20
}

seed_text() {
  printf '# scan export\n1.0 2.0 3.0\n-1e3 4.5 .25\n\n// done\n7 8 9\n' >xyz3.xyz
  printf '3\r\n1 2 3 -1204 255 128 0\r\n4 5 6 12 0 0 0\r\nnan 5 6 12 0 0 0\r\n' >pts7.pts
  printf 'X,Y,Z,Intensity,Red,Green,Blue,Nx,Ny,Nz,time\n1,2,3,40,1,2,3,0,0,1,9.5\n+4;5;6;1;2;3;4;5;6;7;8\n' \
    >header.csv
  printf '1\t2\t3\t0.5\n4\t5\t6\t1e-9\ninf 1 1 2\n' >xyzi.txt
  printf '1 2 3 10 20 30\n4 5 6 300 -5 1.5\n' >xyzrgb.xyz
}

seed_obj() {
  printf '# cube corner\nmtllib a.mtl\no thing\nv 0 0 0\nv 1 0 0 1.0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvn 0 0 1
g side\nusemtl red\nf 1 2 3\nf 1/1 3/1 4/1\nf -4//1 -3//1 -2//1 -1//1\nf 1 2\nf 1 2 99\n' >quad.obj
  printf 'v 0 0 0 255 0 0\r\nv 1 0 0 0 255 0\r\nv 0 1 0 0 0 255\r\nv nan 0 0 1 1 1\r\nf 1/1/1 2/2/2 3/3/3\r\nf 1 2 4\r\n' \
    >colors.obj
  printf 'v 0.5 0.5 0.5 0.1 0.2 0.3\nv 1 2 3 0.4 0.5 0.6\nv 4 5 6\nf 1 2 3\n' >unit-colors.obj
}

# .conf listings against the fixture folder conf_fuzz.h writes (a.ply, b.xyz, self.conf, ...).
seed_conf() {
  printf '# two scans\ncamera 0 0 0 0 0 0 1\nbmesh a.ply 0 0 0 0 0 0 1\nbmesh b.xyz 1 2 3 0 0 0.7071068 0.7071068\n' >two.conf
  printf 'bmesh nest.conf 0 0 0 0 0 0 1\r\nbmesh a.ply 0 0 0 1 0 0 0\r\n' >nested.conf
  printf 'bmesh ping.conf 0 0 0 0 0 0 1\n' >cycle.conf
  printf 'bmesh missing.ply 0 0 0 0 0 0 1\n' >missing.conf
}

# LAZ: pointwise (LAS 1.2 format 3, 1065 points) and layered (LAS 1.4 format 7, the coloured
# cube's 7680 points), both written by tessera-lod; bare chunks come from mutations of these.
seed_laz() {
  "$LOD_TOOL" export "$DATA/lidar/1.2-with-color.las" -o color-1.2.laz --quiet >/dev/null
  "$LOD_TOOL" export "$DATA/e57/ColouredCubeFloat.e57" -o cube-1.4.laz --quiet >/dev/null
}

# E57: the small shared files (the cube as floats, a file without scans, a scan without
# points, a page whose CRC does not match).
seed_e57() {
  cp "$DATA/e57/ColouredCubeFloat.e57" "$DATA/e57/ZeroPoints.e57" "$DATA/e57/empty.e57" \
    "$DATA/e57/bad-crc.e57" .
}

# Stores: one node (1065 points, colour and intensity), and a root with children (a 26^3 grid:
# more points than a leaf holds, and small, as regular positions compress to almost nothing).
seed_tlod() {
  "$LOD_TOOL" build "$DATA/lidar/1.2-with-color.las" -o one-node.tlod --quiet >/dev/null
  awk 'BEGIN { for (i = 0; i < 26; i++) for (j = 0; j < 26; j++) for (k = 0; k < 26; k++)
    print i, j, k }' >grid.xyz
  "$LOD_TOOL" build grid.xyz -o grid.tlod --quiet >/dev/null
  rm grid.xyz
  ao_store ao.tlod
}

# ao_store OUT: a one-node store of version 3 whose 205 points carry ambient occlusion (three
# 24x20 virtual scans of the bunny's coarsest reconstruction, `build --ao`).
ao_store() {
  "$LOD_TOOL" scan "$DATA/stanford-bunny/reconstruction/bun_zipper_res4.ply" -o ao-scans \
    --scanners 3 --resolution 24x20 --quiet >/dev/null
  "$LOD_TOOL" build ao-scans/scans.conf -o "$1" --ao --quiet >/dev/null
  rm -r ao-scans
}

# Mesh stores: the bunny's coarsest reconstruction (948 triangles) as one patch and as a tree.
seed_tmesh() {
  local res4="$DATA/stanford-bunny/reconstruction/bun_zipper_res4.ply"
  "$LOD_TOOL" build "$res4" -o one-patch.tmesh --quiet >/dev/null
  "$LOD_TOOL" build "$res4" -o tree.tmesh --patch-triangles 64 --quiet >/dev/null
}

# Chunk payloads: a one-node store's payload is exactly its chunk (header fields at byte 144:
# payload_offset, 152: payload_size): format 2 with exact cells on the LAS lattice, with lossy
# cells (`--lossy`), and with ambient occlusion (ao_store's one node); the format 1 chunk of
# stores of version 1-3 is fuzz/seeds/chunk/format1-color.chunk.
seed_chunk() {
  "$LOD_TOOL" build "$DATA/lidar/1.2-with-color.las" -o one.tlod --quiet >/dev/null
  "$LOD_TOOL" build "$DATA/lidar/1.2-with-color.las" -o lossy.tlod --lossy --quiet >/dev/null
  ao_store ao.tlod
  cp "$OLDPWD"/fuzz/seeds/chunk/*.chunk .
  local off size name
  for name in one:color lossy:lossy ao:ao; do
    off=$(od -An -t u8 -j 144 -N 8 "${name%%:*}.tlod" | tr -d ' ')
    size=$(od -An -t u8 -j 152 -N 8 "${name%%:*}.tlod" | tr -d ' ')
    dd if="${name%%:*}.tlod" of="${name##*:}.chunk" iflag=skip_bytes,count_bytes skip="$off" \
      count="$size" status=none
  done
  rm one.tlod lossy.tlod ao.tlod
}

# Frames and snapshots written from protobuf text format (protoc --encode), against the scene
# the fuzzer applies them to: nodes 1 > 2 > 3 and 4, at version 1.
seed_frame() {
  local proto="$OLDPWD/sync/proto"
  encode() { protoc --encode="tessera.scene.$1" -I "$proto" "$proto/tessera/scene.proto" >"$2"; }
  encode Frame changes.frame <<'END'
number: 2 version: 2 time_us: 33333
camera { eye: [636590.5, 847900.25, 1400] view: [0, 1316, -937] roll: 0.25 }
changed { id: 3 opacity: 0.5 visible: false transform { m: [1,0,0,0, 0,1,0,0, 0,0,1,0, 5,6,7,1] } }
changed { id: 2 parent: 4 shading: SHADING_EDL lod_pixels: 2 }
deleted: [1]
created { id: 5 kind: SKETCH parent: 3 sketch { points: [0, 0, 0, 1, 1, 1] width: 2 } }
created { id: 1 kind: AVATAR name: "visitor" avatar { site: "lab" color { g: 1 } } }
settings { background { r: 0.1 } shading: SHADING_COLOR spbr_ensembles: 8 }
commands { screenshot { path: "wall.png" } }
commands { quit {} }
END
  encode Frame unchanged.frame <<'END'
number: 2 version: 1 time_us: 33333
END
  # An avatar's pose in the rigid form (sync/transform.h).
  encode Frame pose.frame <<'END'
number: 2 version: 2 time_us: 33333
changed { id: 3 transform { translation: [636590.5, 847900.25, 3] rotation: [0.5, 0.5, -0.5, 0.5] } }
END
  encode Snapshot scene.snapshot <<'END'
version: 7 frame: 40
scene {
  camera { eye: [0, 0, 1] view: [0, 0, -1] roll: 0 }
  settings { background {} shading: SHADING_EDL lod_pixels: 1 spbr_ensembles: 1 }
  nodes { id: 1 kind: GROUP }
  nodes { id: 2 kind: MODEL parent: 1 model { store: "/s/a.tlod" } opacity: 0.5 }
  nodes { id: 9 kind: VIDEO_INSET parent: 2 video_inset { stream: "cam" width: 1 height: 0.5 } }
  nodes { id: 10 kind: SELECTION parent: 1 selection { model: 2
    lasso_clip_from_world: [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1]
    mask: "\x05\x03\x02\x02\x04" mask_width: 4 mask_height: 4 visible_only: true count: 5 } }
}
END
}

# Cluster link envelopes (cluster.proto): a join, a report, a welcome with a snapshot, a frame,
# and one of another protocol version.
seed_link() {
  local proto="$OLDPWD/sync/proto"
  encode() { protoc --encode="tessera.cluster.$1" -I "$proto" "$proto/tessera/cluster.proto" >"$2"; }
  encode FromNode hello.msg <<'END'
protocol: 2 hello { tile: "b" host: "h1.example.org" pid: 4242 }
END
  encode FromNode hello-any.msg <<'END'
protocol: 2 hello { host: "h2" pid: 1 }
END
  encode FromNode report.msg <<'END'
protocol: 2 report { frame: 7 status { code: NODE_BAD_STORE message: "a.tlod: bad" }
  stats { render_ms: 12.5 points: 1000 frames: 2 } rgba: "0123456789abcdef0123456789abcdef0123456789abcdef0123456789abcdef" }
END
  encode FromNode old.msg <<'END'
protocol: 1 hello { tile: "a" }
END
  encode ToNode welcome.msg <<'END'
protocol: 2 welcome { tile: "a" settled: true splat_scale: 2 gpu_budget_bytes: 1000000
  snapshot { version: 3 frame: 9 scene {
    camera { eye: [0, 0, 1] view: [0, 0, -1] roll: 0 }
    settings { background {} shading: SHADING_EDL lod_pixels: 1 spbr_ensembles: 1 }
    nodes { id: 1 kind: GROUP }
    nodes { id: 2 kind: MODEL parent: 1 model { store: "/s/a.tlod" } opacity: 0.5 } } }
  wall { tiles { name: "a" width: 1 height: 1 pixel_width: 4 pixel_height: 4 } eye { z: 2 } } }
END
  encode ToNode frame.msg <<'END'
protocol: 2 frame { frame: "\x08\x01\x10\x01" read_back: true }
END
  encode ToNode quit.msg <<'END'
protocol: 2 quit { code: 5 reason: "critical tile lost" }
END
}

# Site messages (site.proto ToMaster), each behind a 2-byte little-endian length, as
# site_fuzzer.cpp splits them: a session of poses, strokes and requests, and single messages.
seed_site() {
  local sp="$OLDPWD/sync/proto" cp="$OLDPWD/collab/proto"
  one() {
    protoc --encode=tessera.site.ToMaster -I "$sp" -I "$cp" "$cp/tessera/site.proto" >m.bin
    local n
    n=$(stat -c %s m.bin)
    # shellcheck disable=SC2059
    printf "$(printf '\\x%02x\\x%02x' $((n & 255)) $((n >> 8)))" >>"$1"
    cat m.bin >>"$1"
    rm m.bin
  }
  one session.msgs <<<'pose { sequence: 1 eye: [0, 0, 2] target: [0, 0, 0] up: [0, 1, 0] fovy_deg: 45 aspect: 1.5 }'
  one session.msgs <<<'stroke { points: [0, 0, 0, 0.1, 0, 0, 0.2, 0.1, 0] color { r: 1 } width: 4 }'
  one session.msgs <<<'lead {}'
  one session.msgs <<<'pose { sequence: 2 eye: [636590.5, 847900.25, 1400] target: [636590, 847901, 0] up: [0, 0, 1] fovy_deg: 60 aspect: 1 }'
  one session.msgs <<<'undo {}'
  one session.msgs <<<'clear {}'
  one session.msgs <<<'release {}'
  one session.msgs <<<'bye {}'
  one notes.msgs <<<'note { request: 1 add { position: [0.1, 0.2, 0.3] model: "bunny" item { layer: "damage/cracks" kind: "text" title: "crack" text: "seen" } } }'
  one notes.msgs <<<'note { request: 2 add { position: [1, 2, 3] radius: 0.5 view: [0, 0, 5, 1, 2, 3, 0, 1, 0, 40] item { layer: "history" kind: "number" title: "height" number: 2.5 unit: "m" } } }'
  one notes.msgs <<<'note { request: 3 open { place: 1 open: true } }'
  one notes.msgs <<<'note { request: 4 update { item: 1 base_revision: 1 content { layer: "damage" kind: "link" title: "report" uri: "https://example.org/r.pdf" } } }'
  one notes.msgs <<<'note { request: 5 update { item: 1 base_revision: 1 content { layer: "damage" kind: "text" title: "stale" } } }'
  one notes.msgs <<<'note { request: 6 layer { layer: "damage" visible: false } }'
  one notes.msgs <<<'note { request: 7 remove { item: 2 base_revision: 1 } }'
  one notes.msgs <<<'note { request: 8 add { place: 1 item { layer: "a/b/c" kind: "link" title: "see" link_item: 1 } } }'
  one hello.msgs <<<'hello { protocol: 2 name: "Kyoto lab" }'
  one stroke.msgs <<<'stroke { points: [1e8, 1e8, 1e8, -1e8, -1e8, -1e8] color { b: 1 } width: 64 }'
  local view='view: [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,-1,1] projection: [1.8,0,0,0, 0,2.4,0,0, 0,0,-1.2,-1, 0,0,-0.2,0] width: 640 height: 480'
  one select.msgs <<<"select { model: 2 $view lasso: [100, 100, 300, 100, 200, 300] }"
  one snap.msgs <<<"snap { model: 2 $view foreground: [120, 80, 160, 90, 200, 120] background: [300, 300, 400, 320] }"
  one snap.msgs <<<"snap { model: 2 $view foreground: [100, 100, 300, 100, 300, 300, 100, 300] heavy_width: 16 }"
  one snap.msgs <<<"snap { model: 2 $view foreground: [1e6, -1e6] background: [0, 0] heavy_width: 0.5 }"
}

# Chunk requests (site.proto ChunkRequest), one a file: a range, an identity request, the
# largest range, and ones the server refuses (past the end, overflowing, too long).
seed_chunk_request() {
  local sp="$OLDPWD/sync/proto" cp="$OLDPWD/collab/proto"
  one() {
    protoc --encode=tessera.site.ChunkRequest -I "$sp" -I "$cp" "$cp/tessera/site.proto" >"$1"
  }
  one range.req <<<'id: 7 store: "/data/bunny.tlod" offset: 4096 length: 65536'
  one info.req <<<'id: 1 store: "bunny.tlod" length: 0'
  one largest.req <<<'id: 2 store: "b.tlod" offset: 0 length: 8388608'
  one past.req <<<'id: 3 store: "b.tlod" offset: 746460 length: 100'
  one overflow.req <<<'id: 4 store: "b.tlod" offset: 18446744073709551610 length: 100'
  one long.req <<<'id: 5 store: "b.tlod" offset: 0 length: 8388609'
  one cancel.req <<<'cancel: 3 cancel: 4 cancel: 18446744073709551615'
  one mixed.req <<<'id: 6 store: "b.tlod" length: 100 cancel: 1'
}

# Voice packets (voice_fuzzer.cpp records: 2-byte length, 1-byte delay, packet): real Opus
# packets of a tone, in order, lost and reordered, and in 10 ms frames (fuzz/seeds/voice/, written
# by media::VoiceSender).
seed_voice() {
  cp "$OLDPWD"/fuzz/seeds/voice/*.rec .
}

# Video: records of real H.264 packets (fuzz/video_seeds.cpp: a 96x64 test pattern at 64 kbit/s
# with intra refresh, with IDRs, a key in chunks out of order).
seed_video() {
  "$OLDPWD/$BUILD/fuzz/video_seeds" >/dev/null
}

# WAV files: mono 48 kHz, stereo 22.05 kHz with an extra chunk, an EXTENSIBLE header.
seed_wav() {
  le16() { printf "$(printf '\\x%02x\\x%02x' $(($1 & 255)) $(($1 >> 8 & 255)))"; }
  le32() { le16 $(($1 & 65535)); le16 $(($1 >> 16 & 65535)); }
  wav() {  # wav FILE CHANNELS RATE FRAMES [list]: random samples, a LIST chunk before data
    local data=$(($4 * $2 * 2)) extra=0
    if [ -n "${5:-}" ]; then extra=12; fi
    {
      printf 'RIFF'; le32 $((36 + data + extra)); printf 'WAVEfmt '; le32 16
      le16 1; le16 "$2"; le32 "$3"; le32 $(($3 * $2 * 2)); le16 $(($2 * 2)); le16 16
      if [ -n "${5:-}" ]; then printf 'LIST'; le32 4; printf 'abcd'; fi
      printf 'data'; le32 "$data"
      head -c "$data" /dev/urandom
    } >"$1"
  }
  wav mono48.wav 1 48000 480
  wav stereo22.wav 2 22050 300 list
  wav odd8k.wav 1 8000 101
}

# Serialised selections (annotate/selection.h), checksums left zero (the target fixes them): all of
# a node, two ranges, a bitset, and three nodes at once.
seed_selection() {
  local head='TSEL\x01\x00\x00\x00' sum='\x00\x00\x00\x00\x00\x00\x00\x00'
  local all='\x00\x00\x00\x00\x64\x00\x00\x00\x00'
  local ranges='\x03\x00\x00\x00\x2c\x01\x00\x00\x01\x02\x00\x00\x00'
  ranges+='\x01\x00\x00\x00\x04\x00\x00\x00\xfa\x00\x00\x00\xfb\x00\x00\x00'
  local bits='\x0c\x00\x00\x00\x80\x00\x00\x00\x02' word='\x33\x33\x33\x33\x33\x33\x33\x33'
  printf "$head"'\x01\x00\x00\x00'"$all$sum" >all.sel
  printf "$head"'\x01\x00\x00\x00'"$ranges$sum" >ranges.sel
  printf "$head"'\x01\x00\x00\x00'"$bits$word$word$sum" >bits.sel
  printf "$head"'\x03\x00\x00\x00'"$all$ranges$bits$word$word$sum" >three.sel
}

# Annotation imports: JSON exports with every item and place kind (fuzz/seeds/annotation/,
# written by tessera-annotate export), and an empty one.
seed_annotation() {
  cp "$OLDPWD"/fuzz/seeds/annotation/*.json .
}

# Pictures: tiny PNG, JPEG and GIF (gnuplot), BMP and TIFF (hand-made) in fuzz/seeds/picture/.
seed_picture() {
  cp "$OLDPWD"/fuzz/seeds/picture/* .
}

# The LAS, LAZ and PLY seeds, each behind the two bytes the target reads first: which name the
# bytes go by (0 .las, 1 .laz, 2 .ply) and the points asked for less one (9: every k-th of ten).
seed_scan_sample() {
  local f kind
  seed_las
  seed_laz
  seed_ply
  for f in *.las *.laz *.ply; do
    case "$f" in *.las) kind='\x00' ;; *.laz) kind='\x01' ;; *) kind='\x02' ;; esac
    { printf "$kind"'\x09'; cat "$f"; } >"sample-$f" && rm "$f"
  done
}

seed_pfm() {
  cp "$OLDPWD"/fuzz/seeds/pfm/* .
}

declare -A MAX_LEN=([ply]=8192 [las]=8192 [laz]=65536 [e57]=131072 [text]=4096 [obj]=4096 [conf]=1024 [tlod]=32768
  [chunk]=8192 [frame]=4096 [link]=4096 [site]=4096 [chunk_request]=1024 [voice]=8192
  [wav]=16384 [tmesh]=16384 [video]=32768 [selection]=4096 [annotation]=16384
  [picture]=8192 [pfm]=4096 [scan_sample]=65536)
export UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1
status=0
summary=()
for target in "${TARGETS[@]}"; do
  fuzzer="$BUILD/fuzz/${target}_fuzzer"
  corpus="$BUILD/corpus/$target"
  regressions="fuzz/regressions/$target"
  log="$BUILD/logs/$target.log"
  mkdir -p "$corpus" "$regressions" "$(dirname "$log")"
  (cd "$corpus" && "seed_$target")
  dirs=("$corpus")
  if [ -n "$(ls -A "$regressions")" ]; then dirs+=("$regressions"); fi
  echo "== ${target}_fuzzer: ${SECONDS_PER_TARGET}s, log $log"
  start=$(date +%s)
  rc=0
  "$fuzzer" "${dirs[@]}" -max_total_time="$SECONDS_PER_TARGET" -max_len="${MAX_LEN[$target]}" \
    -rss_limit_mb=2048 -timeout=10 -print_final_stats=1 -artifact_prefix="$regressions/" \
    >"$log" 2>&1 || rc=$?
  elapsed=$(($(date +%s) - start))
  execs=$(awk '/^stat::number_of_executed_units:/ {print $2}' "$log")
  rate=$(awk '/^stat::average_exec_per_sec:/ {print $2}' "$log")
  cov=$(grep -o 'cov: [0-9]* ft: [0-9]*' "$log" | tail -1 || true)
  if [ "$rc" -eq 0 ]; then
    found="no crash"
  else
    status=1
    found="CRASH (exit $rc): $(grep -o "Test unit written to .*" "$log" | tail -1 || true)"
    found+=" $(grep -m1 -E '^(==[0-9]+==ERROR|SUMMARY|.*runtime error|reader fuzz:)' "$log" || true)"
  fi
  summary+=("${target}_fuzzer: ${elapsed}s, ${execs:-?} execs (${rate:-?}/s), ${cov:-cov: ?}, $found")
  echo "${summary[-1]}"
done
echo "== summary"
printf '%s\n' "${summary[@]}"
exit "$status"
