#!/usr/bin/env python3
"""A real ROS 2 peer (rclpy, rmw_fastrtps_cpp) for the node suite (nodes/tests/it/suite_rclpy_peer.rs).

    tools/ros2/netns_run.sh .venv-ros2/bin/python nodes/tests/peers/suite_peer.py REQUESTS_JSON

Run inside the loopback-only namespace of a running suite (params/default.yaml). It
1. reads one message of each predictor topic (predicted_odom, predicted_path, constraint_forces)
   with rclpy's default QoS (reliable, depth 10);
2. calls ~/get_constraint_forces, ~/project_velocity and ~/predict with the requests given in
   REQUESTS_JSON ({"forces": {...}, "project": {...}, "predict": {...}}, field names as in the
   .srv files) and returns the responses field by field;
3. does what `ros2 param list/get/set` does: rcl_interfaces ListParameters, GetParameters and
   SetParameters on /cd_predictor (a refused and an accepted set).
It prints one JSON object on the last line of stdout and exits 0 iff `ok`.
"""
import array
import json
import sys
import time

import numpy
import rclpy
from rclpy.node import Node

from constraint_dynamics_msgs.msg import ConstraintForces
from constraint_dynamics_msgs.srv import GetConstraintForces, Predict, ProjectVelocity
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry, Path
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import GetParameters, ListParameters, SetParameters

TIMEOUT = 20.0


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


def fill(msg, data):
    """Set the fields of a message from plain JSON data (nested messages and lists of them)."""
    for name, value in data.items():
        current = getattr(msg, name)
        if hasattr(current, "get_fields_and_field_types"):
            fill(current, value)
        elif name == "commands":
            items = []
            for v in value:
                t = Twist()
                fill(t, v)
                items.append(t)
            setattr(msg, name, items)
        else:
            if isinstance(value, list):
                value = [float("nan") if v is None else v for v in value]
            setattr(msg, name, value)
    return msg


def call(node, client, request):
    if not client.wait_for_service(timeout_sec=TIMEOUT):
        raise RuntimeError(f"service {client.srv_name} not available")
    fut = client.call_async(request)
    rclpy.spin_until_future_complete(node, fut, timeout_sec=TIMEOUT)
    if not fut.done():
        raise RuntimeError(f"no response from {client.srv_name}")
    return fut.result()


def main():
    requests = json.loads(sys.argv[1])
    out = {"ok": False, "errors": []}
    rclpy.init()
    node = Node("cd_suite_peer")
    try:
        received = {}
        # Every client is made here, while the topics arrive, seconds before its first request:
        # a client made just before its request races the suite's discovery of it, and a lost
        # request waits for Fast DDS's next heartbeat (up to 3 s).
        services = [
            ("forces", GetConstraintForces, "/cd_forces/get_constraint_forces"),
            ("project", ProjectVelocity, "/cd_projection/project_velocity"),
            ("predict", Predict, "/cd_prediction/predict"),
        ]
        clients = {key: node.create_client(srv, name) for key, srv, name in services}
        lstc = node.create_client(ListParameters, "/cd_predictor/list_parameters")
        getc = node.create_client(GetParameters, "/cd_predictor/get_parameters")
        setc = node.create_client(SetParameters, "/cd_predictor/set_parameters")
        for topic, mtype, key in [
            ("/cd_predictor/predicted_odom", Odometry, "odom"),
            ("/cd_predictor/predicted_path", Path, "path"),
            ("/cd_predictor/constraint_forces", ConstraintForces, "forces"),
        ]:
            node.create_subscription(mtype, topic, lambda m, k=key: received.setdefault(k, m), 10)
        deadline = time.monotonic() + TIMEOUT
        while len(received) < 3 and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.05)
        for k in ("odom", "path", "forces"):
            if k not in received:
                out["errors"].append(f"no message on the predictor's {k} topic")
        out["topics"] = {k: to_plain(v) for k, v in received.items()}

        for key, srv, _ in services:
            resp = call(node, clients[key], fill(srv.Request(), requests[key]))
            out[key] = to_plain(resp)

        lst = call(node, lstc, ListParameters.Request())
        out["parameter_names"] = list(lst.result.names)
        get = call(node, getc,
                   GetParameters.Request(names=["rate", "model.scene_file", "command.fallback"]))
        out["parameters"] = [to_plain(v) for v in get.values]

        def set_double(name, x):
            p = Parameter(name=name, value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE,
                                                          double_value=x))
            r = call(node, setc, SetParameters.Request(parameters=[p]))
            return {"successful": r.results[0].successful, "reason": r.results[0].reason}

        out["set_rate"] = set_double("rate", 50.0)
        out["set_mu"] = set_double("slip.friction_coefficient", 0.5)
        get = call(node, getc, GetParameters.Request(names=["slip.friction_coefficient"]))
        out["mu_after"] = get.values[0].double_value
        out["ok"] = not out["errors"]
    except Exception as e:  # noqa: BLE001 - report everything as JSON
        out["errors"].append(f"{type(e).__name__}: {e}")
    finally:
        node.destroy_node()
        rclpy.shutdown()
    print(json.dumps(out))
    return 0 if out["ok"] else 1


if __name__ == "__main__":
    sys.exit(main())
