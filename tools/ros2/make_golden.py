#!/usr/bin/env python3
"""Write golden CDR bytes of ROS 2 messages, made by rclpy (rmw_fastrtps_cpp).

    tools/ros2/netns_run.sh .venv-ros2/bin/python tools/ros2/make_golden.py [OUT_DIR]

OUT_DIR defaults to nodes/tests/golden. For every case it writes CASE.bin (the
bytes of rclpy.serialization.serialize_message: 4-byte encapsulation header +
CDR body) and adds the message's field values to values.json, so the Rust test
nodes/tests/it/golden_messages.rs can build the same message, serialize it with
the serializer ros2-client uses, and compare bytes. serialize_message opens no
DDS participant; run it in the namespace wrapper anyway.

Fast-CDR does not initialise padding bytes, and it sizes the buffer as if an
empty float64[] were followed by alignment, so rclpy's bytes carry a few
bytes of leftover memory (at alignment gaps and up to 7 at the end). This
script walks the CDR layout of each message, sets those bytes to zero, and
checks that rclpy deserializes the zeroed bytes to the same message: so the
golden files are deterministic and still exactly what a Fast DDS peer reads.

The values are chosen to exercise the CDR layout: strings of every length mod 4
(padding), a non-ASCII string, -0.0, a covariance of 36 distinct numbers,
nested sequences of structs with strings, bools next to float64s, and a few
empty sequences.
"""
import array
import json
import os
import sys

import numpy
from rclpy.serialization import deserialize_message, serialize_message
from rosidl_parser import definition as idl

from builtin_interfaces.msg import Time
from std_msgs.msg import Header, String
from geometry_msgs.msg import (Inertia, Point, Pose, PoseStamped, PoseWithCovariance, Quaternion,
                               Twist, TwistStamped, TwistWithCovariance, Vector3, Wrench,
                               WrenchStamped)
from std_msgs.msg import ColorRGBA
from builtin_interfaces.msg import Duration
from visualization_msgs.msg import Marker, MarkerArray, MeshFile, UVCoordinate
from lifecycle_msgs.msg import State, Transition, TransitionDescription, TransitionEvent
from lifecycle_msgs.srv import ChangeState, GetAvailableStates, GetAvailableTransitions, GetState
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger
from nav_msgs.msg import Odometry, Path
from constraint_dynamics_msgs.msg import (AccelerationLimit, AccelerationLimits, ConstraintForce,
                                         ConstraintForces)
from constraint_dynamics_msgs.srv import (GetConstraintForces, Predict, ProjectVelocity, Rollouts,
                                          SetPayload)


def to_plain(value):
    """A message (or field value) as JSON-able data, field names as in the .msg."""
    if hasattr(value, "get_fields_and_field_types"):
        fields = value.get_fields_and_field_types()
        if not fields:
            # rosidl gives every empty structure this uint8 member (it is on the wire).
            return {"structure_needs_at_least_one_member": 0}
        return {name: to_plain(getattr(value, name)) for name in fields}
    if isinstance(value, (list, tuple, array.array, numpy.ndarray)):
        return [to_plain(v) for v in value]
    if isinstance(value, (numpy.floating,)):
        return float(value)
    if isinstance(value, (numpy.integer,)):
        return int(value)
    if isinstance(value, (bool, int, float, str)):
        return value
    raise TypeError(f"cannot convert {type(value)}")


PRIMITIVE_SIZE = {
    "boolean": 1, "octet": 1, "char": 1, "uint8": 1, "int8": 1,
    "int16": 2, "uint16": 2, "wchar": 2,
    "int32": 4, "uint32": 4, "float": 4,
    "int64": 8, "uint64": 8, "double": 8,
}


def padding_offsets(msg):
    """Offsets (relative to the CDR body) of the alignment gaps of msg (XCDR1:
    each primitive aligned to its size; string and sequence lengths are uint32;
    an empty sequence has no element alignment)."""
    pads = []
    off = 0

    def align(n):
        nonlocal off
        while off % n:
            pads.append(off)
            off += 1

    def walk_type(t, value):
        nonlocal off
        if isinstance(t, idl.BasicType):
            size = PRIMITIVE_SIZE[t.typename]
            align(size)
            off += size
        elif isinstance(t, idl.AbstractString) and not isinstance(t, idl.AbstractWString):
            align(4)
            off += 4 + len(value.encode("utf-8")) + 1
        elif isinstance(t, idl.AbstractSequence):
            align(4)
            off += 4
            for v in value:
                walk_type(t.value_type, v)
        elif isinstance(t, idl.Array):
            for v in value:
                walk_type(t.value_type, v)
        elif isinstance(t, idl.NamespacedType):
            walk_struct(value)
        else:
            raise TypeError(f"no CDR layout rule for {t}")

    def walk_struct(m):
        nonlocal off
        if not m.SLOT_TYPES:
            off += 1  # the uint8 member of an empty structure
            return
        for name, t in zip(m.get_fields_and_field_types(), m.SLOT_TYPES):
            walk_type(t, getattr(m, name))

    walk_struct(msg)
    return pads, off


def zero_padding(msg, data):
    """data with its alignment gaps and trailing bytes zeroed; checked to decode to msg."""
    if data[:4] != b"\x00\x01\x00\x00":
        raise ValueError(f"unexpected encapsulation header {data[:4].hex()}")
    pads, end = padding_offsets(msg)
    body = bytearray(data[4:])
    if end > len(body) or len(body) - end > 7:
        raise ValueError(f"walked {end} bytes but the body has {len(body)}")
    for i in pads:
        body[i] = 0
    for i in range(end, len(body)):
        body[i] = 0
    out = data[:4] + bytes(body)
    if deserialize_message(out, type(msg)) != msg:
        raise ValueError("zeroing the padding changed the decoded message")
    return out, len(pads), len(body) - end


def type_name(msg):
    module = type(msg).__module__.split(".")  # e.g. nav_msgs.msg._odometry
    return f"{module[0]}/{module[1]}/{type(msg).__name__}"


def stamp(sec, nanosec):
    return Time(sec=sec, nanosec=nanosec)


def header(frame_id, sec=1_700_000_123, nanosec=456_789_012):
    return Header(stamp=stamp(sec, nanosec), frame_id=frame_id)


def vec3(x, y, z):
    return Vector3(x=x, y=y, z=z)


def pose(x, y, z, qx, qy, qz, qw):
    return Pose(position=Point(x=x, y=y, z=z), orientation=Quaternion(x=qx, y=qy, z=qz, w=qw))


def twist(vx, vy, vz, wx, wy, wz):
    return Twist(linear=vec3(vx, vy, vz), angular=vec3(wx, wy, wz))


def covariance(offset):
    # 36 distinct numbers, none exactly representable as a short decimal.
    return [offset + 0.01 * i + (i % 7) * 1e-5 for i in range(36)]


def constraint_force(i):
    c = ConstraintForce()
    c.name = ["left_wheel_contact", "caster_weld", "ab"][i % 3]
    c.kind = ["rolling", "weld", "distance"][i % 3]
    c.frame_id = ["left_wheel", "caster", "link_a"][i % 3]
    c.axes_frame_id = ["world", "caster", "base_link"][i % 3]
    c.wrench = Wrench(force=vec3(1.5 + i, -2.25, 98.0665), torque=vec3(0.125, -0.0, 3.0e-7 * (i + 1)))
    c.multipliers = [10.5 + i, -3.25, 0.0078125][: 3 - (i % 3)]
    c.row_names = ["x", "yy", "zzz"][: 3 - (i % 3)]
    c.position_residual = [1e-9 * (i + 1), -2e-10]
    c.velocity_residual = [3.5e-8]
    c.normal_force = 49.03325 if i % 3 == 0 else 0.0
    c.tangential_force = 12.5 if i % 3 == 0 else 0.0
    c.slipping = (i % 3 == 0)
    return c


def constraint_forces(n, sec=1_700_000_200):
    f = ConstraintForces()
    f.header = header("world", sec=sec, nanosec=5)
    f.constraints = [constraint_force(i) for i in range(n)]
    f.v_names = ["base_x", "base_y", "base_yaw", "left_wheel", "right_wheel_j"]
    f.generalized_force = [0.5, -1.75, 2.0e3, 0.1, -0.2]
    f.rank_deficiency = 2
    return f


def acceleration_limits():
    m = AccelerationLimits()
    m.header = header("base_footprint", sec=1_700_000_300, nanosec=7)
    # A bool-free message of uint8s next to float64s: padding of 7 after each status.
    m.forward_acceleration = AccelerationLimit(
        status=AccelerationLimit.BOUNDED, max=9.28125,
        binding_kinds=["lift_off", "lift_off"],
        binding_names=["left_wheel_contact", "right_wheel_contact"])
    m.forward_deceleration = AccelerationLimit(
        status=AccelerationLimit.BOUNDED, max=-0.0,
        binding_kinds=["effort", "friction", "lift_off"], binding_names=["a", "ab", "abc"])
    m.yaw_acceleration_left = AccelerationLimit(status=AccelerationLimit.UNBOUNDED, max=0.0)
    m.yaw_acceleration_right = AccelerationLimit(status=AccelerationLimit.INFEASIBLE, max=0.0)
    m.unchecked_kinds = ["friction", "effort"]
    m.unchecked_names = ["left_wheel_contact", "caster_j\u00fc"]
    return m


def cases():
    out = {}

    out["builtin_interfaces__Time"] = stamp(1_700_000_000, 999_999_999)
    out["std_msgs__Header"] = header("odom")
    out["std_msgs__String"] = String(data="<robot name=\"wheelie\"/> \u00fc\u00df")
    out["geometry_msgs__Vector3"] = vec3(1.0, -2.5, 3.25e-3)
    out["geometry_msgs__Point"] = Point(x=-0.0, y=1e-300, z=123456.789)
    out["geometry_msgs__Quaternion"] = Quaternion(x=0.1, y=-0.2, z=0.3, w=0.9273618495495704)
    out["geometry_msgs__Pose"] = pose(1.0, 2.0, 0.05, 0.0, 0.0, 0.38268343236508984, 0.9238795325112867)
    out["geometry_msgs__PoseStamped"] = PoseStamped(
        header=header("map"), pose=pose(-4.5, 0.25, 0.0, 0.0, 0.0, -0.1, 0.99498743710662))
    out["geometry_msgs__PoseWithCovariance"] = PoseWithCovariance(
        pose=pose(3.0, -1.0, 0.0, 0.0, 0.0, 0.0, 1.0), covariance=covariance(0.5))
    out["geometry_msgs__Twist"] = twist(0.5, -0.05, 0.0, 0.001, -0.002, 0.75)
    out["geometry_msgs__TwistStamped"] = TwistStamped(
        header=header("base_link"), twist=twist(0.3, 0.0, 0.0, 0.0, 0.0, -0.4))
    out["geometry_msgs__TwistWithCovariance"] = TwistWithCovariance(
        twist=twist(0.2, 0.1, 0.0, 0.0, 0.0, 0.6), covariance=covariance(-1.0))
    out["geometry_msgs__Wrench"] = Wrench(force=vec3(10.0, -20.0, 30.5), torque=vec3(-0.1, 0.2, -0.3))

    js = JointState()
    js.header = header("")  # empty string: length 1 (just the NUL)
    js.name = ["left_wheel_joint", "right_wheel_joint", "caster_swivel", "c"]
    js.position = [0.1, -0.2, 3.14159, 1e3]
    js.velocity = [1.5, -1.5, 0.0, 2.0]
    js.effort = []  # empty sequence: length 0, no padding
    out["sensor_msgs__JointState"] = js

    odom = Odometry()
    odom.header = header("odom")
    odom.child_frame_id = "base_link"
    odom.pose = PoseWithCovariance(pose=pose(1.25, -0.5, 0.0, 0.0, 0.0, 0.2, 0.9797958971132712),
                                   covariance=covariance(0.001))
    odom.twist = TwistWithCovariance(twist=twist(0.4, -0.01, 0.0, 0.0, 0.0, 0.3),
                                     covariance=covariance(2.0))
    out["nav_msgs__Odometry"] = odom

    path = Path()
    path.header = header("odom")
    path.poses = [PoseStamped(header=header("odom", sec=1_700_000_123 + k, nanosec=k * 1000),
                              pose=pose(0.1 * k, 0.01 * k * k, 0.0, 0.0, 0.0, 0.05 * k, 1.0 - 0.001 * k))
                  for k in range(3)]
    out["nav_msgs__Path"] = path

    out["std_srvs__Trigger_Request"] = Trigger.Request()
    out["std_srvs__Trigger_Response"] = Trigger.Response(success=True, message="triggered")

    out["constraint_dynamics_msgs__ConstraintForce"] = constraint_force(0)
    out["constraint_dynamics_msgs__ConstraintForces"] = constraint_forces(3)
    out["constraint_dynamics_msgs__ConstraintForces_empty"] = ConstraintForces()
    out["constraint_dynamics_msgs__AccelerationLimit"] = AccelerationLimit(
        status=AccelerationLimit.BOUNDED, max=-0.515312345678,
        binding_kinds=["lift_off"], binding_names=["caster_contact"])
    out["constraint_dynamics_msgs__AccelerationLimits"] = acceleration_limits()

    req = GetConstraintForces.Request()
    req.use_latest_state = False
    req.q_names = ["base_x", "base_y", "base_yaw", "left_wheel"]
    req.q = [0.5, -0.25, 1.5707963267948966, 12.0]
    req.v_names = ["base_x", "base_y"]
    req.v = [0.1, 0.2]
    req.tau = [0.0, 1.5, -1.5]
    out["constraint_dynamics_msgs__GetConstraintForces_Request"] = req

    resp = GetConstraintForces.Response()
    resp.success = True
    resp.message = "ok"
    resp.forces = constraint_forces(2, sec=1_700_000_300)
    resp.qdd = [0.01, -9.81, 0.0, 4.5, -4.5]
    out["constraint_dynamics_msgs__GetConstraintForces_Response"] = resp

    req = ProjectVelocity.Request()
    req.use_latest_state = True
    req.q = [0.0, 1.0]
    req.v_names = ["base_x"]
    req.v_des = [0.75]
    req.use_twist = True
    req.base_twist = twist(0.5, 0.1, 0.0, 0.0, 0.0, 0.25)
    req.joint_names = ["arm_joint_1", "gripper"]
    req.joint_velocities = [0.3, -0.01]
    req.bound_names = ["left_wheel", "right_wheel"]
    req.lower = [-10.0, -10.5]
    req.upper = [10.0, 10.5]
    req.accel_limit_dt = 0.02
    req.period = 0.05
    req.v_current = [0.1, 0.0, -0.25]
    out["constraint_dynamics_msgs__ProjectVelocity_Request"] = req

    resp = ProjectVelocity.Response()
    resp.success = False
    resp.message = "constraints conflict"
    resp.status = "infeasible"
    resp.v_names = ["base_x", "base_y", "base_yaw"]
    resp.v = [0.5, 0.0, 0.25]
    resp.base_twist = twist(0.5, 0.0, 0.0, 0.0, 0.0, 0.25)
    resp.joint_names = ["arm_joint_1"]
    resp.joint_velocities = [0.3]
    resp.constraint_names = ["left_wheel_contact", "right_wheel_contact"]
    resp.impulses = [0.125, -0.125]
    resp.active_bounds = ["left_wheel"]
    resp.conflicting = ["left_wheel_contact", "left_wheel.upper"]
    resp.binding_kinds = ["effort", "lift_off"]
    resp.binding_names = ["left_wheel_joint", "caster_contact"]
    resp.unchecked_kinds = ["friction"]
    resp.unchecked_names = ["caster_contact"]
    out["constraint_dynamics_msgs__ProjectVelocity_Response"] = resp

    req = Predict.Request()
    req.use_latest_state = False
    req.q = [0.0, 0.0, 0.1]
    req.v = [0.2, 0.0, 0.0]
    req.commands = [twist(0.2, 0.0, 0.0, 0.0, 0.0, 0.1), twist(0.25, 0.0, 0.0, 0.0, 0.0, -0.1)]
    req.command_period = 0.1
    req.horizon = 2.0
    req.with_forces = True
    req.with_covariance = True
    req.start_covariance = [0.01, 0.002, 0.002, 0.0025]  # bools before float64[]: padding
    out["constraint_dynamics_msgs__Predict_Request"] = req

    resp = Predict.Response()
    resp.success = True
    resp.message = ""
    resp.path = path
    resp.times = [0.0, 0.05, 0.1]
    resp.forces = [constraint_forces(1, sec=1_700_000_400), ConstraintForces()]
    resp.position_error_estimate = 1.5e-4
    resp.covariance_dimension = 2  # uint32 after a float64, before a float64[]
    resp.covariances = [0.01, -0.0, 0.0, 0.0025, 0.0125, 0.001, 0.001, 0.003,
                        0.02, 0.002, 0.002, 0.004]
    resp.orientation_error_estimate = 2.5e-4  # float64s after a float64[]
    resp.joint_error_estimate_rad = 0.0125
    resp.joint_error_estimate_m = 0.0  # a robot without prismatic joints
    out["constraint_dynamics_msgs__Predict_Response"] = resp

    req = Rollouts.Request()
    req.use_latest_state = True
    req.q = []
    req.v = [0.1, -0.0]
    req.commands = [twist(0.2, 0.0, 0.0, 0.0, 0.0, 0.1), twist(0.25, 0.0, 0.0, 0.0, 0.0, -0.1),
                    twist(-0.5, 0.0, 0.0, 0.0, 0.0, 1.0), twist(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)]
    req.sequence_length = 2  # uint32 after a sequence, before a float64: padding
    req.step = 0.05
    req.with_forces = True
    out["constraint_dynamics_msgs__Rollouts_Request"] = req

    resp = Rollouts.Response()
    resp.success = True
    resp.message = "2 rollouts × 2 steps"
    resp.header = header("odom")
    resp.poses = [pose(0.01, 0.0, 0.0, 0.0, 0.0, 0.0025, 1.0), pose(0.02, 1e-4, 0.0, 0.0, 0.0, 0.005, 1.0),
                  pose(-0.025, 0.0, 0.0, 0.0, 0.0, 0.025, 0.9996875), pose(-0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)]
    resp.twists = [twist(0.2, 0.0, 0.0, 0.0, 0.0, 0.1), twist(0.25, 0.0, 0.0, 0.0, 0.0, -0.1)]
    resp.forces = [constraint_forces(1, sec=1_700_000_500)]
    out["constraint_dynamics_msgs__Rollouts_Response"] = resp

    # A string of length 5 + NUL before the float64s (padding), -0.0 and a tiny number.
    inertia = Inertia(m=2.5, com=vec3(0.05, -0.0, 0.125), ixx=0.0125, ixy=-1e-4, ixz=0.0,
                      iyy=0.02, iyz=3e-300, izz=0.015)
    out["geometry_msgs__Inertia"] = inertia
    out["constraint_dynamics_msgs__SetPayload_Request"] = SetPayload.Request(frame="tool0",
                                                                             inertia=inertia)
    out["constraint_dynamics_msgs__SetPayload_Response"] = SetPayload.Response(
        success=False, message="inertia.m: -1 kg must be finite, ≥ 0 and ≤ 1e9")

    out["geometry_msgs__WrenchStamped"] = WrenchStamped(
        header=header("left_wheel"), wrench=Wrench(force=vec3(0.0, -3.0, 50.0),
                                                   torque=vec3(-0.15, 0.0, 1e-17)))
    # float32 fields hold numbers a float32 represents exactly (the JSON holds doubles).
    arrow = Marker(header=header("robot1/odom"), ns="constraint_forces", id=1, type=Marker.ARROW,
                   action=Marker.ADD, scale=vec3(0.02, 0.04, 0.06),
                   color=ColorRGBA(r=1.0, g=0.125, b=0.125, a=1.0),
                   lifetime=Duration(sec=1, nanosec=500_000_000), frame_locked=False,
                   points=[Point(x=1.0, y=2.17, z=0.0), Point(x=1.03, y=2.21, z=0.5)],
                   text="left_wheel_contact")
    lines = Marker(header=header("robot1/odom"), ns="predicted_footprint", id=0,
                   type=Marker.LINE_LIST, action=Marker.ADD, scale=vec3(0.01, 0.0, 0.0),
                   color=ColorRGBA(r=1.0, g=0.5, b=0.25, a=0.75),
                   points=[Point(x=0.15, y=0.15, z=0.0), Point(x=-0.25, y=0.15, z=0.0)],
                   colors=[ColorRGBA(r=0.5, g=0.5, b=0.5, a=1.0)],
                   uv_coordinates=[UVCoordinate(u=0.25, v=0.75)], texture_resource="tex",
                   mesh_resource="package://x/m.dae",
                   mesh_file=MeshFile(filename="m.stl", data=[1, 2, 3]),
                   mesh_use_embedded_materials=True)
    lines.texture.format = "png"
    lines.texture.data = [255, 0]
    out["visualization_msgs__Marker"] = arrow
    out["visualization_msgs__MarkerArray"] = MarkerArray(
        markers=[arrow, lines, Marker(action=Marker.DELETEALL)])

    out["lifecycle_msgs__State"] = State(id=State.TRANSITION_STATE_CONFIGURING, label="configuring")
    out["lifecycle_msgs__TransitionEvent"] = TransitionEvent(
        timestamp=1_795_452_830_400_577_640,
        transition=Transition(id=Transition.TRANSITION_ON_ACTIVATE_SUCCESS,
                              label="transition_success"),
        start_state=State(id=13, label="activating"), goal_state=State(id=3, label="active"))
    out["lifecycle_msgs__ChangeState_Request"] = ChangeState.Request(
        transition=Transition(id=0, label="shutdown"))
    out["lifecycle_msgs__ChangeState_Response"] = ChangeState.Response(success=True)
    out["lifecycle_msgs__GetState_Request"] = GetState.Request()
    out["lifecycle_msgs__GetState_Response"] = GetState.Response(
        current_state=State(id=2, label="inactive"))
    out["lifecycle_msgs__GetAvailableStates_Request"] = GetAvailableStates.Request()
    out["lifecycle_msgs__GetAvailableStates_Response"] = GetAvailableStates.Response(
        available_states=[State(id=1, label="unconfigured"), State(id=15, label="errorprocessing")])
    out["lifecycle_msgs__GetAvailableTransitions_Request"] = GetAvailableTransitions.Request()
    out["lifecycle_msgs__GetAvailableTransitions_Response"] = GetAvailableTransitions.Response(
        available_transitions=[TransitionDescription(
            transition=Transition(id=1, label="configure"),
            start_state=State(id=1, label="unconfigured"),
            goal_state=State(id=10, label="configuring"))])
    return out


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    out_dir = sys.argv[1] if len(sys.argv) > 1 else os.path.join(here, "..", "..", "nodes", "tests", "golden")
    os.makedirs(out_dir, exist_ok=True)
    index = {}
    for case, msg in cases().items():
        data, n_pad, n_trailing = zero_padding(msg, serialize_message(msg))
        with open(os.path.join(out_dir, case + ".bin"), "wb") as f:
            f.write(data)
        index[case] = {"type": type_name(msg), "bytes": len(data), "padding_bytes": n_pad,
                       "trailing_bytes": n_trailing, "value": to_plain(msg)}
    with open(os.path.join(out_dir, "values.json"), "w", encoding="utf-8") as f:
        json.dump(index, f, indent=1, ensure_ascii=False, allow_nan=False)
        f.write("\n")
    print(f"make_golden: wrote {len(index)} cases to {os.path.normpath(out_dir)}")


if __name__ == "__main__":
    main()
