#!/usr/bin/env python3
"""Calibrates the suite's scene on a drive that follows its commands through a first-order lag
(tests/data/logs/command_lag.mcap, make_logs.py: τ 0.15 s, raw steps) with the lag declared
(`actuators.diff_drive.command_lag`, a guess of 0.05 s to start from) and without it, and writes
docs/logs.md's table between its `command_lag:begin` / `command_lag:end` markers: the fitted
lag, and `evaluate` against the simulator's true pose on both lagged drives.

    python3 tools/logs/command_lag_table.py [--print]
"""
import os
import sys
import tempfile
import textwrap

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from doc_block import block_args, emit_block  # noqa: E402
from calibration_table import LOGS, ROOT, SCENE, cell, cli, evaluate  # noqa: E402

DOC = os.path.join(ROOT, "docs", "logs.md")
BEGIN = "<!-- command_lag:begin -->"
END = "<!-- command_lag:end -->"
GUESS_S = 0.05
KI = "    ki: 20.0                     # [N·m/rad]\n"


def lagged_scene(tmp):
    """The suite's scene with a command lag of GUESS_S declared, written into `tmp`."""
    with open(SCENE) as f:
        text = f.read()
    if KI not in text:
        sys.exit(f"{SCENE}: the diff drive's ki line moved")
    text = text.replace(KI, f"{KI}    command_lag: {GUESS_S}\n")
    text = text.replace("urdf: ../urdf/", f"urdf: {os.path.join(ROOT, 'urdf')}/")
    path = os.path.join(tmp, "lagged.yaml")
    with open(path, "w") as f:
        f.write(text)
    return path


def main():
    args = block_args(__doc__)
    bag = os.path.join(LOGS, "command_lag.mcap")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        with_lag, without = os.path.join(tmp, "with.yaml"), os.path.join(tmp, "without.yaml")
        cal = cli("calibrate", "--scene", lagged_scene(tmp), "--bag", bag, "--out", with_lag)
        cli("calibrate", "--scene", SCENE, "--bag", bag, "--out", without)
        scenes = (("scene", SCENE), ("calibrated without a lag", without),
                  ("calibrated with the lag", with_lag))
        for drive in ("command_lag.mcap", "command_lag_smooth.mcap"):
            for label, scene in scenes:
                hs = evaluate(scene, drive)["horizons"]
                cov = " / ".join(f"{h['coverage']['p95']:.2f}" for h in hs
                                 if h["horizon_s"] in (1.0, 2.0))
                rows.append(f"| {drive.split('.')[0]} | {label} | "
                            + " | ".join(cell(h) for h in hs) + f" | {cov} |")
    lag = next(p for p in cal["parameters"] if p["name"] == "command_lag")
    head = (f"Fitted lag: {lag['value']:.4f} ± {lag['std_error']:.4f} s (from {GUESS_S} s; the "
            f"simulator's 0.15 s), in {cal['run_time_s']:.0f} s. Position / yaw error against "
            "the true pose, median / worst, and the coverage p95 at 1 s / 2 s:")
    lines = ["<!-- written by python3 tools/logs/command_lag_table.py: do not edit -->", "",
             textwrap.fill(head, width=96, break_on_hyphens=False), "",
             "| drive | scene | 0.25 s | 0.5 s | 1 s | 2 s | coverage p95 at 1 s / 2 s |",
             "|---|---|---|---|---|---|---|", *rows]
    emit_block(args.print, DOC, BEGIN, END, "\n".join(lines))


if __name__ == "__main__":
    main()
