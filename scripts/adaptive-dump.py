#!/usr/bin/env python3
"""Where adaptive-maps' banding test fails, and why.

Reads the dump `PENUMBRA_ADAPTIVE_DUMP=DIR penumbra render ... --technique
adaptive-maps` writes (per light: every decision point's hard-test bit per
receiver, the G-buffer, the quad log), rebuilds each tested quad's 0-4
counts and failing receivers (checked against the log), writes one PNG per
subdivision depth (the image in grey, failing receivers of any quad at that
depth in red, receivers the bias band left out of the test (their hard test
from one of the quad's corners flips between the band's biases: acne or
leak) in yellow, the object boundaries in blue) and prints, per depth, how
the failing receivers split by kind:

  discontinuity  a 1-ring neighbour is on another surface (depth jump or
                 normal turn), so its count is no evidence about banding
  grazing        the receiver's plane passes between the quad's corners
                 (some corners in front of it, some behind)
  other

Usage: scripts/adaptive-dump.py DIR [--light 0] [--out DIR]
"""

import argparse
import json
import os

import numpy as np
from PIL import Image


def load(d, k):
    meta = json.load(open(os.path.join(d, "light%d-meta.json" % k)))
    note = json.loads(meta["note"])
    w, h, words = meta["width"], meta["height"], meta["words"]
    bits = np.fromfile(os.path.join(d, "light%d-bits.bin" % k), dtype="<u8").reshape(h, w, words)
    g = np.fromfile(os.path.join(d, "light%d-gbuffer.bin" % k), dtype="<f4").reshape(h, w, 10)
    amb = np.fromfile(os.path.join(d, "light%d-ambiguous.bin" % k), dtype="<u8")
    amb = amb.reshape(h, w, words) if amb.size else None
    return meta, note, bits, g, amb


def bit(bits, di):
    return ((bits[:, :, di // 64] >> np.uint64(di % 64)) & np.uint64(1)).astype(np.int8)


def ring_differs(count, valid):
    """Per pixel: some valid 1-ring neighbour has a different count."""
    h, w = count.shape
    out = np.zeros((h, w), bool)
    pc = np.pad(count, 1, constant_values=-1)
    pv = np.pad(valid, 1, constant_values=False)
    for dj in (-1, 0, 1):
        for di in (-1, 0, 1):
            if di == 0 and dj == 0:
                continue
            nc = pc[1 + dj:1 + dj + h, 1 + di:1 + di + w]
            nv = pv[1 + dj:1 + dj + h, 1 + di:1 + di + w]
            out |= nv & (nc != count)
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("dir")
    ap.add_argument("--light", type=int, default=0)
    ap.add_argument("--out")
    a = ap.parse_args()
    out = a.out or a.dir
    meta, note, bits, g, amb = load(a.dir, a.light)
    if meta["target"] != [meta["width"], meta["height"]]:
        print("note: comparison target %s, image %dx%d; analysed at image resolution"
              % (meta["target"], meta["width"], meta["height"]))
    gd = meta["grid"]
    pts = np.array(meta["points"], dtype=np.float64).reshape(gd, gd, 3)
    dmax = note["max_depth"]
    flags = g[:, :, 9].astype(int)
    compared = (flags & 2) != 0
    pos = g[:, :, 0:3].astype(np.float64)
    nrm = g[:, :, 3:6].astype(np.float64)
    obj = g[:, :, 7].astype(int)
    h, w = compared.shape
    lum = np.where(compared, 0.0, 0.0)
    # object boundaries (blue)
    edge = np.zeros((h, w), bool)
    edge[:, 1:] |= obj[:, 1:] != obj[:, :-1]
    edge[1:, :] |= obj[1:, :] != obj[:-1, :]
    for depth in range(dmax):
        quads = [q for q in note["quads"] if q[0] == depth]
        if not quads:
            continue
        s = (gd - 1) >> depth  # decision-grid cells per quad side
        fail_any = np.zeros((h, w), int)
        left_out = np.zeros((h, w), bool)
        kinds = {"discontinuity": 0, "grazing": 0, "other": 0}
        where = {}
        tot = 0
        for d, qi, qj, pf, prf, split in quads:
            i0, j0 = qi * s, qj * s
            cs = [(i0, j0), (i0 + s, j0), (i0, j0 + s), (i0 + s, j0 + s)]
            dis = [i + j * gd for i, j in cs]
            count = 4 - sum(bit(bits, di) for di in dis).astype(int)
            tested = compared.copy()
            if amb is not None:
                for di in dis:
                    tested &= bit(amb, di) == 0
            left_out |= compared & ~tested
            # Ambiguous receivers cannot fail but stay neighbours.
            pen = tested & (count >= 1) & (count <= 3)
            fails = pen & ~ring_differs(count, compared)
            n = int(fails.sum())
            assert n == pf, ("quad", d, qi, qj, "log", pf, "rebuilt", n)
            tot += n
            fail_any += fails
            if n == 0:
                continue
            ys, xs = np.nonzero(fails)
            for y, x in zip(ys, xs):
                p, nn = pos[y, x], nrm[y, x]
                side = [np.dot(nn, pts[j, i] - p) > 0 for i, j in cs]
                # neighbours on another surface: other object, or > 3x the
                # median neighbour spacing away, or normal turned > 30 deg
                disc = False
                for dy in (-1, 0, 1):
                    for dx in (-1, 0, 1):
                        yy, xx = y + dy, x + dx
                        if (dx or dy) and 0 <= yy < h and 0 <= xx < w and compared[yy, xx]:
                            if obj[yy, xx] != obj[y, x] or np.dot(nrm[yy, xx], nn) < 0.866:
                                disc = True
                if any(side) and not all(side):
                    k = "grazing"
                elif disc:
                    k = "discontinuity"
                else:
                    k = "other"
                kinds[k] += 1
                where[int(obj[y, x])] = where.get(int(obj[y, x]), 0) + 1
        img = np.zeros((h, w, 3), np.uint8)
        shade = np.clip(np.abs(nrm[:, :, 1]) * 120 + 40, 0, 255)
        img[:, :, 0] = img[:, :, 1] = img[:, :, 2] = np.where(compared, shade, 0).astype(np.uint8)
        img[left_out] = (255, 255, 0)
        img[edge] = (0, 0, 255)
        img[fail_any > 0] = (255, 0, 0)
        path = os.path.join(out, "light%d-depth%d-fails.png" % (a.light, depth))
        Image.fromarray(img).save(path)
        print("depth %d: %d quads, %d failing (%s), by object %s -> %s" % (
            depth, len(quads), tot, ", ".join("%s %d" % kv for kv in kinds.items()),
            where, path))


if __name__ == "__main__":
    main()
