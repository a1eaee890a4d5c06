#!/usr/bin/env python3
"""Tile a LAS file side by side into one larger LAS of exactly N points.

Copies of the input are shifted in x and y by the input's extent (in its own
integer units, plus one unit so seams never hold duplicate positions) on a
square grid, row by row; the last copy is cut short so the output holds exactly
--points records. The header and VLRs are copied verbatim, then the point
count, the per-return counts and the bounds are rewritten. The output is
written one copy at a time, so 10^7-10^8 points stream in a few MB of memory.

Pure python3 (struct, array): no numpy. LAS 1.0-1.4, point formats 0-10;
EVLRs of a LAS 1.4 input are not copied.
"""

import argparse
import array
import math
import os
import struct
import sys


def fail(msg):
    print("tile_las.py: error: " + msg, file=sys.stderr)
    sys.exit(1)


def column(points, n, rec_len, offset):
    """The int32 at `offset` of each of n records, as array('i')."""
    raw = bytearray(4 * n)
    for k in range(4):
        raw[k::4] = points[offset + k::rec_len]
    col = array.array("i")
    col.frombytes(bytes(raw))
    if sys.byteorder != "little":
        col.byteswap()
    return col


def put_column(out, col, rec_len, offset):
    if sys.byteorder != "little":
        col = array.array("i", col)
        col.byteswap()
    raw = col.tobytes()
    for k in range(4):
        out[offset + k::rec_len] = raw[k::4]


def main():
    ap = argparse.ArgumentParser(
        description="Tile a LAS file side by side (copies shifted in x/y by the "
        "file's extent on a square grid) into ONE LAS of exactly N points.")
    ap.add_argument("input", help="input LAS (uncompressed)")
    ap.add_argument("-o", "--output", required=True, help="output LAS")
    ap.add_argument("-n", "--points", required=True, type=float,
                    help="points in the output (1e7 and 30000000 both work)")
    args = ap.parse_args()

    n_out = int(args.points)
    if n_out <= 0 or n_out != args.points:
        fail("--points must be a positive integer, got %r" % args.points)
    if not os.path.isfile(args.input):
        fail("no such input file: " + args.input)

    with open(args.input, "rb") as f:
        data = f.read()
    if data[:4] != b"LASF":
        fail(args.input + " is not a LAS file (LAZ is not supported)")
    ver_major, ver_minor = data[24], data[25]
    hdr_size, = struct.unpack_from("<H", data, 94)
    pt_offset, = struct.unpack_from("<I", data, 96)
    fmt = data[104] & 0x3F
    if data[104] & 0xC0:
        fail("compressed (LAZ) point data is not supported")
    rec_len, = struct.unpack_from("<H", data, 105)
    n_in, = struct.unpack_from("<I", data, 107)
    is14 = (ver_major, ver_minor) >= (1, 4) and hdr_size >= 375
    if is14 and n_in == 0:
        n_in, = struct.unpack_from("<Q", data, 247)
    scale = struct.unpack_from("<3d", data, 131)
    offs = struct.unpack_from("<3d", data, 155)
    if n_in == 0:
        fail("input has no points")
    points = memoryview(data)[pt_offset:pt_offset + n_in * rec_len]
    if len(points) != n_in * rec_len:
        fail("input is truncated: %d points of %d bytes declared" % (n_in, rec_len))
    if n_out > 0xFFFFFFFF and not is14:
        fail("more than 2^32-1 points need a LAS 1.4 input")

    xs = column(points, n_in, rec_len, 0)
    ys = column(points, n_in, rec_len, 4)
    zs = column(points, n_in, rec_len, 8)
    step_x = max(xs) - min(xs) + 1
    step_y = max(ys) - min(ys) + 1
    n_tiles = -(-n_out // n_in)
    side = math.isqrt(n_tiles - 1) + 1 if n_tiles > 1 else 1
    last_x = max(xs) + (side - 1) * step_x
    last_y = max(ys) + ((n_tiles - 1) // side) * step_y
    if last_x > 0x7FFFFFFF or last_y > 0x7FFFFFFF:
        fail("tiled coordinates overflow int32 at this scale; ask for fewer points")

    ret_mask = 0x0F if fmt >= 6 else 0x07
    n_returns = 15 if is14 else 5

    def return_counts(recs, count):
        counts = [0] * 16
        rb = recs[14::rec_len]
        for v in range(256):
            c = rb.count(bytes((v,)))
            if c:
                counts[v & ret_mask] += c
        return counts

    full_counts = return_counts(bytes(points), n_in)

    header = bytearray(data[:pt_offset])
    if is14:
        struct.pack_into("<Q", header, 235, 0)   # no EVLRs copied
        struct.pack_into("<I", header, 243, 0)
    tot_counts = [0] * 16
    bmin = [None] * 3
    bmax = [None] * 3

    tmp = args.output + ".part"
    written = 0
    with open(tmp, "wb") as out:
        out.write(header)
        tile = 0
        while written < n_out:
            m = min(n_in, n_out - written)
            ix, iy = tile % side, tile // side
            dx, dy = ix * step_x, iy * step_y
            block = bytearray(points[:m * rec_len])
            tx = array.array("i", [v + dx for v in xs[:m]])
            ty = array.array("i", [v + dy for v in ys[:m]])
            put_column(block, tx, rec_len, 0)
            put_column(block, ty, rec_len, 4)
            tz = zs[:m]
            for a, col in enumerate((tx, ty, tz)):
                lo, hi = min(col), max(col)
                bmin[a] = lo if bmin[a] is None else min(bmin[a], lo)
                bmax[a] = hi if bmax[a] is None else max(bmax[a], hi)
            counts = full_counts if m == n_in else return_counts(bytes(block), m)
            for r in range(16):
                tot_counts[r] += counts[r]
            out.write(block)
            written += m
            tile += 1

        # header: counts and bounds of what was written
        struct.pack_into("<I", header, 107, n_out if n_out <= 0xFFFFFFFF and fmt < 6 or not is14 else 0)
        legacy = [tot_counts[r] if (fmt < 6 or not is14) else 0 for r in range(1, 6)]
        struct.pack_into("<5I", header, 111, *[min(c, 0xFFFFFFFF) for c in legacy])
        world = [(bmin[a] * scale[a] + offs[a], bmax[a] * scale[a] + offs[a]) for a in range(3)]
        struct.pack_into("<6d", header, 179, world[0][1], world[0][0], world[1][1],
                         world[1][0], world[2][1], world[2][0])
        if is14:
            struct.pack_into("<Q", header, 247, n_out)
            struct.pack_into("<15Q", header, 255, *tot_counts[1:16])
        out.seek(0)
        out.write(header)
    os.replace(tmp, args.output)
    print("%s: %d points, %d copies of %s on a %dx%d grid, %.1f MB" % (
        args.output, n_out, n_tiles, os.path.basename(args.input), side,
        -(-n_tiles // side), os.path.getsize(args.output) / 1e6))


if __name__ == "__main__":
    main()
