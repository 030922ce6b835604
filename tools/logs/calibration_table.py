#!/usr/bin/env python3
"""Calibrates params/suite_mobile_manipulator.yaml on tests/data/logs/calibration.mcap and
writes docs/logs.md's before/after table (between its `calibration:begin` / `calibration:end`
markers): `evaluate` against the simulator's true pose on every bundled drive, with the scene as
it is and as calibrated, and the fitted values.

    python3 tools/logs/calibration_table.py [--print]
"""
import json
import os
import subprocess
import sys
import tempfile
import textwrap

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from doc_block import block_args, emit_block  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
DOC = os.path.join(ROOT, "docs", "logs.md")
BEGIN = "<!-- calibration:begin -->"
END = "<!-- calibration:end -->"
SCENE = os.path.join(ROOT, "params", "suite_mobile_manipulator.yaml")
LOGS = os.path.join(ROOT, "tests", "data", "logs")
DRIVES = ["calibration.mcap", "validation_smooth.mcap", "validation_steps"]
HORIZONS = "0.25,0.5,1,2"


def cli(*args):
    out = subprocess.run(
        ["cargo", "run", "--quiet", "--locked", "-p", "constraint_dynamics_cli",
         "--", *args], cwd=ROOT, check=True, stdout=subprocess.PIPE, text=True)
    return json.loads(out.stdout)


def evaluate(scene, drive):
    return cli("evaluate", "--scene", scene, "--bag", os.path.join(LOGS, drive),
               "--truth-topic", "/ground_truth/odom", "--horizons", HORIZONS)


def cell(h):
    p, y = h["position_error_m"], h["yaw_error_rad"]
    return (f"{1e3 * p['median']:.1f} / {1e3 * p['max']:.1f} mm, "
            f"{1e3 * y['median']:.1f} / {1e3 * y['max']:.0f} mrad")


def main():
    args = block_args(__doc__)
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "calibrated.yaml")
        cal = cli("calibrate", "--scene", SCENE, "--bag", os.path.join(LOGS, DRIVES[0]),
                  "--out", out)
        rows = []
        for drive in DRIVES:
            for label, scene in (("scene", SCENE), ("calibrated", out)):
                ev = evaluate(scene, drive)
                hs = ev["horizons"]
                cov = " / ".join(f"{h['coverage']['p95']:.2f} [{h['coverage']['p95_interval'][0]:.2f}, "
                                 f"{h['coverage']['p95_interval'][1]:.2f}]" for h in hs
                                 if h["horizon_s"] in (1.0, 2.0))
                nees = " / ".join(f"{h['nees_mean']:.3g}" if h["nees_mean"] < 1e3
                                  else f"{h['nees_mean']:.0f}" for h in hs
                                  if h["horizon_s"] in (1.0, 2.0))
                rows.append(f"| {drive.split('.')[0]} | {label} | "
                            + " | ".join(cell(h) for h in hs) + f" | {cov} | {nees} |")
    lines = ["<!-- written by python3 tools/logs/calibration_table.py: do not edit -->", ""]
    lines.append("Fitted on calibration.mcap against its `/odom` "
                 f"({cal['run_time_s']:.0f} s, {cal['replays']} replays of the drive):")
    lines.append("")
    lines.append("| parameter | scene | calibrated | standard error | fitted |")
    lines.append("|---|---|---|---|---|")
    for p in cal["parameters"]:
        se = p.get("std_error")
        lines.append(f"| `{p['name']}` [{p['unit']}] | {p['scene_value']:.5g} | "
                     f"{p['value']:.5g} | {'—' if se is None else f'{se:.2g}'} | "
                     f"{'yes' if p['fitted'] else 'no, confirmed' if p['determined'] else 'no'} |")
    pn = cal.get("process_noise")
    if pn:
        joints = ", ".join(pn["joints"])
        lines.append(f"| effort noise on {joints} [(N·m)/√Hz] | 0 | "
                     f"{pn['effort_noise']:.3g} | — | coverage p95 "
                     f"{pn['unsaturated_coverage_p95']:.2f} of the predictions through no "
                     "saturation (at the fit horizon where it is least) |")
        if pn.get("saturation_slip_coordinates"):
            lines.append(f"| skid slide on {', '.join(pn['saturation_slip_coordinates'])} "
                         f"[m/s] | 0 | {pn['saturation_slip']:.3g} | — | the most likely with "
                         "the turn below |")
        if pn.get("slip_coordinate"):
            lines.append(f"| skid turn on {pn['slip_coordinate']} [rad/s] | 0 | "
                         f"{pn['saturation_turn']:.3g} | — | with the slide, coverage p95 "
                         f"{pn['saturated_coverage_p95']:.2f} of the "
                         f"{pn['saturated_predictions']} predictions through a saturation (the "
                         "same) |")
        if pn.get("slip_coordinate"):
            lines.append(f"| slip noise on {pn['slip_coordinate']} [rad/√s] | 0 | "
                         f"{pn['slip_noise']:.3g} | — | the most likely beside them: log score "
                         f"{pn['log_score']:.2f}, coverage p95 {pn['coverage_p95']:.2f} of all the "
                         "predictions |")
    strong = sorted((c for c in cal.get("correlations", []) if abs(c["value"]) >= 0.5),
                    key=lambda c: -abs(c["value"]))
    if strong:
        text = ("Correlations of the estimates beyond ±0.5 (the drive tells these apart least): "
                + ", ".join(f"`{c['between'][0]}` and `{c['between'][1]}` {c['value']:+.2f}"
                            for c in strong) + ".")
        lines += ["", textwrap.fill(text, width=96, break_on_hyphens=False)]
    lines += ["", "Position / yaw error against the true pose, median / worst, and the coverage "
              "p95 with its 95 % interval and the mean NEES at 1 s / 2 s (χ²(3): 0.95 and 3 "
              "for an exact covariance):", "",
              "| drive | scene | 0.25 s | 0.5 s | 1 s | 2 s | coverage p95 [interval] at 1 s / 2 s | "
              "mean NEES at 1 s / 2 s |",
              "|---|---|---|---|---|---|---|---|", *rows, ""]
    emit_block(args.print, DOC, BEGIN, END, "\n".join(lines))

if __name__ == "__main__":
    main()
