#!/usr/bin/env python3
"""Side by side: penumbra's default render against Mitsuba 3 and Blender Cycles, at equal error.

Drives the renderers peer (Mitsuba 3 `direct` integrator, LLVM variant;
Blender Cycles on the CPU, with and without Open Image Denoise), which
renders the same scenes with all of them, interleaved on the same threads,
measures every image against `penumbra --technique reference --samples
4096` (FLIP and RMSE on the masked interior: foreground pixels away from
depth and normal edges) and finds, on each peer's error-against-time curve
over its sample counts, the time it needs to reach penumbra's error. This
script runs the peer once per image size, reads its summary.json files and
prints one table of those equal-error ratios (peer time ÷ penumbra time,
wall and CPU) for penumbra's `dcs` at each --samples.

What is timed (the peer's rules): penumbra as the whole `penumbra render`
process (scene load, BVH, render, PNG + EXR write; CPU time of the child);
Cycles from its first sample to the end of the render call (no scene sync,
BVH or file write; OIDN included); Mitsuba `mi.render()` and the transfer
of the image (no scene load, no JIT compile: an untimed warm-up renders
every sample count once). This favours the peers. `>`: the peer did not
reach penumbra's error by its highest sample count (a lower bound); `<=`:
its lowest sample count was already below it (an upper bound).

The peer is not part of the repository. Its folder (--peer) holds
README.md, setup.sh and peer.py; `bash DIR/setup.sh` makes its virtual
environment DIR/.venv (Python 3.11, bpy, mitsuba, flip-evaluator, ...),
whose python runs peer.py. Default --peer: $PENUMBRA_RENDERERS_PEER, else
../shared/peers/renderers beside this checkout (the project machine's
layout).

    bash PEER/setup.sh
    scripts/renderers-peer.py --peer PEER --penumbra target/release/penumbra \\
        --scenes scenes/spheres.toml scenes/bunny.toml --sizes 512 1024 \\
        --samples 64 256 --reps 3 --out /tmp/renderers-peer

Writes OUT/<size>/ (the peer's output: tables.md, summary.json, images,
side-by-side PNGs), OUT/run.json and OUT/equal-error.md (the table printed).
--table-only rebuilds the table from an existing OUT.
"""

import argparse
import json
import os
import shlex
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PEERS = (("mitsuba", "Mitsuba 3"), ("cycles", "Cycles"), ("cycles+oidn", "Cycles + OIDN"))
METRICS = {"flip_m": "FLIP", "rmse_m": "RMSE", "rmse_s": "RMSE strict", "flip_a": "FLIP all",
           "rmse_a": "RMSE all"}
# Peer sample counts, for every size unless a SIZE:LIST entry names it
# (measured at 256², 2026-12-06). On spheres they reach penumbra's masked
# error at 64 samples; at 256 samples Mitsuba needs 4096-16384 spp, Cycles
# about 1024, and Cycles + OIDN's FLIP levels off above it, so there the
# ratio is a `>` bound: the top count's time. At 1024² a render at the top
# counts takes minutes on 2 cores (Mitsuba 4096 spp about 9 min, Cycles 256
# spp about 12), so the lists stop one count earlier; those top counts
# still take over 20× penumbra's 256-sample time.
MITSUBA_SPP = ["16,64,256,1024,4096", "1024:16,64,256,1024"]
CYCLES_SPP = ["4,16,64,256", "1024:4,16,64"]


def spp_for(entries, size):
    """The sample list of one size from 'LIST' / 'SIZE:LIST' entries (a SIZE:LIST entry wins)."""
    lists = {}
    for e in entries:
        key, _, spp = e.rpartition(":")
        if spp and not all(x.strip().isdigit() for x in spp.split(",") if x.strip()) or key and not key.isdigit():
            sys.exit(f"bad sample list {e!r}: LIST or SIZE:LIST, a LIST being comma-separated counts ('' for none)")
        lists[int(key) if key else None] = spp
    return lists.get(size, lists.get(None, ""))


def default_peer():
    return os.environ.get("PENUMBRA_RENDERERS_PEER") or \
        os.path.normpath(os.path.join(ROOT, "..", "shared", "peers", "renderers"))


def machine():
    cpu, flags = "unknown CPU", ""
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name") and cpu == "unknown CPU":
                    cpu = line.split(":", 1)[1].strip()
                elif line.startswith("flags") and not flags:
                    flags = line
    except OSError:
        pass
    mem = ""
    try:
        with open("/proc/meminfo") as f:
            kb = int(next(l for l in f if l.startswith("MemTotal")).split()[1])
        mem = f", {kb / 2**20:.0f} GiB"
    except (OSError, StopIteration, ValueError):
        pass
    avx = " (AVX-512)" if " avx512f" in flags else ""
    return f"{cpu}{avx}, {os.cpu_count()} cores{mem}"


def loadavg():
    try:
        with open("/proc/loadavg") as f:
            return " ".join(f.read().split()[:3])
    except OSError:
        return "?"


def commit():
    def git(*a):
        p = subprocess.run(["git", "-C", ROOT, *a], capture_output=True, text=True)
        return p.stdout.strip() if p.returncode == 0 else ""
    c = git("rev-parse", "--short", "HEAD") or "unknown"
    return c + ("+dirty" if git("status", "--porcelain", "--untracked-files=no") else "")


def run_peer(a, py, size, out):
    """One peer.py run (all scenes, one size); its output goes to OUT/<size>/peer.log and stderr."""
    os.makedirs(out, exist_ok=True)
    cmd = [py, os.path.join(a.peer, "peer.py"), "--scenes", *a.scenes, "--size", str(size),
           "--out", out, "--reps", str(a.reps), "--threads", str(a.threads), "--oidn",
           "--penumbra", a.penumbra, "--penumbra-runs", ",".join(f"{a.technique_name}:{n}" +
                                                                  (f":{a.technique_args}" if a.technique_args else "")
                                                                  for n in a.samples),
           "--mitsuba-spp", spp_for(a.mitsuba_spp, size), "--cycles-spp", spp_for(a.cycles_spp, size), "--gt-samples", str(a.gt_samples),
           "--normal-deg", str(a.normal_deg)]
    print(f"## {size}²: {shlex.join(cmd)}", file=sys.stderr, flush=True)
    t0 = time.monotonic()
    with open(os.path.join(out, "peer.log"), "w") as log:
        p = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        for line in p.stdout:
            log.write(line)
            log.flush()
            if line.startswith("{") or line.startswith("ground truth") or ": warm-up" in line:
                print(f"  [{time.monotonic() - t0:7.1f} s] {line.rstrip()}", file=sys.stderr, flush=True)
        rc = p.wait()
    if rc != 0:
        sys.exit(f"peer.py failed (exit {rc}) for {size}²; see {os.path.join(out, 'peer.log')}")
    return time.monotonic() - t0


def ratio(x):
    return f"{x:.1f}" if x >= 1 else f"{x:.2f}"


def cell(heads, pen, peer, metric):
    """'wall× / CPU×' with the peer's bound markers, from summary.json's equal-error entries."""
    got = {h["time"]: h for h in heads
           if h["penumbra"] == pen and h["peer"] == peer and h["metric"] == metric}
    if not {"wall", "cpu"} <= got.keys() or any(got[t]["ratio"] is None for t in ("wall", "cpu")):
        return "–"
    return " / ".join(f"{got[t]['bound']}{ratio(got[t]['ratio'])}×" for t in ("wall", "cpu"))


def table(meta):
    metrics = meta["metrics"]
    head = ["scene", "size", "penumbra", "wall s", "CPU s"] + [f"{METRICS[m]}" for m in metrics]
    for _, name in PEERS:
        head += [f"{name}: {METRICS[m]}" for m in metrics]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * 3 + "--:|" * (len(head) - 3)]
    peers_seen = {}
    for size in meta["sizes"]:
        path = os.path.join(meta["out"], str(size), "summary.json")
        if not os.path.isfile(path):
            lines.append(f"| (no {path}) |")
            continue
        with open(path) as f:
            summary = json.load(f)
        for scene, v in summary.items():
            h, w = v["size"]
            for row in v["table"]:
                if row["renderer"] != "penumbra":
                    spp = peers_seen.setdefault(row["renderer"], {})
                    spp.setdefault(size, set()).add(int(row["setting"]))
                    continue
                cells = [scene, f"{w}²" if w == h else f"{w}×{h}", row["setting"],
                         f"{row['wall']:.3f}", f"{row['cpu']:.3f}"]
                cells += [f"{row[m]:.4f}" if m.startswith("flip") else f"{row[m]:.2e}" for m in metrics]
                for peer, _ in PEERS:
                    cells += [cell(v["heads"], row["setting"], peer, m) for m in metrics]
                lines.append("| " + " | ".join(cells) + " |")
    spp = "; ".join(f"{peer} " + ", ".join(f"{','.join(map(str, sorted(s)))} spp at {size}²"
                                           for size, s in sorted(by_size.items()))
                    for peer, by_size in sorted(peers_seen.items()))
    return "\n".join(lines), spp


def versions(meta):
    """Blender and Mitsuba versions, from the peer's server handshakes in its results.jsonl."""
    got = {}
    for size in meta["sizes"]:
        try:
            with open(os.path.join(meta["out"], str(size), "runs", "results.jsonl")) as f:
                for line in f:
                    r = json.loads(line)
                    if (r.get("ready_cycles") or {}).get("blender"):
                        got["Blender"] = r["ready_cycles"]["blender"]
                    m = r.get("ready_mitsuba") or {}
                    if m.get("mitsuba"):
                        got["Mitsuba"] = f"{m['mitsuba']} ({m.get('variant', '?')})"
        except (OSError, ValueError):
            pass
    return ", ".join(f"{k} {v}" for k, v in sorted(got.items())) or "?"


def render(meta):
    tab, spp = table(meta)
    out = [f"# Equal-error ratios: penumbra against Mitsuba 3 and Cycles",
           "",
           f"- machine: {meta['machine']}; load average {meta['load_before']} before, "
           f"{meta.get('load_after', '?')} after",
           f"- penumbra commit {meta['commit']} (binary {meta['penumbra']}); {meta['date']}",
           f"- command: `{meta['command']}`",
           f"- peers: {versions(meta)}",
           f"- peer settings measured: {spp}; {meta['reps']} interleaved repetitions (medians), "
           f"{meta['threads']} threads each; ground truth `reference --samples {meta['gt_samples']}`; "
           f"mask: normals within {meta.get('normal_deg', 20):g}° of their neighbours",
           f"- run time: " + ", ".join(f"{s}² {t:.0f} s" for s, t in meta.get("elapsed", {}).items()),
           "",
           "penumbra's FLIP and RMSE on the masked interior against the ground truth; each peer's cell is "
           "the time it needs to reach that error ÷ penumbra's time, wall / CPU (above 1: penumbra is "
           "faster; `>`: the peer's highest sample count did not get there, a lower bound; `<=`: its "
           "lowest was already there, an upper bound).",
           "",
           tab,
           ""]
    return "\n".join(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                 epilog="See the module docstring (head -40 of this file) for the timing rules.")
    ap.add_argument("--peer", default=default_peer(),
                    help="the renderers peer's folder (default: $PENUMBRA_RENDERERS_PEER, else "
                         "../shared/peers/renderers beside the checkout; now %(default)s)")
    ap.add_argument("--python", help="python of the peer's venv (default: PEER/.venv/bin/python)")
    ap.add_argument("--penumbra", default=os.path.join(ROOT, "target", "release", "penumbra"),
                    help="penumbra binary (default: target/release/penumbra of this checkout)")
    ap.add_argument("--scenes", nargs="+", default=["scenes/spheres.toml", "scenes/bunny.toml"])
    ap.add_argument("--sizes", nargs="+", type=int, default=[512, 1024],
                    help="image width = height; one peer run per size")
    ap.add_argument("--samples", nargs="+", type=int, default=[64, 256],
                    help="penumbra's light samples (one setting each)")
    ap.add_argument("--technique", default="dcs",
                    help="penumbra technique and its options, quoted (default: dcs, the default render)")
    ap.add_argument("--reps", type=int, default=3, help="interleaved repetitions (medians)")
    ap.add_argument("--threads", type=int, default=2, help="threads for every renderer")
    ap.add_argument("--mitsuba-spp", nargs="+", default=MITSUBA_SPP, metavar="[SIZE:]LIST",
                    help="Mitsuba sample counts, comma-separated, for every size or for SIZE "
                         "(default %(default)s)")
    ap.add_argument("--cycles-spp", nargs="+", default=CYCLES_SPP, metavar="[SIZE:]LIST",
                    help="Cycles sample counts, each also with OIDN, as --mitsuba-spp (default %(default)s)")
    ap.add_argument("--gt-samples", type=int, default=4096, help="ground truth: reference samples")
    ap.add_argument("--metrics", nargs="+", default=["flip_m", "rmse_m"], choices=list(METRICS),
                    help="errors of the table (default flip_m rmse_m: FLIP and RMSE on the masked "
                         "interior; rmse_s: RMSE on the 1° mask, without flat-shaded facet edges)")
    ap.add_argument("--normal-deg", type=float, default=20,
                    help="the mask's normal threshold in degrees (the peer's --normal-deg): 1 leaves out "
                         "the facet edges of flat-shaded meshes such as the bunny, across which the peers "
                         "average the pixel's area and penumbra takes its centre (default %(default)s)")
    ap.add_argument("--out", required=True, help="output folder (one subfolder per size)")
    ap.add_argument("--table-only", action="store_true", help="print the table of an existing --out")
    a = ap.parse_args()

    out = os.path.abspath(a.out)
    meta_path = os.path.join(out, "run.json")
    if a.table_only:
        with open(meta_path) as f:
            meta = json.load(f)
        meta["metrics"] = a.metrics
        md = render(meta)
    else:
        a.peer = os.path.abspath(a.peer)
        py = a.python or os.path.join(a.peer, ".venv", "bin", "python")
        if not os.path.isfile(os.path.join(a.peer, "peer.py")):
            sys.exit(f"no peer.py in {a.peer}: pass --peer DIR (the renderers peer) or set "
                     "PENUMBRA_RENDERERS_PEER")
        if not os.access(py, os.X_OK):
            sys.exit(f"no venv python at {py}: run `bash {os.path.join(a.peer, 'setup.sh')}` first "
                     "(or pass --python)")
        a.penumbra = os.path.abspath(a.penumbra)
        if not os.access(a.penumbra, os.X_OK):
            sys.exit(f"no penumbra binary at {a.penumbra}: `cargo build --release`, or pass --penumbra")
        a.scenes = [os.path.abspath(s) for s in a.scenes]
        parts = a.technique.split(None, 1)
        a.technique_name, a.technique_args = parts[0], (parts[1] if len(parts) > 1 else "")
        meta = {"machine": machine(), "commit": commit(), "penumbra": a.penumbra,
                "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
                "command": shlex.join([os.path.relpath(sys.argv[0], ROOT)
                                       if os.path.abspath(sys.argv[0]).startswith(ROOT) else sys.argv[0],
                                       *sys.argv[1:]]),
                "load_before": loadavg(), "sizes": a.sizes, "reps": a.reps, "threads": a.threads,
                "gt_samples": a.gt_samples, "metrics": a.metrics, "out": out, "elapsed": {},
                "normal_deg": a.normal_deg}
        os.makedirs(out, exist_ok=True)
        for size in a.sizes:
            meta["elapsed"][str(size)] = run_peer(a, py, size, os.path.join(out, str(size)))
            with open(meta_path, "w") as f:
                json.dump(meta, f, indent=1)
        meta["load_after"] = loadavg()
        with open(meta_path, "w") as f:
            json.dump(meta, f, indent=1)
        md = render(meta)
    with open(os.path.join(out, "equal-error.md"), "w") as f:
        f.write(md)
    print(md)


if __name__ == "__main__":
    main()
