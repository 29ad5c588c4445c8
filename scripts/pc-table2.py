#!/usr/bin/env python3
"""Table 2 of Laine & Aila 2005 for penumbra casting.

Per scene (spheres, bunny, sponza-plants, flowers) the paper's five rows:
640×480, 1280×960 and 2560×1920 with 256 samples, 1280×960 with 1024
samples, and 1280×960 with 256 samples and a 4× light (u and v of the
scene's light doubled: four times the area). Per row it prints
penumbra-casting's sort, build and cast times (its `--timings` line),
the peak hierarchy and bit-mask memory (its `--explain` notes), its
shadow time, and the shadow times and ratios (other ÷ penumbra casting,
above 1: penumbra casting is faster) of native Embree
(scripts/embree-peer.py's peer, stream mode, same receivers, same sample
count and thread count), our reference and exact DCS, measured in the
same run, interleaved, medians over `--rounds`.

Full table (the lead, on a quiet machine):

    scripts/embree-peer.py --setup /tmp/peers
    scripts/pc-table2.py --peer /tmp/peers/embree-rays --rounds 3 --out /tmp/pc-table2.json

Quick check (spheres and bunny, 640×480 and 256 samples, one round;
Embree only when --peer is given):

    scripts/pc-table2.py --quick [--peer /tmp/peers/embree-rays]
"""

import argparse
import importlib.util
import json
import os
import re
import shlex
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENES = ["spheres", "bunny", "sponza-plants", "flowers"]
# (label, width, height, samples, light scale)
ROWS = [
    ("640×480", 640, 480, 256, 1),
    ("1280×960", 1280, 960, 256, 1),
    ("2560×1920", 2560, 1920, 256, 1),
    ("1K smp", 1280, 960, 1024, 1),
    ("4× light", 1280, 960, 256, 2),
]
PC_LINE = re.compile(r"sort ([0-9.]+) s, (?:probe [0-9.]+ s, )?build ([0-9.]+) s, cast ([0-9.]+) s")
NOTE = re.compile(r"^\s*([0-9.]+) (B|KiB|MiB|GiB)\s+(receiver hierarchy|bit masks) light 0")
UNIT = {"B": 1 / 2**20, "KiB": 1 / 1024, "MiB": 1.0, "GiB": 1024.0}


def peer_module():
    spec = importlib.util.spec_from_file_location("embree_peer", os.path.join(ROOT, "scripts", "embree-peer.py"))
    m = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(m)
    return m


def scaled_light_scene(scene, factor, work):
    """A copy of `scene` beside it (relative model paths) whose [[light]]
    u and v are multiplied by `factor`."""
    if factor == 1:
        return scene
    out, in_light = [], False
    for line in open(scene):
        s = line.strip()
        if s.startswith("["):
            in_light = s in ("[[light]]", "[[lights]]")
        m = re.match(r"^(\s*)(u|v)\s*=\s*\[([^\]]*)\](.*)$", line)
        if in_light and m:
            vals = [float(x) * factor for x in m.group(3).split(",")]
            line = f"{m.group(1)}{m.group(2)} = [{', '.join(repr(v) for v in vals)}]{m.group(4)}\n"
        out.append(line)
    path = os.path.join(os.path.dirname(scene), f".pc-table2-{factor}x-{os.path.basename(scene)}")
    with open(path, "w") as f:
        f.writelines(out)
    work.append(path)
    return path


def run_pc(exe, scene, w, h, n, threads, tmp, extra):
    cmd = [exe, "render", scene, "--technique", "penumbra-casting", *extra, "--width", str(w),
           "--height", str(h), "--samples", str(n), "--threads", str(threads), "--timings",
           "--explain", "-o", os.path.join(tmp, "pc.png")]
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"penumbra failed: {shlex.join(cmd)}\n{p.stderr}")
    text = p.stdout + "\n" + p.stderr
    m = PC_LINE.search(text)
    if not m:
        sys.exit(f"no penumbra-casting timing line in:\n{text}")
    sort, build, cast = (float(x) for x in m.groups())
    mem = {}
    for line in text.splitlines():
        q = NOTE.match(line)
        if q:
            mem[q.group(3)] = float(q.group(1)) * UNIT[q.group(2)]
    shadow = sum(v for k, v in timings(text).items() if k.split(" ")[0] not in ("load", "geometry", "gbuffer", "shading"))
    return {"sort": sort, "build": build, "cast": cast, "shadow": shadow,
            "hier_mib": mem.get("receiver hierarchy", float("nan")),
            "mask_mib": mem.get("bit masks", float("nan"))}


def timings(text):
    out = {}
    for line in text.splitlines():
        m = re.match(r"^\s*([0-9.]+) ms\s+(.*)$", line)
        if m:
            out[m.group(2)] = float(m.group(1)) / 1000.0
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--peer", help="a built embree-rays (scripts/embree-peer.py --setup DIR)")
    ap.add_argument("--penumbra", help="penumbra binary (default: cargo build --release)")
    ap.add_argument("--scenes", nargs="+", default=SCENES)
    ap.add_argument("--rows", nargs="+", default=[r[0] for r in ROWS], help="row labels to run")
    ap.add_argument("--compare", nargs="*", default=["reference", "dcs"],
                    help="our techniques to time beside it (empty: none)")
    ap.add_argument("--pc-options", default="", help="extra penumbra-casting options, quoted")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--quick", action="store_true",
                    help="spheres and bunny, 640×480 at 256 samples, one round")
    ap.add_argument("--out", help="write every measurement as JSON here")
    args = ap.parse_args()
    if args.quick:
        args.scenes, args.rows, args.rounds = ["spheres", "bunny"], ["640×480"], 1
    peer = peer_module()
    exe = args.penumbra or peer.penumbra_bin(argparse.Namespace(penumbra=None))
    extra = shlex.split(args.pc_options)
    print(f"# load before: {open('/proc/loadavg').read().split()[:3]}; "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; {os.cpu_count()} cores")
    print(f"# {shlex.join(sys.argv)}")
    rows, records, made = [], [], []
    try:
        with tempfile.TemporaryDirectory(prefix="pc-table2-") as tmp:
            for name in args.scenes:
                base = name if name.endswith(".toml") else os.path.join(ROOT, "scenes", f"{name}.toml")
                for label, w, h, n, factor in ROWS:
                    if label not in args.rows:
                        continue
                    scene = scaled_light_scene(base, factor, made)
                    binary = None
                    if args.peer:
                        g = os.path.join(tmp, "g.exr")
                        subprocess.run([exe, "render", scene, "--technique", "none", "--width", str(w),
                                        "--height", str(h), "--exr", g, "--aov", "position,normal,mask",
                                        "-o", os.path.join(tmp, "g.png")], check=True, capture_output=True)
                        binary = os.path.join(tmp, "in.bin")
                        subprocess.run([sys.executable, os.path.join(args.peer, "prep.py"), scene, g, binary,
                                        "--light", "0"], check=True, capture_output=True)
                    runs = {"pc": [], "embree": []}
                    for t in args.compare:
                        runs[t] = []
                    for r in range(args.rounds):
                        if binary:
                            e, j = peer.run_embree(args.peer, binary, n, args.threads)
                            runs["embree"].append(e)
                            records.append({"scene": name, "row": label, "round": r, "run": "embree", "s": e, "detail": j})
                        pc = run_pc(exe, scene, w, h, n, args.threads, tmp, extra)
                        runs["pc"].append(pc)
                        records.append({"scene": name, "row": label, "round": r, "run": "penumbra-casting", **pc})
                        for t in args.compare:
                            s, passes = peer.run_penumbra(exe, scene, t, w, h, n, args.threads, tmp)
                            runs[t].append(s)
                            records.append({"scene": name, "row": label, "round": r, "run": t, "s": s, "detail": passes})
                    med = lambda key: statistics.median(p[key] for p in runs["pc"])
                    row = {k: med(k) for k in ("sort", "build", "cast", "shadow", "hier_mib", "mask_mib")}
                    for t in ["embree", *args.compare]:
                        row[t] = statistics.median(runs[t]) if runs[t] else None
                    rows.append((name, label, row))
                    print(f"# {name} {label}: {json.dumps(row)}", flush=True)
    finally:
        for p in made:
            os.remove(p)
    print(f"# load after: {open('/proc/loadavg').read().split()[:3]}")
    print()
    others = ["embree", *args.compare]
    head = "| scene | row | sort (s) | build (s) | cast (s) | PC shadow (s) | hierarchy (MiB) | masks (MiB) | " + \
        " | ".join(f"{t} (s) | {t} ÷ PC" for t in others) + " |"
    print(head)
    print("|" + "---|" * 2 + "--:|" * (6 + 2 * len(others)))
    for name, label, r in rows:
        cells = [name, label] + [f"{r[k]:.3f}" for k in ("sort", "build", "cast", "shadow")] + \
            [f"{r['hier_mib']:.1f}", f"{r['mask_mib']:.1f}"]
        for t in others:
            v = r[t]
            cells += ["–", "–"] if v is None else [f"{v:.3f}", f"**{v / r['shadow']:.2f}×**"]
        print("| " + " | ".join(cells) + " |")
    if args.out:
        with open(args.out, "w") as f:
            json.dump({"argv": sys.argv, "records": records}, f, indent=1)


if __name__ == "__main__":
    main()
