#!/usr/bin/env python3
"""rclpy as a robot's state, a planner reading ~/acceleration_limits and a Nav2 velocity
smoother (nodes/tests/it/suite_envelope_rclpy.rs): the suite runs the floating mobile manipulator
(params/suite_mobile_manipulator_floating.yaml) at 10 Hz with
envelope.velocity_smoother: velocity_smoother and envelope.min_interval: MIN_INTERVAL.

The peer publishes, every 20 ms, /odom (base at the origin on the ground, upright, moving forward
at V) and /joint_states (wheels rolling at V / R, the arm at the phase's shoulder pitch, at rest).
Its node `velocity_smoother` declares max_accel and max_decel as Nav2's velocity smoother does
(double arrays [x, y, θ]) and refuses what Nav2's refuses (not 3 values, an acceleration < 0, a
deceleration > 0); every accepted set is recorded with its time.

Phases (shoulder pitch [rad], duration [s]): the arm upright, leaning forward (the caster behind
the axle unloads: the braking limit falls), a little further (within the dead band), far
forward (the braking limit < 0), upright again (the limit loosens). The peer checks nothing
about the numbers: it prints one JSON object on its last line with the state it published per
phase, every AccelerationLimits received (receive time, stamp, values), every set of the
smoother's parameters, and the phase boundaries; the Rust test compares them with the core's
envelope and the documented bridge rules. Exits 0 when it could run the phases.
"""
import json
import sys
import threading
import time

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rcl_interfaces.msg import SetParametersResult

from constraint_dynamics_msgs.msg import AccelerationLimits
from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Odometry
from sensor_msgs.msg import JointState

V = 0.2  # forward speed [m/s]
R = 0.05  # wheel radius [m]
WHEELS = (0.3, -0.2)  # wheel angles [rad] (the envelope does not depend on them)
ARM = {"arm_shoulder_yaw": 0.0, "arm_elbow": 0.0, "arm_wrist": 0.0}
PHASES = [("upright", 0.0, 6.0), ("leaning", 0.4, 3.0), ("dead_band", 0.402, 3.0),
          ("far_forward", 0.8, 1.0), ("upright_again", 0.0, 3.0)]
# The smoother's own limits [m/s², m/s², rad/s²] cap what the bridge sends. 9.5 m/s² lies
# between the forward acceleration limit with the arm upright (9.28) and leaning (10.45), so
# the arm's return from far forward loosens every value (the forward acceleration stays within
# the dead band of the cap): the send waits for envelope.min_interval.
SMOOTHER_ACCEL = [9.5, 0.0, 3.2]
SMOOTHER_DECEL = [-100.0, 0.0, -3.2]


def stamp_s(t):
    return t.sec + t.nanosec * 1e-9


def limit(l):
    return {"status": l.status, "max": l.max, "binding_kinds": list(l.binding_kinds),
            "binding_names": list(l.binding_names)}


class Smoother(Node):
    """A stand-in for nav2_velocity_smoother's parameter interface."""

    def __init__(self):
        super().__init__("velocity_smoother")
        self.declare_parameter("max_accel", SMOOTHER_ACCEL)
        self.declare_parameter("max_decel", SMOOTHER_DECEL)
        self.sets = []
        self.current = {"max_accel": list(SMOOTHER_ACCEL), "max_decel": list(SMOOTHER_DECEL)}
        self.add_on_set_parameters_callback(self.on_set)

    def on_set(self, params):
        """rclpy's set_parameters service calls this once per parameter: each call records
        both values as they stand after it."""
        t = time.time()
        got = {}
        for p in params:
            x = list(p.value)
            if len(x) != 3:
                return SetParametersResult(successful=False, reason=f"{p.name} needs 3 values")
            if p.name == "max_accel" and any(v < 0.0 for v in x):
                return SetParametersResult(successful=False, reason="negative acceleration")
            if p.name == "max_decel" and any(v > 0.0 for v in x):
                return SetParametersResult(successful=False, reason="positive deceleration")
            got[p.name] = x
        self.current.update(got)
        self.sets.append({"t": t, **{k: list(v) for k, v in self.current.items()}})
        return SetParametersResult(successful=True)


class Peer(Node):
    def __init__(self):
        super().__init__("cd_envelope_peer")
        self.lock = threading.Lock()
        self.pitch = PHASES[0][1]
        self.limits, self.diagnostics = [], []
        self.odom_pub = self.create_publisher(Odometry, "/odom", 10)
        self.js_pub = self.create_publisher(JointState, "/joint_states", 10)
        self.create_subscription(AccelerationLimits, "/cd_predictor/acceleration_limits",
                                 self.on_limits, 50)
        self.create_subscription(DiagnosticArray, "/diagnostics", self.on_diagnostics, 50)
        self.create_timer(0.02, self.tick)

    def on_diagnostics(self, m):
        t = time.time()
        for s in m.status:
            if "cd_predictor" in s.name:
                rec = {"t": t, "level": int.from_bytes(s.level, "little") if isinstance(s.level, bytes)
                       else int(s.level), "message": s.message,
                       "values": {kv.key: kv.value for kv in s.values}}
                with self.lock:
                    self.diagnostics.append(rec)

    def on_limits(self, m):
        rec = {"t": time.time(), "stamp": stamp_s(m.header.stamp), "frame_id": m.header.frame_id,
               "limits": [limit(l) for l in (m.forward_acceleration, m.forward_deceleration,
                                             m.yaw_acceleration_left, m.yaw_acceleration_right)],
               "unchecked": [list(m.unchecked_kinds), list(m.unchecked_names)]}
        with self.lock:
            self.limits.append(rec)

    def state(self):
        with self.lock:
            pitch = self.pitch
        joints = {"left_wheel_joint": (WHEELS[0], V / R), "right_wheel_joint": (WHEELS[1], V / R),
                  "arm_shoulder_pitch": (pitch, 0.0)}
        joints.update({k: (v, 0.0) for k, v in ARM.items()})
        return joints

    def tick(self):
        now = self.get_clock().now().to_msg()
        od = Odometry()
        od.header.stamp = now
        od.header.frame_id = "odom"
        od.child_frame_id = "base_footprint"
        od.pose.pose.orientation.w = 1.0
        od.twist.twist.linear.x = V
        self.odom_pub.publish(od)
        js = JointState()
        js.header.stamp = now
        joints = self.state()
        js.name = list(joints)
        js.position = [p for p, _ in joints.values()]
        js.velocity = [w for _, w in joints.values()]
        self.js_pub.publish(js)


def main():
    rclpy.init()
    peer, smoother = Peer(), Smoother()
    ex = SingleThreadedExecutor()
    ex.add_node(peer)
    ex.add_node(smoother)
    spin = threading.Thread(target=ex.spin, daemon=True)
    spin.start()
    phases = []
    for name, pitch, duration in PHASES:
        with peer.lock:
            peer.pitch = pitch
        t0 = time.time()
        time.sleep(duration)
        joints = peer.state()
        phases.append({"name": name, "t0": t0, "t1": time.time(), "pitch": pitch,
                       "base_forward_speed": V,
                       "joints": {k: {"position": p, "velocity": w} for k, (p, w) in joints.items()}})
    with peer.lock:
        limits, diagnostics = list(peer.limits), list(peer.diagnostics)
    report = {"phases": phases, "limits": limits, "sets": list(smoother.sets),
              "diagnostics": diagnostics,
              "smoother_setting": {"max_accel": SMOOTHER_ACCEL, "max_decel": SMOOTHER_DECEL}}
    ex.shutdown()
    spin.join(timeout=5)
    peer.destroy_node()
    smoother.destroy_node()
    rclpy.try_shutdown()
    print(json.dumps(report))
    return 0


if __name__ == "__main__":
    sys.exit(main())
