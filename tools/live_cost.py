#!/usr/bin/env python3
"""Measure the default suite's live cost and accuracy, and write the table of
docs/performance.md ("The live cost") between its `live:begin` / `live:end` markers.

    python3 tools/live_cost.py [--runs N] [--no-write]

What it runs, in order:
- the release suite, fed at 20 Hz inside a private network namespace (tools/ros2/live_cpu.py,
  the peer venv of tools/ros2/setup_peer_venv.sh), under a steady command and under one that
  changes at every message: CPU share and predicted-odometry rate, `--runs` times each;
- the live-prediction and covariance tests (tests/it/live_prediction.rs, tests/it/covariance.rs,
  in the core's one `it` target):
  the base pose against the controllers' 1 ms hold integrated at 0.1 ms, the error estimate
  against the true error, the tick's work, the covariance against Monte Carlo.
The machine should be otherwise idle: a CPU share is only as good as the quiet around it.
"""

import argparse
import datetime
import json
import os
import re
import subprocess
import sys

from bench import machine
from doc_block import write_block

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DOC = os.path.join(ROOT, "docs", "performance.md")
BEGIN = "<!-- live:begin -->"
END = "<!-- live:end -->"


def run(cmd, **kw):
    print("+", " ".join(cmd), file=sys.stderr)
    return subprocess.run(cmd, cwd=ROOT, check=True, text=True, **kw)


def suite_cpu(runs):
    run(["cargo", "build", "--release", "--locked", "-p", "constraint_dynamics_nodes",
         "--bin", "constraint_dynamics_suite"])
    run(["bash", "tools/ros2/setup_peer_venv.sh"])
    out = []
    for _ in range(runs):
        for feed in ("steady", "changing"):
            r = run(["tools/ros2/netns_run.sh", ".venv-ros2/bin/python", "tools/ros2/live_cpu.py",
                     "--suite", "target/release/constraint_dynamics_suite", "--feed", feed],
                    stdout=subprocess.PIPE)
            out.append(json.loads(r.stdout.strip().splitlines()[-1]))
    return out


def accuracy():
    r = run(["cargo", "test", "--locked", "-p", "constraint_dynamics", "--test", "it", "--",
             "--nocapture", "live_prediction::", "covariance::live"],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    text = r.stdout
    base = [(float(a), float(b)) for a, b in
            re.findall(r"base ([0-9.e+-]+) m, yaw ([0-9.e+-]+) rad from the held reference", text)]
    ratios = [float(x) for x in re.findall(r"\(×([0-9.]+)\)", text)]
    work = re.search(r"evaluations (\d+) \+ (\d+) \(estimate\), Jacobians (\d+), covariance "
                     r"linearizations (\d+)", text)
    mc = [float(x) for x in re.findall(r"live mobile manipulator[^:]*: achieved \|P_mc − P\| / "
                                       r"\|P\| = ([0-9.]+)", text)]
    if not (base and ratios and work and mc):
        sys.exit("live_cost.py: the tests' printout changed; nothing written\n" + text[-3000:])
    return {
        "position_m": max(b[0] for b in base),
        "yaw_rad": max(b[1] for b in base),
        "ratio": (min(ratios), max(ratios)),
        "work": tuple(int(x) for x in work.groups()),
        "mc": max(mc),
    }


def span(values, fmt):
    """'lo–hi' in `fmt`, or one value when they print the same."""
    lo, hi = format(min(values), fmt), format(max(values), fmt)
    return lo if lo == hi else f"{lo}–{hi}"


def table(cpu, acc, load):
    steady = [c for c in cpu if c["feed"] == "steady"]
    changing = [c for c in cpu if c["feed"] == "changing"]
    share = span([c["cpu_share"] for c in steady], ".3f")
    share_changing = span([c["cpu_share"] for c in changing], ".3f")
    rate = span([c["predicted_odom_hz"] for c in cpu], ".1f")
    cov = "yes" if all(c["covariance"] for c in cpu) else "**no**"
    ev, est, jac, lin = acc["work"]
    ratio = span(acc["ratio"], ".2f")
    return "\n".join([
        "<!-- written by python3 tools/live_cost.py: do not edit -->",
        "",
        f"Measured {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d} on {machine()}, "
        f"load average {load:.2f} at the start.",
        "",
        "| suite CPU share, steady command [cores] | changing commands [cores] "
        "| predicted_odom [Hz] | with covariance | evaluations per tick (answer + estimate) "
        "| Jacobians | covariance linearizations | base position vs held "
        "| yaw vs held | estimate / true error | covariance vs Monte Carlo |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
        f"| {share} ({len(steady)} runs) | {share_changing} ({len(changing)} runs) | {rate} "
        f"| {cov} | {ev} + {est} | {jac} | {lin} "
        f"| {acc['position_m']:.1e} m | {acc['yaw_rad']:.1e} rad | {ratio} "
        f"| {100 * acc['mc']:.1f} % |",
        "",
    ])


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=2, help="suite CPU measurements")
    ap.add_argument("--no-write", action="store_true", help="print the table only")
    args = ap.parse_args()
    load = os.getloadavg()[0]
    cpu = suite_cpu(args.runs)
    acc = accuracy()
    t = table(cpu, acc, load)
    print(t)
    if args.no_write:
        return
    write_block(DOC, BEGIN, END, t)


if __name__ == "__main__":
    main()
