"""ROS 2 CDR made and read by `rosbags` (PyPI), an implementation independent
of ours, for the ROS 2 tests of ICKON-rs.

    rosbags_cdr.py decode TYPE FILE...   -> {"hash": RIHS01, "messages": [...]}
    rosbags_cdr.py odom < samples.json   -> ["<hex CDR>", ...]
    rosbags_cdr.py imu  < samples.json   -> ["<hex CDR>", ...]

Odometry samples: {"sec", "nanosec", "x", "y", "yaw", "vx", "wz"}; IMU
samples: {"sec", "nanosec", "wz"}. Messages are printed as nested JSON
objects, arrays as lists.
"""

import dataclasses
import json
import math
import sys

import numpy as np
from rosbags.typesys import Stores, get_typestore

TS = get_typestore(Stores.ROS2_JAZZY)
T = TS.types


def to_json(v):
    if dataclasses.is_dataclass(v):
        return {f.name: to_json(getattr(v, f.name)) for f in dataclasses.fields(v)}
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, (list, tuple)):
        return [to_json(x) for x in v]
    return v


def header(s, frame):
    stamp = T["builtin_interfaces/msg/Time"](sec=s["sec"], nanosec=s["nanosec"])
    return T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)


def vec3(x, y, z):
    return T["geometry_msgs/msg/Vector3"](x=x, y=y, z=z)


def odom(s):
    q = T["geometry_msgs/msg/Quaternion"](
        x=0.0, y=0.0, z=math.sin(s["yaw"] / 2), w=math.cos(s["yaw"] / 2)
    )
    p = T["geometry_msgs/msg/Point"](x=s["x"], y=s["y"], z=0.0)
    pose = T["geometry_msgs/msg/PoseWithCovariance"](
        pose=T["geometry_msgs/msg/Pose"](position=p, orientation=q),
        covariance=np.diag([1e-3, 1e-3, 1e6, 1e6, 1e6, 3e-3]).reshape(36),
    )
    twist = T["geometry_msgs/msg/TwistWithCovariance"](
        twist=T["geometry_msgs/msg/Twist"](
            linear=vec3(s["vx"], 0.0, 0.0), angular=vec3(0.0, 0.0, s["wz"])
        ),
        covariance=np.diag([1e-4, 1e6, 1e6, 1e6, 1e6, 1e-4]).reshape(36),
    )
    msg = T["nav_msgs/msg/Odometry"](
        header=header(s, "odom"), child_frame_id="base_link", pose=pose, twist=twist
    )
    return TS.serialize_cdr(msg, "nav_msgs/msg/Odometry")


def imu(s):
    unknown = np.array([-1.0] + [0.0] * 8)
    msg = T["sensor_msgs/msg/Imu"](
        header=header(s, "imu_link"),
        orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=unknown,
        angular_velocity=vec3(0.0, 0.0, s["wz"]),
        angular_velocity_covariance=np.diag([1e-5, 1e-5, 1e-5]).reshape(9),
        linear_acceleration=vec3(0.0, 0.0, 9.81),
        linear_acceleration_covariance=unknown,
    )
    return TS.serialize_cdr(msg, "sensor_msgs/msg/Imu")


def main():
    cmd = sys.argv[1]
    if cmd == "decode":
        typename = sys.argv[2]
        out = []
        for path in sys.argv[3:]:
            with open(path, "rb") as f:
                out.append(to_json(TS.deserialize_cdr(f.read(), typename)))
        print(json.dumps({"hash": TS.hash_rihs01(typename), "messages": out}))
    elif cmd in ("odom", "imu"):
        make = odom if cmd == "odom" else imu
        print(json.dumps([bytes(make(s)).hex() for s in json.load(sys.stdin)]))
    else:
        sys.exit(f"unknown command {cmd}")


if __name__ == "__main__":
    main()
