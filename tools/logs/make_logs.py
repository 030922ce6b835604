"""Recorded test logs of the bundled mobile manipulator from an independent simulator (MuJoCo),
written as rosbag2 MCAP by a real writer (mcap-ros2-support): tests/data/logs/.

    .venv-logs/bin/python tools/logs/make_logs.py [OUT_DIR]     (tools/logs/setup_venv.sh first)

The robot is rebuilt from its URDF with what the scene does not know (robot_mjcf.py) and driven
at 1 kHz by the scene's own controllers, read from params/suite_mobile_manipulator.yaml: the
diff drive's wheel-speed PI (torque clamped to the URDF effort, no integration while clamped)
and the arm's PD, held at the scene's initial arm pose. Each drive follows phases of ~20 s of
Nav2-like cmd_vel at 20 Hz (arcs, spins, reverses, stops), smoothed to 1 m/s² and 2 rad/s² as a
velocity smoother would, or raw steps: the validation drives one phase each, the calibration
drive a smoothed phase and then a phase of steps. One shorter drive carries a payload on the
tool that the scene is not told of (payload_3kg.mcap: 3 kg at tool0, robot_mjcf.py), its arm
held with the tool above the wheel axle (shoulder pitch −0.1, elbow −0.15 rad), where it loads
the shoulder without tipping the robot off its wheels (at rest ~61 N on each wheel, ~34 N on
the caster). Another runs on a slippery floor (slippery_floor.mcap: the tyres' μ 0.1), and one
pair on a drive that follows its commands late (command_lag.mcap, raw steps, and
command_lag_smooth.mcap: a first-order lag of 0.15 s between cmd_vel and the wheel controllers,
as a motor controller's own velocity loop gives). Topics:

    /cmd_vel            geometry_msgs/Twist (TwistStamped in validation_steps), 20 Hz
    /odom               nav_msgs/Odometry, 50 Hz: the true base pose and twist plus white noise
                        (σ 2 mm, 2 mrad, 0.01 m/s, 0.01 rad/s) and a covariance that states it
    /joint_states       sensor_msgs/JointState, 50 Hz, 5 ms after /odom: positions and
                        velocities plus noise (σ 1e-4 rad, 1e-3 rad/s), the applied efforts
    /ground_truth/odom  nav_msgs/Odometry, 50 Hz: the simulator's true pose, zero covariance

Deterministic: seeded noise and command plans, single-threaded MuJoCo.
"""

import math
import os
import sys
from dataclasses import dataclass

import mujoco
import numpy as np
import yaml
from mcap_ros2.writer import Writer

import msgdefs
from robot_mjcf import ARM_JOINTS, TYRE_MU, mjcf

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.normpath(os.path.join(HERE, "..", ".."))
# The scene whose controllers drive the simulated robot, and the robot's URDF.
SCENE = os.path.join(REPO, "params", "suite_mobile_manipulator.yaml")
URDF = os.path.join(REPO, "urdf", "mobile_manipulator.urdf")

# The scene's controllers (params/suite_mobile_manipulator.yaml, `actuators:`), read by
# read_scene_controllers so a change there reaches the logs.
CONTROL_PERIOD_S = 0.001
SIM_SUBSTEPS = 2
ODOM_PERIOD_TICKS = 20
JOINT_STATES_OFFSET_TICKS = 5
CMD_PERIOD_TICKS = 50
SETTLE_S = 1.0
T0_NS = 1_700_000_000 * 10**9
SIGMA_POS, SIGMA_YAW, SIGMA_V, SIGMA_W = 0.002, 0.002, 0.01, 0.01
SIGMA_JOINT_Q, SIGMA_JOINT_V = 1e-4, 1e-3
ACCEL_LIMITS = (1.0, 2.0)  # m/s², rad/s²


@dataclass
class Drive:
    name: str
    seed: int
    # ((commands, duration_s), …) in order: "smoothed" (a velocity smoother's ramps) or "steps"
    # (raw steps).
    phases: tuple
    stamped: bool
    bag_directory: bool
    payload_kg: float = 0.0
    arm_pose: dict = None  # {joint: rad} the arm's PD holds instead of the scene's initial pose
    tyre_mu: float = TYRE_MU  # the tyres' grip on the floor (robot_mjcf.py)
    command_lag_s: float = 0.0  # τ of a first-order lag between cmd_vel and the wheels' PI

    @property
    def duration_s(self):
        return sum(d for _, d in self.phases)


DRIVES = [
    # A calibration drive excites what a team wants fitted: after a smoothed third it steps the
    # commands as a planner without a smoother would, up to the tyres' grip, for twice as long:
    # the skids are what the process noise's saturation bias is sized on.
    Drive("calibration", seed=11, phases=(("smoothed", 20.0), ("steps", 20.0), ("steps", 20.0)),
          stamped=False, bag_directory=False),
    Drive("validation_smooth", seed=22, phases=(("smoothed", 20.0),), stamped=False,
          bag_directory=False),
    Drive("validation_steps", seed=33, phases=(("steps", 20.0),), stamped=True,
          bag_directory=True),
    Drive("payload_3kg", seed=44, phases=(("smoothed", 10.0),), stamped=False,
          bag_directory=False, payload_kg=3.0,
          arm_pose={"arm_shoulder_yaw": 0.0, "arm_shoulder_pitch": -0.1, "arm_elbow": -0.15,
                    "arm_wrist": 0.0}),
    # A slippery floor (wet or dusty polish: the tyres' μ 0.1 where the scene's rolling
    # contacts hold whatever it takes): the smoothed drive's 1 m/s² and its turns need more
    # grip than the floor gives, so the wheels spin and the base lags and slides.
    Drive("slippery_floor", seed=55, phases=(("smoothed", 10.0),), stamped=False,
          bag_directory=False, tyre_mu=0.1),
    # A drive whose motor controllers follow their commands through a first-order lag the
    # scene does not know; raw steps, so that the lag shows at every one.
    Drive("command_lag", seed=66, phases=(("steps", 20.0),), stamped=False,
          bag_directory=False, command_lag_s=0.15),
    # The same robot on another plan, smoothed: what a calibration on the drive above is
    # scored on.
    Drive("command_lag_smooth", seed=67, phases=(("smoothed", 10.0),), stamped=False,
          bag_directory=False, command_lag_s=0.15),
]


def read_scene_controllers(path):
    """The diff drive (r, b, kp, ki) and the arm's PD gains and initial pose of the scene."""
    with open(path) as f:
        scene = yaml.safe_load(f)
    dd = scene["actuators"]["diff_drive"]
    pd = {c["joint"]: (c["kp"], c["kd"]) for c in scene["actuators"]["position"]}
    q0 = scene["initial_state"]["q"]
    arm_q0 = {j: q0.get(j, 0.0) for j in ARM_JOINTS}
    return (dd["wheel_radius"], dd["wheel_separation"], dd["kp"], dd["ki"]), pd, arm_q0


def phase_plan(rng, duration):
    """Targets (t_start [s], v [m/s], ω [rad/s]) of a Nav2-like drive: every kind of motion in a
    seeded order with seeded magnitudes, a stop at the end."""
    kinds = ["straight", "arc", "spin", "reverse", "stop", "arc", "spin", "straight", "arc"]
    rng.shuffle(kinds)
    t, plan = 0.5, [(0.0, 0.0, 0.0)]
    for kind in kinds:
        sign = rng.choice([-1.0, 1.0])
        v, w = {
            "straight": (rng.uniform(0.3, 0.6), 0.0),
            "arc": (rng.uniform(0.2, 0.5), sign * rng.uniform(0.4, 1.2)),
            "spin": (0.0, sign * rng.uniform(0.8, 1.5)),
            "reverse": (-rng.uniform(0.15, 0.3), sign * rng.uniform(0.0, 0.3)),
            "stop": (0.0, 0.0),
        }[kind]
        plan.append((t, v, w))
        t += rng.uniform(1.4, 2.4)
        if t > duration - 1.5:
            break
    plan.append((t, 0.0, 0.0))
    return plan


def command_plan(rng, phases):
    """The drive's targets (t_start [s], v [m/s], ω [rad/s], raw), phase after phase; raw: the
    command steps straight to the target (else a smoother ramps it)."""
    plan, start = [], 0.0
    for commands, duration in phases:
        for t, v, w in phase_plan(rng, duration):
            plan.append((start + t, v, w, commands == "steps"))
        start += duration
    return plan


def target_at(plan, t):
    """(v, ω, raw) of the plan's segment in force at t."""
    return next(p[1:] for p in reversed(plan) if p[0] <= t + 1e-9)


def smooth(prev, target, dt):
    """A velocity smoother's step: each component moves toward its target at most a·dt."""
    return tuple(p + max(-a * dt, min(a * dt, x - p)) for p, x, a in zip(prev, target, ACCEL_LIMITS))


class Robot:
    """The MuJoCo model and its controllers, ticked at the control period."""

    def __init__(self, scene_path, urdf_path, payload_kg=0.0, arm_pose=None, tyre_mu=TYRE_MU,
                 command_lag_s=0.0):
        xml, self.effort, self.wheel_radius, self.base_height = mjcf(
            urdf_path, CONTROL_PERIOD_S / SIM_SUBSTEPS, payload_kg, tyre_mu)
        self.m = mujoco.MjModel.from_xml_string(xml)
        self.d = mujoco.MjData(self.m)
        (self.r, self.b, self.kp, self.ki), self.pd, self.arm_q0 = read_scene_controllers(scene_path)
        self.arm_q0.update(arm_pose or {})
        names = ["left_wheel_joint", "right_wheel_joint", *ARM_JOINTS]
        self.joints = [(n, self.m.joint(n).qposadr[0], self.m.joint(n).dofadr[0]) for n in names]
        self.integral = [0.0, 0.0]
        # The lagged command (v, ω) and the factor it keeps of its distance to the command per
        # tick: the lag's exact discrete form under a command held over the tick.
        self.lagged = (0.0, 0.0)
        self.lag_keep = math.exp(-CONTROL_PERIOD_S / command_lag_s) if command_lag_s > 0 else 0.0
        self.tau = np.zeros(len(names))
        self.d.qpos[2] = self.wheel_radius
        for n, iq, _ in self.joints:
            if n in self.arm_q0:
                self.d.qpos[iq] = self.arm_q0[n]
        mujoco.mj_forward(self.m, self.d)

    def tick(self, cmd):
        """One control tick under cmd = (v, ω), then the physics to the next tick."""
        if self.lag_keep > 0.0:
            v, w = self.lagged
            self.lagged = tuple(c + (x - c) * self.lag_keep for x, c in zip(self.lagged, cmd))
        else:
            v, w = cmd
        targets = [(v - w * self.b / 2) / self.r, (v + w * self.b / 2) / self.r]
        for k in range(2):
            name, _, iv = self.joints[k]
            e = targets[k] - self.d.qvel[iv]
            raw = self.kp * e + self.ki * (self.integral[k] + e * CONTROL_PERIOD_S)
            if abs(raw) <= self.effort[name]:
                self.integral[k] += e * CONTROL_PERIOD_S
            self.tau[k] = max(-self.effort[name], min(self.effort[name], raw))
        for k, (name, iq, iv) in enumerate(self.joints[2:], start=2):
            kp, kd = self.pd[name]
            raw = kp * (self.arm_q0[name] - self.d.qpos[iq]) - kd * self.d.qvel[iv]
            self.tau[k] = max(-self.effort[name], min(self.effort[name], raw))
        self.d.qfrc_applied[:] = 0.0
        for k, (_, _, iv) in enumerate(self.joints):
            self.d.qfrc_applied[iv] = self.tau[k]
        for _ in range(SIM_SUBSTEPS):
            mujoco.mj_step(self.m, self.d)

    def base(self):
        """base_footprint's (x, y, yaw) in the world and (vx, vy, ωz) in its own frame."""
        p = self.d.qpos[0:3]
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, self.d.qpos[3:7])
        rot = rot.reshape(3, 3)
        offset = rot @ np.array([0.0, 0.0, -self.base_height])
        foot = p + offset
        omega_body = self.d.qvel[3:6]
        v_foot = self.d.qvel[0:3] + np.cross(rot @ omega_body, offset)
        v_body = rot.T @ v_foot
        yaw = math.atan2(rot[1, 0], rot[0, 0])
        return (foot[0], foot[1], yaw), (v_body[0], v_body[1], omega_body[2])


def stamp(ns):
    return {"sec": ns // 10**9, "nanosec": ns % 10**9}


def odometry(ns, pose, twist, pose_var, twist_var):
    x, y, yaw = pose
    cov = lambda var: [var[i // 6] if i % 7 == 0 else 0.0 for i in range(36)]
    return {
        "header": {"stamp": stamp(ns), "frame_id": "odom"},
        "child_frame_id": "base_footprint",
        "pose": {
            "pose": {
                "position": {"x": x, "y": y, "z": 0.0},
                "orientation": {"x": 0.0, "y": 0.0, "z": math.sin(yaw / 2), "w": math.cos(yaw / 2)},
            },
            "covariance": cov(pose_var),
        },
        "twist": {
            "twist": {
                "linear": {"x": twist[0], "y": twist[1], "z": 0.0},
                "angular": {"x": 0.0, "y": 0.0, "z": twist[2]},
            },
            "covariance": cov(twist_var),
        },
    }


def twist_msg(v, w):
    return {"linear": {"x": v, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": w}}


def drive_ticks(drive, scene_path, urdf_path):
    """Simulate one drive, yielding at every control tick k, before the physics steps to the
    next: (k, robot, odom, joints, cmd). odom = (true pose, true twist, noisy pose, noisy twist)
    at the odometry's ticks, else None; joints = (names, noisy q, noisy v, efforts) at the
    joint states' ticks, else None; cmd = the command published at this tick, else None (the
    robot runs the last one). The noise and the plan come from one generator seeded by the drive."""
    rng = np.random.default_rng(drive.seed)
    plan = command_plan(rng, drive.phases)
    robot = Robot(scene_path, urdf_path, drive.payload_kg, drive.arm_pose, drive.tyre_mu,
                  drive.command_lag_s)
    for _ in range(int(SETTLE_S / CONTROL_PERIOD_S)):
        robot.tick((0.0, 0.0))
    cmd = (0.0, 0.0)
    n_ticks = int(round(drive.duration_s / CONTROL_PERIOD_S))
    for k in range(n_ticks + 1):
        odom = joints = published = None
        if k % ODOM_PERIOD_TICKS == 0:
            pose, tw = robot.base()
            noisy_pose = (pose[0] + rng.normal(0, SIGMA_POS), pose[1] + rng.normal(0, SIGMA_POS),
                          pose[2] + rng.normal(0, SIGMA_YAW))
            noisy_tw = (tw[0] + rng.normal(0, SIGMA_V), tw[1] + rng.normal(0, SIGMA_V),
                        tw[2] + rng.normal(0, SIGMA_W))
            odom = (pose, tw, noisy_pose, noisy_tw)
        if k % ODOM_PERIOD_TICKS == JOINT_STATES_OFFSET_TICKS:
            names = [n for n, _, _ in robot.joints]
            q = [robot.d.qpos[iq] + rng.normal(0, SIGMA_JOINT_Q) for _, iq, _ in robot.joints]
            v = [robot.d.qvel[iv] + rng.normal(0, SIGMA_JOINT_V) for _, _, iv in robot.joints]
            joints = (names, q, v, [float(x) for x in robot.tau])
        if k % CMD_PERIOD_TICKS == 0 and k < n_ticks:
            v, w, raw = target_at(plan, k * CONTROL_PERIOD_S)
            cmd = (v, w) if raw else smooth(cmd, (v, w), CMD_PERIOD_TICKS * CONTROL_PERIOD_S)
            published = cmd
        yield k, robot, odom, joints, published
        if k < n_ticks:
            robot.tick(cmd)


def record(drive, out_path, scene_path, urdf_path):
    """Simulate one drive and write its MCAP file; returns {topic: (type, count)} and the span."""
    # ROS pose covariance over (x, y, z, rot x, rot y, rot z): what the noise is, and large
    # values for what a planar odometry does not measure.
    pose_var = [SIGMA_POS**2, SIGMA_POS**2, 1e6, 1e6, 1e6, SIGMA_YAW**2]
    twist_var = [SIGMA_V**2, SIGMA_V**2, 1e6, 1e6, 1e6, SIGMA_W**2]
    cmd_type = "geometry_msgs/TwistStamped" if drive.stamped else "geometry_msgs/Twist"
    counts = {}
    n_ticks = int(round(drive.duration_s / CONTROL_PERIOD_S))
    with open(out_path, "wb") as f:
        w = Writer(f)
        schemas = {t: w.register_msgdef(msgdefs.schema_name(t), msgdefs.definition(t))
                   for t in ("nav_msgs/Odometry", "sensor_msgs/JointState", cmd_type)}

        def write(topic, datatype, msg, ns):
            w.write_message(topic, schemas[datatype], msg, log_time=ns, publish_time=ns,
                            sequence=counts.get(topic, (None, 0))[1])
            counts[topic] = (msgdefs.schema_name(datatype), counts.get(topic, (None, 0))[1] + 1)

        for k, _, odom, joints, cmd in drive_ticks(drive, scene_path, urdf_path):
            ns = T0_NS + k * 10**6
            if odom is not None:
                pose, tw, noisy_pose, noisy_tw = odom
                write("/ground_truth/odom", "nav_msgs/Odometry",
                      odometry(ns, pose, tw, [0.0] * 6, [0.0] * 6), ns)
                write("/odom", "nav_msgs/Odometry",
                      odometry(ns, noisy_pose, noisy_tw, pose_var, twist_var), ns)
            if joints is not None:
                names, q, v, effort = joints
                write("/joint_states", "sensor_msgs/JointState", {
                    "header": {"stamp": stamp(ns), "frame_id": ""},
                    "name": names, "position": q, "velocity": v, "effort": effort,
                }, ns)
            if cmd is not None:
                msg = twist_msg(*cmd)
                if drive.stamped:
                    msg = {"header": {"stamp": stamp(ns), "frame_id": "base_footprint"}, "twist": msg}
                write("/cmd_vel", cmd_type, msg, ns)
        w.finish()
    return counts, (T0_NS, n_ticks * 10**6)


def metadata_yaml(drive, file_name, counts, span):
    """rosbag2's metadata.yaml (format version 9, as Jazzy writes it) of a one-file bag."""
    start, duration = span
    total = sum(c for _, c in counts.values())
    topics = "".join(
        f"    - topic_metadata:\n        name: {topic}\n        type: {t}\n"
        f"        serialization_format: cdr\n        offered_qos_profiles: []\n"
        f"        type_description_hash: \"\"\n      message_count: {c}\n"
        for topic, (t, c) in counts.items())
    return (
        "rosbag2_bagfile_information:\n  version: 9\n  storage_identifier: mcap\n"
        f"  duration:\n    nanoseconds: {duration}\n"
        f"  starting_time:\n    nanoseconds_since_epoch: {start}\n"
        f"  message_count: {total}\n  topics_with_message_count:\n{topics}"
        "  compression_format: \"\"\n  compression_mode: \"\"\n"
        f"  relative_file_paths:\n    - {file_name}\n"
        f"  files:\n    - path: {file_name}\n      starting_time:\n"
        f"        nanoseconds_since_epoch: {start}\n      duration:\n"
        f"        nanoseconds: {duration}\n      message_count: {total}\n"
        "  custom_data: ~\n  ros_distro: jazzy\n"
    )


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(REPO, "tests", "data", "logs")
    os.makedirs(out, exist_ok=True)
    for drive in DRIVES:
        if drive.bag_directory:
            folder = os.path.join(out, drive.name)
            os.makedirs(folder, exist_ok=True)
            file_name = f"{drive.name}_0.mcap"
            counts, span = record(drive, os.path.join(folder, file_name), SCENE, URDF)
            with open(os.path.join(folder, "metadata.yaml"), "w") as f:
                f.write(metadata_yaml(drive, file_name, counts, span))
            path = folder
        else:
            path = os.path.join(out, f"{drive.name}.mcap")
            counts, _ = record(drive, path, SCENE, URDF)
        print(f"make_logs: {path}: " + ", ".join(f"{t} {c}" for t, (_, c) in counts.items()))


if __name__ == "__main__":
    main()
