#!/usr/bin/env python3
"""A real ROS 2 peer (rclpy, rmw_fastrtps_cpp) that sets a payload (nodes/tests/it/suite_payload_rclpy.rs).

    tools/ros2/netns_run.sh .venv-ros2/bin/python nodes/tests/peers/payload_peer.py NODE REQUEST_JSON

Run inside the loopback-only namespace of a running node NODE (e.g. /cd_forces). It
1. calls NODE/set_payload with two bad requests (a negative mass; an unknown frame) and then the
   good one in REQUEST_JSON ({"frame": ..., "inertia": {"m": ..., "com": {...}, "ixx": ...}});
2. reads /diagnostics until NODE's status reports the payload in use.
It prints one JSON object on the last line of stdout and exits 0 iff `ok`.
"""
import copy
import json
import sys
import time

import rclpy
from rclpy.node import Node

from constraint_dynamics_msgs.srv import SetPayload
from diagnostic_msgs.msg import DiagnosticArray

TIMEOUT = 20.0


def fill(msg, data):
    for name, value in data.items():
        current = getattr(msg, name)
        if hasattr(current, "get_fields_and_field_types"):
            fill(current, value)
        else:
            setattr(msg, name, value)
    return msg


def call(node, client, request):
    if not client.wait_for_service(timeout_sec=TIMEOUT):
        raise RuntimeError(f"service {client.srv_name} not available")
    fut = client.call_async(request)
    rclpy.spin_until_future_complete(node, fut, timeout_sec=TIMEOUT)
    if not fut.done():
        raise RuntimeError(f"no response from {client.srv_name}")
    r = fut.result()
    return {"success": r.success, "message": r.message}


def main():
    target, good = sys.argv[1], json.loads(sys.argv[2])
    out = {"ok": False, "errors": []}
    rclpy.init()
    node = Node("cd_payload_peer")
    try:
        statuses = []
        node.create_subscription(DiagnosticArray, "/diagnostics",
                                 lambda m: statuses.extend(m.status), 10)
        client = node.create_client(SetPayload, target + "/set_payload")
        negative = copy.deepcopy(good)
        negative["inertia"]["m"] = -1.0
        unknown = copy.deepcopy(good)
        unknown["frame"] = "gripper"
        for key, data in [("negative_mass", negative), ("unknown_frame", unknown), ("good", good)]:
            out[key] = call(node, client, fill(SetPayload.Request(), data))
        deadline = time.monotonic() + TIMEOUT
        out["diagnostics_payload"] = None
        while time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.05)
            mine = [s for s in statuses if s.name == target]
            values = [kv.value for s in mine for kv in s.values if kv.key == "payload"]
            if values and values[-1] != "none":
                out["diagnostics_payload"] = values[-1]
                break
        if out["diagnostics_payload"] is None:
            out["errors"].append(f"no /diagnostics status of {target} with a payload")
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
