#!/usr/bin/env python3
"""Benchmark the dynamics core beside Pinocchio in the same run and print the ratios.

    python3 tools/bench_vs_pinocchio.py [--out docs/bench.md]

1. a pinned venv with Pinocchio (PyPI `pin`) at .venv-anchors (reused when present);
2. `cargo bench --bench dynamics` (criterion medians);
3. the measuring script ../shared/tools/anchors/bench_pin.py (Pinocchio through Python; its
   measured per-call Python overhead is subtracted to estimate the compiled library's time);
4. a markdown table: ours / Pinocchio (< 1 means faster).

No DDS participant is opened: this runs outside the network namespace.
"""
import argparse, json, os, pathlib, shutil, subprocess, sys, tempfile

ROOT = pathlib.Path(__file__).resolve().parent.parent
ANCHORS = ROOT.parent / "shared" / "tools" / "anchors"
VENV = pathlib.Path(os.environ.get("PIN_VENV", ROOT / ".venv-anchors"))
PINS = ["pin==4.1.0", "example-robot-data==6.0.0", "numpy"]
# (robot, our criterion id, Pinocchio column)
PAIRS = [(r, ours, pin) for r in ("ur5", "solo12") for ours, pin in
         (("rnea", "rnea"), ("crba", "crba"), ("aba", "aba"), ("constrained_dynamics", "cnstrDyn"),
          ("constrained_dynamics", "fwdDynJ"))]


def run(cmd, **kw):
    print("+", " ".join(map(str, cmd)), file=sys.stderr)
    return subprocess.run(cmd, check=True, **kw)


def ensure_venv():
    py = VENV / "bin" / "python"
    if not py.exists():
        run([sys.executable, "-m", "venv", str(VENV)])
        run([str(py), "-m", "pip", "install", "-q", *PINS])
    return py


def criterion_median_us(bench_id):
    est = ROOT / "target" / "criterion" / bench_id.replace("/", "_") / "new" / "estimates.json"
    return json.loads(est.read_text())["median"]["point_estimate"] / 1e3


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default=str(ROOT / "docs" / "bench.md"))
    ap.add_argument("--n", default="20000")
    args = ap.parse_args()
    py = ensure_venv()
    run(["cargo", "bench", "--bench", "dynamics", "--", "--noplot"], cwd=ROOT, stdout=subprocess.DEVNULL)
    with tempfile.TemporaryDirectory() as tmp:
        for f in ANCHORS.iterdir():
            shutil.copy(f, tmp)
        run([str(py), "bench_pin.py", args.n, "5"], cwd=tmp, stdout=subprocess.DEVNULL)
        pin = json.loads((pathlib.Path(tmp) / "bench_pin.json").read_text())
    overhead = pin["overhead_us"]
    ov = overhead["rnea_empty_model"] if isinstance(overhead, dict) else float(overhead)
    rows = {r["robot"]: r["us"] for r in pin["rows"]}
    lines = [
        f"Measured in one run on this machine (`{os.uname().machine}`, {os.cpu_count()} cores): criterion "
        f"medians for this project; Pinocchio {pin['pinocchio']} through Python, best of 5 × {pin['N']} calls, "
        f"minus its measured call overhead of {ov:.3f} µs.",
        "",
        "| robot | algorithm | ours [µs] | Pinocchio [µs] | ratio ours / Pinocchio |",
        "|---|---|---|---|---|",
    ]
    for robot, ours, col in PAIRS:
        o = criterion_median_us(f"{robot}/{ours}")
        p = rows[robot][col] - ov
        lines.append(f"| {robot} | {ours} vs `{col}` | {o:.3f} | {p:.3f} | {o / p:.2f} |")
    text = "\n".join(lines) + "\n"
    pathlib.Path(args.out).write_text(text)
    print(text)


if __name__ == "__main__":
    main()
