"""The default suite's CPU share as a robot stack feeds it (docs/performance.md, "The live cost").

Starts the suite (params/default.yaml), feeds it at 20 Hz what a robot gives it -- /odom with a
covariance (sigma 1 cm, 0.01 rad, 0.01 m/s), /joint_states and cmd_vel: (0.3 m/s, 0.5 rad/s)
steady, or with `--feed changing` a command that changes at every message as a Nav2 controller's
does (v = 0.3 + 0.1 sin(1.3 t) m/s, w = 0.5 sin(0.7 t) rad/s, the odometry and wheels following
it) -- and, after `--settle` seconds of feed, reads the suite process's user + system time from
/proc/PID/stat over `--window` seconds. Prints one JSON line: the CPU share (cores), the rate of
/cd_predictor/predicted_odom over the window [Hz], and whether its covariance came through.

Opens DDS participants: run it only inside tools/ros2/netns_run.sh, with the peer venv's Python
(tools/ros2/setup_peer_venv.sh):
    tools/ros2/netns_run.sh .venv-ros2/bin/python tools/ros2/live_cpu.py --suite target/release/constraint_dynamics_suite

To see where the suite's time goes, `--perf-record FILE` samples it over the window with
`perf record` (cpu-clock at 999 Hz, DWARF call graphs: a VM may have no hardware counters; read
with `perf report -i FILE`), and `--wrap "valgrind --tool=callgrind ..."` starts the suite under
a tool (it then runs far slower than its rates: read the counts per tick and per message, not
per second).
"""

import argparse
import json
import math
import os
import shlex
import signal
import subprocess
import sys
import time

import rclpy
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from sensor_msgs.msg import JointState

# The suite's mobile manipulator (params/suite_mobile_manipulator.yaml): wheel radius and track [m].
RADIUS, TRACK = 0.05, 0.34
V, W = 0.3, 0.5  # the steady command and odometry twist [m/s, rad/s]


def command(feed, t):
    """The fed command and odometry twist (v [m/s], w [rad/s]) at `t` [s] into the feed."""
    if feed == "steady":
        return V, W
    return V + 0.1 * math.sin(1.3 * t), W * math.sin(0.7 * t)
ARM = {"arm_shoulder_yaw": 0.0, "arm_shoulder_pitch": 0.5, "arm_elbow": 1.0, "arm_wrist": 0.5}


def cpu_seconds(pid):
    """User + system time of process `pid` and its threads [s]."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    # utime and stime are fields 14 and 15 of stat(5); fields[0] here is field 3.
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def covariance(sigmas):
    c = [0.0] * 36
    for i, s in enumerate(sigmas):
        c[7 * i] = s * s
    return c


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--suite", required=True, help="the constraint_dynamics_suite binary")
    ap.add_argument("--params", default="params/default.yaml")
    ap.add_argument("--settle", type=float, default=10.0, help="[s] of feed before the window")
    ap.add_argument("--window", type=float, default=8.0, help="[s] of CPU time read")
    ap.add_argument("--feed", choices=["steady", "changing"], default="steady",
                    help="a steady command, or one that changes at every message")
    ap.add_argument("--perf-record", metavar="FILE",
                    help="sample the suite over the window with perf record -g into FILE")
    ap.add_argument("--wrap", default="", help="a command the suite runs under (e.g. valgrind)")
    args = ap.parse_args()
    if os.environ.get("CD_NETNS") != "1":
        sys.exit("live_cpu.py opens DDS participants: run it inside tools/ros2/netns_run.sh")

    suite = subprocess.Popen(
        [*shlex.split(args.wrap), args.suite, "--ros-args", "--params-file", args.params],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    rclpy.init()
    node = rclpy.create_node("live_cpu_feed")
    odom = node.create_publisher(Odometry, "/odom", 10)
    joints = node.create_publisher(JointState, "/joint_states", 10)
    cmd = node.create_publisher(Twist, "/cmd_vel", 10)
    received = []
    node.create_subscription(
        Odometry,
        "/cd_predictor/predicted_odom",
        lambda m: received.append((time.monotonic(), float(m.pose.covariance[0]))),
        10,
    )
    pose_cov = covariance([0.01, 0.01, 1e6, 1e6, 1e6, 0.01])
    twist_cov = covariance([0.01, 0.01, 1e6, 1e6, 1e6, 0.01])
    start = time.monotonic()
    window = None
    perf = None
    try:
        while time.monotonic() - start < args.settle + args.window:
            v, w = command(args.feed, time.monotonic() - start)
            wheel = [(v - w * TRACK / 2) / RADIUS, (v + w * TRACK / 2) / RADIUS]
            now = node.get_clock().now().to_msg()
            o = Odometry()
            o.header.stamp = now
            o.header.frame_id = "odom"
            o.child_frame_id = "base_footprint"
            o.twist.twist.linear.x, o.twist.twist.angular.z = v, w
            o.pose.covariance, o.twist.covariance = pose_cov, twist_cov
            odom.publish(o)
            j = JointState()
            j.header.stamp = now
            j.name = ["left_wheel_joint", "right_wheel_joint", *ARM]
            j.position = [0.0, 0.0, *ARM.values()]
            j.velocity = [*wheel] + [0.0] * len(ARM)
            j.effort = [0.0] * len(j.name)
            joints.publish(j)
            c = Twist()
            c.linear.x, c.angular.z = v, w
            cmd.publish(c)
            if window is None and time.monotonic() - start >= args.settle:
                window = (time.monotonic(), cpu_seconds(suite.pid))
                if args.perf_record:
                    perf = subprocess.Popen(
                        ["perf", "record", "--call-graph", "dwarf,32768", "-F", "999",
                         "-o", args.perf_record, "-p", str(suite.pid)],
                        stdout=subprocess.DEVNULL,
                        stderr=subprocess.DEVNULL,
                    )
            until = time.monotonic() + 0.05
            while time.monotonic() < until:
                rclpy.spin_once(node, timeout_sec=0.01)
        t1, cpu1 = time.monotonic(), cpu_seconds(suite.pid)
    finally:
        if perf is not None:
            perf.send_signal(signal.SIGINT)
            perf.wait(timeout=60)
        suite.send_signal(signal.SIGINT)
        try:
            suite.wait(timeout=10)
        except subprocess.TimeoutExpired:
            suite.kill()
        node.destroy_node()
        rclpy.shutdown()
    t0, cpu0 = window
    late = [r for r in received if r[0] >= t0]
    rate = (len(late) - 1) / (late[-1][0] - late[0][0]) if len(late) > 1 else 0.0
    print(
        json.dumps(
            {
                "cpu_share": (cpu1 - cpu0) / (t1 - t0),
                "predicted_odom_hz": rate,
                "covariance": bool(late and late[-1][1] > 0.0),
                "window_s": t1 - t0,
                "feed": args.feed,
            }
        )
    )


if __name__ == "__main__":
    main()
