#!/usr/bin/env python3
"""Pinocchio's view of every example-robot-data URDF: does it load (fixed and floating base), and
its joint-space inertia M at two configurations, as JSON on stdout.

    .venv-anchors/bin/python tools/robots/pin_mass_matrices.py ROBOTS_DIR > pin.json

ROBOTS_DIR is example-robot-data's `robots/` folder (tools/robots/setup_venv.sh prints it).
The second configuration is drawn here (numpy, fixed seed) and written out joint by joint, so the
Rust test (tests/it/example_robot_data.rs) evaluates M at exactly the same state: joint angles
[rad] or positions [m] by URDF joint name, and the floating base's pose [x, y, z, qx, qy, qz, qw].
M's rows and columns are given in Pinocchio's order with each joint's name and first velocity
index, so the test maps them to its own order by name. No DDS, no network.
"""
import json, pathlib, sys

import numpy as np
import pinocchio as pin


def joints(model):
    """(name, idx_q, idx_v, nq, nv) of every joint except the universe."""
    return [(model.names[j], model.joints[j].idx_q, model.joints[j].idx_v,
             model.joints[j].nq, model.joints[j].nv) for j in range(1, model.njoints)]


def configuration(model, rng):
    """(pin q, {joint: value}, base pose or None); None, None, None for the neutral one."""
    q = pin.neutral(model)
    values, base = {}, None
    for name, iq, iv, nq, nv in joints(model):
        if nq == 7:  # free-flyer: a position and a random unit quaternion
            quat = rng.normal(size=4)
            quat /= np.linalg.norm(quat)
            base = list(rng.uniform(-1, 1, 3)) + list(quat)
            q[iq:iq + 7] = base
        elif nq == 2 and nv == 1:  # unbounded revolute: (cos θ, sin θ)
            a = rng.uniform(-1.5, 1.5)
            q[iq:iq + 2] = [np.cos(a), np.sin(a)]
            values[name] = a
        elif nq == 1:
            a = rng.uniform(-1.5, 1.5)
            q[iq] = a
            values[name] = a
        else:
            raise ValueError(f"joint {name}: nq = {nq}, nv = {nv} not handled")
    return q, values, base


def describe(path, floating):
    try:
        model = (pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer()) if floating
                 else pin.buildModelFromUrdf(str(path)))
    except Exception as e:  # Pinocchio's refusal is data here
        return {"ok": False, "error": str(e).strip()[:300]}
    data = model.createData()
    rng = np.random.default_rng(20261123)
    configs = []
    for k in range(2):
        if k == 0:
            q, values, base = pin.neutral(model), {n: 0.0 for n, *_ in joints(model) if n != "root_joint"}, None
            if floating:
                base = [0, 0, 0, 0, 0, 0, 1]
        else:
            q, values, base = configuration(model, rng)
        m = pin.crba(model, data, q)
        m = np.triu(m) + np.triu(m, 1).T
        configs.append({"q": values, "base": base, "M": m.tolist()})
    return {
        "ok": True,
        "nv": model.nv,
        "joints": [{"name": n, "idx_v": iv, "nv": nv} for n, iq, iv, nq, nv in joints(model)],
        "configs": configs,
    }


def main():
    root = pathlib.Path(sys.argv[1])
    out = []
    for path in sorted(root.rglob("*.urdf")):
        out.append({
            "file": str(path.relative_to(root)),
            "fixed": describe(path, False),
            "floating": describe(path, True),
        })
    json.dump({"pinocchio": pin.__version__, "robots": out}, sys.stdout)


if __name__ == "__main__":
    main()
