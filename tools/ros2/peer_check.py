#!/usr/bin/env python3
"""A real ROS 2 peer (rclpy, rmw_fastrtps_cpp) checking a Rust node.

    tools/ros2/netns_run.sh .venv-ros2/bin/python tools/ros2/peer_check.py \
        [--odom /odom] [--service /cd_smoke/get_constraint_forces] \
        [--trigger /cd_smoke/trigger] [--calls 50] [--timeout 20]

Run it inside the loopback-only namespace (it opens a DDS participant), in
the same namespace as the Rust node. It
1. subscribes to nav_msgs/Odometry (reliable, depth 10, rclpy's default) and
   measures the time from subscription creation to the first message, and the
   age of the next messages (now - header.stamp);
2. calls the Rust node's constraint_dynamics_msgs/GetConstraintForces service
   `--calls` times, checking every response against the echo rule of
   nodes/tests/it/ros_smoke.rs, and measures the round trip;
3. calls the std_srvs/Trigger service once.
It prints one JSON object on the last line of stdout (the received Odometry
field by field, the numbers, `ok` and any `errors`), and exits 0 iff ok.
"""
import argparse
import array
import json
import statistics
import sys
import time

import numpy
import rclpy
from rclpy.node import Node

from nav_msgs.msg import Odometry
from std_srvs.srv import Trigger
from constraint_dynamics_msgs.srv import GetConstraintForces


def to_plain(value):
    if hasattr(value, "get_fields_and_field_types"):
        return {name: to_plain(getattr(value, name)) for name in value.get_fields_and_field_types()}
    if isinstance(value, (list, tuple, array.array, numpy.ndarray)):
        return [to_plain(v) for v in value]
    if isinstance(value, numpy.floating):
        return float(value)
    if isinstance(value, numpy.integer):
        return int(value)
    return value


def request(i):
    """The i-th GetConstraintForces request (distinct values each call)."""
    req = GetConstraintForces.Request()
    req.use_latest_state = (i % 2 == 1)
    req.q_names = ["base_x", "base_yaw", f"j{i}"]
    req.q = [0.5 * i, -0.25, 1e-3 * i]
    req.v_names = ["base_x", "wheel"]
    req.v = [0.1 * i, -2.0]
    req.tau = [1.5, -1.5 * i]
    return req


def check_response(req, resp):
    """The echo rule of the Rust test server (nodes/tests/it/ros_smoke.rs)."""
    errors = []

    def expect(what, got, want):
        if got != want:
            errors.append(f"{what}: got {got!r}, want {want!r}")

    expect("success", resp.success, True)
    expect("message", resp.message, f"echo use_latest_state={str(req.use_latest_state).lower()}")
    f = resp.forces
    expect("header.frame_id", f.header.frame_id, "world")
    expect("header.stamp.sec", f.header.stamp.sec, len(req.q))
    expect("v_names", list(f.v_names), list(req.v_names))
    expect("generalized_force", list(f.generalized_force), list(req.tau))
    expect("rank_deficiency", f.rank_deficiency, len(req.q_names))
    expect("qdd", list(resp.qdd), [2.0 * x for x in req.v])
    expect("len(constraints)", len(f.constraints), 1)
    if f.constraints:
        c = f.constraints[0]
        expect("constraint.name", c.name, ",".join(req.q_names))
        expect("constraint.kind", c.kind, "rolling")
        expect("constraint.multipliers", list(c.multipliers), list(req.q))
        expect("constraint.row_names", list(c.row_names), list(req.q_names))
        expect("constraint.wrench.force.x", c.wrench.force.x, sum(req.v))
        expect("constraint.slipping", c.slipping, True)
    return errors


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--odom", default="/odom")
    ap.add_argument("--service", default="/cd_smoke/get_constraint_forces")
    ap.add_argument("--trigger", default="/cd_smoke/trigger")
    ap.add_argument("--calls", type=int, default=50)
    ap.add_argument("--timeout", type=float, default=20.0)
    args = ap.parse_args()

    out = {"ok": False, "errors": []}
    rclpy.init()
    node = Node("cd_peer_check")
    try:
        received = []

        def on_odom(msg):
            received.append((time.monotonic(), time.time(), msg))

        t_sub = time.monotonic()
        node.create_subscription(Odometry, args.odom, on_odom, 10)
        deadline = t_sub + args.timeout
        while not received and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.05)
        if not received:
            out["errors"].append(f"no Odometry on {args.odom} within {args.timeout} s")
            return out
        out["first_message_s"] = received[0][0] - t_sub
        out["odom"] = to_plain(received[0][2])
        # Age of the following messages (publisher stamps with its system clock).
        n0 = len(received)
        while len(received) < n0 + 10 and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.05)
        ages = [wall - (m.header.stamp.sec + m.header.stamp.nanosec * 1e-9) for _, wall, m in received[1:]]
        if ages:
            out["message_age_median_s"] = statistics.median(ages)
        out["odom_received"] = len(received)

        client = node.create_client(GetConstraintForces, args.service)
        t_wait = time.monotonic()
        if not client.wait_for_service(timeout_sec=args.timeout):
            out["errors"].append(f"service {args.service} not available within {args.timeout} s")
            return out
        out["service_discovery_s"] = time.monotonic() - t_wait
        rtts = []
        for i in range(args.calls):
            req = request(i)
            t0 = time.perf_counter()
            fut = client.call_async(req)
            rclpy.spin_until_future_complete(node, fut, timeout_sec=5.0)
            rtt = time.perf_counter() - t0
            if not fut.done() or fut.result() is None:
                out["errors"].append(f"call {i}: no response within 5 s")
                return out
            rtts.append(rtt)
            errs = check_response(req, fut.result())
            if errs:
                out["errors"].append(f"call {i}: " + "; ".join(errs))
                return out
            if i == 0:
                out["first_response"] = to_plain(fut.result())
        out["service_calls"] = len(rtts)
        out["service_rtt_median_s"] = statistics.median(rtts)
        out["service_rtt_max_s"] = max(rtts)
        out["service_rtt_first_s"] = rtts[0]

        trig = node.create_client(Trigger, args.trigger)
        if not trig.wait_for_service(timeout_sec=args.timeout):
            out["errors"].append(f"service {args.trigger} not available")
            return out
        fut = trig.call_async(Trigger.Request())
        rclpy.spin_until_future_complete(node, fut, timeout_sec=5.0)
        if fut.result() is None:
            out["errors"].append("Trigger: no response")
            return out
        out["trigger"] = to_plain(fut.result())
        out["ok"] = True
        return out
    finally:
        node.destroy_node()
        rclpy.shutdown()


if __name__ == "__main__":
    result = main()
    print(json.dumps(result, allow_nan=False))
    sys.exit(0 if result["ok"] else 1)
