#!/usr/bin/env python3
"""rclpy as the mobile manipulator's odometry and joint states, reading the predictor's
scores of its own predictions (nodes/tests/it/suite_monitor_rclpy.rs).

The peer drives the bundled mobile manipulator (params/suite_mobile_manipulator.yaml) on an arc
at (V, W) from the origin: every 20 ms /odom (the unicycle's closed-form pose at its stamp,
σ 2 mm / 2 mrad on x, y, yaw), /cmd_vel (V, W), /joint_states of the wheels (positions and
speeds of (V, W), no effort) and, as a second JointState, of the arm (all four joints at 0, at
rest: the arm stands vertical) with efforts.

Efforts, closed form: a vertical arm at rest needs no torque on its pitch joints (every centre
of mass above the axes); with `--payload M` the tool carries an unannounced mass M at D_X
forward of tool0, so each pitch joint (arm_shoulder_pitch, arm_elbow, arm_wrist; axes +y) holds
M·g·D_X (the mass's horizontal lever is D_X from every one of them), the yaw joint nothing.

Records every ~/prediction_residuals (diagnostic_msgs/DiagnosticArray, one status per horizon)
until every horizon's window holds `--window N` odometry and effort samples (then a drive this
steady changes its figures no more) and one second more, or for DURATION s at most, and prints
one JSON object on the last line: ok, errors, figures (messages, the last status of each
horizon, the highest level seen); exits 0 iff ok.
"""
import json
import math
import sys
import threading
import time

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from sensor_msgs.msg import JointState

V, W = 0.3, 0.2  # [m/s, rad/s]
R, C = 0.05, 0.17  # wheel radius, half separation [m] (the scene's)
SXY, SYAW = 2e-3, 2e-3  # odometry σ [m, rad]
G = 9.81
D_X = 0.2  # the payload's lever forward of tool0 [m]
ARM = ["arm_shoulder_yaw", "arm_shoulder_pitch", "arm_elbow", "arm_wrist"]
DURATION = float(sys.argv[sys.argv.index("--duration") + 1]) if "--duration" in sys.argv else 25.0
PAYLOAD = float(sys.argv[sys.argv.index("--payload") + 1]) if "--payload" in sys.argv else 0.0
WINDOW = int(sys.argv[sys.argv.index("--window") + 1]) if "--window" in sys.argv else None
HORIZONS = 3  # the statuses of a report: the predictor's three horizons
ERRORS = []
FIGURES = {}


def stamp_s(t):
    return t.sec + t.nanosec * 1e-9


class Peer(Node):
    def __init__(self):
        super().__init__("cd_monitor_peer")
        self.lock = threading.Lock()
        self.t0 = None
        self.odom_pub = self.create_publisher(Odometry, "/odom", 10)
        self.js_pub = self.create_publisher(JointState, "/joint_states", 10)
        self.cmd_pub = self.create_publisher(Twist, "/cmd_vel", 10)
        self.reports = []
        self.create_subscription(DiagnosticArray, "/cd_predictor/prediction_residuals",
                                 self.keep, 50)
        self.create_timer(0.02, self.tick)

    def keep(self, msg):
        with self.lock:
            self.reports.append(msg)

    def tick(self):
        now = self.get_clock().now()
        stamp = now.to_msg()
        t = stamp_s(stamp)
        if self.t0 is None:
            self.t0 = t
        s = t - self.t0
        th = W * s
        tw = Twist()
        tw.linear.x, tw.angular.z = V, W
        self.cmd_pub.publish(tw)
        od = Odometry()
        od.header.stamp = stamp
        od.header.frame_id, od.child_frame_id = "odom", "base_footprint"
        od.pose.pose.position.x = V / W * math.sin(th)
        od.pose.pose.position.y = V / W * (1.0 - math.cos(th))
        od.pose.pose.orientation.z, od.pose.pose.orientation.w = math.sin(th / 2), math.cos(th / 2)
        cov = [0.0] * 36
        cov[0] = cov[7] = SXY**2
        cov[14] = cov[21] = cov[28] = 1e6
        cov[35] = SYAW**2
        od.pose.covariance = cov
        od.twist.twist = tw
        self.odom_pub.publish(od)
        wl, wr = (V - C * W) / R, (V + C * W) / R
        wheels = JointState(name=["left_wheel_joint", "right_wheel_joint"],
                            position=[wl * s, wr * s], velocity=[wl, wr])
        wheels.header.stamp = stamp
        self.js_pub.publish(wheels)
        hold = PAYLOAD * G * D_X
        arm = JointState(name=ARM, position=[0.0] * 4, velocity=[0.0] * 4,
                         effort=[0.0, hold, hold, hold])
        arm.header.stamp = stamp
        self.js_pub.publish(arm)


def windows_full(peer):
    """Whether the last report's every horizon holds WINDOW odometry and effort samples."""
    if WINDOW is None:
        return False
    with peer.lock:
        last = peer.reports[-1] if peer.reports else None
    if last is None or len(last.status) < HORIZONS:
        return False
    count = lambda s, key: next((int(kv.value) for kv in s.values if kv.key == key), 0)
    return all(count(s, "odometry samples") >= WINDOW and count(s, "effort samples") >= WINDOW
               for s in last.status)


def main():
    rclpy.init()
    peer = Peer()
    ex = SingleThreadedExecutor()
    ex.add_node(peer)
    spin = threading.Thread(target=ex.spin, daemon=True)
    spin.start()
    try:
        end = time.monotonic() + DURATION
        while time.monotonic() < end and not windows_full(peer):
            time.sleep(0.1)
        time.sleep(min(1.0, max(0.0, end - time.monotonic())))
        with peer.lock:
            reports = list(peer.reports)
        FIGURES["residual messages"] = len(reports)
        if not reports:
            ERRORS.append("no ~/prediction_residuals in the run")
        else:
            FIGURES["highest level"] = max(int.from_bytes(s.level, "little")
                                           if isinstance(s.level, bytes) else int(s.level)
                                           for m in reports for s in m.status)
            last = reports[-1]
            FIGURES["last"] = {s.name: {"level": int.from_bytes(s.level, "little")
                                        if isinstance(s.level, bytes) else int(s.level),
                                        "message": s.message,
                                        "values": {kv.key: kv.value for kv in s.values}}
                               for s in last.status}
        FIGURES["payload hold torque [N m]"] = PAYLOAD * G * D_X
    except Exception as e:  # reported, not raised: the test reads the JSON
        ERRORS.append(f"{type(e).__name__}: {e}")
    finally:
        ex.shutdown()
        spin.join(timeout=5)
        peer.destroy_node()
        rclpy.try_shutdown()
    print(json.dumps({"ok": not ERRORS, "errors": ERRORS, "figures": FIGURES}))
    sys.exit(0 if not ERRORS else 1)


if __name__ == "__main__":
    main()
