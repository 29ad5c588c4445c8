#!/usr/bin/env python3
"""Triangle-count scaling: penumbra's exact techniques against native Embree 3.

Two scene series derived from scenes/spheres.toml (same camera, light and
ground), written to a temp dir:
- tessellation: the 81 spheres with `segments` = `rings` = 20, 40, 80, 160
  (61,562; 252,722; 1,023,842; 4,121,282 triangles);
- many spheres: N × N spheres of 40 × 40 (3,120 triangles each), N = 9, 18,
  36 (81, 324, 1,296 spheres; 252,722; 1,010,882; 4,043,522 triangles): the
  9 × 9 grid's square is cut into N × N cells, and each sphere is scaled
  with its cell (radius 0.35 × 9 / N, same height), so the spheres cover the
  same area under the same light. N = 9 is the tessellation series' 40 scene
  (measured once, drawn in both).
A sphere is 2 · segments · (rings − 1) triangles, the ground quad 2; each
count is checked against `penumbra info` and the peer's own scene loader.
- models: the shipped Stanford bunny scan (scenes/bunny.toml, 69,451
  triangles) refined by Loop subdivision `--bunny-levels` times (1, 2:
  277,804 and 1,111,216 triangles; 3 gives 4,444,864): a real scanned
  surface at a million triangles, its silhouette that of the scan. (No
  million-triangle scan can ship: the model store keeps no file over about
  4 MiB, and such a scan is 20 MB or more; see docs/performance.md.)
`--extra-scenes` adds single-light scenes of your own (a large model).

For each scene × size × sample count, in interleaved rounds, it runs every
technique (`penumbra render --timings`) and the embree-rays peer (stream
mode) on penumbra's own G-buffer, each as its own process, and records the
shadow-work time (scripts/embree-peer.py's definition: penumbra's passes
except load, geometry, G-buffer and shading; Embree's BVH build + trace), every
pass's time, the wall time, the CPU time and the peak resident memory of
the process (wait4). A run longer than --timeout is killed and recorded as
"timed out" (and that technique is then skipped at more triangles, more
samples or more pixels); one whose resident memory passes --mem-limit is
killed and recorded as "memory limit".

    python3 -m venv /tmp/peers/.venv && /tmp/peers/.venv/bin/pip install matplotlib
    PYTHON=/tmp/peers/.venv/bin/python scripts/embree-peer.py --setup /tmp/peers
    /tmp/peers/.venv/bin/python scripts/scaling.py --peer /tmp/peers/embree-rays \\
        --penumbra target/release/penumbra --out docs/results-scaling/

Writes OUT/results.json (machine, commit, scenes, every run), results.csv
(one row per run), table.md (medians) and scaling.png (log-log: shadow
work against triangles, one panel per size and sample count);
`--plot-only OUT` redraws the table and plot from OUT/results.json.
`--quick`: the 2 smallest scenes of each series at 512², 64 samples, one
round, with --check (for validation; not for docs).
`--check`: once per scene and size, untimed, compares the Vcoef of
penumbra's reference with Embree's on the same receivers.

Python: the peer's prep.py runs with this script's interpreter, which
therefore needs numpy, OpenEXR and embreex (what `--setup` installs into
$PYTHON), and matplotlib for the plot (a venv, as above).
"""

import argparse
import csv
import importlib.util
import json
import math
import os
import re
import shlex
import signal
import statistics
import subprocess
import sys
import tempfile
import time
import tomllib

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
BASE_SCENE = os.path.join(ROOT, "scenes", "spheres.toml")
BUNNY_SCENE = os.path.join(ROOT, "scenes", "bunny.toml")

_spec = importlib.util.spec_from_file_location("embree_peer", os.path.join(HERE, "embree-peer.py"))
peer_lib = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(peer_lib)

TECHNIQUES = ["dcs", "dcs --dcs-rays never", "penumbra-casting", "reference"]
EMBREE = "embree"
COLOURS = {"dcs": "tab:blue", "dcs --dcs-rays never": "tab:purple", "penumbra-casting": "tab:green", "reference": "tab:orange", EMBREE: "black"}
SERIES_STYLE = {"tessellation": "-", "many spheres": "--", "models": ":"}


# ---------------------------------------------------------------- scenes

def sphere_triangles(segments, rings):
    return 2 * segments * (rings - 1)


def base_parts():
    """spheres.toml as (header text, ground quad block text, sphere grid)."""
    with open(BASE_SCENE) as f:
        text = f.read()
    blocks = re.split(r"(?m)^(?=\[\[object\]\])", text)
    header, objects = blocks[0], blocks[1:]
    # Comment lines right before an [[object]] belong to that object.
    header = re.sub(r"(?m)(^#[^\n]*\n)+\s*\Z", "", header).rstrip() + "\n"
    data = tomllib.loads(text)
    spheres = [o for o in data["object"] if o.get("shape") == "sphere"]
    quads = [o for o in data["object"] if o.get("shape") == "quad"]
    if not spheres or len(quads) != 1 or len(spheres) + 1 != len(data["object"]) \
            or len(data.get("light", [])) != 1:
        sys.exit(f"{BASE_SCENE}: expected a grid of spheres, one ground quad and one light")
    ground = re.sub(r"(?m)^#[^\n]*\n", "", objects[-1]).strip() + "\n"
    if 'shape = "quad"' not in ground:
        sys.exit(f"{BASE_SCENE}: the last [[object]] is not the ground quad")
    n = math.isqrt(len(spheres))
    xs = sorted({o["translate"][0] for o in spheres})
    zs = sorted({o["translate"][2] for o in spheres})
    ys = {o["translate"][1] for o in spheres}
    radii = {o["radius"] for o in spheres}
    if n * n != len(spheres) or len(xs) != n or len(zs) != n or len(ys) != 1 or len(radii) != 1:
        sys.exit(f"{BASE_SCENE}: the spheres are not a square grid of equal spheres")
    grid = {"n": n, "spacing": (xs[-1] - xs[0]) / (n - 1), "cx": (xs[0] + xs[-1]) / 2,
            "cz": (zs[0] + zs[-1]) / 2, "y": ys.pop(), "radius": radii.pop()}
    return text, header, ground, grid


def grid_scene(header, ground, grid, n, segments, rings, name):
    """N × N spheres over the base grid's square, each scaled with its cell."""
    k = grid["n"] / n
    spacing, radius = grid["spacing"] * k, grid["radius"] * k
    header = re.sub(r"\A(#[^\n]*\n)+\s*", "", header)  # the base file's own description
    lines = [f"# Generated by scripts/scaling.py from scenes/spheres.toml: {n} x {n} spheres,",
             f"# radius {radius:.6g}, {segments} segments x {rings} rings.", "",
             re.sub(r'(?m)^name = .*$', f'name = "{name}"', header, count=1)]
    for i in range(n):
        for j in range(n):
            x = grid["cx"] + (i - (n - 1) / 2) * spacing
            z = grid["cz"] + (j - (n - 1) / 2) * spacing
            lines += ["[[object]]", 'shape = "sphere"', f"radius = {radius!r}", f"segments = {segments}",
                      f"rings = {rings}", f"translate = [{x!r}, {grid['y']!r}, {z!r}]", ""]
    lines.append(ground)
    return "\n".join(lines)


def tessellated_scene(text, segments, rings, name):
    """spheres.toml with every sphere's segments and rings set."""
    out, ns = re.subn(r"(?m)^segments = \d+$", f"segments = {segments}", text)
    out, nr = re.subn(r"(?m)^rings = \d+$", f"rings = {rings}", out)
    out = re.sub(r'(?m)^name = .*$', f'name = "{name}"', out, count=1)
    return f"# Generated by scripts/scaling.py: {segments} segments x {rings} rings.\n" + out, ns, nr


def read_obj(path):
    """Positions (n × 3 float64) and triangles (m × 3 int64, 0-based) of an
    OBJ of triangles (the first index of each `f` corner; no negative
    indices, as in the shipped bunny)."""
    import numpy as np
    vs, fs = [], []
    with open(path) as f:
        for line in f:
            if line.startswith("v "):
                vs.append([float(x) for x in line.split()[1:4]])
            elif line.startswith("f "):
                corners = [int(c.split("/")[0]) - 1 for c in line.split()[1:]]
                if len(corners) != 3 or min(corners) < 0:
                    sys.exit(f"{path}: expected triangles with positive indices: {line.strip()}")
                fs.append(corners)
    return np.array(vs, dtype=np.float64), np.array(fs, dtype=np.int64)


def loop_subdivide(v, f):
    """One step of Loop subdivision (Loop 1987): every triangle into four,
    an edge point 3/8 (a + b) + 1/8 (c + d) on an edge of two faces (the
    midpoint on any other edge), and a vertex moved to (1 − kβ) v + β Σ
    neighbours, β = 3 / (8k) (3/16 for k = 3), unless it lies on an edge
    that is not shared by exactly two faces (a hole's rim: kept in place).
    Orientation is kept: each corner triangle runs as its parent."""
    import numpy as np
    n, m = len(v), len(f)
    half = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    opposite = np.concatenate([f[:, 2], f[:, 0], f[:, 1]])
    lo, hi = half.min(axis=1), half.max(axis=1)
    keys, edge_of, uses = np.unique(lo * n + hi, return_inverse=True, return_counts=True)
    ea, eb = keys // n, keys % n
    ne = len(keys)
    opp_sum = np.stack([np.bincount(edge_of, weights=v[opposite, k], minlength=ne) for k in range(3)], axis=1)
    interior = uses == 2
    edge_points = np.where(interior[:, None], 3 / 8 * (v[ea] + v[eb]) + 1 / 8 * opp_sum,
                           0.5 * (v[ea] + v[eb]))
    ends = np.concatenate([ea, eb])
    others = np.concatenate([eb, ea])
    valence = np.bincount(ends, minlength=n)
    ring = np.stack([np.bincount(ends, weights=v[others, k], minlength=n) for k in range(3)], axis=1)
    rim = np.zeros(n, dtype=bool)
    rim[ea[~interior]] = True
    rim[eb[~interior]] = True
    k = np.maximum(valence, 1).astype(np.float64)
    beta = np.where(valence == 3, 3 / 16, 3 / (8 * k))
    moved = (1 - k * beta)[:, None] * v + beta[:, None] * ring
    keep = rim | (valence == 0)
    new_v = np.concatenate([np.where(keep[:, None], v, moved), edge_points])
    e01, e12, e20 = (n + edge_of[i * m:(i + 1) * m] for i in range(3))
    new_f = np.concatenate([np.stack([f[:, 0], e01, e20], axis=1), np.stack([f[:, 1], e12, e01], axis=1),
                            np.stack([f[:, 2], e20, e12], axis=1), np.stack([e01, e12, e20], axis=1)])
    return new_v, new_f


def bunny_scenes(levels, work):
    """scenes/bunny.toml with its scan Loop-subdivided `level` times, for each
    level: (id, path, triangles). Made in a child process: a child's peak
    RSS (wait4's ru_maxrss) starts from its parent's RSS at the fork, so
    the subdivision's arrays, held here, would set a floor under every
    run's measured peak."""
    if not levels:
        return []
    p = subprocess.run([sys.executable, os.path.abspath(__file__), "--write-bunny-scenes", work,
                        *map(str, sorted(set(levels)))], capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"the models series: {p.stderr.strip() or p.stdout.strip()}")
    return [tuple(x) for x in json.loads(p.stdout)]


def write_bunny_scenes(levels, work):
    """`bunny_scenes`' work, in the process that runs it."""
    with open(BUNNY_SCENE) as f:
        text = f.read()
    objs = re.findall(r'(?m)^obj = "([^"]+)"$', text)
    if len(objs) != 1:
        sys.exit(f"{BUNNY_SCENE}: expected one `obj = ...` line, found {len(objs)}")
    v, f = read_obj(os.path.join(os.path.dirname(BUNNY_SCENE), objs[0]))
    out = []
    for level in range(1, max(levels, default=0) + 1):
        v, f = loop_subdivide(v, f)
        if level not in levels:
            continue
        sid = f"bunny-loop{level}"
        obj = os.path.join(work, sid + ".obj")
        with open(obj, "w") as o:
            o.write(f"# scenes/models/stanford-bunny (Stanford 3D Scanning Repository), Loop-subdivided "
                    f"{level} times by scripts/scaling.py\n")
            o.write("".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in v.tolist()))
            o.write("".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in f.tolist()))
        scene = re.sub(r'(?m)^obj = "[^"]+"$', f'obj = "{os.path.basename(obj)}"', text)
        scene = re.sub(r'(?m)^name = .*$', f'name = "{sid}"', scene, count=1)
        path = os.path.join(work, sid + ".toml")
        with open(path, "w") as o:
            o.write(f"# Generated by scripts/scaling.py: scenes/bunny.toml, its scan Loop-subdivided "
                    f"{level} times.\n" + scene)
        out.append((sid, path, len(f) + 2))
    return out


def make_scenes(args, work):
    """The scene list: dicts with id, path, series, spheres, segments, rings, triangles."""
    text, header, ground, grid = base_parts()
    n0 = grid["n"] ** 2
    scenes = {}

    def add(key, series, make, spheres, segments, rings):
        if key in scenes:
            scenes[key]["series"].append(series)
            return
        sid = f"spheres{spheres}-s{segments}"
        path = os.path.join(work, sid + ".toml")
        with open(path, "w") as f:
            f.write(make(sid))
        scenes[key] = {"id": sid, "path": path, "series": [series], "spheres": spheres,
                       "segments": segments, "rings": rings,
                       "triangles": spheres * sphere_triangles(segments, rings) + 2}

    for s in args.segments:
        def make(sid, s=s):
            out, ns, nr = tessellated_scene(text, s, s, sid)
            if ns != n0 or nr != n0:
                sys.exit(f"{BASE_SCENE}: {ns} `segments` and {nr} `rings` lines for {n0} spheres")
            return out
        add((n0, s, s), "tessellation", make, n0, s, s)
    g = args.grid_segments
    for n in args.grids:
        add((n * n, g, g), "many spheres",
            lambda sid, n=n: grid_scene(header, ground, grid, n, g, g, sid), n * n, g, g)
    out = sorted(scenes.values(), key=lambda s: s["triangles"])
    for sid, path, triangles in bunny_scenes(args.bunny_levels, work):
        out.append({"id": sid, "path": path, "series": ["models"], "spheres": None, "segments": None,
                    "rings": None, "triangles": triangles})
    for path in args.extra_scenes:
        if peer_lib.light_count(path) != 1:
            sys.exit(f"{path}: the peer traces one light; this scene has {peer_lib.light_count(path)}")
        out.append({"id": os.path.splitext(os.path.basename(path))[0], "path": os.path.abspath(path),
                    "series": ["models"], "spheres": None, "segments": None, "rings": None,
                    "triangles": None})
    return out


def penumbra_info(exe, path):
    p = subprocess.run([exe, "info", path], capture_output=True, text=True)
    m = re.search(r"(?m)^triangles\s+(\d+)", p.stdout)
    if p.returncode != 0 or not m:
        raise RuntimeError(f"`penumbra info {path}` failed:\n{(p.stderr or p.stdout).strip()}")
    return int(m.group(1))


# ---------------------------------------------------------------- measuring

def rss_bytes(pid):
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) * 1024
    except (FileNotFoundError, ProcessLookupError):
        pass
    return 0


def kill_group(pid):
    try:
        os.killpg(pid, signal.SIGKILL)
    except ProcessLookupError:
        pass


def measure(cmd, timeout, mem_limit):
    """Runs cmd as its own process group; kills it past timeout (s) or when its
    resident memory passes mem_limit (bytes). Returns status, output, wall,
    user and system CPU and peak RSS (from wait4, bytes)."""
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        t0 = time.perf_counter()
        p = subprocess.Popen(cmd, stdout=out, stderr=err, start_new_session=True)
        status, killed = None, None
        try:
            while True:
                pid, st, ru = os.wait4(p.pid, os.WNOHANG)
                if pid:
                    break
                if killed is None:
                    if time.perf_counter() - t0 > timeout:
                        killed = "timed out"
                    elif rss_bytes(p.pid) > mem_limit:
                        killed = "memory limit"
                    if killed:
                        kill_group(p.pid)
                time.sleep(0.02)
        except BaseException:  # interrupted (Ctrl-C, SIGTERM): take the run down with us
            kill_group(p.pid)
            os.wait4(p.pid, 0)
            p.returncode = -signal.SIGKILL
            raise
        wall = time.perf_counter() - t0
        p.returncode = os.waitstatus_to_exitcode(st)
        out.seek(0)
        err.seek(0)
        stdout = out.read().decode(errors="replace")
        stderr = err.read().decode(errors="replace")
    if killed:
        status = killed
    elif p.returncode != 0:
        status = "failed"
    else:
        status = "ok"
    return {"status": status, "returncode": p.returncode, "stdout": stdout, "stderr": stderr,
            "wall_s": wall, "user_s": ru.ru_utime, "sys_s": ru.ru_stime,
            "peak_rss_mib": ru.ru_maxrss / 1024.0}


def run_one(args, exe, scene, w, h, n, run, binary, work):
    if run == EMBREE:
        cmd = peer_lib.embree_command(args.peer, binary, n, args.threads)
    else:
        cmd = peer_lib.penumbra_command(exe, scene["path"], run, w, h, n, args.threads, work)
    r = measure(cmd, args.timeout, args.mem_limit_bytes)
    rec = {"scene": scene["id"], "triangles": scene["triangles"], "width": w, "height": h, "samples": n,
           "run": run, "status": r["status"], "shadow_s": None, "passes": None,
           "wall_s": r["wall_s"], "user_s": r["user_s"], "sys_s": r["sys_s"],
           "peak_rss_mib": r["peak_rss_mib"]}
    if r["status"] == "ok":
        try:
            if run == EMBREE:
                s, j = peer_lib.embree_times(r["stdout"])
                rec.update(shadow_s=s, passes={"build": j["build_s"], "trace": j["trace_s"]}, embree=j)
            else:
                s, passes = peer_lib.penumbra_times(r["stdout"] + r["stderr"])
                if not passes:
                    raise ValueError("no --timings lines in its output")
                rec.update(shadow_s=s, passes=passes)
        except (ValueError, KeyError, IndexError) as e:
            rec["status"] = "failed"
            rec["error"] = f"unreadable output ({e}): {r['stdout'][-500:]}"
    elif r["status"] == "failed":
        rec["error"] = f"exit {r['returncode']}: {shlex.join(cmd)}\n{r['stderr'].strip()[-2000:]}"
    if rec["status"] != "ok":
        rec["command"] = shlex.join(cmd)
    return rec


def check_vcoef(args, exe, scene, w, h, n, binary, prep_info, work):
    """Untimed: penumbra's reference and Embree on the same receivers. When
    both trace the same triangles from the same points, penumbra's reference
    casts receivers × n rays and its Vcoef differs from Embree's by no more
    than two Embree runs with different seeds differ from each other (the
    noise of two n-sample estimates), and their means agree."""
    import numpy as np
    sys.path.insert(0, args.peer)
    import finish  # the peer's reader of its input (and, through it, the oracle's EXR reader)

    emb = []
    for seed in (0, 1):
        vout = os.path.join(work, f"vcoef{seed}.f32")
        e = subprocess.run(peer_lib.embree_command(args.peer, binary, n, args.threads)
                           + ["--seed", str(seed), "--out", vout], capture_output=True, text=True)
        if e.returncode != 0:
            return {"ok": False, "error": f"embree_rays: {e.stderr.strip()[-2000:]}"}
        emb.append(np.fromfile(vout, dtype="<f4").astype(np.float64))
    exr = os.path.join(work, "check.exr")
    p = subprocess.run(peer_lib.penumbra_command(exe, scene["path"], "reference", w, h, n, args.threads, work)
                       + ["--exr", exr, "--aov", "vcoef"], capture_output=True, text=True)
    if p.returncode != 0:
        return {"ok": False, "error": f"penumbra: {p.stderr.strip()[-2000:]}"}
    rays = sum(int(m.group(1)) for m in re.finditer(r"\((\d+) rays\)", p.stderr))
    _, _, pix = finish.read_header(binary)
    ch = finish.oracle.read_exr(exr)
    names = [c for c in ch if c.startswith("vcoef")]
    if len(names) != 1:
        return {"ok": False, "error": f"expected one vcoef channel in the EXR, found {sorted(ch)}"}
    pen = np.asarray(ch[names[0]], dtype=np.float64).reshape(-1)[pix]
    finite = np.isfinite(pen) & np.isfinite(emb[0]) & np.isfinite(emb[1])
    rms = lambda d: float(np.sqrt(np.mean(d * d))) if len(d) else float("nan")
    d = pen[finite] - emb[0][finite]
    res = {"receivers": int(len(pix)), "compared": int(finite.sum()),
           "penumbra_rays": rays, "embree_rays": int(len(pix)) * n,
           "mean_vcoef_penumbra": float(pen[finite].mean()), "mean_vcoef_embree": float(emb[0][finite].mean()),
           "mean_diff": float(d.mean()), "rmse": rms(d),
           "noise_rmse": rms(emb[0][finite] - emb[1][finite]),
           "prep_triangles": prep_info.get("triangles_total"),
           "prep_casters": prep_info.get("caster_triangles_opaque")}
    res["ok"] = bool(rays == len(pix) * n and finite.sum() == len(pix)
                     and res["rmse"] <= 1.5 * res["noise_rmse"]
                     and abs(res["mean_diff"]) <= 5 * res["rmse"] / math.sqrt(max(len(d), 1)) + 1e-4)
    return res


# ---------------------------------------------------------------- outputs

def median_or_none(xs):
    xs = [x for x in xs if x is not None]
    return statistics.median(xs) if xs else None


def summarise(data):
    """Median per scene × size × samples × run, and Embree ÷ run."""
    groups = {}
    for r in data["records"]:
        groups.setdefault((r["scene"], r["width"], r["height"], r["samples"], r["run"]), []).append(r)
    scenes = {s["id"]: s for s in data["scenes"]}
    rows = []
    for (sid, w, h, n, run), rs in groups.items():
        ok = [r for r in rs if r["status"] == "ok"]
        rows.append({"scene": sid, "series": scenes[sid]["series"], "triangles": scenes[sid]["triangles"],
                     "width": w, "height": h, "samples": n, "run": run,
                     "status": "ok" if ok else rs[-1]["status"], "runs": len(ok),
                     "shadow_s": median_or_none([r["shadow_s"] for r in ok]),
                     "wall_s": median_or_none([r["wall_s"] for r in ok]),
                     "peak_rss_mib": median_or_none([r["peak_rss_mib"] for r in ok])})
    emb = {(r["scene"], r["width"], r["height"], r["samples"]): r["shadow_s"] for r in rows if r["run"] == EMBREE}
    for r in rows:
        e = emb.get((r["scene"], r["width"], r["height"], r["samples"]))
        r["embree_over_run"] = e / r["shadow_s"] if e and r["shadow_s"] else None
    order = {t: k for k, t in enumerate(data["settings"]["techniques"] + [EMBREE])}
    rows.sort(key=lambda r: (r["width"] * r["height"], r["samples"], r["triangles"] or 0, r["scene"],
                             order.get(r["run"], 99)))
    return rows


def write_table(data, rows, path):
    m = data["machine"]
    lines = [f"{m['cpu']}{' (AVX-512)' if m['avx512'] else ''}, {m['cores']} cores; commit {data['commit']}; "
             f"{data['date']}; {data['settings']['threads']} threads, {data['settings']['rounds']} round(s), "
             f"medians; load average before {data['load_before']}, after {data.get('load_after', '?')}.", "",
             "| scene | series | triangles | size | samples | run | shadow work (s) | wall (s) | peak memory (MiB) "
             "| Embree ÷ run |", "|---|---|--:|---|--:|---|--:|--:|--:|--:|"]
    for r in rows:
        f = lambda v, d: "—" if v is None else f"{v:.{d}f}"
        shadow = f(r["shadow_s"], 3) if r["status"] == "ok" else r["status"]
        ratio = f"{r['embree_over_run']:.2f}×" if r["embree_over_run"] and r["run"] != EMBREE else "—"
        lines.append(f"| {r['scene']} | {', '.join(r['series'])} | {r['triangles']:,} | {r['width']}×{r['height']} "
                     f"| {r['samples']} | {r['run']} | {shadow} | {f(r['wall_s'], 2)} | {f(r['peak_rss_mib'], 0)} "
                     f"| {ratio} |")
    with open(path, "w") as fh:
        fh.write("\n".join(lines) + "\n")
    return lines


def write_csv(data, path):
    cols = ["scene", "series", "spheres", "segments", "rings", "triangles", "width", "height", "samples", "run",
            "round", "status", "shadow_s", "wall_s", "user_s", "sys_s", "peak_rss_mib", "passes", "error"]
    scenes = {s["id"]: s for s in data["scenes"]}
    with open(path, "w", newline="") as f:
        wr = csv.writer(f)
        wr.writerow(cols)
        for r in data["records"]:
            s = scenes[r["scene"]]
            passes = "; ".join(f"{k}={v:.6f}" for k, v in (r["passes"] or {}).items())
            row = {**r, "series": "+".join(s["series"]), "spheres": s["spheres"], "segments": s["segments"],
                   "rings": s["rings"], "passes": passes, "error": (r.get("error") or "").splitlines()[-1:]}
            row["error"] = row["error"][0] if row["error"] else ""
            wr.writerow(["" if row.get(c) is None else round(row[c], 6) if isinstance(row[c], float)
                         else row[c] for c in cols])


def have_matplotlib():
    try:
        import matplotlib  # noqa: F401
        return True
    except ImportError:
        return False


def plot(data, rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    panels = sorted({(r["width"], r["height"], r["samples"]) for r in rows}, key=lambda p: (p[0] * p[1], p[2]))
    sizes = sorted({(w, h) for w, h, _ in panels}, key=lambda s: s[0] * s[1])
    samples = sorted({n for _, _, n in panels})
    fig, axes = plt.subplots(len(sizes), len(samples), squeeze=False, sharex=True,
                             figsize=(max(7.0, 5.2 * len(samples)), 1.4 + 4.0 * len(sizes)))
    runs = [t for t in data["settings"]["techniques"] + [EMBREE] if any(r["run"] == t for r in rows)]
    series = [s for s in SERIES_STYLE if any(s in r["series"] for r in rows)]
    timeout = data["settings"]["timeout_s"]
    for (w, h, n) in panels:
        ax = axes[sizes.index((w, h))][samples.index(n)]
        for run in runs:
            for ser in series:
                pts = sorted((r["triangles"], r["shadow_s"]) for r in rows
                             if (r["width"], r["height"], r["samples"], r["run"]) == (w, h, n, run)
                             and ser in r["series"] and r["status"] == "ok" and r["triangles"])
                if pts:
                    ax.plot(*zip(*pts), SERIES_STYLE[ser], marker="o", ms=4, color=COLOURS.get(run),
                            label=None)
                lost = [r["triangles"] for r in rows
                        if (r["width"], r["height"], r["samples"], r["run"]) == (w, h, n, run)
                        and ser in r["series"] and r["status"] in ("timed out", "memory limit") and r["triangles"]]
                if lost:
                    ax.plot(lost, [timeout] * len(lost), "^", ms=7, mfc="none", color=COLOURS.get(run))
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(f"{w}×{h}, {n} samples")
        ax.set_xlabel("triangles")
        ax.set_ylabel("shadow work (s)")
        ax.grid(True, which="both", alpha=0.3)
    handles = [Line2D([], [], color=COLOURS.get(r), marker="o", ms=4, label=r) for r in runs]
    handles += [Line2D([], [], color="grey", ls=SERIES_STYLE[s], label=s) for s in series]
    if any(r["status"] in ("timed out", "memory limit") for r in rows):
        handles.append(Line2D([], [], color="grey", marker="^", mfc="none", ls="none",
                              label=f"timed out / memory limit (drawn at {timeout:g} s)"))
    ncol = 3
    fig.legend(handles=handles, loc="lower center", ncol=ncol, frameon=False, fontsize=9)
    m = data["machine"]
    fig.suptitle(f"Shadow work against triangles (log-log)\n{m['cpu']}, {m['cores']} cores, "
                 f"{data['settings']['threads']} threads, commit {data['commit']}, {data['date'][:10]}", fontsize=10)
    legend_h = (0.25 * math.ceil(len(handles) / ncol) + 0.2) / fig.get_figheight()
    fig.tight_layout(rect=(0, legend_h, 1, 1 - 0.6 / fig.get_figheight()))
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_outputs(data, out, draw=True):
    with open(os.path.join(out, "results.json"), "w") as f:
        json.dump(data, f, indent=1)
    write_csv(data, os.path.join(out, "results.csv"))
    rows = summarise(data)
    lines = write_table(data, rows, os.path.join(out, "table.md"))
    if draw:
        plot(data, rows, os.path.join(out, "scaling.png"))
    return lines


# ---------------------------------------------------------------- main

def git_commit():
    p = subprocess.run(["git", "-C", ROOT, "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
    if p.returncode != 0:
        return "unknown"
    dirty = subprocess.run(["git", "-C", ROOT, "status", "--porcelain", "--untracked-files=no"],
                           capture_output=True, text=True).stdout.strip()
    return p.stdout.strip() + ("-dirty" if dirty else "")


def mem_available():
    with open("/proc/meminfo") as f:
        for line in f:
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    return 0


def preflight(args):
    if not args.peer or not os.access(os.path.join(args.peer, "embree_rays"), os.X_OK):
        sys.exit("--peer DIR must hold a built embree_rays: run `scripts/embree-peer.py --setup /tmp/peers`, "
                 "then pass --peer /tmp/peers/embree-rays")
    if not os.path.exists(os.path.join(args.peer, "prep.py")) or \
            not os.path.exists(os.path.join(args.peer, "..", "oracle", "oracle.py")):
        sys.exit(f"--peer {args.peer}: needs prep.py and a copy of the oracle beside it (../oracle/oracle.py); "
                 "see `scripts/embree-peer.py --setup`")
    p = subprocess.run([sys.executable, "-c", "import numpy, OpenEXR, embreex"], capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"{sys.executable} cannot run the peer's prep.py ({p.stderr.strip().splitlines()[-1]}): "
                 "run this script with a Python that has numpy, OpenEXR and embreex "
                 f"(bash {os.path.normpath(os.path.join(args.peer, '..', 'oracle', 'setup.sh'))}, or a venv)")
    if not args.no_plot and not have_matplotlib():
        sys.exit(f"matplotlib is not importable by {sys.executable}; the plot needs it: run with a venv's "
                 "Python that has it (python3 -m venv V && V/bin/pip install matplotlib ...), or pass --no-plot")
    if not args.penumbra:
        sys.exit("--penumbra PATH is required (e.g. target/release/penumbra after `cargo build --release`)")
    if not os.access(args.penumbra, os.X_OK):
        sys.exit(f"--penumbra {args.penumbra}: no such executable (build it with `cargo build --release`)")


def main():
    if len(sys.argv) > 2 and sys.argv[1] == "--write-bunny-scenes":
        # bunny_scenes' child process: the scenes as JSON on stdout.
        print(json.dumps(write_bunny_scenes([int(x) for x in sys.argv[3:]], sys.argv[2])))
        return
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                 epilog="\n".join(__doc__.split("\n")[1:]),
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--peer", help="a built copy of embree-rays (beside a copy of the oracle)")
    ap.add_argument("--penumbra", help="the penumbra binary (target/release/penumbra)")
    ap.add_argument("--out", help="output directory (results.json, results.csv, table.md, scaling.png)")
    ap.add_argument("--quick", action="store_true",
                    help="2 smallest scenes of each series, 512², 64 samples, 1 round, --check")
    ap.add_argument("--segments", nargs="+", type=int, default=[20, 40, 80, 160],
                    help="tessellation series: segments = rings of the 81 spheres")
    ap.add_argument("--grids", nargs="+", type=int, default=[9, 18, 36],
                    help="many-spheres series: N for N × N spheres")
    ap.add_argument("--grid-segments", type=int, default=40, help="segments = rings of each sphere of --grids")
    ap.add_argument("--bunny-levels", nargs="*", type=int, default=[1, 2],
                    help="models series: Loop subdivision steps of the shipped bunny scan (none: no series)")
    ap.add_argument("--extra-scenes", nargs="+", default=[], help="more single-light scenes (e.g. a large model)")
    ap.add_argument("--sizes", nargs="+", type=int, default=[512, 1024], help="square image sides")
    ap.add_argument("--samples", nargs="+", type=int, default=[64, 256])
    ap.add_argument("--techniques", nargs="+", default=TECHNIQUES)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--rounds", type=int, default=1, help="interleaved rounds (medians)")
    ap.add_argument("--timeout", type=float, default=900.0, help="seconds per run (default 900)")
    ap.add_argument("--mem-limit", type=float,
                    help="GiB of resident memory per run (default: 85%% of MemAvailable at the start)")
    ap.add_argument("--check", action="store_true",
                    help="compare Vcoef of penumbra's reference and Embree once per scene and size (untimed)")
    ap.add_argument("--no-plot", action="store_true", help="skip the PNG (no matplotlib needed)")
    ap.add_argument("--plot-only", metavar="DIR", help="redraw table.md and scaling.png from DIR/results.json")
    args = ap.parse_args()
    # A SIGTERM unwinds like Ctrl-C: the running child is killed, the temp dir removed.
    signal.signal(signal.SIGTERM, lambda *_: sys.exit("terminated"))

    if args.plot_only:
        src = os.path.join(args.plot_only, "results.json")
        if not os.path.exists(src):
            sys.exit(f"{src}: no such file")
        if not have_matplotlib():
            sys.exit(f"matplotlib is not importable by {sys.executable}: run with a venv's Python that has it")
        with open(src) as f:
            data = json.load(f)
        print("\n".join(write_outputs(data, args.plot_only)))
        return
    if not args.out:
        sys.exit("--out DIR is required")
    if args.quick:
        args.segments, args.grids = sorted(args.segments)[:2], sorted(args.grids)[:2]
        args.bunny_levels = sorted(args.bunny_levels)[:1]
        args.sizes, args.samples, args.rounds, args.check = [512], [64], 1, True
    preflight(args)
    exe = os.path.abspath(args.penumbra)
    args.peer = os.path.abspath(args.peer)
    args.mem_limit_bytes = int(args.mem_limit * 2**30) if args.mem_limit else int(0.85 * mem_available())
    os.makedirs(args.out, exist_ok=True)

    data = {"machine": peer_lib.machine(), "commit": git_commit(),
            "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), "argv": sys.argv,
            "load_before": " ".join(open("/proc/loadavg").read().split()[:3]),
            "settings": {"sizes": args.sizes, "samples": args.samples, "techniques": args.techniques,
                         "threads": args.threads, "rounds": args.rounds, "timeout_s": args.timeout,
                         "mem_limit_gib": round(args.mem_limit_bytes / 2**30, 2), "quick": args.quick,
                         "shadow_work": "penumbra: --timings passes except load, geometry, gbuffer, shading; "
                                        "Embree: build_s + trace_s (stream mode)"},
            "scenes": [], "checks": [], "records": []}
    m = data["machine"]
    print(f"# {m['cpu']}{' (AVX-512)' if m['avx512'] else ''}, {m['cores']} cores; commit {data['commit']}; "
          f"load {data['load_before']}; memory limit {data['settings']['mem_limit_gib']} GiB per run", flush=True)
    draw = not args.no_plot
    runs = args.techniques + [EMBREE]
    lost = []  # (run, triangles, pixels, samples) that timed out or ran out of memory
    with tempfile.TemporaryDirectory(prefix="penumbra-scaling-") as work:
        scenes = make_scenes(args, work)
        for scene in scenes:
            try:
                counted = penumbra_info(exe, scene["path"])
            except RuntimeError as e:
                sys.exit(str(e))
            if scene["triangles"] is None:
                scene["triangles"] = counted
            scene["penumbra_triangles"] = counted
            if counted != scene["triangles"]:
                sys.exit(f"{scene['id']}: penumbra counts {counted:,} triangles, expected {scene['triangles']:,}")
        scenes.sort(key=lambda s: s["triangles"])
        data["scenes"] = [{k: v for k, v in s.items() if k != "path"} for s in scenes]
        total = len(scenes) * len(args.sizes) * len(args.samples) * args.rounds * len(runs)
        done = 0
        for scene, meta in zip(scenes, data["scenes"]):
            print(f"## {scene['id']} ({', '.join(scene['series'])}): {scene['triangles']:,} triangles", flush=True)
            for size in args.sizes:
                w = h = size
                info_path = os.path.join(work, "prep.json")
                try:
                    binary = peer_lib.prepare_peer_input(exe, args.peer, scene["path"], w, h, work, info=info_path)
                except RuntimeError as e:
                    sys.exit(f"{scene['id']} at {w}×{h}, the peer's input: {e}")
                with open(info_path) as f:
                    prep = json.load(f)
                meta.setdefault("receivers", {})[f"{w}x{h}"] = prep["receivers"]
                meta["peer_triangles"] = prep["triangles_total"]
                meta["peer_caster_triangles"] = prep["caster_triangles_opaque"]
                if prep["triangles_total"] != scene["triangles"]:
                    sys.exit(f"{scene['id']}: the peer loads {prep['triangles_total']:,} triangles, "
                             f"penumbra {scene['triangles']:,}")
                print(f"   {w}×{h}: {prep['receivers']:,} receivers; the peer traces "
                      f"{prep['caster_triangles_opaque']:,} caster triangles", flush=True)
                if args.check:
                    n0 = args.samples[0]
                    c = check_vcoef(args, exe, scene, w, h, n0, binary, prep, work)
                    c.update(scene=scene["id"], width=w, height=h, samples=n0)
                    data["checks"].append(c)
                    if "error" in c:
                        print(f"   check FAILED: {c['error']}", flush=True)
                    else:
                        print(f"   check {'ok' if c['ok'] else 'FAILED'} ({n0} samples): {c['compared']:,} of "
                              f"{c['receivers']:,} receivers, penumbra's reference cast {c['penumbra_rays']:,} rays "
                              f"(receivers × samples: {c['embree_rays']:,}); mean Vcoef reference "
                              f"{c['mean_vcoef_penumbra']:.5f}, Embree {c['mean_vcoef_embree']:.5f}; RMSE between "
                              f"them {c['rmse']:.4f}, between two Embree seeds {c['noise_rmse']:.4f}", flush=True)
                for n in args.samples:
                    for rnd in range(args.rounds):
                        for run in runs:
                            done += 1
                            head = f"[{done}/{total}] {scene['id']} {w}² {n} spp {run}"
                            if any(r == run and t <= scene["triangles"] and px <= w * h and k <= n
                                   for r, t, px, k in lost):
                                rec = {"scene": scene["id"], "triangles": scene["triangles"], "width": w,
                                       "height": h, "samples": n, "run": run, "status": "skipped",
                                       "shadow_s": None, "passes": None, "wall_s": None, "user_s": None,
                                       "sys_s": None, "peak_rss_mib": None,
                                       "error": "timed out or out of memory with fewer triangles, pixels "
                                                "and samples"}
                            else:
                                rec = run_one(args, exe, scene, w, h, n, run, binary, work)
                            rec["round"] = rnd
                            data["records"].append(rec)
                            if rec["status"] in ("timed out", "memory limit"):
                                lost.append((run, scene["triangles"], w * h, n))
                            if rec["status"] == "ok":
                                print(f"{head}: shadow {rec['shadow_s']:.3f} s, wall {rec['wall_s']:.2f} s, "
                                      f"peak {rec['peak_rss_mib']:.0f} MiB", flush=True)
                            else:
                                why = (rec.get("error") or "").strip().splitlines()
                                print(f"{head}: {rec['status']}{': ' + why[-1] if why else ''}", flush=True)
                            if rec["run"] == EMBREE and rec["status"] == "ok" and \
                                    (rec["embree"]["rays"], rec["embree"]["triangles"]) != \
                                    (prep["receivers"] * n, prep["caster_triangles_opaque"]):
                                sys.exit(f"{scene['id']}: Embree traced {rec['embree']['rays']:,} rays through "
                                         f"{rec['embree']['triangles']:,} triangles, expected {prep['receivers']:,} "
                                         f"receivers × {n} and {prep['caster_triangles_opaque']:,}")
                            write_outputs(data, args.out, draw=False)
    data["load_after"] = " ".join(open("/proc/loadavg").read().split()[:3])
    lines = write_outputs(data, args.out, draw=draw)
    print()
    print("\n".join(lines))
    bad = [c for c in data["checks"] if not c.get("ok")]
    if bad:
        sys.exit(f"{len(bad)} Vcoef check(s) failed (see checks in {os.path.join(args.out, 'results.json')})")


if __name__ == "__main__":
    main()
