"""Where the bundled test drives leave a planar model's assumptions: replays each drive of
make_logs.py in MuJoCo (the same robot, controllers, command plans and seeds) and reports, from
the simulator's contact forces, how often and how long the wheels lose the floor and what carries
the robot then (the caster behind, the anti-tip skid in front), and how far the chassis pitches.

    .venv-logs/bin/python tools/logs/contact_probe.py [--print]

writes docs/logs.md's table between its `contact_probe:begin` / `contact_probe:end` markers
(`--print`: to stdout instead). A wheel counts as off the floor below UNLOADED_N of normal force
(its static share is ~62 N).
"""

import math
import os
import sys

import mujoco
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.dirname(HERE))
import make_logs as ml  # noqa: E402
from doc_block import block_args, emit_block  # noqa: E402

DOC = os.path.join(ml.REPO, "docs", "logs.md")
BEGIN = "<!-- contact_probe:begin -->"
END = "<!-- contact_probe:end -->"

UNLOADED_N = 5.0
WHEELS = ("left_wheel_tyre", "right_wheel_tyre")


def normal_forces(m, d):
    """{geom name: normal force [N]} of every geom touching the floor."""
    out = {}
    f = np.zeros(6)
    for i in range(d.ncon):
        c = d.contact[i]
        g1, g2 = m.geom(c.geom1).name, m.geom(c.geom2).name
        if "floor" not in (g1, g2):
            continue
        mujoco.mj_contactForce(m, d, i, f)
        name = g2 if g1 == "floor" else g1
        out[name] = out.get(name, 0.0) + f[0]
    return out


def probe(drive):
    dt = ml.CONTROL_PERIOD_S
    off = {w: 0.0 for w in WHEELS}
    both_off, longest_both, run = 0.0, 0.0, 0.0
    support = {"caster": 0.0, "anti_tip": 0.0}
    max_pitch = 0.0
    for k, robot, _, _, _ in ml.drive_ticks(drive, ml.SCENE, ml.URDF):
        if k == 0:
            continue  # the settled start; every tick's end state from here
        n = normal_forces(robot.m, robot.d)
        unloaded = [n.get(w, 0.0) < UNLOADED_N for w in WHEELS]
        for w, u in zip(WHEELS, unloaded):
            off[w] += dt * u
        run = run + dt if all(unloaded) else 0.0
        both_off += dt * all(unloaded)
        longest_both = max(longest_both, run)
        for s in support:
            support[s] = max(support[s], n.get(s, 0.0))
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, robot.d.qpos[3:7])
        max_pitch = max(max_pitch, abs(math.asin(max(-1.0, min(1.0, -rot[6])))))
    return (f"{100 * off[WHEELS[0]] / drive.duration_s:.1f} / "
            f"{100 * off[WHEELS[1]] / drive.duration_s:.1f}",
            f"{100 * both_off / drive.duration_s:.1f} % / {1e3 * longest_both:.0f} ms",
            f"{support['caster']:.0f} / {support['anti_tip']:.0f} N",
            f"{1e3 * max_pitch:.0f} mrad")


def main():
    args = block_args(__doc__)
    lines = ["<!-- written by .venv-logs/bin/python tools/logs/contact_probe.py: do not edit -->",
             "",
             "| drive | a wheel off the floor [% of the drive, left / right] | both wheels off "
             "[% / longest] | largest push on the caster / anti-tip skid | largest pitch |",
             "|---|---|---|---|---|"]
    for d in ml.DRIVES:
        lines.append(f"| {d.name} | " + " | ".join(probe(d)) + " |")
    emit_block(args.print, DOC, BEGIN, END, "\n".join(lines))


if __name__ == "__main__":
    main()
