#!/usr/bin/env python3
"""Calibrates the suite's scene on a drive that follows its commands through a first-order lag
(tests/data/logs/command_lag.mcap, make_logs.py: τ 0.15 s, raw steps) with the lag
(`--fit default,command_lag`: the scene declares none, so calibrate declares one and starts it
where the drive's response puts it) and without it, and writes docs/logs.md's block between its
`command_lag:begin` / `command_lag:end` markers: the fitted lag and what moved with it, and
`evaluate` against the simulator's true pose on both lagged drives.

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


def fitted(cal, name):
    return next(p for p in cal["parameters"] if p["name"] == name)


def correlation(cal, a, b):
    return next(c["value"] for c in cal["correlations"] if set(c["between"]) == {a, b})


def main():
    args = block_args(__doc__)
    bag = os.path.join(LOGS, "command_lag.mcap")
    rows, nees = [], None
    with tempfile.TemporaryDirectory() as tmp:
        with_lag, without = os.path.join(tmp, "with.yaml"), os.path.join(tmp, "without.yaml")
        cal = cli("calibrate", "--scene", SCENE, "--bag", bag, "--fit", "default,command_lag",
                  "--out", with_lag)
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
                if drive == "command_lag_smooth.mcap" and label == "calibrated with the lag":
                    nees = next(h["nees_mean"] for h in hs if h["horizon_s"] == 1.0)
    lag, start = fitted(cal, "command_lag"), cal["command_lag_start"]["value_s"]
    mass, torque = fitted(cal, "base_mass"), fitted(cal, "traction_torque")
    head = (f"Fitted lag: {lag['value']:.4f} ± {lag['std_error']:.4f} s (started at {start:.3f} "
            f"s, the lag the drive's response shows with the scene as given; the simulator's "
            f"0.15 s), in {cal['run_time_s']:.0f} s. The lag's estimate correlates with the "
            f"traction torque's ({correlation(cal, 'command_lag', 'traction_torque'):+.2f}); "
            f"the fit makes the chassis {mass['value'] - mass['scene_value']:.1f} ± "
            f"{mass['std_error']:.1f} kg heavier and the torque {torque['value']:.1f} N·m. "
            f"The smoothed drive's mean NEES at 1 s: {nees:.1f}. Position / yaw error against "
            "the true pose, median / worst, and the coverage p95 at 1 s / 2 s:")
    lines = ["<!-- written by python3 tools/logs/command_lag_table.py: do not edit -->", "",
             textwrap.fill(head, width=96, break_on_hyphens=False), "",
             "| drive | scene | 0.25 s | 0.5 s | 1 s | 2 s | coverage p95 at 1 s / 2 s |",
             "|---|---|---|---|---|---|---|", *rows]
    emit_block(args.print, DOC, BEGIN, END, "\n".join(lines))


if __name__ == "__main__":
    main()
