#!/usr/bin/env python3
"""A second, independent DDS (Eclipse Cyclone DDS, Python) decoding the
nav_msgs/Odometry (or nav_msgs/Path) that a Rust node publishes.

    tools/ros2/netns_run.sh .venv-ros2/bin/python tools/ros2/cyclone_check.py [--topic rt/odom] [--timeout 20]
    ... cyclone_check.py --type path --topic rt/cd_predictor/predicted_path --min-poses 1000

The types below are written from the ROS .msg definitions (ROS maps
`pkg/msg/Name` to the DDS type `pkg::msg::dds_::Name_` and topic `/odom` to
`rt/odom`). Restricted to the loopback interface via CYCLONEDDS_URI, and run
inside the loopback-only namespace anyway. Prints one JSON object (the first
Odometry, field by field, and the time to receive it; for a Path its pose count and first and
last poses) on the last line; exits 0 iff a message arrived (a Path: with at least --min-poses).
"""
import argparse
import dataclasses
import json
import os
import sys
import time

os.environ.setdefault(
    "CYCLONEDDS_URI",
    '<CycloneDDS><Domain><General><Interfaces><NetworkInterface name="lo"/></Interfaces>'
    "</General></Domain></CycloneDDS>",
)

from cyclonedds.core import Policy, Qos  # noqa: E402
from cyclonedds.domain import DomainParticipant  # noqa: E402
from cyclonedds.idl import IdlStruct  # noqa: E402
from cyclonedds.idl.types import array, float64, int32, sequence, uint32  # noqa: E402
from cyclonedds.sub import DataReader  # noqa: E402
from cyclonedds.topic import Topic  # noqa: E402
from cyclonedds.util import duration  # noqa: E402


@dataclasses.dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: int32
    nanosec: uint32


@dataclasses.dataclass
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time
    frame_id: str


@dataclasses.dataclass
class Point(IdlStruct, typename="geometry_msgs::msg::dds_::Point_"):
    x: float64
    y: float64
    z: float64


@dataclasses.dataclass
class Quaternion(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    x: float64
    y: float64
    z: float64
    w: float64


@dataclasses.dataclass
class Vector3(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    x: float64
    y: float64
    z: float64


@dataclasses.dataclass
class Pose(IdlStruct, typename="geometry_msgs::msg::dds_::Pose_"):
    position: Point
    orientation: Quaternion


@dataclasses.dataclass
class PoseWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::PoseWithCovariance_"):
    pose: Pose
    covariance: array[float64, 36]


@dataclasses.dataclass
class Twist(IdlStruct, typename="geometry_msgs::msg::dds_::Twist_"):
    linear: Vector3
    angular: Vector3


@dataclasses.dataclass
class TwistWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::TwistWithCovariance_"):
    twist: Twist
    covariance: array[float64, 36]


@dataclasses.dataclass
class Odometry(IdlStruct, typename="nav_msgs::msg::dds_::Odometry_"):
    header: Header
    child_frame_id: str
    pose: PoseWithCovariance
    twist: TwistWithCovariance


@dataclasses.dataclass
class PoseStamped(IdlStruct, typename="geometry_msgs::msg::dds_::PoseStamped_"):
    header: Header
    pose: Pose


@dataclasses.dataclass
class Path(IdlStruct, typename="nav_msgs::msg::dds_::Path_"):
    header: Header
    poses: sequence[PoseStamped]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--topic", default="rt/odom")
    ap.add_argument("--domain", type=int, default=int(os.environ.get("ROS_DOMAIN_ID", "0") or 0))
    ap.add_argument("--timeout", type=float, default=20.0)
    ap.add_argument("--type", choices=["odometry", "path"], default="odometry")
    ap.add_argument("--min-poses", type=int, default=1, help="path: wait for one this long")
    args = ap.parse_args()
    if args.type == "path":
        return read_path(args)

    t0 = time.monotonic()
    dp = DomainParticipant(args.domain)
    topic = Topic(dp, args.topic, Odometry)
    reader = DataReader(dp, topic, qos=Qos(Policy.Reliability.Reliable(duration(seconds=1)),
                                          Policy.History.KeepLast(10)))
    out = {"ok": False}
    deadline = t0 + args.timeout
    while time.monotonic() < deadline:
        for sample in reader.take_iter(timeout=duration(milliseconds=100)):
            out["first_message_s"] = time.monotonic() - t0
            out["odom"] = dataclasses.asdict(sample)
            out["ok"] = True
            break
        if out["ok"]:
            break
    if not out["ok"]:
        out["errors"] = [f"no Odometry on {args.topic} within {args.timeout} s"]
    return out


def read_path(args):
    """The first nav_msgs/Path on the topic with at least --min-poses poses (a large message:
    fragmented on any network, as a long predicted_path is)."""
    t0 = time.monotonic()
    dp = DomainParticipant(args.domain)
    topic = Topic(dp, args.topic, Path)
    reader = DataReader(dp, topic, qos=Qos(Policy.Reliability.Reliable(duration(seconds=1)),
                                          Policy.History.KeepLast(10)))
    out = {"ok": False, "longest": 0}
    deadline = t0 + args.timeout
    while time.monotonic() < deadline and not out["ok"]:
        for sample in reader.take_iter(timeout=duration(milliseconds=100)):
            n = len(sample.poses)
            out["longest"] = max(out["longest"], n)
            if n >= args.min_poses:
                out.update(ok=True, first_message_s=time.monotonic() - t0, poses=n,
                           first=dataclasses.asdict(sample.poses[0].pose),
                           last=dataclasses.asdict(sample.poses[-1].pose))
                break
    if not out["ok"]:
        out["errors"] = [f"no Path with >= {args.min_poses} poses on {args.topic} within "
                         f"{args.timeout} s (longest {out['longest']})"]
    return out


if __name__ == "__main__":
    result = main()
    print(json.dumps(result, allow_nan=False))
    sys.exit(0 if result["ok"] else 1)
