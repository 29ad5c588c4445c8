#!/usr/bin/env python3
"""Schwärzler et al. 2012's numbers, reproduced: maps used and time of
adaptive-maps against multi-map with 289 maps (the 17 × 17 grid, their
ground truth), on spheres, bunny and sponza-plants, each from the scene's
camera ("far") and from halfway to its target ("close").

Error is the mean |ΔVcoef| over surface pixels against the 289-map result
(the paper's ground truth) and against the ray-traced reference at the
same 289 grid points (which also holds the maps' own depth and resolution
error). Times are the technique's pass (`--timings`), median of --repeat
runs.

PCSS 64/64 (the paper's Fig. 7 setting) is rendered next to both. For
every adaptive run the per-depth decisions (quads tested / split, failing
receivers) from `--explain` are printed below the table: the evidence of
where and why the quadtree went deep.

Usage: scripts/adaptive-table.py [--bin target/release/penumbra]
       [--size 512] [--map-size 512] [--repeat 1] [--scenes a,b,c]
       [--variants default,paper,half-pcf] [--no-times]
Prints a markdown table. `--scenes spheres-paper,bunny-paper,sponza-plants-paper`
are the scenes with the lights at the paper's regime
(docs/algorithms/adaptive-light-sampling.md). With `--no-times` the time
column is a placeholder (map counts and errors do not depend on load).
"""

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# (label: first word is the --variants key, extra options)
VARIANTS = [("default", "adaptive-maps", []),
            ("paper", "adaptive-maps, paper (no probe, no bias band)",
             ["--adaptive-centre-depth", "0", "--adaptive-band-high", "0"]),
            ("noband", "adaptive-maps, no bias band", ["--adaptive-band-high", "0"]),
            ("half-pcf", "adaptive-maps, ½ target + 3×3 PCF",
             ["--comparison-scale", "0.5", "--pcf", "3x3"])]
NOTES = []


def closer(toml_text, factor):
    """The scene with the camera's eye moved toward its target."""
    eye = re.search(r"^eye\s*=\s*\[([^\]]*)\]", toml_text, re.M)
    target = re.search(r"^target\s*=\s*\[([^\]]*)\]", toml_text, re.M)
    e = [float(x) for x in eye.group(1).split(",")]
    t = [float(x) for x in target.group(1).split(",")]
    n = [t[i] + factor * (e[i] - t[i]) for i in range(3)]
    line = "eye = [%s]" % ", ".join("%.6g" % x for x in n)
    return toml_text[: eye.start()] + line + toml_text[eye.end():]


def render(args, scene, technique, extra, exr):
    cmd = [args.bin, "render", scene, "--technique", technique, "--width", str(args.size),
           "--height", str(args.size), "--map-size", str(args.map_size), "--aov", "vcoef,mask",
           "-o", exr[:-4] + ".png", "--exr", exr, "--timings", "--explain"] + extra \
        + args.extra.split()
    times = []
    maps = None
    points = None
    for _ in range(args.repeat):
        p = subprocess.run(cmd, capture_output=True, text=True)
        if p.returncode != 0:
            sys.exit("render failed: %s\n%s" % (" ".join(cmd), p.stderr))
        t = 0.0
        # Counts are summed over the lights of one run, not over repeats.
        maps = None
        points = None
        for line in p.stderr.splitlines():
            m = re.match(r"\s*([0-9.]+) ms\s+(multi-map|adaptive maps|reference|pcss)\b", line)
            if m:
                t += float(m.group(1))
            m = re.search(r"shadow maps: (\d+) rendered", line)
            if m:
                maps = (maps or 0) + int(m.group(1))
                m2 = re.search(r"(\d+) sample points", line)
                points = int(m2.group(1)) if m2 else maps
                levels = re.findall(r"depth (\d+): (\d+) of (\d+) split, (\d+) failing", line)
                if levels:
                    LEVELS[exr] = levels
        times.append(t)
    return statistics.median(times), (maps, points)


LEVELS = {}


def error(args, a, b):
    p = subprocess.run([args.bin, "diff", a, b, "--channels-a", "vcoef.0", "--mask", b, "--json"],
                       capture_output=True, text=True)
    return json.loads(p.stdout)["overall"]["mean_abs"]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bin", default=os.path.join(ROOT, "target/release/penumbra"))
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--map-size", type=int, default=512)
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--scenes", default="spheres,bunny,sponza-plants")
    ap.add_argument("--variants", default="default,paper,half-pcf")
    ap.add_argument("--no-times", action="store_true")
    ap.add_argument("--extra", default="",
                    help="options for every render, e.g. '--normal-offset 2 --slope-bias 2'")
    args = ap.parse_args()
    args.variants = args.variants.split(",")
    tmp = tempfile.mkdtemp(prefix="adaptive-table-")
    print("| scene | camera | technique | maps rendered | sample points | time (ms) "
          "| error vs 289 maps | error vs reference |")
    print("|---|---|---|---|---|---|---|---|")
    # Every scene from far first, then every scene close.
    for camera, factor in [("far", 1.0), ("close", 0.5)]:
        for name in args.scenes.split(","):
            text = open(os.path.join(ROOT, "scenes", name + ".toml")).read()
            # Next to the original, so relative model paths still resolve.
            scene = os.path.join(ROOT, "scenes", ".adaptive-table-%s-%s.toml" % (name, camera))
            with open(scene, "w") as f:
                f.write(closer(text, factor))
            try:
                out = lambda t: os.path.join(tmp, "%s-%s-%s.exr" % (name, camera, t))
                grid = ["--samples", "289", "--pattern", "grid"]
                ref_t, _ = render(args, scene, "reference", grid, out("reference"))
                mm_t, mm_maps = render(args, scene, "multi-map", grid, out("multi"))
                rows = [("multi-map 289", mm_t, mm_maps, out("multi"))]
                for k, (key, label, extra) in enumerate(VARIANTS):
                    if key not in args.variants:
                        continue
                    t, maps = render(args, scene, "adaptive-maps", grid + extra, out("adaptive%d" % k))
                    rows.append((label, t, maps, out("adaptive%d" % k)))
                t, _ = render(args, scene, "pcss", ["--pcss-blocker-samples", "64",
                                                    "--pcss-filter-samples", "64"], out("pcss"))
                rows.append(("pcss 64/64 (one map)", t, (1, 1), out("pcss")))
                for label, t, maps, exr in rows:
                    print("| %s | %s | %s | %s | %s | %s | %.4f | %.4f |" % (
                        name, camera, label, maps[0], maps[1],
                        "(quiet run)" if args.no_times else "%.0f" % t,
                        error(args, exr, out("multi")), error(args, exr, out("reference"))))
                    if exr in LEVELS:
                        NOTES.append("%s, %s, %s: %s" % (name, camera, label, "; ".join(
                            "depth %s: %s of %s split, %s failing" % l for l in LEVELS[exr])))
                sys.stdout.flush()
            finally:
                os.remove(scene)


if __name__ == "__main__":
    main()
    if NOTES:
        print()
        print("Per-depth decisions (quads tested / split, failing receivers summed):")
        print()
        for n in NOTES:
            print("- " + n)
