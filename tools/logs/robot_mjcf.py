"""The bundled mobile manipulator (urdf/mobile_manipulator.urdf) as a MuJoCo model, built from the
URDF's own numbers, with what its scene (params/suite_mobile_manipulator.yaml) does not know:

- a heavier chassis (its mass and inertia scaled by CHASSIS_MASS_FACTOR),
- worn tyres: the wheels' rolling radius WORN_RADIUS_FACTOR of the nominal one,
- wide tyres: TYRE_WIDTH_M wide on soft contacts with Coulomb friction TYRE_MU and a little
  torsional and rolling friction, so a turn scrubs the tyres' width. MuJoCo's cylinder touches a
  plane at its two rims; a tyre's patch of uniform pressure carries each half of its load at a
  quarter of its width from the middle, so the collision cylinder is half the tyre's width long
  (its rims where the patch's halves push),
- a low-friction ball caster (a sphere sliding with CASTER_MU), and a front anti-tip skid of the
  same kind ANTI_TIP_CLEARANCE_M above the floor: with the arm leaning forward (the scene's
  initial pose) the robot's centre of mass is within millimetres of the wheel axle, and without
  it a braking robot pitches onto its nose, which the URDF leaves without a collision shape.

A drive may also carry a payload the scene is not told of: a solid sphere of PAYLOAD_RADIUS_M
with its centre at tool0's origin (`mjcf(..., payload_kg=M)`).

MuJoCo gives a contact the larger of its two geoms' frictions (and condims) unless one geom has
the higher `priority`; the floor's friction (1, as the default's) would then override every
number above. The robot's contact geoms carry priority 1, so each contact has the robot's own.

The base is a free body (it may pitch and roll on the soft contacts); the arm's joints and the
wheels are hinges with the URDF's damping. The controllers are not part of the model: the
simulation applies their torques (make_logs.py).
"""

import xml.etree.ElementTree as ET

CHASSIS_MASS_FACTOR = 1.175
WORN_RADIUS_FACTOR = 0.985
TYRE_WIDTH_M = 0.03
TYRE_MU = 0.8
TYRE_TORSIONAL_M = 0.003   # MuJoCo's torsional friction: a length [m], torque = it × normal force
TYRE_ROLLING_M = 1e-4      # rolling friction [m]
CASTER_MU = 0.02
ANTI_TIP_X_M = 0.15
ANTI_TIP_CLEARANCE_M = 0.004
PAYLOAD_RADIUS_M = 0.05

WHEELS = ("left_wheel", "right_wheel")
ARM_JOINTS = ("arm_shoulder_yaw", "arm_shoulder_pitch", "arm_elbow", "arm_wrist")


def _floats(text):
    return [float(x) for x in text.split()]


class Urdf:
    """The numbers of a URDF: links' inertials and joints' origins, axes, damping and limits."""

    def __init__(self, path):
        root = ET.parse(path).getroot()
        self.links = {}
        for link in root.findall("link"):
            inertial = link.find("inertial")
            if inertial is None:
                self.links[link.get("name")] = None
                continue
            i = inertial.find("inertia").attrib
            self.links[link.get("name")] = {
                "mass": float(inertial.find("mass").get("value")),
                "com": _floats(inertial.find("origin").get("xyz")),
                "inertia": [float(i[k]) for k in ("ixx", "iyy", "izz")],
                "visual": link.find("visual"),
            }
        self.joints = {}
        for j in root.findall("joint"):
            origin = j.find("origin")
            dyn = j.find("dynamics")
            limit = j.find("limit")
            axis = j.find("axis")
            self.joints[j.get("name")] = {
                "type": j.get("type"),
                "parent": j.find("parent").get("link"),
                "child": j.find("child").get("link"),
                "xyz": _floats(origin.get("xyz")) if origin is not None else [0, 0, 0],
                "rpy": _floats(origin.get("rpy")) if origin is not None else [0, 0, 0],
                "axis": _floats(axis.get("xyz")) if axis is not None else [1, 0, 0],
                "damping": float(dyn.get("damping")) if dyn is not None else 0.0,
                "effort": float(limit.get("effort")) if limit is not None else 0.0,
            }

    def joint_to(self, child):
        return next((n, j) for n, j in self.joints.items() if j["child"] == child)

    def children(self, parent):
        return [(n, j) for n, j in self.joints.items() if j["parent"] == parent]


def _vec(xs):
    return " ".join(f"{x:.12g}" for x in xs)


def _inertial(link, factor=1.0):
    return (f'<inertial pos="{_vec(link["com"])}" mass="{link["mass"] * factor:.12g}" '
            f'diaginertia="{_vec([x * factor for x in link["inertia"]])}"/>')


def mjcf(urdf_path, timestep, payload_kg=0.0, tyre_mu=TYRE_MU):
    """The MJCF text of the robot on a floor (with `payload_kg` on tool0, and its tyres gripping
    with Coulomb friction `tyre_mu`: a slippery floor below TYRE_MU), the effort limits
    {joint: N·m}, the worn wheels' radius [m] and base_link's height above base_footprint [m]."""
    u = Urdf(urdf_path)
    _, base_joint = u.joint_to("base_link")
    z0 = base_joint["xyz"][2]
    wheel_r = None
    body = []
    chassis = u.links["base_link"]
    box = chassis["visual"].find("geometry/box").get("size")
    half = [0.5 * x for x in _floats(box)]
    body.append(f'<body name="base_link" pos="0 0 {z0:.12g}"><freejoint name="root"/>')
    body.append(_inertial(chassis, CHASSIS_MASS_FACTOR))
    body.append(f'<geom name="chassis" type="box" size="{_vec(half)}" '
                f'pos="{_vec(chassis["com"])}" contype="0" conaffinity="0" mass="0"/>')
    for name, j in u.children("base_link"):
        child = u.links[j["child"]]
        if j["child"] in WHEELS:
            cyl = child["visual"].find("geometry/cylinder")
            wheel_r = float(cyl.get("radius")) * WORN_RADIUS_FACTOR
            body.append(f'<body name="{j["child"]}" pos="{_vec(j["xyz"])}">')
            body.append(_inertial(child))
            body.append(f'<joint name="{name}" type="hinge" axis="{_vec(j["axis"])}" '
                        f'damping="{j["damping"]:.12g}"/>')
            body.append(f'<geom name="{j["child"]}_tyre" type="cylinder" '
                        f'size="{wheel_r:.12g} {0.25 * TYRE_WIDTH_M:.12g}" euler="1.5707963267948966 0 0" '
                        f'condim="6" priority="1" friction="{tyre_mu} {TYRE_TORSIONAL_M} {TYRE_ROLLING_M}" mass="0"/>')
            body.append("</body>")
        elif j["type"] == "fixed" and j["child"] == "caster_link":
            r = float(child["visual"].find("geometry/sphere").get("radius"))
            body.append(f'<body name="caster_link" pos="{_vec(j["xyz"])}">')
            body.append(_inertial(child))
            body.append(f'<geom name="caster" type="sphere" size="{r:.12g}" condim="3" priority="1" '
                        f'friction="{CASTER_MU} 0 0" mass="0"/>')
            body.append("</body>")
            skid = [ANTI_TIP_X_M, 0.0, j["xyz"][2] + ANTI_TIP_CLEARANCE_M]
            body.append(f'<geom name="anti_tip" type="sphere" size="{r:.12g}" pos="{_vec(skid)}" '
                        f'condim="3" priority="1" friction="{CASTER_MU} 0 0" mass="0"/>')
        elif j["type"] == "fixed" and j["child"] == "arm_mount":
            body.append(f'<body name="arm_mount" pos="{_vec(j["xyz"])}">')
            body.extend(_arm(u, "arm_mount", payload_kg))
            body.append("</body>")
    body.append("</body>")
    effort = {n: j["effort"] for n, j in u.joints.items() if j["type"] != "fixed"}
    xml = f"""<mujoco model="mobile_manipulator_sim">
  <compiler angle="radian"/>
  <option timestep="{timestep}" integrator="implicitfast" cone="elliptic" impratio="10"
          gravity="0 0 -9.81"/>
  <worldbody>
    <geom name="floor" type="plane" size="50 50 0.1" friction="1 0.005 0.0001" condim="6"/>
    {"".join(body)}
  </worldbody>
</mujoco>"""
    return xml, effort, wheel_r, z0


def _arm(u, parent, payload_kg):
    out = []
    for name, j in u.children(parent):
        child = u.links[j["child"]]
        assert j["rpy"] == [0, 0, 0], f"{name}: a rotated joint origin is not handled"
        out.append(f'<body name="{j["child"]}" pos="{_vec(j["xyz"])}">')
        if child is not None:
            out.append(_inertial(child))
        elif j["child"] == "tool0" and payload_kg > 0.0:
            i = 0.4 * payload_kg * PAYLOAD_RADIUS_M**2  # a solid sphere's
            out.append(f'<inertial pos="0 0 0" mass="{payload_kg:.12g}" diaginertia="{_vec([i] * 3)}"/>')
        if j["type"] == "revolute":
            out.append(f'<joint name="{name}" type="hinge" axis="{_vec(j["axis"])}" '
                       f'damping="{j["damping"]:.12g}"/>')
        out.extend(_arm(u, j["child"], payload_kg))
        out.append("</body>")
    return out
