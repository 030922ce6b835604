"""What a perfect model leaves: the simulator that wrote the bundled drives (make_logs.py) predicts
its own future from the starts `evaluate` uses, and is scored as `evaluate` scores a prediction.
The model is then exact; what remains is what the start does not know.

    .venv-logs/bin/python tools/logs/model_floor.py [--print]

Starts as `evaluate` takes them (every 0.5 s on an odometry stamp, from the first odometry after
the first joint states; the recorded commands from there), each predicted three ways by MuJoCo itself:

- `measured`: the simulator's true state with what the logs measure replaced by the logged
  values — the base's planar pose and twist by /odom's (noise σ 2 mm, 2 mrad, 0.01 m/s,
  0.01 rad/s), the joints by the last /joint_states (15 ms old, σ 1e-4 rad, 1e-3 rad/s); the
  chassis's true height, roll, pitch and their rates, and the wheel controllers' true integrals;
- `as the node starts`: the same, but what no log holds taken as a predictor takes it — the
  chassis at its rest height, roll and pitch, not rocking, and the wheel controllers' integrals at
  zero (a prediction starts its controllers afresh);
- `as the node starts, true integrals`: that start with the controllers' true integrals (what
  `--controllers-from-efforts` infers from the logged efforts, for a model whose wheels meet
  the simulator's resistances).

Scored against the simulator's true pose at t0 + h: position error |(Δx, Δy)| and |Δyaw|, median
and worst over the starts: of each bundled drive, and as ranges over five fresh raw-step drives
(step_spread.py's, from make_logs' generator with seeds no bundled drive uses). Writes
docs/logs.md's table between its `model_floor:begin` / `model_floor:end` markers (`--print`: to
stdout instead).
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
from step_spread import STEPS_SEEDS, fresh_drive, span  # noqa: E402

DOC = os.path.join(ml.REPO, "docs", "logs.md")
BEGIN = "<!-- model_floor:begin -->"
END = "<!-- model_floor:end -->"
EVERY_TICKS = 500
HORIZONS_S = (0.25, 0.5, 1.0, 2.0)
VARIANTS = ("measured", "node", "node_integrals")


def rot(quat):
    r = np.zeros(9)
    mujoco.mju_quat2Mat(r, quat)
    return r.reshape(3, 3)


def quat_of(r):
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, r.reshape(9))
    return q


def rot_z(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def set_base(robot, pose, twist, tilt, omega_tilt, height, v_up_body):
    """Put base_footprint at planar pose (x, y, yaw) with body-frame planar twist (vx, vy, ωz):
    the chassis's orientation Rz(yaw)·tilt, base_footprint's height `height`, its roll and
    pitch rates `omega_tilt` (body frame) and its vertical velocity `v_up_body`."""
    x, y, yaw = pose
    vx, vy, wz = twist
    r = rot_z(yaw) @ tilt
    offset = r @ np.array([0.0, 0.0, -robot.base_height])
    foot = np.array([x, y, height])
    robot.d.qpos[0:3] = foot - offset
    robot.d.qpos[3:7] = quat_of(r)
    omega_body = np.array([omega_tilt[0], omega_tilt[1], wz])
    v_foot = r @ np.array([vx, vy, v_up_body])
    robot.d.qvel[0:3] = v_foot - np.cross(r @ omega_body, offset)
    robot.d.qvel[3:6] = omega_body


def planar_parts(robot):
    """(tilt = Rz(−yaw)·R, body roll/pitch rates, base_footprint's height, its body-frame
    vertical velocity) of the simulator's current state."""
    r = rot(robot.d.qpos[3:7])
    yaw = math.atan2(r[1, 0], r[0, 0])
    tilt = rot_z(-yaw) @ r
    offset = r @ np.array([0.0, 0.0, -robot.base_height])
    foot = robot.d.qpos[0:3] + offset
    omega_body = robot.d.qvel[3:6].copy()
    v_foot = robot.d.qvel[0:3] + np.cross(r @ omega_body, offset)
    return tilt, omega_body[:2].copy(), foot[2], (r.T @ v_foot)[2]


def run_drive(drive):
    """[(horizon, variant, position error, yaw error)] over the drive's starts."""
    starts, cmds, truth = [], [], {}
    last_joints = None
    rest = None
    cmd = (0.0, 0.0)
    for k, robot, odom, joints, published in ml.drive_ticks(drive, ml.SCENE, ml.URDF):
        if rest is None:
            rest = planar_parts(robot)  # settled, standing still
            template = robot
        if published is not None:
            cmd = published
        cmds.append(cmd)
        if joints is not None:
            last_joints = joints
        if odom is not None:
            truth[k] = odom[0]
            if last_joints is not None and (k - ml.ODOM_PERIOD_TICKS) % EVERY_TICKS == 0:
                # The drive's command lag (command_lag.mcap) is the commands' before the start,
                # which a predictor has as exactly as the simulator: every variant keeps it.
                starts.append((k, mujoco.MjData(robot.m), odom, last_joints, list(robot.integral),
                               robot.lagged))
                mujoco.mj_copyData(starts[-1][1], robot.m, robot.d)
    out = []
    sim = template
    for k0, state, odom, joints, integral, lagged in starts:
        _, _, noisy_pose, noisy_twist = odom
        for variant in VARIANTS:
            mujoco.mj_copyData(sim.d, sim.m, state)
            sim.lagged = lagged
            names, q, v, _ = joints
            for (name, iq, iv), qi, vi in zip(sim.joints, q, v):
                sim.d.qpos[iq], sim.d.qvel[iv] = qi, vi
            if variant == "measured":
                tilt, omega_tilt, height, v_up = planar_parts(sim)
                sim.integral = list(integral)
            else:
                tilt, omega_tilt, height, v_up = rest[0], (0.0, 0.0), rest[2], 0.0
                sim.integral = list(integral) if variant == "node_integrals" else [0.0, 0.0]
            set_base(sim, noisy_pose, noisy_twist, tilt, omega_tilt, height, v_up)
            mujoco.mj_forward(sim.m, sim.d)
            # evaluate's reference is the last one at or before t0 + h, and the prediction is
            # taken at its stamp: the step where it was published.
            ends = {}
            for h in HORIZONS_S:
                k_end = k0 + int(round(h / ml.CONTROL_PERIOD_S))
                ends[k_end - k_end % ml.ODOM_PERIOD_TICKS - k0] = h
            for step in range(1, max(ends) + 1):
                if k0 + step >= len(cmds):
                    break
                sim.tick(cmds[k0 + step - 1])
                if step in ends:
                    ref = k0 + step
                    x, y, yaw = sim.base()[0]
                    tx, ty, tyaw = truth[ref]
                    dyaw = (yaw - tyaw + math.pi) % (2 * math.pi) - math.pi
                    out.append((ends[step], variant, math.hypot(x - tx, y - ty), abs(dyaw)))
    return out


def main():
    args = block_args(__doc__)
    lines = ["<!-- written by .venv-logs/bin/python tools/logs/model_floor.py: do not edit -->",
             "",
             "| drive | start | " + " | ".join(f"{h:g} s" for h in HORIZONS_S) + " |",
             "|---|---|" + "---|" * len(HORIZONS_S)]
    label = {"measured": "measured (true tilt and integrals)", "node": "as the node starts",
             "node_integrals": "as the node starts, true integrals"}
    fresh = [fresh_drive(f"steps_{s}", s, ["steps"]) for s in STEPS_SEEDS]
    groups = [(d.name, [d]) for d in ml.DRIVES] + [(f"{len(fresh)} fresh steps", fresh)]
    for name, drives in groups:
        runs = [run_drive(d) for d in drives]
        for variant in VARIANTS:
            cells = []
            for h in HORIZONS_S:
                stats = []
                for rows in runs:
                    p = [r[2] for r in rows if r[0] == h and r[1] == variant]
                    y = [r[3] for r in rows if r[0] == h and r[1] == variant]
                    stats.append((1e3 * np.median(p), 1e3 * max(p), 1e3 * np.median(y),
                                  1e3 * max(y)))
                col = [span([s[i] for s in stats], f) for i, f in
                       enumerate(("{:.1f}", "{:.1f}", "{:.1f}", "{:.0f}"))]
                cells.append(f"{col[0]} / {col[1]} mm, {col[2]} / {col[3]} mrad")
            lines.append(f"| {name} | {label[variant]} | " + " | ".join(cells) + " |")
        print("\n".join(lines[-len(VARIANTS):]), file=sys.stderr)
    emit_block(args.print, DOC, BEGIN, END, "\n".join(lines))


if __name__ == "__main__":
    main()
