#!/usr/bin/env python3
"""Golden CDR bytes of the ROS 2 messages robokey exchanges (Twist, TwistStamped, Odometry,
PoseStamped), from two independent pure-Python
serialisers: rosbags (its own ROS 2 Jazzy message definitions) and pycdr2 (Cyclone DDS's IDL
layer, with the layouts written out below). Prints each message's bytes as hex once both agree;
crates/robokey-net/src/ros2/msg.rs checks robokey's encoding against them.

    python3 -m venv /tmp/cdr && /tmp/cdr/bin/pip install rosbags==0.11.9 pycdr2==1.0.0
    /tmp/cdr/bin/python scripts/ros2-golden-cdr.py
"""
from dataclasses import dataclass

import numpy as np
from pycdr2 import IdlStruct
from pycdr2.types import array, float64, int32, uint32
from rosbags.typesys import Stores, get_typestore

# The values, written identically in the Rust test.
STAMP = (1_700_000_000, 123_456_789)
LINEAR = (0.25, -1.5, 3.0)
ANGULAR = (0.125, -0.0625, 2.84)
POSITION = (1.5, -2.25, 0.0)
ORIENTATION = (0.0, 0.0, 0.38268343236508984, 0.9238795325112867)  # yaw π/4
POSE_COV = [0.5 * i for i in range(36)]
TWIST_COV = [-0.25 * i for i in range(36)]

ts = get_typestore(Stores.ROS2_JAZZY)
T = ts.types
time = T["builtin_interfaces/msg/Time"](sec=STAMP[0], nanosec=STAMP[1])
vec = lambda v: T["geometry_msgs/msg/Vector3"](x=v[0], y=v[1], z=v[2])
twist = T["geometry_msgs/msg/Twist"](linear=vec(LINEAR), angular=vec(ANGULAR))
rosbags_bytes = {
    "Twist": ts.serialize_cdr(twist, "geometry_msgs/msg/Twist"),
    "TwistStamped": ts.serialize_cdr(
        T["geometry_msgs/msg/TwistStamped"](
            header=T["std_msgs/msg/Header"](stamp=time, frame_id="base_link"), twist=twist
        ),
        "geometry_msgs/msg/TwistStamped",
    ),
    "Odometry": ts.serialize_cdr(
        T["nav_msgs/msg/Odometry"](
            header=T["std_msgs/msg/Header"](stamp=time, frame_id="odom"),
            child_frame_id="base_footprint",
            pose=T["geometry_msgs/msg/PoseWithCovariance"](
                pose=T["geometry_msgs/msg/Pose"](
                    position=T["geometry_msgs/msg/Point"](
                        x=POSITION[0], y=POSITION[1], z=POSITION[2]
                    ),
                    orientation=T["geometry_msgs/msg/Quaternion"](
                        x=ORIENTATION[0], y=ORIENTATION[1], z=ORIENTATION[2], w=ORIENTATION[3]
                    ),
                ),
                covariance=np.array(POSE_COV, dtype=np.float64),
            ),
            twist=T["geometry_msgs/msg/TwistWithCovariance"](
                twist=twist, covariance=np.array(TWIST_COV, dtype=np.float64)
            ),
        ),
        "nav_msgs/msg/Odometry",
    ),
    "PoseStamped": ts.serialize_cdr(
        T["geometry_msgs/msg/PoseStamped"](
            header=T["std_msgs/msg/Header"](stamp=time, frame_id="mocap"),
            pose=T["geometry_msgs/msg/Pose"](
                position=T["geometry_msgs/msg/Point"](x=POSITION[0], y=POSITION[1], z=POSITION[2]),
                orientation=T["geometry_msgs/msg/Quaternion"](
                    x=ORIENTATION[0], y=ORIENTATION[1], z=ORIENTATION[2], w=ORIENTATION[3]
                ),
            ),
        ),
        "geometry_msgs/msg/PoseStamped",
    ),
}


# The same layouts for pycdr2, field by field as in the .msg files.
@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::Time"):
    sec: int32
    nanosec: uint32


@dataclass
class Header(IdlStruct, typename="std_msgs::msg::Header"):
    stamp: Time
    frame_id: str


@dataclass
class Vector3(IdlStruct, typename="geometry_msgs::msg::Vector3"):
    x: float64
    y: float64
    z: float64


@dataclass
class Twist(IdlStruct, typename="geometry_msgs::msg::Twist"):
    linear: Vector3
    angular: Vector3


@dataclass
class TwistStamped(IdlStruct, typename="geometry_msgs::msg::TwistStamped"):
    header: Header
    twist: Twist


@dataclass
class Point(IdlStruct, typename="geometry_msgs::msg::Point"):
    x: float64
    y: float64
    z: float64


@dataclass
class Quaternion(IdlStruct, typename="geometry_msgs::msg::Quaternion"):
    x: float64
    y: float64
    z: float64
    w: float64


@dataclass
class Pose(IdlStruct, typename="geometry_msgs::msg::Pose"):
    position: Point
    orientation: Quaternion


@dataclass
class PoseWithCovariance(IdlStruct, typename="geometry_msgs::msg::PoseWithCovariance"):
    pose: Pose
    covariance: array[float64, 36]


@dataclass
class TwistWithCovariance(IdlStruct, typename="geometry_msgs::msg::TwistWithCovariance"):
    twist: Twist
    covariance: array[float64, 36]


@dataclass
class Odometry(IdlStruct, typename="nav_msgs::msg::Odometry"):
    header: Header
    child_frame_id: str
    pose: PoseWithCovariance
    twist: TwistWithCovariance


@dataclass
class PoseStamped(IdlStruct, typename="geometry_msgs::msg::PoseStamped"):
    header: Header
    pose: Pose


ptwist = Twist(Vector3(*LINEAR), Vector3(*ANGULAR))
ptime = Time(*STAMP)
pycdr2_bytes = {
    "Twist": ptwist.serialize(),
    "TwistStamped": TwistStamped(Header(ptime, "base_link"), ptwist).serialize(),
    "Odometry": Odometry(
        Header(ptime, "odom"),
        "base_footprint",
        PoseWithCovariance(Pose(Point(*POSITION), Quaternion(*ORIENTATION)), POSE_COV),
        TwistWithCovariance(ptwist, TWIST_COV),
    ).serialize(),
    "PoseStamped": PoseStamped(
        Header(ptime, "mocap"), Pose(Point(*POSITION), Quaternion(*ORIENTATION))
    ).serialize(),
}

for name, data in rosbags_bytes.items():
    data = bytes(data)
    assert data == pycdr2_bytes[name], f"{name}: rosbags and pycdr2 disagree"
    print(f"{name} ({len(data)} bytes):")
    for i in range(0, len(data), 32):
        print("    " + data[i : i + 32].hex())
