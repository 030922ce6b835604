"""How far one calibration carries: the calibrated scene scored on fresh drives of the same
kinds, and what a calibration drive with fewer raw steps changes.

    .venv-logs/bin/python tools/logs/step_spread.py [--print]

Fresh drives come from make_logs.py's own generator with seeds no bundled drive uses (five of
20 s of raw command steps, two of 20 s smoothed), written to a temporary directory. The suite's
scene is calibrated twice with the CLI's defaults: on the bundled calibration.mcap (20 s
smoothed, then two 20 s phases of steps) and on a 40 s drive of the same seed with one phase of
steps. Each calibrated scene is then scored by `evaluate` against the simulator's true pose on
the two bundled validation drives and on the fresh ones. Writes docs/logs.md's table between its
`step_spread:begin` / `step_spread:end` markers (`--print`: to stdout instead).
"""

import json
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.dirname(HERE))
import make_logs as ml  # noqa: E402
from doc_block import block_args, emit_block  # noqa: E402

DOC = os.path.join(ml.REPO, "docs", "logs.md")
BEGIN = "<!-- step_spread:begin -->"
END = "<!-- step_spread:end -->"
LOGS = os.path.join(ml.REPO, "tests", "data", "logs")
STEPS_SEEDS = [101, 102, 103, 104, 105]
SMOOTH_SEEDS = [201, 202]


def cli(*args):
    out = subprocess.run(
        ["cargo", "run", "--quiet", "--locked", "-p", "constraint_dynamics_cli", "--", *args],
        cwd=ml.REPO, check=True, stdout=subprocess.PIPE, text=True)
    return json.loads(out.stdout)


def fresh_drive(name, seed, phases):
    """A drive of 20 s per phase from make_logs' generator with a seed of its own."""
    return ml.Drive(name, seed=seed, phases=tuple((k, 20.0) for k in phases), stamped=False,
                    bag_directory=False)


def drive(tmp, name, seed, phases):
    path = os.path.join(tmp, f"{name}.mcap")
    ml.record(fresh_drive(name, seed, phases), path, ml.SCENE, ml.URDF)
    return path


def scored(scene, bag):
    """{horizon: (worst position [mm], worst yaw [mrad], median yaw [mrad], coverage p95,
    mean NEES)}."""
    ev = cli("evaluate", "--scene", scene, "--bag", bag, "--truth-topic", "/ground_truth/odom",
             "--horizons", "1,2")
    return {h["horizon_s"]: (1e3 * h["position_error_m"]["max"], 1e3 * h["yaw_error_rad"]["max"],
                             1e3 * h["yaw_error_rad"]["median"], h["coverage"]["p95"],
                             h["nees_mean"])
            for h in ev["horizons"]}


def span(values, fmt):
    lo, hi = min(values), max(values)
    return fmt.format(lo) if fmt.format(lo) == fmt.format(hi) else \
        f"{fmt.format(lo)}–{fmt.format(hi)}"


def group_cells(scene, bags):
    """`scene` scored on `bags`, as table cells: at 1 s and at 2 s the worst position, worst
    and median yaw; the coverage p95 and the mean NEES at 1 s / 2 s (ranges over the bags)."""
    s = [scored(scene, b) for b in bags]
    cells = []
    for h in (1.0, 2.0):
        cells.append(f"{span([x[h][0] for x in s], '{:.1f}')} mm, "
                     f"{span([x[h][1] for x in s], '{:.0f}')} mrad, "
                     f"{span([x[h][2] for x in s], '{:.1f}')} mrad")
    cov = " / ".join(span([x[h][3] for x in s], "{:.2f}") for h in (1.0, 2.0))
    nees = " / ".join(span([x[h][4] for x in s], "{:.1f}") for h in (1.0, 2.0))
    return f"{cells[0]} | {cells[1]} | {cov} | {nees}"


def main():
    args = block_args(__doc__)
    with tempfile.TemporaryDirectory() as tmp:
        calibrations = [
            ("calibration.mcap (60 s: smoothed, steps, steps)",
             os.path.join(LOGS, "calibration.mcap")),
            ("40 s: smoothed, steps", drive(tmp, "calibration_40", 11, ["smoothed", "steps"])),
        ]
        steps = [drive(tmp, f"steps_{s}", s, ["steps"]) for s in STEPS_SEEDS]
        smooth = [drive(tmp, f"smooth_{s}", s, ["smoothed"]) for s in SMOOTH_SEEDS]
        rows = []
        for label, bag in calibrations:
            out = os.path.join(tmp, "calibrated.yaml")
            cal = cli("calibrate", "--scene", ml.SCENE, "--bag", bag, "--out", out)
            values = {p["name"]: p["value"] for p in cal["parameters"]}
            pn = cal["process_noise"]
            fitted = (f"r {values['rolling_radius']:.5f} m, track {1e3 * values['track_offset']:+.1f}"
                      f" mm + {1e3 * values['track_turn_gain']:.2f} mm/(rad/s)² · ω², sideways "
                      f"creep {1e3 * values['lateral_creep']:.2f} (mm/s)/N, traction "
                      f"{values['traction_torque']:.2f} N·m; σ_τ "
                      f"{pn['effort_noise']:.3g}, σ_k {pn['saturation_slip']:.2g}, "
                      f"σ_t {pn['saturation_turn']:.2g}, σ_s {pn['slip_noise']:.2g}")
            groups = [("validation_smooth", [os.path.join(LOGS, "validation_smooth.mcap")]),
                      ("validation_steps", [os.path.join(LOGS, "validation_steps")]),
                      (f"{len(smooth)} fresh smoothed", smooth),
                      (f"{len(steps)} fresh steps", steps)]
            for name, bags in groups:
                rows.append(f"| {label} | {fitted} | {name} | {group_cells(out, bags)} |")
                label = fitted = ""
    lines = ["<!-- written by .venv-logs/bin/python tools/logs/step_spread.py: do not edit -->",
             "",
             "| calibrated on | fitted | scored on | 1 s: worst position, worst / median yaw | "
             "2 s: the same | coverage p95 at 1 s / 2 s | mean NEES at 1 s / 2 s |",
             "|---|---|---|---|---|---|---|", *rows]
    body = "\n".join(lines)
    emit_block(args.print, DOC, BEGIN, END, body)


if __name__ == "__main__":
    main()
