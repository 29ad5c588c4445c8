#!/usr/bin/env python3
"""Per-pass times of two penumbra binaries, measured side by side.

    scripts/pass-times.py BASE_BIN NEW_BIN [--runs N] [--] RENDER_ARGS...

Runs `render RENDER_ARGS --timings` with each binary alternately N times
(default 5), and prints each pass's median time for both, the ratio of the
medians and of the minima (new / base), plus the whole render's. Alternating the two keeps machine
noise (other load, frequency changes) from favouring either.
"""
import re
import statistics
import subprocess
import sys
import tempfile
import time


def run(binary, args):
    with tempfile.TemporaryDirectory() as d:
        t0 = time.perf_counter()
        p = subprocess.run([binary, "render", *args, "-o", f"{d}/x.png", "--timings"],
                           capture_output=True, text=True)
        total = (time.perf_counter() - t0) * 1e3
    if p.returncode != 0:
        sys.exit(f"{binary} failed: {p.stderr}")
    passes = {}
    for line in p.stderr.splitlines():
        m = re.match(r"\s*([0-9.]+) ms\s+(.*)$", line)
        if m:
            passes.setdefault(m.group(2), 0.0)
            passes[m.group(2)] += float(m.group(1))
    passes["(whole process)"] = total
    return passes


def main():
    argv = sys.argv[1:]
    runs = 5
    if "--runs" in argv:
        i = argv.index("--runs")
        runs = int(argv[i + 1])
        del argv[i:i + 2]
    if "--" in argv:
        argv.remove("--")
    base, new, args = argv[0], argv[1], argv[2:]
    samples = {"base": [], "new": []}
    for _ in range(runs):
        samples["base"].append(run(base, args))
        samples["new"].append(run(new, args))
    names = list(samples["new"][0].keys())
    print(f"render {' '.join(args)}: median of {runs} alternating runs")
    print("| pass | base ms | new ms | new / base | min new / min base |\n|---|--:|--:|--:|--:|")
    for n in names:
        b = [s.get(n) for s in samples["base"] if n in s]
        w = [s[n] for s in samples["new"]]
        if not b:
            print(f"| {n} | — | {statistics.median(w):.1f} | — | — |")
            continue
        mb, mw = statistics.median(b), statistics.median(w)
        ratio = mw / mb if mb else float("nan")
        low = min(w) / min(b) if min(b) else float("nan")
        print(f"| {n} | {mb:.1f} | {mw:.1f} | {ratio:.2f} | {low:.2f} |")


if __name__ == "__main__":
    main()
