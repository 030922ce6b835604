#!/usr/bin/env python3
"""A real ROS 2 peer (rclpy, rmw_fastrtps_cpp) that sets parameters as `ros2 param set` does
(nodes/tests/it/suite_params_rclpy.rs), for a suite started with a predictor-only `-p` for every
node and a scene for cd_forces that does not exist.

    tools/ros2/netns_run.sh .venv-ros2/bin/python nodes/tests/peers/params_peer.py

It
1. sets each garbage payload value measured as accepted before (payload.com = [NaN, 0, 0],
   [0.0]; payload.inertia = [1.0, 2.0]) on /cd_predictor through rcl_interfaces/SetParameters,
   reading every payload.* parameter back with GetParameters after each;
2. sets payload.frame = base_link (valid) and back to "", then atomically payload.mass = 1.5
   with payload.frame = tool0 (a mass needs a frame: valid only as a whole), then atomically a
   valid mass with a bad inertia (refused as a whole, nothing stored); waits for /diagnostics
   to report the payload in use;
3. reads envelope.velocity_smoother on every node, the lifecycle state of every node, and the
   /diagnostics status of /cd_forces.
It prints one JSON object on the last line of stdout and exits 0 iff `ok` (the peer could do
all of it; the test judges the values).
"""
import json
import math
import sys
import time

import rclpy
from rclpy.node import Node

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from lifecycle_msgs.srv import GetState
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import GetParameters, SetParameters, SetParametersAtomically

NODES = ["cd_predictor", "cd_forces", "cd_projection", "cd_prediction"]
PAYLOAD = ["payload.frame", "payload.mass", "payload.com", "payload.inertia"]
TIMEOUT = 20.0


def call(node, client, request):
    if not client.wait_for_service(timeout_sec=TIMEOUT):
        raise RuntimeError(f"service {client.srv_name} not available")
    fut = client.call_async(request)
    rclpy.spin_until_future_complete(node, fut, timeout_sec=TIMEOUT)
    if not fut.done():
        raise RuntimeError(f"no response from {client.srv_name}")
    return fut.result()


def value(v):
    """A ParameterValue as JSON (NaN as the string "nan": JSON has no NaN)."""
    def num(x):
        return "nan" if math.isnan(x) else x
    if v.type == ParameterType.PARAMETER_NOT_SET:
        return {"not_set": True}
    if v.type == ParameterType.PARAMETER_DOUBLE:
        return num(v.double_value)
    if v.type == ParameterType.PARAMETER_STRING:
        return v.string_value
    if v.type == ParameterType.PARAMETER_DOUBLE_ARRAY:
        return [num(x) for x in v.double_array_value]
    return {"type": v.type}


def param(name, x):
    v = ParameterValue()
    if isinstance(x, str):
        v.type, v.string_value = ParameterType.PARAMETER_STRING, x
    elif isinstance(x, float):
        v.type, v.double_value = ParameterType.PARAMETER_DOUBLE, x
    else:
        v.type, v.double_array_value = ParameterType.PARAMETER_DOUBLE_ARRAY, [float(e) for e in x]
    return Parameter(name=name, value=v)


def main():
    out = {"ok": False, "errors": []}
    rclpy.init()
    node = Node("cd_params_peer")
    try:
        statuses = []
        node.create_subscription(DiagnosticArray, "/diagnostics",
                                 lambda m: statuses.extend(m.status), 10)
        pred = "/cd_predictor"
        get = node.create_client(GetParameters, pred + "/get_parameters")
        setp = node.create_client(SetParameters, pred + "/set_parameters")
        atomic = node.create_client(SetParametersAtomically, pred + "/set_parameters_atomically")
        # Every client is made here, seconds before its first request: a client made just before
        # its request races the suite's discovery of it, and a lost request waits for Fast DDS's
        # next heartbeat (up to 3 s).
        smoother_get = {n: node.create_client(GetParameters, f"/{n}/get_parameters")
                        for n in NODES}
        state_get = {n: node.create_client(GetState, f"/{n}/get_state") for n in NODES}

        def read():
            r = call(node, get, GetParameters.Request(names=PAYLOAD))
            return dict(zip(PAYLOAD, (value(v) for v in r.values)))

        def one(name, x):
            r = call(node, setp, SetParameters.Request(parameters=[param(name, x)]))
            res = r.results[0]
            return {"successful": res.successful, "reason": res.reason, "after": read()}

        def whole(pairs):
            req = SetParametersAtomically.Request(parameters=[param(n, x) for n, x in pairs])
            res = call(node, atomic, req).result
            return {"successful": res.successful, "reason": res.reason, "after": read()}

        out["before"] = read()
        out["garbage"] = [
            one("payload.com", [math.nan, 0.0, 0.0]),
            one("payload.com", [0.0]),
            one("payload.inertia", [1.0, 2.0]),
        ]
        out["valid_frame"] = one("payload.frame", "base_link")
        out["frame_cleared"] = one("payload.frame", "")
        out["atomic_good"] = whole([("payload.mass", 1.5), ("payload.frame", "tool0")])
        out["atomic_bad"] = whole([("payload.mass", 3.0), ("payload.inertia", [1.0, 2.0])])

        out["velocity_smoother"] = {}
        for n in NODES:
            r = call(node, smoother_get[n],
                     GetParameters.Request(names=["envelope.velocity_smoother"]))
            out["velocity_smoother"][n] = value(r.values[0])
        out["states"] = {}
        for n in NODES:
            out["states"][n] = call(node, state_get[n], GetState.Request()).current_state.id

        deadline = time.monotonic() + TIMEOUT
        out["forces_status"] = None
        out["predictor_payload"] = None
        while time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.05)
            for s in statuses:
                if s.name == "/cd_forces" and out["forces_status"] is None:
                    out["forces_status"] = {
                        "error": s.level == DiagnosticStatus.ERROR,
                        "message": s.message,
                        "values": {kv.key: kv.value for kv in s.values},
                    }
                if s.name == pred:
                    payload = [kv.value for kv in s.values if kv.key == "payload"]
                    if payload and payload[-1] != "none":
                        out["predictor_payload"] = payload[-1]
            if out["forces_status"] and out["predictor_payload"]:
                break
        if out["forces_status"] is None:
            out["errors"].append("no /diagnostics status of /cd_forces")
        if out["predictor_payload"] is None:
            out["errors"].append("no /diagnostics status of /cd_predictor with a payload")
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
