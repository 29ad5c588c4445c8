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

Usage: scripts/adaptive-table.py [--bin target/release/penumbra]
       [--size 512] [--map-size 512] [--repeat 1] [--scenes a,b,c]
Prints a markdown table.
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
           "-o", exr[:-4] + ".png", "--exr", exr, "--timings", "--explain"] + extra
    times = []
    maps = None
    points = None
    for _ in range(args.repeat):
        p = subprocess.run(cmd, capture_output=True, text=True)
        if p.returncode != 0:
            sys.exit("render failed: %s\n%s" % (" ".join(cmd), p.stderr))
        t = 0.0
        for line in p.stderr.splitlines():
            m = re.match(r"\s*([0-9.]+) ms\s+(multi-map|adaptive maps|reference) light \d+", line)
            if m:
                t += float(m.group(1))
            m = re.search(r"shadow maps: (\d+) rendered", line)
            if m:
                maps = (maps or 0) + int(m.group(1))
                m = re.search(r"(\d+) sample points", line)
                points = int(m.group(1)) if m else maps
        times.append(t)
    return statistics.median(times), (maps, points)


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
    args = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix="adaptive-table-")
    print("| scene | camera | technique | maps rendered | sample points | time (ms) "
          "| error vs 289 maps | error vs reference |")
    print("|---|---|---|---|---|---|---|---|")
    for name in args.scenes.split(","):
        src = os.path.join(ROOT, "scenes", name + ".toml")
        text = open(src).read()
        for camera, factor in [("far", 1.0), ("close", 0.5)]:
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
                for k, (label, extra) in enumerate([("adaptive-maps", []),
                                     ("adaptive-maps, paper (no probe)",
                                      ["--adaptive-centre-depth", "0"]),
                                     ("adaptive-maps, ½ target + 3×3 PCF",
                                      ["--comparison-scale", "0.5", "--pcf", "3x3"])]):
                    t, maps = render(args, scene, "adaptive-maps", grid + extra, out("adaptive%d" % k))
                    rows.append((label, t, maps, out("adaptive%d" % k)))
                for label, t, maps, exr in rows:
                    print("| %s | %s | %s | %s | %s | %.0f | %.4f | %.4f |" % (
                        name, camera, label, maps[0], maps[1], t, error(args, exr, out("multi")),
                        error(args, exr, out("reference"))))
                sys.stdout.flush()
            finally:
                os.remove(scene)


if __name__ == "__main__":
    main()
