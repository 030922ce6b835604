#!/usr/bin/env python3
"""A real ROS 2 peer (rclpy, rmw_fastrtps_cpp) that loads the predictor's robot with a payload and
reads its acceleration limits (nodes/tests/it/suite_payload_rclpy.rs).

    tools/ros2/netns_run.sh .venv-ros2/bin/python nodes/tests/peers/payload_limits_peer.py REQUEST_JSON

Run inside the loopback-only namespace of a running suite whose /cd_predictor predicts the
floating cart. It publishes the cart at rest (/odom, /joint_states at 50 Hz), reads
/cd_predictor/acceleration_limits for 1.5 s, calls /cd_predictor/set_payload with REQUEST_JSON
({"frame": ..., "inertia": {"m": ..., "com": {...}, "ixx": ...}}), and reads the limits again from
1 s after the answer (a tick that started before it may still publish the old limits) for 1.5 s.
The rate is not checked here (nodes/tests/it/suite_envelope_rclpy.rs does). It prints one JSON object on the last line of stdout (the four
limits of every message before and after) and exits 0 iff `ok`.
"""
import json
import sys
import threading
import time

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from constraint_dynamics_msgs.msg import AccelerationLimits
from constraint_dynamics_msgs.srv import SetPayload
from nav_msgs.msg import Odometry
from sensor_msgs.msg import JointState

TIMEOUT = 20.0


def fill(msg, data):
    for name, value in data.items():
        current = getattr(msg, name)
        if hasattr(current, "get_fields_and_field_types"):
            fill(current, value)
        else:
            setattr(msg, name, value)
    return msg


class Peer(Node):
    def __init__(self):
        super().__init__("cd_payload_limits_peer")
        self.lock = threading.Lock()
        self.limits = []
        self.odom_pub = self.create_publisher(Odometry, "/odom", 10)
        self.js_pub = self.create_publisher(JointState, "/joint_states", 10)
        self.create_subscription(AccelerationLimits, "/cd_predictor/acceleration_limits",
                                 self.on_limits, 50)
        self.create_timer(0.02, self.tick)

    def on_limits(self, m):
        rec = {"t": time.monotonic(),
               "limits": [[l.status, l.max] for l in (m.forward_acceleration, m.forward_deceleration,
                                                     m.yaw_acceleration_left, m.yaw_acceleration_right)]}
        with self.lock:
            self.limits.append(rec)

    def tick(self):
        now = self.get_clock().now().to_msg()
        od = Odometry()
        od.header.stamp = now
        od.header.frame_id = "odom"
        od.child_frame_id = "base_footprint"
        od.pose.pose.orientation.w = 1.0
        self.odom_pub.publish(od)
        js = JointState()
        js.header.stamp = now
        js.name = ["left_wheel_joint", "right_wheel_joint"]
        js.position = [0.0, 0.0]
        js.velocity = [0.0, 0.0]
        self.js_pub.publish(js)

    def window(self, start, length):
        with self.lock:
            return [r["limits"] for r in self.limits if start <= r["t"] <= start + length]


def main():
    good = json.loads(sys.argv[1])
    out = {"ok": False, "errors": []}
    rclpy.init()
    peer = Peer()
    ex = SingleThreadedExecutor()
    ex.add_node(peer)
    spin = threading.Thread(target=ex.spin, daemon=True)
    spin.start()
    try:
        deadline = time.monotonic() + TIMEOUT
        while not peer.window(0.0, 1e9) and time.monotonic() < deadline:
            time.sleep(0.05)
        # Made before the 1.5 s window, not just before its request: a client made just before
        # its request races the suite's discovery of it, and a lost request waits for Fast
        # DDS's next heartbeat (up to 3 s).
        client = peer.create_client(SetPayload, "/cd_predictor/set_payload")
        t0 = time.monotonic()
        time.sleep(1.5)
        out["before"] = peer.window(t0, 1.5)
        if not client.wait_for_service(timeout_sec=TIMEOUT):
            raise RuntimeError("/cd_predictor/set_payload not available")
        fut = client.call_async(fill(SetPayload.Request(), good))
        deadline = time.monotonic() + TIMEOUT
        while not fut.done() and time.monotonic() < deadline:
            time.sleep(0.01)
        if not fut.done():
            raise RuntimeError("no response from /cd_predictor/set_payload")
        out["set_payload"] = {"success": fut.result().success, "message": fut.result().message}
        t1 = time.monotonic() + 1.0
        time.sleep(2.5)
        out["after"] = peer.window(t1, 1.5)
        for key in ("before", "after"):
            if not out[key]:
                out["errors"].append(f"no limits message {key} the payload")
        out["ok"] = not out["errors"]
    except Exception as e:  # noqa: BLE001 - report everything as JSON
        out["errors"].append(f"{type(e).__name__}: {e}")
    finally:
        ex.shutdown()
        spin.join(timeout=5)
        peer.destroy_node()
        rclpy.shutdown()
    print(json.dumps(out))
    return 0 if out["ok"] else 1


if __name__ == "__main__":
    sys.exit(main())
