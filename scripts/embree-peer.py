#!/usr/bin/env python3
"""Side by side: native Embree 3 shadow rays against penumbra's techniques.

Runs the embree-rays peer (../shared/peers/embree-rays: stream mode, the
fastest way it has) and `penumbra render` on the same receivers (the peer
reads penumbra's own G-buffer) with the same sample count and thread
count, in interleaved rounds, and prints the medians and the ratios
"Embree time / technique time" (above 1: penumbra is faster).

What is timed, on both sides, is the shadow work alone:
- Embree: `build_s + trace_s` from its JSON line (BVH build and tracing).
- penumbra: the sum of its `--timings` lines except `load`, `geometry`, `gbuffer`
  and `shading` (scene loading, the camera pass and shading are not shadow
  work and the peer has none of them); so every technique's own build
  (BVH, wedges, hierarchies, maps) is counted.

The peer needs a built copy beside a copy of the oracle (its prep.py
imports the oracle's scene loader):

    scripts/embree-peer.py --setup /tmp/peers      # copies, make, pip deps
    scripts/embree-peer.py --peer /tmp/peers/embree-rays \\
        --scenes scenes/spheres.toml scenes/bunny.toml --size 1024 \\
        --samples 64 256 --techniques dcs 'dcs --silhouettes centre' reference \\
        --rounds 3 --out /tmp/embree-peer.json

Only light 0 of a scene is traced by the peer; scenes with more lights are
refused.
"""

import argparse
import json
import os
import platform
import re
import shlex
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
NOT_SHADOW = {"load", "geometry", "gbuffer", "shading"}
TIMING = re.compile(r"^\s*([0-9.]+) ms\s+(.*)$")


def setup(dest):
    shared = os.path.join(os.path.dirname(ROOT), "shared", "peers")
    os.makedirs(dest, exist_ok=True)
    for name in ("embree-rays", "oracle"):
        target = os.path.join(dest, name)
        if not os.path.exists(target):
            shutil.copytree(os.path.join(shared, name), target)
    if shutil.which("apt-get") and not os.path.exists("/usr/include/embree3"):
        subprocess.run(["apt-get", "install", "-y", "libembree-dev"], check=True)
    subprocess.run(["make", "-s", "-C", os.path.join(dest, "embree-rays")], check=True)
    subprocess.run(["bash", os.path.join(dest, "oracle", "setup.sh")], check=True)
    print(f"peer ready: --peer {os.path.join(dest, 'embree-rays')}")


def penumbra_bin(args):
    if args.penumbra:
        if not os.access(args.penumbra, os.X_OK):
            sys.exit(f"--penumbra {args.penumbra}: no such executable (build it with `cargo build --release`)")
        return args.penumbra
    subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=ROOT, check=True)
    return os.path.join(ROOT, "target", "release", "penumbra")


def machine():
    """The CPU model (and whether it has AVX-512) and the core count."""
    with open("/proc/cpuinfo") as f:
        info = f.read()
    cpu = next((l.split(":", 1)[1].strip() for l in info.splitlines() if l.startswith("model name")),
               platform.processor())
    return {"cpu": cpu, "avx512": "avx512f" in info, "cores": os.cpu_count()}


def light_count(scene):
    try:
        with open(scene) as f:
            return len(re.findall(r"^\s*\[\[lights?\]\]", f.read(), re.M))
    except OSError as e:
        sys.exit(f"{scene}: {e.strerror}")


def prepare_peer_input(exe, peer, scene, w, h, work, info=None):
    """penumbra's G-buffer of SCENE at w×h, turned into the peer's input
    (the same receivers); returns its path. Not timed. Raises RuntimeError
    with the failing command's stderr."""
    g = os.path.join(work, "g.exr")
    binary = os.path.join(work, "in.bin")
    for cmd in ([exe, "render", scene, "--technique", "none", "--width", str(w), "--height", str(h),
                 "--exr", g, "--aov", "position,normal,mask", "-o", os.path.join(work, "g.png")],
                [sys.executable, os.path.join(peer, "prep.py"), scene, g, binary, "--light", "0",
                 *(["--info", info] if info else [])]):
        p = subprocess.run(cmd, capture_output=True, text=True)
        if p.returncode != 0:
            raise RuntimeError(f"failed ({p.returncode}): {shlex.join(cmd)}\n{p.stderr.strip()}")
    return binary


def penumbra_command(exe, scene, technique, w, h, samples, threads, work):
    return [exe, "render", scene, "--technique", *shlex.split(technique),
            "--width", str(w), "--height", str(h), "--samples", str(samples),
            "--threads", str(threads), "--timings", "-o", os.path.join(work, "t.png")]


def penumbra_times(output):
    """The shadow-work time (s) and every pass's time from `--timings` output."""
    passes = {}
    for line in output.splitlines():
        m = TIMING.match(line)
        if m:
            passes[m.group(2)] = float(m.group(1)) / 1000.0
    shadow = sum(v for k, v in passes.items() if k.split(" ")[0] not in NOT_SHADOW)
    return shadow, passes


def run_penumbra(exe, scene, technique, w, h, samples, threads, work):
    cmd = penumbra_command(exe, scene, technique, w, h, samples, threads, work)
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"penumbra failed: {shlex.join(cmd)}\n{p.stderr}")
    return penumbra_times(p.stdout + p.stderr)


def embree_command(peer, binary, samples, threads):
    return [os.path.join(peer, "embree_rays"), binary, "--samples", str(samples),
            "--threads", str(threads), "--mode", "stream"]


def embree_times(stdout):
    """The shadow-work time (s: BVH build + trace) and the peer's JSON line."""
    j = json.loads(stdout.strip().splitlines()[-1])
    return j["build_s"] + j["trace_s"], j


def run_embree(peer, binary, samples, threads):
    cmd = embree_command(peer, binary, samples, threads)
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"embree_rays failed: {shlex.join(cmd)}\n{p.stderr}")
    return embree_times(p.stdout)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--setup", metavar="DIR", help="copy and build the peer into DIR, then exit")
    ap.add_argument("--peer", help="a built copy of embree-rays (beside a copy of the oracle)")
    ap.add_argument("--penumbra", help="penumbra binary (default: cargo build --release)")
    ap.add_argument("--scenes", nargs="+", default=["scenes/spheres.toml", "scenes/bunny.toml"])
    ap.add_argument("--size", nargs="+", default=["1024"], help="W or WxH, one or more")
    ap.add_argument("--samples", nargs="+", type=int, default=[64, 256])
    ap.add_argument("--techniques", nargs="+", default=["dcs", "reference"],
                    help="each a technique name with its options, quoted")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--out", help="write every measurement as JSON here")
    args = ap.parse_args()
    if args.setup:
        setup(args.setup)
        return
    if not args.peer or not os.access(os.path.join(args.peer, "embree_rays"), os.X_OK):
        sys.exit("--peer DIR must hold a built embree_rays (see --setup)")
    exe = penumbra_bin(args)
    m = machine()
    cpu = m["cpu"]
    print(f"# {cpu}{' (AVX-512)' if m['avx512'] else ''}, {m['cores']} cores; "
          f"load before: {open('/proc/loadavg').read().split()[:3]}; {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")
    print(f"# {shlex.join(sys.argv)}")
    records = []
    rows = []
    with tempfile.TemporaryDirectory(prefix="embree-peer-") as work:
        for scene in args.scenes:
            if light_count(scene) != 1:
                sys.exit(f"{scene}: the peer traces one light; this scene has {light_count(scene)}")
            for size in args.size:
                w, h = (int(x) for x in (size.split("x") if "x" in size else (size, size)))
                try:
                    binary = prepare_peer_input(exe, args.peer, scene, w, h, work)
                except RuntimeError as e:
                    sys.exit(f"the peer's input: {e}")
                for n in args.samples:
                    times = {"embree": []}
                    for t in args.techniques:
                        times[t] = []
                    for r in range(args.rounds):
                        e, j = run_embree(args.peer, binary, n, args.threads)
                        times["embree"].append(e)
                        records.append({"scene": scene, "w": w, "h": h, "samples": n, "round": r,
                                        "run": "embree", "s": e, "detail": j})
                        for t in args.techniques:
                            s, passes = run_penumbra(exe, scene, t, w, h, n, args.threads, work)
                            times[t].append(s)
                            records.append({"scene": scene, "w": w, "h": h, "samples": n, "round": r,
                                            "run": t, "s": s, "detail": passes})
                    emb = statistics.median(times["embree"])
                    for t, v in times.items():
                        med = statistics.median(v)
                        rows.append((os.path.basename(scene), f"{w}×{h}", n, t, med, min(v), max(v),
                                     emb / med if med > 0 else float("inf")))
    print(f"# load after: {open('/proc/loadavg').read().split()[:3]}")
    print()
    print("| scene | size | samples | run | median (s) | range (s) | Embree ÷ run |")
    print("|---|---|--:|---|--:|--:|--:|")
    for scene, size, n, t, med, lo, hi, ratio in rows:
        print(f"| {scene} | {size} | {n} | {t} | {med:.3f} | {lo:.3f}–{hi:.3f} | **{ratio:.2f}×** |")
    if args.out:
        with open(args.out, "w") as f:
            json.dump({"cpu": cpu, "argv": sys.argv, "records": records}, f, indent=1)


if __name__ == "__main__":
    main()
