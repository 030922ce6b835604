"""The floating-base soft-floor scene calibrated as a team would calibrate it, and how far that
calibration carries.

    .venv-logs/bin/python tools/logs/soft_floor_table.py [--print]

Calibrates params/mobile_manipulator_soft_floor.yaml (the robot as built, on a soft floor that
lets it pitch onto its caster and skid) on the bundled calibration.mcap with the CLI's defaults,
then scores it by `evaluate` against the simulator's true pose on the two bundled validation
drives and on step_spread.py's fresh drives (make_logs' generator, seeds no bundled drive uses).
Writes docs/logs.md's block between its `soft_floor:begin` / `soft_floor:end` markers
(`--print`: to stdout instead): the fit's run time on this machine's cores, the fitted values
and noise, and the figures per drive.
"""

import os
import sys
import tempfile
import textwrap

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.dirname(HERE))
import make_logs as ml  # noqa: E402
from doc_block import block_args, emit_block  # noqa: E402
from step_spread import (LOGS, SMOOTH_SEEDS, STEPS_SEEDS, cli, drive,  # noqa: E402
                         group_cells)

DOC = os.path.join(ml.REPO, "docs", "logs.md")
BEGIN = "<!-- soft_floor:begin -->"
END = "<!-- soft_floor:end -->"
SCENE = os.path.join(ml.REPO, "params", "mobile_manipulator_soft_floor.yaml")


def fitted_values(cal):
    """The fitted parameters, each with its standard error and the scene's value."""
    out = []
    for p in cal["parameters"]:
        if p["fitted"]:
            unit = "" if p["unit"] == "1" else f" {p['unit']}"
            out.append(f"{p['name']} {p['value']:.5g} ± {p['std_error']:.2g}{unit} "
                       f"(scene {p['scene_value']:.4g})")
    return ", ".join(out)


def main():
    args = block_args(__doc__)
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "calibrated.yaml")
        cal = cli("calibrate", "--scene", SCENE, "--bag", os.path.join(LOGS, "calibration.mcap"),
                  "--out", out)
        steps = [drive(tmp, f"steps_{s}", s, ["steps"]) for s in STEPS_SEEDS]
        smooth = [drive(tmp, f"smooth_{s}", s, ["smoothed"]) for s in SMOOTH_SEEDS]
        groups = [("validation_smooth", [os.path.join(LOGS, "validation_smooth.mcap")]),
                  ("validation_steps", [os.path.join(LOGS, "validation_steps")]),
                  (f"{len(smooth)} fresh smoothed", smooth),
                  (f"{len(steps)} fresh steps", steps)]
        rows = [f"| {name} | {group_cells(out, bags)} |" for name, bags in groups]
    pn = cal["process_noise"]
    head = (f"Calibrated on calibration.mcap (60 s) in {cal['run_time_s']:.0f} s on "
            f"{os.cpu_count()} cores, {cal['replays']} replays: {fitted_values(cal)}; yaw slip "
            f"noise {pn['slip_noise']:.2g} rad/√s, the skid's slide {pn['saturation_slip']:.2g} "
            f"m/s and turn {pn['saturation_turn']:.2g} rad/s. Against the true pose:")
    lines = ["<!-- written by .venv-logs/bin/python tools/logs/soft_floor_table.py: do not edit "
             "-->", "", textwrap.fill(head, width=96, break_on_hyphens=False), "",
             "| scored on | 1 s: worst position, worst / median yaw | 2 s: the same | "
             "coverage p95 at 1 s / 2 s | mean NEES at 1 s / 2 s |",
             "|---|---|---|---|---|", *rows]
    emit_block(args.print, DOC, BEGIN, END, "\n".join(lines))


if __name__ == "__main__":
    main()
