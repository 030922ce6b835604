"""How the simulated robot's wide tyres scrub in steady turns: the track it turns as if it had.

    .venv-logs/bin/python tools/logs/scrub_sweep.py [--print]

The robot of make_logs.py (MuJoCo, its PI wheel controllers at 1 kHz) is commanded to a steady
turn (v, ω), ramped over 1 s and held; over the third second the chassis's yaw rate Ω and the
wheels' rates φ̇_L, φ̇_R are averaged. With the effective rolling radius r' measured the same way
on a straight run (v / mean wheel rate), the half-track the robot turns as if it had is
b' = r' (φ̇_R − φ̇_L) / (2 Ω); its widening s = b' − b (b = 0.17 m, the URDF's) is what a rolling
contact's `axle_offset` stands for, and s/Ω² what its `axle_offset_turn_gain` does. In the
arcs the chassis also slides outward at v_y (base_footprint's sideways velocity): the tyres give
the turn's centripetal force, about M v Ω (M the robot's mass), by creeping sideways; the creep
per newton on each of the two wheels, c' = −2 v_y/(M v Ω), is what `lateral: tyre` with its
tyre's s₀/(μ N) stands for. Writes
docs/contacts.md's table between its `scrub_sweep:begin` / `scrub_sweep:end` markers
(`--print`: to stdout instead).
"""

import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.dirname(HERE))
import make_logs as ml  # noqa: E402
from doc_block import block_args, emit_block  # noqa: E402

DOC = os.path.join(ml.REPO, "docs", "contacts.md")
BEGIN = "<!-- scrub_sweep:begin -->"
END = "<!-- scrub_sweep:end -->"
HALF_TRACK_M = 0.17
TURN_RATES = (0.2, 0.4, 0.6, 0.8, 1.0, 1.2, 1.4, 1.6, 2.0)
SPEEDS = (0.0, 0.3)


def steady(v, w):
    """Mean (forward speed [m/s], yaw rate [rad/s], left and right wheel rates [rad/s],
    sideways speed [m/s]) over the third second of a turn ramped to (v, ω) over the first, and
    the robot's mass [kg]."""
    robot = ml.Robot(ml.SCENE, ml.URDF)
    for _ in range(int(0.5 / ml.CONTROL_PERIOD_S)):
        robot.tick((0.0, 0.0))
    acc = []
    for k in range(int(3.0 / ml.CONTROL_PERIOD_S)):
        t = k * ml.CONTROL_PERIOD_S
        f = min(1.0, t / 1.0)
        robot.tick((v * f, w * f))
        if t > 2.0:
            _, twist = robot.base()
            acc.append((twist[0], twist[2], robot.d.qvel[robot.joints[0][2]],
                        robot.d.qvel[robot.joints[1][2]], twist[1]))
    return np.mean(acc, axis=0), float(np.sum(robot.m.body_mass))


def main():
    args = block_args(__doc__)
    (v, _, left, right, _), mass = steady(0.4, 0.0)
    r_eff = v / ((left + right) / 2)
    rows = []
    for w in TURN_RATES:
        cells = []
        for speed in SPEEDS:
            (forward, turn, left, right, sideways), _ = steady(speed, w)
            widening = r_eff * (right - left) / (2 * turn) - HALF_TRACK_M
            cells.append(f"{turn:.3f} rad/s, s {1e3 * widening:+.1f} mm, "
                         f"s/Ω² {1e3 * widening / turn ** 2:.1f} mm/(rad/s)²")
        creep = -2 * sideways / (mass * forward * turn)
        cells.append(f"{1e3 * sideways:+.2f} mm/s, {1e3 * creep:.2f} (mm/s)/N")
        rows.append(f"| {w:.1f} | " + " | ".join(cells) + " |")
    body = "\n".join([
        "<!-- written by .venv-logs/bin/python tools/logs/scrub_sweep.py: do not edit -->",
        "",
        f"Effective rolling radius on a straight run at 0.4 m/s: r' = {r_eff:.5f} m; "
        f"the robot's mass M = {mass:.2f} kg.",
        "",
        "| commanded ω [rad/s] | in place (v = 0): Ω, widening s, s/Ω² | at v = 0.3 m/s: the same "
        "| at v = 0.3 m/s: sideways speed v_y, creep c' |",
        "|---|---|---|---|",
        *rows,
    ])
    emit_block(args.print, DOC, BEGIN, END, body)


if __name__ == "__main__":
    main()
