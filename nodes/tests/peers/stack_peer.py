#!/usr/bin/env python3
"""rclpy as the rest of a robot stack (nodes/tests/it/suite_stack_rclpy.rs): a fake simulator, a
lifecycle manager and rviz2's reader of the markers, for a suite started in /robot1 with
`use_sim_time`, params/namespaced.yaml and `autostart: false`.

    tools/ros2/netns_run.sh .venv-ros2/bin/python nodes/tests/peers/stack_peer.py

The simulator publishes /clock (sim time from 1000 s), /robot1/odom (base at rest at x = 1,
y = 2, yaw 0), /robot1/joint_states and /robot1/cmd_vel (TwistStamped, later plain Twist).
Phases, each checked against numbers from outside the suite:
1. unconfigured: lifecycle services answer (state 1, transitions configure/shutdown with the
   transition states as goals, 10 states); no predictor topic, no ~/predict service;
2. configure every node as Nav2's lifecycle_manager does: inactive (2), still no topic or
   service, ~/transition_event carries (1→10, id 1) and (10→2, id 10);
3. activate: active (3), the topics and services appear; predicted odometry stamped sim time +
   horizon (1 s) and following the TwistStamped command (v, ω) the base is not moving at;
4. markers (visualization_msgs/MarkerArray decoded by rclpy): an arrow per wheel contact starting
   at the contact point from the URDF (base pose + (0, ±0.17, 0) m), arrow = 0.01 m/N × the force
   of the ConstraintForces message of the same stamp, red iff that message says it slips; the
   footprint outlines every 0.2 s of the 1 s path (6 × 4 edges), the first corner at the base
   pose + (0.15, 0.15) m;
5. the command publisher is replaced by a plain Twist one: the predictor follows it;
6. /diagnostics: every node OK, then the predictor WARN "odom stale" once odometry stops;
7. deactivate the predictor: its topics disappear and nothing more arrives; cleanup; shutdown
   by label; finalized (4) has no transition left and refuses activate.
Prints one JSON object (ok, errors, figures) on the last line; exits 0 iff ok.
"""
import json
import math
import sys
import time

import rclpy
from rclpy.node import Node

from builtin_interfaces.msg import Time
from constraint_dynamics_msgs.msg import ConstraintForces
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import Twist, TwistStamped, WrenchStamped
from lifecycle_msgs.msg import Transition, TransitionEvent
from lifecycle_msgs.srv import ChangeState, GetAvailableStates, GetAvailableTransitions, GetState
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from visualization_msgs.msg import Marker, MarkerArray

NS = "/robot1"
NODES = ["cd_predictor", "cd_forces", "cd_projection", "cd_prediction"]
T0 = 1000 * 10**9  # sim time at the start [ns]
HORIZON = 1.0  # [s] params/namespaced.yaml
X0, Y0 = 1.0, 2.0  # base pose fed as odometry [m], yaw 0
HALF_TRACK = 0.17  # [m] urdf/mobile_manipulator.urdf wheel joints at y = ±0.17
FOOTPRINT0 = (0.15, 0.15)  # first vertex of the default markers.footprint [m]
FORCE_SCALE = 0.01  # [m/N] default markers.force_scale
TIMEOUT = 20.0
ERRORS = []
FIGURES = {}


def check(what, ok, detail=""):
    if not ok:
        ERRORS.append(f"{what}: {detail}")
    return ok


def stamp_ns(t):
    return t.sec * 10**9 + t.nanosec


class Stack(Node):
    def __init__(self):
        super().__init__("cd_stack_peer")
        self.sim = T0
        self.k = 0
        self.odom_on = True
        self.command = (0.3, 0.5)
        self.clock_pub = self.create_publisher(Clock, "/clock", 10)
        self.odom_pub = self.create_publisher(Odometry, NS + "/odom", 10)
        self.js_pub = self.create_publisher(JointState, NS + "/joint_states", 10)
        self.cmd_pub = self.create_publisher(TwistStamped, NS + "/cmd_vel", 10)
        self.stamped = True
        self.create_timer(0.01, self.tick)
        self.odom, self.markers, self.forces, self.diags = [], [], [], []
        self.wrenches = []
        self.events = {n: [] for n in NODES}
        p = NS + "/cd_predictor/"
        self.create_subscription(Odometry, p + "predicted_odom", self.odom.append, 10)
        self.create_subscription(MarkerArray, p + "markers", self.markers.append, 10)
        self.create_subscription(ConstraintForces, p + "constraint_forces", self.forces.append, 10)
        self.create_subscription(DiagnosticArray, "/diagnostics", self.diags.append, 50)
        self.create_subscription(WrenchStamped, p + "wrench/left_wheel_contact",
                                 self.wrenches.append, 10)
        for n in NODES:
            self.create_subscription(TransitionEvent, f"{NS}/{n}/transition_event",
                                     self.events[n].append, 10)
        # One client per lifecycle service, made up front and kept, as Nav2's lifecycle_manager
        # keeps one per managed node. A client made just before its first request races the
        # suite's discovery of it: a request that arrives first is lost and Fast DDS resends it
        # on its next heartbeat, up to 3 s later (measured: 0 or 3.0 s per fresh client).
        self.service_clients = {}
        for n in NODES:
            self.service_clients[f"{NS}/{n}/get_state"] = self.create_client(
                GetState, f"{NS}/{n}/get_state")
            self.service_clients[f"{NS}/{n}/change_state"] = self.create_client(
                ChangeState, f"{NS}/{n}/change_state")
        for srv, name in ((GetAvailableTransitions, "get_available_transitions"),
                          (GetAvailableStates, "get_available_states")):
            self.service_clients[f"{NS}/cd_predictor/{name}"] = self.create_client(
                srv, f"{NS}/cd_predictor/{name}")

    def tick(self):
        self.k += 1
        self.sim = T0 + self.k * 10**7
        now = Time(sec=self.sim // 10**9, nanosec=self.sim % 10**9)
        self.clock_pub.publish(Clock(clock=now))
        if self.k % 2:
            return
        if self.odom_on:
            od = Odometry()
            od.header.stamp, od.header.frame_id = now, "robot1/odom"
            od.child_frame_id = "robot1/base_footprint"
            od.pose.pose.position.x, od.pose.pose.position.y = X0, Y0
            od.pose.pose.orientation.w = 1.0
            self.odom_pub.publish(od)
        js = JointState(name=["left_wheel_joint", "right_wheel_joint"], position=[0.0, 0.0],
                        velocity=[0.0, 0.0])
        js.header.stamp = now
        self.js_pub.publish(js)
        tw = Twist()
        tw.linear.x, tw.angular.z = self.command
        if self.stamped:
            msg = TwistStamped(twist=tw)
            msg.header.stamp = now
            self.cmd_pub.publish(msg)
        else:
            self.cmd_pub.publish(tw)

    def spin_until(self, cond, timeout=TIMEOUT):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if cond():
                return True
            rclpy.spin_once(self, timeout_sec=0.02)
        return cond()

    def spin_for(self, seconds):
        self.spin_until(lambda: False, seconds)

    def call(self, srv, name, request):
        client = self.service_clients[name]
        assert client.srv_type is srv, (name, srv)
        if not client.wait_for_service(timeout_sec=TIMEOUT):
            raise RuntimeError(f"service {name} not available")
        fut = client.call_async(request)
        self.spin_until(fut.done)
        if not fut.done():
            raise RuntimeError(f"no response from {name}")
        return fut.result()

    def state(self, node):
        s = self.call(GetState, f"{NS}/{node}/get_state", GetState.Request()).current_state
        return (s.id, s.label)

    def change(self, node, tid, label=""):
        req = ChangeState.Request(transition=Transition(id=tid, label=label))
        return self.call(ChangeState, f"{NS}/{node}/change_state", req).success

    def has_service(self, name):
        return any(n == name for n, _ in self.get_service_names_and_types())


def follows(peer, v, w, since, what):
    """Every predicted odometry of `since` or later (sim ns) follows (v, w); ≥ 5 of them."""
    def good():
        return len([m for m in peer.odom if stamp_ns(m.header.stamp) >= since]) >= 5
    peer.spin_until(good)
    msgs = [m for m in peer.odom if stamp_ns(m.header.stamp) >= since]
    if not check(f"{what}: 5 predictions", len(msgs) >= 5, f"{len(msgs)}"):
        return
    ev = max(abs(m.twist.twist.linear.x - v) for m in msgs)
    ew = max(abs(m.twist.twist.angular.z - w) for m in msgs)
    FIGURES[f"{what}: max |v - v_cmd| [m/s]"] = ev
    FIGURES[f"{what}: max |w - w_cmd| [rad/s]"] = ew
    # The PI wheel controllers' transient from rest, 1 s on: achieved 3–5e-8 m/s and
    # 2–4e-5 rad/s (tolerances 40× and 30× that).
    check(f"{what}: forward speed", ev <= 2e-6, f"{ev}")
    check(f"{what}: turn rate", ew <= 1e-3, f"{ew}")


def phase_lifecycle_up(peer):
    for n in NODES:
        check(f"{n} starts unconfigured", peer.state(n) == (1, "unconfigured"), peer.state(n))
    tr = peer.call(GetAvailableTransitions, NS + "/cd_predictor/get_available_transitions",
                   GetAvailableTransitions.Request()).available_transitions
    got = [(d.transition.id, d.transition.label, d.start_state.id, d.goal_state.id) for d in tr]
    check("transitions from unconfigured", got == [(1, "configure", 1, 10), (5, "shutdown", 1, 12)],
          got)
    st = peer.call(GetAvailableStates, NS + "/cd_predictor/get_available_states",
                   GetAvailableStates.Request()).available_states
    check("available states", sorted(s.id for s in st) == [1, 2, 3, 4, 10, 11, 12, 13, 14, 15],
          [s.id for s in st])
    odom_topic = NS + "/cd_predictor/predicted_odom"
    check("unconfigured: no predicted_odom publisher", peer.count_publishers(odom_topic) == 0)
    check("unconfigured: no ~/predict", not peer.has_service(NS + "/cd_prediction/predict"))
    for n in NODES:
        check(f"{n} configure", peer.change(n, Transition.TRANSITION_CONFIGURE))
        check(f"{n} inactive", peer.state(n) == (2, "inactive"), peer.state(n))
    peer.spin_for(1.0)  # time for endpoints to show if they (wrongly) existed
    check("inactive: no predicted_odom publisher", peer.count_publishers(odom_topic) == 0)
    check("inactive: no ~/predict", not peer.has_service(NS + "/cd_prediction/predict"))
    check("inactive: nothing published", not peer.odom and not peer.markers, len(peer.odom))
    for n in NODES:
        check(f"{n} activate", peer.change(n, Transition.TRANSITION_ACTIVATE))
        check(f"{n} active", peer.state(n) == (3, "active"), peer.state(n))
    check("active: ~/predict appears",
          peer.spin_until(lambda: peer.has_service(NS + "/cd_prediction/predict")))
    peer.spin_until(lambda: len(peer.events["cd_predictor"]) >= 4, 5.0)
    ev = [(e.start_state.id, e.goal_state.id, e.transition.id) for e in peer.events["cd_predictor"]]
    check("transition events", ev == [(1, 10, 1), (10, 2, 10), (2, 13, 3), (13, 3, 30)], ev)


def phase_prediction(peer):
    since = peer.sim + 500 * 10**6  # settling after activation: 0.5 s of sim time
    follows(peer, 0.3, 0.5, since + int(HORIZON * 1e9), "TwistStamped (0.3, 0.5)")
    m = peer.odom[-1]
    lag = (peer.sim + HORIZON * 1e9 - stamp_ns(m.header.stamp)) * 1e-9
    FIGURES["predicted_odom stamp lag behind sim time + horizon [s]"] = lag
    check("stamp = sim time + horizon", -0.05 <= lag <= 0.5, lag)
    check("odom frame", m.header.frame_id == "robot1/odom", m.header.frame_id)


def phase_markers(peer):
    forces = {stamp_ns(f.header.stamp): f for f in peer.forces}
    pair = next(((m, forces[stamp_ns(m.markers[0].header.stamp)]) for m in reversed(peer.markers)
                 if m.markers and stamp_ns(m.markers[0].header.stamp) in forces), None)
    if not check("a MarkerArray with the ConstraintForces of its stamp", pair is not None):
        return
    array, cf = pair
    arrows = [m for m in array.markers if m.ns == "constraint_forces"]
    outline = [m for m in array.markers if m.ns == "predicted_footprint"]
    check("an arrow per wheel contact", [a.id for a in arrows] == [0, 1], [a.id for a in arrows])
    err_start = err_vec = 0.0
    for a, c, y in zip(arrows, cf.constraints, (HALF_TRACK, -HALF_TRACK)):
        check(f"{c.name} arrow", a.type == Marker.ARROW and a.header.frame_id == "robot1/odom"
              and len(a.points) == 2, a)
        p, q = a.points[0], a.points[1]
        err_start = max(err_start, abs(p.x - X0), abs(p.y - (Y0 + y)), abs(p.z))
        f = c.wrench.force
        err_vec = max(err_vec, abs(q.x - p.x - FORCE_SCALE * f.x),
                      abs(q.y - p.y - FORCE_SCALE * f.y), abs(q.z - p.z - FORCE_SCALE * f.z))
        red = a.color.r == 1.0 and a.color.g < 0.5  # slip (1, 0.1, 0.1), grip (0.1, 0.8, 0.1)
        check(f"{c.name} red iff slipping", red == c.slipping, (a.color, c.slipping))
    FIGURES["arrow start vs URDF contact point [m]"] = err_start
    FIGURES["arrow vs 0.01 m/N x ConstraintForces force [m]"] = err_vec
    # Achieved 0 and 1.6e-16 m (float sums of numbers of order 1).
    check("arrows start at the contact points", err_start <= 1e-12, err_start)
    check("arrow = scale x force", err_vec <= 1e-14, err_vec)
    if check("one footprint marker", len(outline) == 1, len(outline)):
        o = outline[0]
        check("footprint: 6 outlines of 4 edges", o.type == Marker.LINE_LIST
              and len(o.points) == 48, len(o.points))
        e = max(abs(o.points[0].x - X0 - FOOTPRINT0[0]), abs(o.points[0].y - Y0 - FOOTPRINT0[1]))
        FIGURES["footprint first corner vs odometry pose + vertex [m]"] = e
        check("footprint starts at the base pose", e <= 1e-14, e)  # achieved 8.3e-17 m
    FIGURES["markers in the array"] = len(array.markers)
    # markers.wrenches: the wheel's wrench in its own frame about its origin. At the start
    # state the wheel angle is 0 (joint_states) and the yaw 0 (odometry): the wheel's axes are
    # the odom axes, so it equals the ConstraintForce's wrench (odom axes, about the same origin).
    w = next((w for w in peer.wrenches if stamp_ns(w.header.stamp) == stamp_ns(cf.header.stamp)),
             None)
    if check("a WrenchStamped of the same stamp", w is not None, len(peer.wrenches)):
        c = cf.constraints[0]
        check("wrench frame = the wheel link", w.header.frame_id == "left_wheel",
              w.header.frame_id)
        a, b = w.wrench, c.wrench
        e = max(abs(getattr(getattr(a, k), i) - getattr(getattr(b, k), i))
                for k in ("force", "torque") for i in "xyz")
        FIGURES["WrenchStamped vs ConstraintForce wrench (wheel at angle 0) [N, N m]"] = e
        check("wrench = the constraint force's", e <= 1e-12, e)


def phase_twist(peer):
    peer.command = (0.1, -0.3)
    since = peer.sim + int(HORIZON * 1e9) + 500 * 10**6
    follows(peer, 0.1, -0.3, since, "TwistStamped (0.1, -0.3)")
    # A plain Twist publisher replaces the stamped one: the predictor must switch (graph).
    peer.destroy_publisher(peer.cmd_pub)
    peer.stamped = False
    peer.cmd_pub = peer.create_publisher(Twist, NS + "/cmd_vel", 10)
    peer.command = (0.2, -0.4)
    t_switch = time.monotonic()
    switched = peer.spin_until(
        lambda: any(abs(m.twist.twist.linear.x - 0.2) < 2e-3 for m in peer.odom[-3:]))
    check("the predictor follows a plain Twist publisher", switched)
    FIGURES["Twist publisher → first prediction following it [s wall]"] = time.monotonic() - t_switch
    # Predictions started from now on.
    follows(peer, 0.2, -0.4, peer.sim + int(HORIZON * 1e9), "Twist (0.2, -0.4)")


def phase_diagnostics(peer):
    names = {f"{NS}/{n}" for n in NODES}
    ok_seen, last = set(), {}

    def all_ok():
        for d in peer.diags:
            for s in d.status:
                last[s.name] = (s.level, s.message)
                if s.level == DiagnosticStatus.OK:
                    ok_seen.add(s.name)
        return names <= ok_seen
    check("every node reports OK on /diagnostics", peer.spin_until(all_ok), last)
    peer.odom_on = False
    n0 = len(peer.diags)

    def warn():
        return any(s.name == NS + "/cd_predictor" and s.level == DiagnosticStatus.WARN
                   and "odom stale" in s.message for d in peer.diags[n0:] for s in d.status)
    check("predictor WARN when odometry stops", peer.spin_until(warn),
          [(s.name, s.level, s.message) for d in peer.diags[n0:] for s in d.status][-4:])


def phase_lifecycle_down(peer):
    n = "cd_predictor"
    topic = NS + "/cd_predictor/predicted_odom"
    check("deactivate", peer.change(n, Transition.TRANSITION_DEACTIVATE))
    check("inactive again", peer.state(n) == (2, "inactive"), peer.state(n))
    peer.spin_for(0.3)  # messages already in flight
    count = len(peer.odom) + len(peer.markers)
    check("deactivated: predicted_odom publisher gone",
          peer.spin_until(lambda: peer.count_publishers(topic) == 0, 5.0))
    peer.spin_for(1.5)
    FIGURES["messages received 0.3–1.8 s after deactivate"] = len(peer.odom) + len(peer.markers) - count
    check("deactivated: nothing published", len(peer.odom) + len(peer.markers) == count)
    check("other nodes still serve", peer.has_service(NS + "/cd_prediction/predict"))
    check("cleanup", peer.change(n, Transition.TRANSITION_CLEANUP))
    check("unconfigured again", peer.state(n) == (1, "unconfigured"), peer.state(n))
    check("shutdown by label", peer.change(n, 0, "shutdown"))
    check("finalized", peer.state(n) == (4, "finalized"), peer.state(n))
    tr = peer.call(GetAvailableTransitions, NS + "/cd_predictor/get_available_transitions",
                   GetAvailableTransitions.Request()).available_transitions
    check("finalized: no transitions", len(tr) == 0, tr)
    check("finalized refuses activate", not peer.change(n, Transition.TRANSITION_ACTIVATE))
    peer.spin_until(lambda: len(peer.events[n]) >= 10, 5.0)
    ev = [(e.start_state.id, e.goal_state.id, e.transition.id) for e in peer.events[n]][4:]
    check("events down", ev == [(3, 14, 4), (14, 2, 40), (2, 11, 2), (11, 1, 20), (1, 12, 5),
                                (12, 4, 50)], ev)


def main():
    rclpy.init()
    peer = Stack()
    try:
        # The suite's lifecycle services, discovered.
        client = peer.service_clients[NS + "/cd_predictor/get_state"]
        if not client.wait_for_service(timeout_sec=TIMEOUT):
            raise RuntimeError("the suite's lifecycle services were not discovered")
        for phase in (phase_lifecycle_up, phase_prediction, phase_markers, phase_twist,
                      phase_diagnostics, phase_lifecycle_down):
            phase(peer)
    except Exception as e:  # noqa: BLE001 - report everything as JSON
        ERRORS.append(f"{type(e).__name__}: {e}")
    finally:
        peer.destroy_node()
        rclpy.shutdown()
    print(json.dumps({"ok": not ERRORS, "errors": ERRORS, "figures": FIGURES}))
    return 0 if not ERRORS else 1


if __name__ == "__main__":
    sys.exit(main())
