#!/usr/bin/env python3
"""Shadow-map depth-bias study: acne against peter-panning, measured
against the ray-traced reference on the shipped scenes.

    scripts/bias-study.py [--bin target/release/penumbra] [--size 256]
                          [--samples 256] [--map-size 1024] [--pcf 1]
                          [--scenes quad,spheres,...] [--out DIR]

For each scene it renders the reference once (Vcoef and mask, cached in
DIR), then `--technique shadow-map` for every bias setting of the grid, and
measures with `penumbra diff --json`:

- over every surface pixel (mask = the reference's `mask` channel): the
  Vcoef RMSE and mean absolute error;
- over the pixels the reference lights more than half (mask = its
  `vcoef.0` channel > 0.5): the error there is the map darkening lit
  receivers: **acne** (and the hard map's inner penumbra, the same for
  every bias);
- the rest, derived from the two (count-weighted): the error on the
  pixels the reference shadows more than half, the map lighting shadowed
  receivers: **peter-panning** (and the outer penumbra, again constant).

A bias too small raises the first, too large the second; the table prints
both per scene and their sum, and the grid's best setting by the sum over
scenes. Nothing is averaged in a way that hides a scene: every row is
printed.
"""
import argparse
import itertools
import json
import os
import subprocess
import sys

CONSTANT = [0.0, 1e-4, 1e-3]
SLOPE = [0.0, 0.5, 1.0, 2.0]
NORMAL = [0.0, 0.5, 1.0, 2.0]


def run(cmd):
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode not in (0, 1):
        sys.exit(f"failed: {' '.join(cmd)}\n{p.stderr}")
    return p.stdout


def diff(binary, a, ref, mask_channel):
    out = run([binary, "diff", a, ref, "--channels-a", "vcoef.0", "--channels-b",
               "vcoef.0", "--mask", ref, "--mask-channel", mask_channel, "--json"])
    m = json.loads(out)["overall"]
    return m["count"], m["mean_abs"], m["rmse"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bin", default="target/release/penumbra")
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--samples", type=int, default=256)
    ap.add_argument("--map-size", type=int, default=1024)
    ap.add_argument("--pcf", default="1")
    ap.add_argument("--scenes", default="quad,spheres,bunny,sponza-plants,dabrovic")
    ap.add_argument("--out", default="target/bias-study")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    size = ["--width", str(a.size), "--height", str(a.size)]
    scenes = a.scenes.split(",")
    results = {}  # (c, s, n) -> {scene: (lit, dark, rmse)}
    for scene in scenes:
        path = f"scenes/{scene}.toml"
        ref = f"{a.out}/ref-{scene}-{a.size}-{a.samples}.exr"
        if not os.path.exists(ref):
            run([a.bin, "render", path, *size, "--technique", "reference", "--samples",
                 str(a.samples), "-o", f"{a.out}/ref.png", "--exr", ref, "--aov", "vcoef,mask"])
        for c, s, n in itertools.product(CONSTANT, SLOPE, NORMAL):
            img = f"{a.out}/sm-{scene}.exr"
            run([a.bin, "render", path, *size, "--technique", "shadow-map", "--map-size",
                 str(a.map_size), "--pcf", a.pcf, "--depth-bias", str(c), "--slope-bias",
                 str(s), "--normal-offset", str(n), "-o", f"{a.out}/sm.png", "--exr", img,
                 "--aov", "vcoef"])
            n_all, mae_all, rmse = diff(a.bin, img, ref, "mask.Y")
            n_lit, mae_lit, _ = diff(a.bin, img, ref, "vcoef.0")
            n_dark = n_all - n_lit
            dark = (mae_all * n_all - mae_lit * n_lit) / n_dark if n_dark else 0.0
            # Errors per surface pixel, so the two sides add up to the MAE.
            lit = mae_lit * n_lit / n_all
            dark_share = dark * n_dark / n_all
            results.setdefault((c, s, n), {})[scene] = (lit, dark_share, rmse)
            print(f"{scene:14} c={c:<7g} s={s:<4g} n={n:<4g} acne {lit:.5f} "
                  f"peter-panning {dark_share:.5f} rmse {rmse:.4f}", file=sys.stderr)
    print(f"map {a.map_size}², pcf {a.pcf}, {a.size}², reference {a.samples} samples; "
          "per scene: acne-side / peter-panning-side MAE (per surface pixel)\n")
    print("| `--depth-bias` | `--slope-bias` | `--normal-offset` | "
          + " | ".join(scenes) + " | sum |")
    print("|--:|--:|--:|" + "--:|" * (len(scenes) + 1))
    ranked = sorted(results.items(), key=lambda kv: sum(l + d for l, d, _ in kv[1].values()))
    for (c, s, n), per in sorted(results.items()):
        cells = [f"{per[x][0]:.4f} / {per[x][1]:.4f}" for x in scenes]
        total = sum(l + d for l, d, _ in per.values())
        print(f"| {c:g} | {s:g} | {n:g} | " + " | ".join(cells) + f" | {total:.4f} |")
    (c, s, n), per = ranked[0]
    print(f"\nbest by the sum: --depth-bias {c:g} --slope-bias {s:g} --normal-offset {n:g}")
    print("five best: " + "; ".join(
        f"({c:g}, {s:g}, {n:g}) {sum(l + d for l, d, _ in p.values()):.4f}"
        for (c, s, n), p in ranked[:5]))


if __name__ == "__main__":
    main()
