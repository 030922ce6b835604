#!/usr/bin/env python3
"""Measure how the cost of an unconstrained tree grows with its size, and write the tables of
docs/performance.md ("Cost against the size of the tree") between its `chain:begin` /
`chain:end` markers.

    python3 tools/chain_cost.py [--repeats N] [--no-write]

What it runs, in order:
- `cargo bench --bench chain` (criterion; needs the example-robot-data venv of
  tools/robots/setup_venv.sh, or CD_ROBOTS_DIR): forward dynamics alone, linear-time path (ABA)
  and dense path (CRBA + LTL), on generated chains of n revolute links (tests/it/common/chain.rs;
  the bench also writes their URDF and scene files here) and on the four robots without contacts;
- the same bench's multiplier form of the chains held at both ends (three rows): without M
  (`dynamics/tree_multipliers.rs`) and dense;
- the release CLI's whole `eval --scene` process on each chain scene, free and held (URDF
  reading, model building, the scene's checks, the dynamics, the constraint forces, the JSON
  output): wall time (best of `--repeats`) and peak RSS (the process's own, from wait4);
- the release CLI's whole `predict --scene` process on the same scenes: RK4 at a fixed 1 ms
  step for 0.1 s (100 steps), the scene's defaults otherwise (error estimate on: its companion
  takes two half steps per step, 1 200 evaluations in all; drift projection; one sample at the
  end): wall time (best of `--repeats`) and peak RSS.
The exponent is the least-squares slope of log(cost) against log(n) over n >= 1000. The load
average when the measurement starts and ends is written beside the tables.
"""

import argparse
import json
import math
import os
import subprocess
import sys
import time

from doc_block import write_block

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DOC = os.path.join(ROOT, "docs", "performance.md")
BEGIN = "<!-- chain:begin -->"
END = "<!-- chain:end -->"
TABLE_N = [10, 30, 100, 300, 1000, 3000, 5000]
# The prediction timed: RK4 at a fixed step over a fixed horizon.
PREDICT = ["--method", "rk4", "--dt", "1e-3", "--horizon", "0.1", "--sample-period", "0.1"]
FIT_FROM = 1000


def target_dir():
    return os.environ.get("CARGO_TARGET_DIR", os.path.join(ROOT, "target"))


def run(cmd, **kw):
    print("+", " ".join(cmd), file=sys.stderr)
    return subprocess.run(cmd, cwd=ROOT, check=True, text=True, **kw)


def criterion_median_s(group, path, param):
    p = os.path.join(target_dir(), "criterion", group, path, param, "new", "estimates.json")
    with open(p) as f:
        return json.load(f)["median"]["point_estimate"] * 1e-9


def timed_process(cmd):
    """(wall seconds, peak RSS in MB) of one run of `cmd`, its output discarded."""
    t0 = time.perf_counter()
    p = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t0
    if status != 0:
        sys.exit(f"chain_cost.py: {' '.join(cmd)} failed: {p.stderr.read().decode()[-2000:]}")
    return wall, usage.ru_maxrss / 1024.0


def exponent(ns, values):
    pts = [(math.log(n), math.log(v)) for n, v in zip(ns, values) if n >= FIT_FROM]
    mx = sum(x for x, _ in pts) / len(pts)
    my = sum(y for _, y in pts) / len(pts)
    return sum((x - mx) * (y - my) for x, y in pts) / sum((x - mx) ** 2 for x, _ in pts)


def best_of(repeats, cmd):
    """(best wall seconds, largest peak RSS in MB) of `repeats` runs of `cmd`."""
    runs = [timed_process(cmd) for _ in range(repeats)]
    return min(w for w, _ in runs), max(r for _, r in runs)


def measure(repeats):
    scenes = os.path.join(target_dir(), "chain_scenes")
    load = [os.getloadavg()[0]]
    run(["cargo", "build", "--release", "-p", "constraint_dynamics_cli"])
    run(["cargo", "bench", "--bench", "chain"], env={**os.environ, "CHAIN_SCENES_DIR": scenes})
    cli = os.path.join(target_dir(), "release", "constraint_dynamics")

    def processes(name, n):
        scene = os.path.join(scenes, f"{name}_{n}.yaml")
        eval_s, rss_mb = best_of(repeats, [cli, "eval", "--scene", scene])
        predict_s, predict_mb = best_of(repeats, [cli, "predict", "--scene", scene] + PREDICT)
        return {"n": n, "eval_s": eval_s, "rss_mb": rss_mb, "predict_s": predict_s,
                "predict_mb": predict_mb}

    rows = []
    for n in TABLE_N:
        r = processes("chain", n)
        r["dynamics_s"] = criterion_median_s("chain", "linear", str(n))
        rows.append(r)
    loops = []
    for n in TABLE_N:
        r = processes("chain_loop", n)
        dense_dir = os.path.join(target_dir(), "criterion", "chain_loop", "dense", str(n))
        r["dynamics_s"] = criterion_median_s("chain_loop", "linear", str(n))
        r["dense_s"] = (criterion_median_s("chain_loop", "dense", str(n))
                        if os.path.isdir(dense_dir) else None)
        loops.append(r)
    sizes = sorted(int(d) for d in os.listdir(os.path.join(target_dir(), "criterion", "chain",
                                                              "dense")) if d.isdigit())
    paths = [(n, criterion_median_s("chain", "linear", str(n)),
              criterion_median_s("chain", "dense", str(n))) for n in sizes]
    robots = []
    for name in ["ur5", "panda", "solo12", "talos_reduced"]:
        robots.append((name, criterion_median_s("robot", "linear", name),
                       criterion_median_s("robot", "dense", name)))
    load.append(os.getloadavg()[0])
    return rows, paths, robots, loops, load


def fmt_time(s):
    if s >= 0.1:
        return f"{s:.2f} s"
    if s >= 1e-3:
        return f"{s * 1e3:.2f} ms"
    return f"{s * 1e6:.2f} µs"


def crossover(paths):
    """The smallest n from which on the linear path is the faster on every chain timed."""
    best = None
    for n, lin, dense in reversed(paths):
        if lin >= dense:
            break
        best = n
    return best


KEYS = ("eval_s", "rss_mb", "predict_s", "predict_mb", "dynamics_s")


def process_cells(r):
    return (f"{fmt_time(r['eval_s'])} | {r['rss_mb']:.0f} MB | {fmt_time(r['predict_s'])} "
            f"| {r['predict_mb']:.0f} MB | {fmt_time(r['dynamics_s'])}")


def exponent_cells(fit):
    return " | ".join(f"{fit[k]:.2f}" for k in KEYS)


def table(rows, paths, robots, loops, load):
    ns = [r["n"] for r in rows]
    fit = {k: exponent(ns, [r[k] for r in rows]) for k in KEYS}
    cpu = ""
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next(l.split(":", 1)[1].strip() for l in f if l.startswith("model name"))
    except (OSError, StopIteration):
        pass
    out = [
        "<!-- written by python3 tools/chain_cost.py: do not edit -->",
        "",
        f"Measured on {cpu}, {os.cpu_count()} cores, "
        f"{time.strftime('%Y-%m-%d', time.gmtime())}; load average {load[0]:.1f} at the start, "
        f"{load[1]:.1f} at the end. `predict`: `{' '.join(PREDICT)}`, the scene's defaults "
        "otherwise (error estimate on: 1 200 evaluations; drift projection).",
        "",
        "| n (links = nv) | `eval --scene` process, URDF reading included | peak RSS "
        "| `predict --scene` process | peak RSS | forward dynamics alone (ABA) |",
        "|---|---|---|---|---|---|",
    ]
    for r in rows:
        out.append(f"| {r['n']} | {process_cells(r)} |")
    out.append(f"| exponent (n ≥ {FIT_FROM}) | {exponent_cells(fit)} |")
    out += [
        "",
        "Forward dynamics alone, both paths (criterion medians):",
        "",
        "| model | nv | linear (ABA) | dense (CRBA + LTL) | dense / linear |",
        "|---|---|---|---|---|",
    ]
    for n, lin, dense in paths:
        out.append(f"| chain | {n} | {fmt_time(lin)} | {fmt_time(dense)} | {dense / lin:.2f} |")
    nvs = {"ur5": 6, "panda": 7, "solo12": 18, "talos_reduced": 38}
    for name, lin, dense in robots:
        out.append(f"| {name} | {nvs[name]} | {fmt_time(lin)} | {fmt_time(dense)} "
                   f"| {dense / lin:.2f} |")
    x = crossover(paths)
    out += [
        "",
        f"Crossover on a chain: the linear path is the faster from n = {x} on." if x else
        "Crossover on a chain: none among the sizes timed.",
        "",
        "The chain held at both ends (its last link's end held at its start point: three rows), "
        "multiplier form with its forces:",
        "",
        "| n | `eval --scene` process | peak RSS | `predict --scene` process | peak RSS "
        "| constrained dynamics without M | dense (CRBA + LTL + Schur) | dense / without M |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in loops:
        ratio = r["dense_s"] / r["dynamics_s"] if r["dense_s"] else None
        dense = (f"{fmt_time(r['dense_s'])} | {ratio:.{1 if ratio < 10 else 0}f}"
                 if ratio else "— | —")
        out.append(f"| {r['n']} | {process_cells(r)} | {dense} |")
    lfit = {k: exponent(ns, [r[k] for r in loops]) for k in KEYS}
    out += [
        f"| exponent (n ≥ {FIT_FROM}) | {exponent_cells(lfit)} | | |",
        "",
    ]
    return "\n".join(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3, help="eval processes per size")
    ap.add_argument("--no-write", action="store_true", help="print the tables only")
    args = ap.parse_args()
    t = table(*measure(args.repeats))
    print(t)
    if args.no_write:
        return
    write_block(DOC, BEGIN, END, t)


if __name__ == "__main__":
    main()
