#!/usr/bin/env python3
"""rclpy replaying a recorded drive into the suite, reading the predictor's scores of its own
predictions (nodes/tests/it/suite_monitor_log_rclpy.rs).

    replay_peer.py --bag FILE.mcap [--topics /odom,/joint_states,/cmd_vel] [--limit S]
                   [--rate R] [--payload-kg M --urdf URDF]

The peer reads the rosbag2 MCAP file with the `mcap` package's reader (another reader than the
suite's), decodes each message's CDR with rclpy (`rclpy.serialization.deserialize_message`, the
type named by the message's schema) and publishes it on its recorded topic at its recorded log
time, as `ros2 bag play --clock` does: /clock (rosgraph_msgs/Clock) carries the log time before
every message, so a suite under use_sim_time runs on the log's time, whatever this machine's
load. The log's time runs at R times wall time (`--rate`, as `ros2 bag play --rate`; 1 by
default).

Before the replay the peer waits until the suite subscribes to every replayed topic and
publishes ~/prediction_residuals, then 1.5 s for the predictor's command subscription to take
the published command type (`command.type: auto`). It records every
~/prediction_residuals (diagnostic_msgs/DiagnosticArray, one status per horizon) and prints
one JSON object on the last line: ok, errors, figures (messages replayed per topic, residual
messages, the highest level seen and when, the last status of each horizon); exits 0 iff ok.

With --payload-kg M the log's robot carries M kg at tool0 that the suite is not told of; the peer
states, closed form, the torque the shoulder pitch joint needs to hold it at the replayed arm
pose: −M·g·d, d the horizontal distance from the shoulder pitch axis to tool0 over the planar
chain shoulder → elbow → wrist → tool0 in the arm's vertical plane (pitch axes +y, the URDF's
link offsets along z; the shoulder yaw turns the plane about the vertical, which leaves d as it
is), d = l₁ sin q₁ + l₂ sin(q₁+q₂) + l₃ sin(q₁+q₂+q₃), median over the replayed joint states.
The base stands level in the closed form. Gravity's torque about +y of a mass at +x is +x·M·g, so the joint holds −x·M·g.
"""
import importlib
import json
import math
import statistics
import sys
import threading
import time
import xml.etree.ElementTree as ET

import rclpy
from mcap.reader import make_reader
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.serialization import deserialize_message

from diagnostic_msgs.msg import DiagnosticArray
from rosgraph_msgs.msg import Clock


def arg(name, default):
    return sys.argv[sys.argv.index(name) + 1] if name in sys.argv else default


BAG = arg("--bag", None)
TOPICS = arg("--topics", "/odom,/joint_states,/cmd_vel").split(",")
LIMIT_S = float(arg("--limit", "inf"))  # replay at most this much of the log [s]
RATE = float(arg("--rate", "1"))  # log seconds per wall second
PAYLOAD_KG = float(arg("--payload-kg", "0"))
URDF = arg("--urdf", None)
G = 9.81
PITCH_CHAIN = ["arm_shoulder_pitch", "arm_elbow", "arm_wrist"]
DISCOVERY_TIMEOUT_S = 15.0
TYPE_SWITCH_S = 1.5
RESIDUALS = "/cd_predictor/prediction_residuals"
ERRORS = []
FIGURES = {}


def level(s):
    return int.from_bytes(s.level, "little") if isinstance(s.level, bytes) else int(s.level)


def finite_or_none(text):
    """A report's number, None when it is not finite (JSON has no NaN)."""
    x = float(text)
    return x if math.isfinite(x) else None


def message_class(schema):
    """The rclpy class of a schema named pkg/msg/Type (or pkg/Type)."""
    pkg, *_, name = schema.split("/")
    return getattr(importlib.import_module(f"{pkg}.msg"), name)


def read_log(path):
    """[(log time [ns], topic, message)] of TOPICS in log-time order, and each topic's type."""
    out, types = [], {}
    with open(path, "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages(topics=TOPICS,
                                                                    log_time_order=True):
            if channel.message_encoding != "cdr":
                raise ValueError(f"{channel.topic}: encoding {channel.message_encoding}, not cdr")
            cls = types.setdefault(channel.topic, message_class(schema.name))
            out.append((message.log_time, channel.topic, deserialize_message(message.data, cls)))
    missing = [t for t in TOPICS if t not in types]
    if missing:
        raise ValueError(f"{path}: no messages on {missing}")
    return out, types


def link_lengths(urdf):
    """The z offsets of the joints after the shoulder pitch: elbow, wrist, tool0 [m]."""
    joints = {j.get("name"): j for j in ET.parse(urdf).getroot().findall("joint")}
    out = []
    for name in ("arm_elbow", "arm_wrist", "tool0_joint"):
        x, y, z = (float(v) for v in joints[name].find("origin").get("xyz").split())
        if abs(x) > 0 or abs(y) > 0:
            raise ValueError(f"{urdf}: {name} is not offset along z alone")
        out.append(z)
    return out


def payload_hold_torque(log, lengths):
    """Median over the log's joint states of the shoulder pitch torque holding PAYLOAD_KG."""
    torques = []
    for _, topic, msg in log:
        if topic != "/joint_states":
            continue
        q = dict(zip(msg.name, msg.position))
        angle, d = 0.0, 0.0
        for joint, length in zip(PITCH_CHAIN, lengths):
            angle += q[joint]
            d += length * math.sin(angle)
        torques.append(-PAYLOAD_KG * G * d)
    return statistics.median(torques)


class Peer(Node):
    def __init__(self, types):
        super().__init__("cd_replay_peer")
        self.lock = threading.Lock()
        self.reports = []  # (clock at receipt [ns], DiagnosticArray)
        self.clock_ns = 0
        self.clock_pub = self.create_publisher(Clock, "/clock", 10)
        self.pubs = {t: self.create_publisher(cls, t, 50) for t, cls in types.items()}
        self.create_subscription(DiagnosticArray, RESIDUALS, self.keep, 50)

    def keep(self, msg):
        with self.lock:
            self.reports.append((self.clock_ns, msg))

    def ready(self):
        """Whether the suite subscribes to every replayed topic and publishes the residuals."""
        subscribed = all(p.get_subscription_count() > 0 for p in self.pubs.values())
        return subscribed and self.count_publishers(RESIDUALS) > 0

    def clock(self, ns):
        c = Clock()
        c.clock.sec, c.clock.nanosec = ns // 10**9, ns % 10**9
        self.clock_ns = ns
        self.clock_pub.publish(c)


def replay(peer, log):
    """Publishes the log at RATE times its recorded rate; returns the messages published per
    topic."""
    counts = {}
    t_first = log[0][0]
    start = time.monotonic()
    for t, topic, msg in log:
        if (t - t_first) * 1e-9 > LIMIT_S:
            break
        delay = start + (t - t_first) * 1e-9 / RATE - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        peer.clock(t)
        peer.pubs[topic].publish(msg)
        counts[topic] = counts.get(topic, 0) + 1
    FIGURES["replay wall time [s]"] = time.monotonic() - start
    return counts


def main():
    log, types = read_log(BAG)
    if PAYLOAD_KG > 0:
        FIGURES["payload hold torque at the logged arm pose [N m]"] = payload_hold_torque(
            log, link_lengths(URDF))
    rclpy.init()
    peer = Peer(types)
    ex = SingleThreadedExecutor()
    ex.add_node(peer)
    spin = threading.Thread(target=ex.spin, daemon=True)
    spin.start()
    try:
        deadline = time.monotonic() + DISCOVERY_TIMEOUT_S
        while not peer.ready():
            if time.monotonic() > deadline:
                raise TimeoutError(f"the suite did not subscribe to {TOPICS} and publish "
                                   f"{RESIDUALS} within {DISCOVERY_TIMEOUT_S} s")
            time.sleep(0.05)
        peer.clock(log[0][0])
        time.sleep(TYPE_SWITCH_S)
        with peer.lock:
            peer.reports.clear()  # those before the replay score nothing
        FIGURES["replayed"] = replay(peer, log)
        time.sleep(0.5)  # the last tick's report
        with peer.lock:
            reports = list(peer.reports)
        FIGURES["residual messages"] = len(reports)
        if not reports:
            ERRORS.append(f"no {RESIDUALS} during the replay")
        else:
            t0 = log[0][0]
            worst = max(((level(s), t) for t, m in reports for s in m.status), default=(0, t0))
            FIGURES["highest level"] = worst[0]
            FIGURES["highest level first at [s of the log]"] = next(
                (t - t0) * 1e-9 for t, m in reports for s in m.status if level(s) == worst[0])
            # Each second of the log: the level and every horizon's median NEES and worst
            # effort error.
            timeline, next_t = [], 0.0
            for t, m in reports:
                if (t - t0) * 1e-9 >= next_t:
                    next_t += 1.0
                    timeline.append([round((t - t0) * 1e-9, 2), max(level(s) for s in m.status)]
                                    + [[finite_or_none(v.value) for v in s.values if v.key.startswith(
                                        ("NEES median", "worst effort error"))] for s in m.status])
            FIGURES["each second: t [s], level, per horizon [NEES median, worst effort]"] = timeline
            # The slip statistic (not per horizon: every status carries it), over the replay.
            slip = [finite_or_none(v.value) for _, m in reports for s in m.status[:1]
                    for v in s.values if v.key.startswith("measured state velocity residual")]
            slip = [x for x in slip if x is not None]
            FIGURES["slip statistic's largest median [m/s]"] = max(slip, default=None)
            FIGURES["last"] = {s.name: {"level": level(s), "message": s.message,
                                        "values": {kv.key: kv.value for kv in s.values}}
                               for s in reports[-1][1].status}
    except Exception as e:  # reported, not raised: the test reads the JSON
        ERRORS.append(f"{type(e).__name__}: {e}")
    finally:
        ex.shutdown()
        spin.join(timeout=5)
        peer.destroy_node()
        rclpy.try_shutdown()
    print(json.dumps({"ok": not ERRORS, "errors": ERRORS, "figures": FIGURES}), flush=True)
    sys.exit(0 if not ERRORS else 1)


if __name__ == "__main__":
    main()
