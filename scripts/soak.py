#!/usr/bin/env python3
"""A wall under churn, as a museum runs one all day: tessera-master and N tessera-node processes
over ZeroMQ on this host, the camera orbiting the Stanford bunny, while a seeded chaos kills
nodes (kill -9, restarted), stops them past the node timeout (SIGSTOP, then SIGCONT), and brings
remote sites that draw, lead, write a note and leave (some killed instead).

Every --interval seconds it samples the master's and the nodes' memory (RSS), the frame rate,
the live tiles and the drops; at quiet moments (no fault for a while) the master writes the
wall's picture, compared afterwards pixel for pixel with `tessera-render --mosaic` for the same
camera. It writes into --out:
  samples.csv   t_s, master_rss_mb, node_rss_mb (each node, ';'), fps, live_tiles, drops,
                healthy_drops
  events.csv    t_s, event (kill, restart, stop, continue, site, site_kill), target, detail
  drops.csv     t_s, tile, pid, cause, faulted (whether that process had been faulted)
  soak.png      memory, frame rate and live tiles over time (gnuplot)
  summary.txt   the goals and whether each was met
and exits 0 when every goal is met, 1 when one is missed, 2 when it could not run.

Goals: no healthy tile dropped; every return (a restarted or continued node) rejoined exactly
once within 2 s; RSS growth under 1% an hour, after a warm-up (--warmup) in which caches fill,
for the master and the nodes never restarted; no
frame gap longer than the node timeout except where a node died; every quiet-moment picture
exactly the mosaic.

  scripts/soak.py --duration 3600 --out out/soak          an hour, as docs/performance.md
  scripts/soak.py --duration 120 --interval 20 --pictures 40 --every 5:9 --out out/soak-short
                                                          the short form the tests run
"""
import argparse
import math
import os
import random
import re
import signal
import struct
import subprocess
import sys
import threading
import time
import zlib

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def die(why):
    print(f"soak: {why}", file=sys.stderr)
    sys.exit(2)


def read_png(path):
    """The RGBA (or RGB) pixels of an 8-bit, non-interlaced PNG, as (width, height, bytes)."""
    with open(path, "rb") as f:
        data = f.read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError(f"{path}: not a PNG")
    pos, idat, width, height, channels = 8, b"", 0, 0, 4
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        chunk = data[pos + 8:pos + 8 + length]
        if kind == b"IHDR":
            width, height, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", chunk)
            if depth != 8 or interlace != 0 or colour not in (2, 6):
                raise ValueError(f"{path}: only 8-bit RGB(A) non-interlaced PNGs are read")
            channels = 4 if colour == 6 else 3
        elif kind == b"IDAT":
            idat += chunk
        pos += 12 + length
    raw = zlib.decompress(idat)
    stride = width * channels
    out = bytearray(height * stride)
    prev = bytearray(stride)
    for y in range(height):
        kind = raw[y * (stride + 1)]
        line = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for x in range(stride):
            a = line[x - channels] if x >= channels else 0
            b = prev[x]
            c = prev[x - channels] if x >= channels else 0
            if kind == 1:
                line[x] = (line[x] + a) & 255
            elif kind == 2:
                line[x] = (line[x] + b) & 255
            elif kind == 3:
                line[x] = (line[x] + (a + b) // 2) & 255
            elif kind == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[x] = (line[x] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        out[y * stride:(y + 1) * stride] = line
        prev = line
    if channels == 3:  # as RGBA
        rgba = bytearray(width * height * 4)
        rgba[0::4], rgba[1::4], rgba[2::4] = out[0::3], out[1::3], out[2::3]
        rgba[3::4] = b"\xff" * (width * height)
        out = rgba
    return width, height, bytes(out)


class Proc:
    """A process of the soak, its log appended to a file, its lines kept with their time."""

    started = []  # every Proc, so that an interrupted soak leaves none behind

    def __init__(self, argv, log, keep_lines=False):
        self.argv = argv
        self.lines = []  # (monotonic time, line)
        self.log = open(log, "a", buffering=1)
        self.p = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                  stdin=subprocess.DEVNULL, text=True, errors="replace")
        self.keep = keep_lines
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()
        Proc.started.append(self)

    def _read(self):
        for line in self.p.stdout:
            self.log.write(line)
            if self.keep:
                self.lines.append((time.monotonic(), line.rstrip("\n")))

    @property
    def pid(self):
        return self.p.pid

    def running(self):
        return self.p.poll() is None

    def signal(self, sig):
        if self.running():
            os.kill(self.p.pid, sig)

    def wait(self, timeout):
        try:
            return self.p.wait(timeout)
        except subprocess.TimeoutExpired:
            return None

    def wait_for(self, pattern, timeout):
        rx = re.compile(pattern)
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            for _, line in list(self.lines):
                m = rx.search(line)
                if m:
                    return m
            if not self.running():
                break
            time.sleep(0.05)
        return None


def rss_mb(pid):
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return float("nan")


def slope_per_hour(points):
    """Least-squares slope of (t_s, value) points, as % of their mean per hour."""
    if len(points) < 3:
        return float("nan")
    n = len(points)
    mt = sum(t for t, _ in points) / n
    mv = sum(v for _, v in points) / n
    var = sum((t - mt) ** 2 for t, _ in points)
    if var == 0 or mv == 0:
        return float("nan")
    slope = sum((t - mt) * (v - mv) for t, v in points) / var
    return 100.0 * slope * 3600.0 / mv


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog=__doc__.split("\n\n", 1)[1])
    ap.add_argument("--duration", type=float, default=3600, help="seconds of churn (default 3600)")
    ap.add_argument("--nodes", type=int, default=4, help="render nodes, one tile each (default 4)")
    ap.add_argument("--sites", type=int, default=2, help="remote sites at most at once (default 2)")
    ap.add_argument("--every", default="20:40",
                    help="seconds between faults, MIN:MAX (default 20:40)")
    ap.add_argument("--interval", type=float, default=30, help="sampling interval, s (default 30)")
    ap.add_argument("--pictures", type=float, default=120,
                    help="seconds between quiet-moment pictures (default 120)")
    ap.add_argument("--node-timeout", type=float, default=1500, help="ms (default 1500)")
    ap.add_argument("--seed", type=int, default=1, help="the chaos's seed (default 1)")
    ap.add_argument("--warmup", type=float, default=600,
                    help="seconds before memory growth is judged: caches fill (default 600)")
    ap.add_argument("--build", default=os.path.join(ROOT, "build", "dev"),
                    help="where the programs are built (default build/dev)")
    ap.add_argument("--data", default=os.path.join(ROOT, "..", "shared", "data"),
                    help="the data folder (default ../shared/data)")
    ap.add_argument("--out", default=os.path.join(ROOT, "out", "soak"), help="output folder")
    a = ap.parse_args()
    # The mosaic reference renders with the output folder as its working directory.
    a.build, a.data = os.path.abspath(a.build), os.path.abspath(a.data)
    for name, v in (("--duration", a.duration), ("--interval", a.interval),
                    ("--pictures", a.pictures), ("--node-timeout", a.node_timeout)):
        if not (math.isfinite(v) and v > 0):
            die(f"{name}: must be a finite number > 0, got {v}")
    if not 1 <= a.nodes <= 16:
        die(f"--nodes: 1..16, got {a.nodes}")
    if not 0 <= a.sites <= 4:
        die(f"--sites: 0..4, got {a.sites}")
    m = re.fullmatch(r"([0-9.]+):([0-9.]+)", a.every)
    if not m or not 0.5 <= float(m.group(1)) <= float(m.group(2)):
        die(f"--every: MIN:MAX seconds with 0.5 <= MIN <= MAX, got '{a.every}'")
    every = (float(m.group(1)), float(m.group(2)))
    exe = {n: os.path.join(a.build, d, n) for n, d in (
        ("tessera-master", "master"), ("tessera-node", "render_node"),
        ("tessera-site", "collab"), ("tessera-render", "render"), ("tessera-lod", "lod"))}
    for n, p in exe.items():
        if not os.access(p, os.X_OK):
            die(f"{p}: not built (cmake --build --preset dev)")
    scans = os.path.join(a.data, "stanford-bunny", "scans", "bun.conf")
    if not os.path.isfile(scans):
        die(f"{scans}: missing (--data names the data folder)")
    out = os.path.abspath(a.out)
    os.makedirs(os.path.join(out, "shots"), exist_ok=True)
    for f in os.listdir(out):
        if f.endswith(".log"):
            os.remove(os.path.join(out, f))
    rng = random.Random(a.seed)
    timeout_s = a.node_timeout / 1000.0

    # The scene, the wall, the orbit with a picture at each quiet moment.
    store = os.path.join(out, "bunny.tlod")
    if not os.path.isfile(store):
        r = subprocess.run([exe["tessera-lod"], "build", scans, "-o", store, "--quiet"],
                           capture_output=True, text=True)
        if r.returncode != 0:
            die(f"tessera-lod build failed: {r.stdout}{r.stderr}")
    with open(os.path.join(out, "scene.json"), "w") as f:
        f.write('{"nodes": [{"kind": "MODEL", "name": "bunny", "model": {"store": "bunny.tlod"}}],'
                ' "camera": {"eye": {"x": -0.027, "y": 0.12, "z": 0.38}, "target": {"x": -0.027,'
                ' "y": 0.1, "z": 0.0}, "up": {"y": 1}}, "settings": {"background": {"r": 0.05,'
                ' "g": 0.05, "b": 0.08}, "lodPixels": 1.0, "shading": "SHADING_EDL"}}')
    cols = math.ceil(math.sqrt(a.nodes))
    rows = math.ceil(a.nodes / cols)
    tiles = []
    for i in range(a.nodes):
        c, r = i % cols, i // cols
        tiles.append((f"tile-{c}-{r}", c * 0.5, (rows - 1 - r) * 0.29))
    with open(os.path.join(out, "wall.json"), "w") as f:
        f.write('{"name": "soak", "tiles": [' + ", ".join(
            f'{{"name": "{n}", "x": {x}, "y": {y}, "width": 0.48, "height": 0.27, '
            f'"pixelWidth": 320, "pixelHeight": 180}}' for n, x, y in tiles) +
            f'], "eye": {{"x": {0.25 * cols - 0.01}, "y": {0.145 * rows - 0.01}, "z": 1.5}}}}')
    quiet = []  # script times of the pictures
    t = a.pictures
    while t < a.duration:
        quiet.append(t)
        t += a.pictures
    keys, actions = [], []
    span = a.duration + 120
    for k in range(int(span / 2) + 1):
        ang = k * 2 * 0.25
        keys.append('{"time": %d, "eye": {"x": %.6f, "y": 0.12, "z": %.6f}, "target": {"x": -0.027,'
                    ' "y": 0.1, "z": 0}, "up": {"x": 0, "y": 1, "z": 0}}'
                    % (2 * k, -0.027 + 0.38 * math.sin(ang), 0.38 * math.cos(ang)))
    for i, q in enumerate(quiet):
        actions.append('{"time": %.3f, "screenshot": "shots/quiet-%04d.png"}' % (q, i))
    with open(os.path.join(out, "orbit.json"), "w") as f:
        f.write('{"name": "soak orbit", "keyframes": [' + ", ".join(keys) + '], "actions": [' +
                ", ".join(actions) + "]}")
    # Keys for the master and the sites.
    for name in ["master"] + [f"site{i}" for i in range(a.sites)]:
        kf = os.path.join(out, name + ".key")
        if os.path.exists(kf):
            os.remove(kf)
        r = subprocess.run([exe["tessera-site"], "keygen", "-o", kf], capture_output=True,
                           text=True)
        if r.returncode != 0:
            die(f"tessera-site keygen: {r.stdout}{r.stderr}")
        pub = re.search(r"^(\S{40})$", r.stdout, re.M)
        if not pub:
            die(f"tessera-site keygen printed no public key: {r.stdout}")
        if name == "master":
            master_pub = pub.group(1)
        else:
            with open(os.path.join(out, "allow.txt"), "a" if name != "site0" else "w") as f:
                f.write(f"{pub.group(1)} {name}\n")
    if a.sites == 0:
        open(os.path.join(out, "allow.txt"), "w").close()

    # The wall.
    for f in ("stats.csv", "notes.tadb"):
        if os.path.exists(os.path.join(out, f)):
            os.remove(os.path.join(out, f))
    start = time.monotonic()
    master = Proc([exe["tessera-master"], "--transport", "zmq", "--listen", "tcp://127.0.0.1:*",
                   "--wall", os.path.join(out, "wall.json"), "--scene",
                   os.path.join(out, "scene.json"), "--script", os.path.join(out, "orbit.json"),
                   "--max-fps", "10", "--node-timeout", str(a.node_timeout), "--stats",
                   os.path.join(out, "stats.csv"), "--out-dir", out, "--sites",
                   "tcp://127.0.0.1:*", "--site-key", os.path.join(out, "master.key"), "--allow",
                   os.path.join(out, "allow.txt"), "--annotations",
                   os.path.join(out, "notes.tadb")], os.path.join(out, "master.log"), True)
    wall_ep = master.wait_for(r"listening on (tcp://\S+)", 60)
    sites_ep = master.wait_for(r"remote sites join on (tcp://\S+)", 60)
    if not wall_ep or not sites_ep:
        master.signal(signal.SIGKILL)
        die("the master did not start: see " + os.path.join(out, "master.log"))
    wall_ep, sites_ep = wall_ep.group(1), sites_ep.group(1)
    nodes = {}  # tile -> Proc
    restarted = set()  # tiles whose node was restarted (their RSS starts again)

    def start_node(tile):
        nodes[tile] = Proc([exe["tessera-node"], "--master", wall_ep, "--headless", "--tile", tile],
                           os.path.join(out, f"node-{tile}.log"), True)

    for n, _, _ in tiles:
        start_node(n)
    if not master.wait_for(rf"{a.nodes} of {a.nodes} tiles have a node", 120):
        for p in nodes.values():
            p.signal(signal.SIGKILL)
        master.signal(signal.SIGKILL)
        die("the wall did not start: see " + os.path.join(out, "master.log"))
    session0 = time.monotonic()  # about the master's script time 0

    events, samples = [], []
    faults = {}  # pid -> list of fault times
    stopped = {}  # tile -> continue time
    sites, site_count = [], 0

    def event(kind, target, detail=""):
        events.append((time.monotonic() - start, kind, target, detail))

    def near_quiet(t_abs, margin, after=None):
        """Whether a picture falls within `margin` s before `t_abs` or `after` s (default
        `margin`) after it."""
        st = t_abs - session0
        return any(st - margin < q < st + (margin if after is None else after) for q in quiet)

    def site_script(frames):
        return ('{"width": 320, "height": 240, "fps": 10, "frames": %d, "actions": ['
                '{"frame": 0, "camera": {"eye": {"x": -0.11, "y": 0.14, "z": 0.3}, "target": '
                '{"x": -0.027, "y": 0.1, "z": 0.0}, "up": {"y": 1}}}, '
                '{"frame": 10, "stroke": {"pixels": [100, 150, 130, 145, 160, 142, 190, 145, 220,'
                ' 150], "color": {"r": 1.0, "g": 0.2, "b": 0.1}, "width": 4}}, '
                '{"frame": 20, "lead": true}, '
                '{"frame": 30, "note": {"pixel": [160, 120], "note": {"add": {"item": {'
                '"layer": "soak", "kind": "text", "title": "soak note", "text": "written under '
                'churn"}}}}}, '
                '{"frame": 35, "note": {"note": {"layer": {"layer": "soak", "visible": false}}}}, '
                '{"frame": 45, "clear": true}, '
                '{"frame": %d, "release": true}]}' % (frames, max(50, frames - 20)))

    next_fault = time.monotonic() + rng.uniform(*every)
    next_sample = time.monotonic() + a.interval
    end = start + a.duration
    stats_path = os.path.join(out, "stats.csv")
    last_stats = 0
    total_frames_at = []  # (t, frames so far)

    def count_frames():
        try:
            with open(stats_path) as f:
                return sum(1 for line in f if ",master," in line)
        except OSError:
            return 0

    def drops_so_far():
        rx = re.compile(r"tile (\S+) \(host [^,]*, pid (\d+)\) dropped: (.*)$")
        found = []
        for t_line, line in list(master.lines):
            m2 = rx.search(line)
            if m2:
                pid = int(m2.group(2))
                faulted = any(t_line - 12.0 <= ft <= t_line for ft in faults.get(pid, []))
                found.append((t_line - start, m2.group(1), pid, m2.group(3), faulted))
        return found

    def live_tiles():
        joined = {}
        rx = re.compile(r"tile (\S+) \(host [^,]*, pid \d+\) (joined|rejoined|dropped)")
        for _, line in list(master.lines):
            m2 = rx.search(line)
            if m2:
                joined[m2.group(1)] = m2.group(2) != "dropped"
        return sum(1 for v in joined.values() if v)

    print(f"soak: {a.nodes} nodes, up to {a.sites} sites, {a.duration:.0f} s, faults every "
          f"{every[0]:g}-{every[1]:g} s, seed {a.seed}; writing {out}", flush=True)
    while time.monotonic() < end and master.running():
        now = time.monotonic()
        for tile, when in list(stopped.items()):
            if now >= when:
                nodes[tile].signal(signal.SIGCONT)
                event("continue", tile, str(nodes[tile].pid))
                faults.setdefault(nodes[tile].pid, []).append(now)
                del stopped[tile]
        sites = [s for s in sites if s.running()]
        if now >= next_fault and not near_quiet(now, 4.0 + timeout_s):
            kind = rng.choices(["kill", "stop", "site"], [0.45, 0.30, 0.25 if a.sites else 0])[0]
            # A site is on the wall (its avatar, its stroke) until it leaves: none at a picture.
            site_frames = rng.randint(80, 150)
            if kind == "site" and (len(sites) >= a.sites or
                                   near_quiet(now, 2.0, site_frames / 10.0 + 8.0)):
                kind = "kill"
            candidates = [t for t in nodes if t not in stopped]
            if kind in ("kill", "stop") and candidates:
                tile = rng.choice(candidates)
                p = nodes[tile]
                faults.setdefault(p.pid, []).append(now)
                if kind == "kill":
                    p.signal(signal.SIGKILL)
                    event("kill", tile, str(p.pid))
                    p.wait(5)
                    time.sleep(rng.uniform(0.2, 1.0))
                    start_node(tile)
                    restarted.add(tile)
                    event("restart", tile, str(nodes[tile].pid))
                else:
                    p.signal(signal.SIGSTOP)
                    hold = rng.uniform(timeout_s + 0.5, timeout_s + 2.5)
                    stopped[tile] = now + hold
                    event("stop", tile, f"{p.pid} for {hold:.1f} s")
            elif kind == "site":
                name = f"site{site_count % a.sites}"
                if any(s.argv[s.argv.index("--name") + 1] == name for s in sites):
                    name = f"site{(site_count + 1) % a.sites}"
                site_count += 1
                frames = site_frames
                sp = os.path.join(out, f"site-{site_count}.json")
                with open(sp, "w") as f:
                    f.write(site_script(frames))
                s = Proc([exe["tessera-site"], "--master", sites_ep, "--master-key", master_pub,
                          "--name", name, "--key", os.path.join(out, name + ".key"),
                          "--headless", "-o", os.path.join(out, f"site-{site_count}"),
                          "--script", sp], os.path.join(out, f"site-{site_count}.log"))
                sites.append(s)
                event("site", name, f"{frames} frames")
                if rng.random() < 0.3:  # some are killed instead of leaving, after their clear
                    threading.Timer(rng.uniform(6.0, frames / 10.0), lambda s=s, n=name: (
                        s.signal(signal.SIGKILL), event("site_kill", n, str(s.pid)))).start()
            next_fault = time.monotonic() + rng.uniform(*every)
        if now >= next_sample:
            frames = count_frames()
            fps = (frames - last_stats) / a.interval
            last_stats = frames
            drops = drops_so_far()
            node_rss = ";".join(f"{rss_mb(p.pid):.1f}" for _, p in sorted(nodes.items()))
            samples.append((now - start, rss_mb(master.pid), node_rss, fps, live_tiles(),
                            len(drops), sum(1 for d in drops if not d[4]),
                            {t: rss_mb(p.pid) for t, p in nodes.items()}))
            s = samples[-1]
            print(f"soak: {s[0]:7.0f} s  master {s[1]:6.1f} MB  nodes {s[2]} MB  {s[3]:5.1f} fps  "
                  f"{s[4]} live  {s[5]} drops ({s[6]} healthy)", flush=True)
            next_sample += a.interval
        time.sleep(0.05)

    # The end: continue what is stopped, end the session, reap everything.
    for tile in list(stopped):
        nodes[tile].signal(signal.SIGCONT)
    time.sleep(1.0)
    master.signal(signal.SIGTERM)
    master_code = master.wait(60)
    if master_code is None:
        master.signal(signal.SIGKILL)
    for p in list(nodes.values()) + sites:
        if p.wait(20) is None:
            p.signal(signal.SIGKILL)
            p.wait(5)
    master.reader.join(5)
    t_end = time.monotonic()
    drops = drops_so_far()

    # Returns: each restart and each continue that follows a drop rejoins once, within 2 s.
    returns = []
    join_rx = re.compile(r"tile (\S+) \(host [^,]*, pid (\d+)\) (joined|rejoined)")
    joins = [(t_line, m2.group(1), int(m2.group(2))) for t_line, line in master.lines
             for m2 in [join_rx.search(line)] if m2]
    for t_ev, kind, tile, detail in events:
        if kind not in ("restart", "continue"):
            continue
        pid = int(detail)
        t_abs = start + t_ev
        if kind == "continue":
            # Only a node that was dropped while stopped comes back.
            dropped = [d for d in drops if d[2] == pid and t_abs - 6.0 <= start + d[0] <= t_abs + 2.5]
            if not dropped:
                continue
        nxt = [e for e in events if e[2] == tile and e[0] > t_ev and e[1] in ("kill", "stop")]
        horizon = start + nxt[0][0] if nxt else t_end
        mine = [j for j in joins if j[2] == pid and t_abs - 0.5 <= j[0] <= horizon]
        late = (mine[0][0] - t_abs) if mine else float("inf")
        returns.append((t_ev, kind, tile, pid, len(mine), late))
    # Frame gaps from the master's stats (steady-clock starts).
    starts = []
    live_at = {}  # frame -> [start, live tiles]
    try:
        with open(stats_path) as f:
            for line in f:
                parts = line.rstrip("\n").split(",")
                if len(parts) <= 18 or not parts[0].isdigit():
                    continue
                entry = live_at.setdefault(int(parts[0]), [float(parts[18]), 0])
                if parts[3] == "master":
                    starts.append(float(parts[18]))
                elif parts[17] == "live":
                    entry[1] += 1
    except OSError:
        pass
    starts.sort()
    kills = [start + e[0] for e in events if e[1] == "kill"]
    gaps = []
    longest_gap = max((t1 - t0 for t0, t1 in zip(starts, starts[1:])), default=0.0)
    for t0, t1 in zip(starts, starts[1:]):
        if t1 - t0 > timeout_s + 0.2:
            died = any(t0 - timeout_s - 1.0 <= k <= t1 for k in kills)
            gaps.append((t0 - start, t1 - t0, died))
    # Memory: the master and the nodes never restarted, after the warm-up (the whole run too).
    settled = [s for s in samples if s[0] >= a.warmup]
    growth = {"master": slope_per_hour([(s[0], s[1]) for s in settled])}
    whole = {"master": slope_per_hour([(s[0], s[1]) for s in samples])}
    for tile in sorted(nodes):
        if tile not in restarted:
            growth[tile] = slope_per_hour([(s[0], s[7].get(tile, float("nan"))) for s in settled])
            whole[tile] = slope_per_hour([(s[0], s[7].get(tile, float("nan"))) for s in samples])
    # Quiet-moment pictures against tessera-render --mosaic.
    shot_rx = re.compile(r"frame \d+: wrote (\S+quiet-\d+\.png) \(\d+x\d+\); camera (\S+)")
    pictures = []
    for _, line in master.lines:
        m2 = shot_rx.search(line)
        if not m2:
            continue
        ref = m2.group(1)[:-4] + "-mosaic.png"
        r = subprocess.run([exe["tessera-render"], "--scene", os.path.join(out, "scene.json"),
                            "--wall", os.path.join(out, "wall.json"), "--mosaic", "--camera",
                            m2.group(2), "-o", ref], capture_output=True, text=True, cwd=out)
        if r.returncode != 0:
            pictures.append((m2.group(1), -1))
            continue
        w1, h1, p1 = read_png(m2.group(1))
        w2, h2, p2 = read_png(ref)
        differ = -2 if (w1, h1) != (w2, h2) else sum(
            1 for i in range(0, len(p1), 4) if p1[i:i + 4] != p2[i:i + 4])
        pictures.append((m2.group(1), differ))

    # Files: samples, events, drops, chart, summary.
    with open(os.path.join(out, "samples.csv"), "w") as f:
        f.write("t_s,master_rss_mb,node_rss_mb,fps,live_tiles,drops,healthy_drops\n")
        for s in samples:
            f.write(f"{s[0]:.1f},{s[1]:.1f},{s[2]},{s[3]:.2f},{s[4]},{s[5]},{s[6]}\n")
    with open(os.path.join(out, "events.csv"), "w") as f:
        f.write("t_s,event,target,detail\n")
        for e in events:
            f.write(f"{e[0]:.2f},{e[1]},{e[2]},{e[3]}\n")
    with open(os.path.join(out, "drops.csv"), "w") as f:
        f.write("t_s,tile,pid,cause,faulted\n")
        for d in drops:
            f.write(f'{d[0]:.2f},{d[1]},{d[2]},"{d[3]}",{int(d[4])}\n')
    with open(os.path.join(out, "soak.dat"), "w") as f:
        for s in samples:
            nodes_mb = [float(v) for v in s[2].split(";") if v != "nan"]
            f.write(f"{s[0]:.1f} {s[1]:.2f} {sum(nodes_mb) / max(1, len(nodes_mb)):.2f} "
                    f"{s[3]:.2f} {s[4]}\n")
    with open(os.path.join(out, "live.dat"), "w") as f:
        for frame in sorted(live_at):
            f.write(f"{live_at[frame][0] - start:.2f} {live_at[frame][1]}\n")
    gp = f"""set terminal pngcairo size 1000,600 font 'sans,10'
set output '{os.path.join(out, "soak.png")}'
set multiplot layout 2,1 title 'tessera soak: {a.nodes} nodes, {a.duration:.0f} s, faults every {every[0]:g}-{every[1]:g} s (seed {a.seed})'
set xlabel 'time (s)'
set ylabel 'RSS (MB)'
set key outside right
plot '{os.path.join(out, "soak.dat")}' using 1:2 with linespoints title 'master', '' using 1:3 with linespoints title 'node (mean)'
set ylabel 'frames/s, live tiles'
set yrange [0:*]
plot '{os.path.join(out, "soak.dat")}' using 1:4 with linespoints title 'frames/s', '{os.path.join(out, "live.dat")}' using 1:2 with steps title 'live tiles (each frame)'
unset multiplot
"""
    try:
        subprocess.run(["gnuplot"], input=gp, text=True, capture_output=True)
    except OSError as e:  # no chart, the rest stands
        print(f"soak: no chart: gnuplot: {e}", file=sys.stderr)

    healthy = [d for d in drops if not d[4]]
    bad_returns = [r for r in returns if r[4] != 1 or r[5] > 2.0]
    bad_gaps = [g for g in gaps if not g[2]]
    # Memory growth means something over a long run only (a short one is its warm-up).
    judge_memory = a.duration >= a.warmup + 1200
    bad_growth = {k: v for k, v in growth.items() if not (v < 1.0)} if judge_memory else {}
    bad_pictures = [p for p in pictures if p[1] != 0]
    kinds = {k: sum(1 for e in events if e[1] == k) for k in
             ("kill", "stop", "continue", "site", "site_kill")}
    lines = [
        f"tessera soak: {a.nodes} nodes, {a.duration:.0f} s, faults every {every[0]:g}-"
        f"{every[1]:g} s, seed {a.seed}, node timeout {a.node_timeout:.0f} ms",
        f"faults: {kinds['kill']} kill -9 (restarted), {kinds['stop']} SIGSTOP/SIGCONT, "
        f"{kinds['site']} sites ({kinds['site_kill']} killed)",
        f"master exit: {master_code}",
        "",
        f"[{'ok' if not healthy else 'MISSED'}] healthy tiles dropped: {len(healthy)} "
        f"(of {len(drops)} drops)",
    ]
    for d in healthy:
        lines.append(f"    {d[0]:.1f} s: {d[1]} (pid {d[2]}): {d[3]}")
    worst = max((r[5] for r in returns), default=0.0)
    lines.append(f"[{'ok' if not bad_returns else 'MISSED'}] returns rejoined once within 2 s: "
                 f"{len(returns) - len(bad_returns)} of {len(returns)} (slowest "
                 f"{worst:.2f} s)")
    for r in bad_returns:
        lines.append(f"    {r[0]:.1f} s: {r[1]} {r[2]} (pid {r[3]}): {r[4]} joins, first after "
                     f"{r[5]:.2f} s")
        # What the node and the master said meanwhile, to tell where the time went.
        t0, t1 = start + r[0] - 6.0, start + r[0] + min(r[5], 60.0) + 1.0
        said = [(t, f"node: {line}") for p in Proc.started if p.pid == r[3] for t, line in p.lines]
        said += [(t, f"master: {line}") for t, line in master.lines if r[2] + " " in line]
        for t, line in sorted(x for x in said if t0 <= x[0] <= t1):
            lines.append(f"      {t - start:7.2f} s  {line[:200]}")
    lines.append(f"[{'--' if not judge_memory else 'ok' if not bad_growth else 'MISSED'}] RSS "
                 f"growth under 1%/hour after {a.warmup:.0f} s"
                 f"{'' if judge_memory else ' (not judged: too short a run)'}: " +
                 ", ".join(f"{k} {v:+.2f}%/h" for k, v in growth.items()) +
                 "; over the whole run " +
                 ", ".join(f"{k} {v:+.2f}%/h" for k, v in whole.items()))
    lines.append(f"[{'ok' if not bad_gaps else 'MISSED'}] frame gaps over the node timeout "
                 f"without a death: {len(bad_gaps)} ({len(gaps)} after a kill; the longest gap "
                 f"between frames {longest_gap:.2f} s)")
    for g in bad_gaps:
        lines.append(f"    {g[0]:.1f} s: {g[1]:.2f} s")
    lines.append(f"[{'ok' if not bad_pictures and pictures else 'MISSED'}] quiet-moment "
                 f"pictures exactly the mosaic: {len(pictures) - len(bad_pictures)} of "
                 f"{len(pictures)}")
    for p in bad_pictures:
        lines.append(f"    {p[0]}: " + ("tessera-render failed" if p[1] == -1 else
                                        "another size" if p[1] == -2 else f"{p[1]} pixels differ"))
    if samples:
        lines.append(f"memory: master {samples[0][1]:.1f} -> {samples[-1][1]:.1f} MB; mean frame "
                     f"rate {sum(s[3] for s in samples) / len(samples):.1f} fps")
    met = not (healthy or bad_returns or bad_gaps or bad_growth or bad_pictures) and pictures \
        and master_code == 0
    lines.append("all goals met" if met else "a goal was missed")
    text = "\n".join(lines) + "\n"
    with open(os.path.join(out, "summary.txt"), "w") as f:
        f.write(text)
    print(text, end="")
    return 0 if met else 1


def end_all():
    """Kills what the soak started and still runs (an interrupted or failed soak)."""
    for p in Proc.started:
        if p.running():
            p.signal(signal.SIGKILL)
            p.wait(5)


if __name__ == "__main__":
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(2))
    try:
        sys.exit(main())
    finally:
        end_all()
