#!/usr/bin/env python3
"""rclpy (rmw_fastrtps_cpp) client of large ~/predict replies (nodes/tests/it/large_replies.rs).

    tools/ros2/netns_run.sh .venv-ros2/bin/python nodes/tests/peers/large_replies_peer.py CONFIG_JSON

Run inside the loopback-only namespace of a running suite (params/default.yaml). CONFIG_JSON:
  {"sweep": [[horizon, with_forces], ...],   # one call each, sizes around the datagram limits
   "repeat": [horizon, with_forces, count],  # then `count` consecutive calls
   "path_horizon": 20.0,                     # then wait for a ~/predicted_path this long (0: skip)
   "timeout": 30.0}                          # per call / for the path
Every call goes through ONE rclpy client (a lost reply used to block that client for good).
Before the calls it raises /cd_prediction max_horizon to 30 s; before the path check it sets
/cd_predictor horizon to path_horizon. Prints one JSON object on the last line of stdout (sizes:
serialized payload bytes, encapsulation header included) and exits 0 iff `ok`.
"""
import json
import sys
import time

import rclpy
from rclpy.node import Node
from rclpy.serialization import serialize_message

from constraint_dynamics_msgs.srv import Predict
from nav_msgs.msg import Path
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters


def wait(node, fut, timeout):
    deadline = time.monotonic() + timeout
    while not fut.done() and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.05)
    return fut.done()


def set_double(node, service, name, x, timeout):
    c = node.create_client(SetParameters, service)
    if not c.wait_for_service(timeout_sec=timeout):
        raise RuntimeError(f"{service} not available")
    p = Parameter(name=name, value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE,
                                                  double_value=float(x)))
    for _ in range(5):  # the first request can race the server's discovery of this client
        fut = c.call_async(SetParameters.Request(parameters=[p]))
        if wait(node, fut, 3.0):
            r = fut.result().results[0]
            if not r.successful:
                raise RuntimeError(f"set {name}={x}: {r.reason}")
            return
    raise RuntimeError(f"no response from {service}")


def request(horizon, with_forces):
    return Predict.Request(use_latest_state=True, command_period=1.0, horizon=float(horizon),
                           with_forces=bool(with_forces))


def main():
    cfg = json.loads(sys.argv[1])
    timeout = float(cfg.get("timeout", 30.0))
    out = {"ok": False, "errors": [], "sweep": [], "repeat": [], "path": None}
    rclpy.init()
    node = Node("cd_large_replies_peer")
    try:
        set_double(node, "/cd_prediction/set_parameters", "max_horizon", 30.0, timeout)
        client = node.create_client(Predict, "/cd_prediction/predict")
        if not client.wait_for_service(timeout_sec=timeout):
            raise RuntimeError("/cd_prediction/predict not available")
        # A small first call, repeated until answered: settles discovery both ways.
        for _ in range(5):
            fut = client.call_async(request(0.1, False))
            if wait(node, fut, 3.0):
                break
        else:
            raise RuntimeError("no reply to a small Predict request")

        def one(horizon, with_forces):
            t0 = time.monotonic()
            row = {"horizon": horizon, "forces": bool(with_forces)}
            # "busy" is the node's bounded request queue pushing back (a loaded machine):
            # honour it by waiting and asking again, a bounded number of times.
            for _ in range(10):
                fut = client.call_async(request(horizon, with_forces))
                arrived = wait(node, fut, timeout)
                if not (arrived and not fut.result().success
                        and fut.result().message.startswith("busy")):
                    break
                time.sleep(1.0)
            if arrived:
                resp = fut.result()
                row.update(arrived=True, success=resp.success, bytes=len(serialize_message(resp)),
                           samples=len(resp.path.poses), n_forces=len(resp.forces),
                           seconds=round(time.monotonic() - t0, 3))
                if not resp.success:
                    out["errors"].append(f"predict {horizon} s: {resp.message}")
            else:
                row.update(arrived=False)
                out["errors"].append(f"no reply to predict {horizon} s (forces {with_forces}) "
                                     f"within {timeout} s")
            return row

        for horizon, with_forces in cfg.get("sweep", []):
            out["sweep"].append(one(horizon, with_forces))
            if len(out["errors"]) >= 2:
                raise RuntimeError("stopping after two lost or failed replies")
        if cfg.get("repeat"):
            horizon, with_forces, count = cfg["repeat"]
            for _ in range(int(count)):
                out["repeat"].append(one(horizon, with_forces))
                if len(out["errors"]) >= 2:
                    raise RuntimeError("stopping after two lost or failed replies")

        path_horizon = float(cfg.get("path_horizon", 0.0))
        if path_horizon > 0:
            set_double(node, "/cd_predictor/set_parameters", "horizon", path_horizon, timeout)
            want = int(round(path_horizon / 0.02))  # the suite samples paths every 20 ms
            got = {}

            def keep(msg):
                if len(msg.poses) >= want and "msg" not in got:
                    got["msg"] = msg

            node.create_subscription(Path, "/cd_predictor/predicted_path", keep, 10)
            deadline = time.monotonic() + timeout
            while "msg" not in got and time.monotonic() < deadline:
                rclpy.spin_once(node, timeout_sec=0.05)
            if "msg" in got:
                out["path"] = {"poses": len(got["msg"].poses),
                               "bytes": len(serialize_message(got["msg"]))}
            else:
                out["errors"].append(f"no predicted_path with >= {want} poses within {timeout} s")
        out["ok"] = not out["errors"]
    except Exception as e:  # noqa: BLE001 - report everything as JSON
        out["errors"].append(f"{type(e).__name__}: {e}")
    finally:
        node.destroy_node()
        rclpy.shutdown()
    print(json.dumps(out), flush=True)
    return 0 if out["ok"] else 1


if __name__ == "__main__":
    sys.exit(main())
