"""ROS 2 message definitions (ros2msg, as rosbag2 stores them in an MCAP schema: the type's .msg
followed by each dependency's, separated by a line of '=' and 'MSG: pkg/Type')."""

SEP = "=" * 80

MSGS = {
    "builtin_interfaces/Time": "int32 sec\nuint32 nanosec\n",
    "std_msgs/Header": "builtin_interfaces/Time stamp\nstring frame_id\n",
    "geometry_msgs/Point": "float64 x\nfloat64 y\nfloat64 z\n",
    "geometry_msgs/Quaternion": "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n",
    "geometry_msgs/Vector3": "float64 x\nfloat64 y\nfloat64 z\n",
    "geometry_msgs/Pose": "Point position\nQuaternion orientation\n",
    "geometry_msgs/Twist": "Vector3  linear\nVector3  angular\n",
    "geometry_msgs/TwistStamped": "std_msgs/Header header\nTwist twist\n",
    "geometry_msgs/PoseWithCovariance": "Pose pose\nfloat64[36] covariance\n",
    "geometry_msgs/TwistWithCovariance": "Twist twist\nfloat64[36] covariance\n",
    "nav_msgs/Odometry": (
        "std_msgs/Header header\nstring child_frame_id\n"
        "geometry_msgs/PoseWithCovariance pose\ngeometry_msgs/TwistWithCovariance twist\n"
    ),
    "sensor_msgs/JointState": (
        "std_msgs/Header header\nstring[] name\nfloat64[] position\n"
        "float64[] velocity\nfloat64[] effort\n"
    ),
}

DEPS = {
    "nav_msgs/Odometry": [
        "std_msgs/Header", "builtin_interfaces/Time", "geometry_msgs/PoseWithCovariance",
        "geometry_msgs/Pose", "geometry_msgs/Point", "geometry_msgs/Quaternion",
        "geometry_msgs/TwistWithCovariance", "geometry_msgs/Twist", "geometry_msgs/Vector3",
    ],
    "sensor_msgs/JointState": ["std_msgs/Header", "builtin_interfaces/Time"],
    "geometry_msgs/Twist": ["geometry_msgs/Vector3"],
    "geometry_msgs/TwistStamped": [
        "std_msgs/Header", "builtin_interfaces/Time", "geometry_msgs/Twist",
        "geometry_msgs/Vector3",
    ],
}


def definition(datatype):
    """The schema text of `pkg/Type` with its dependencies."""
    parts = [MSGS[datatype]]
    for dep in DEPS[datatype]:
        parts.append(f"{SEP}\nMSG: {dep}\n{MSGS[dep]}")
    return "\n".join(parts)


def schema_name(datatype):
    """rosbag2's schema and topic type name: `pkg/msg/Type`."""
    pkg, name = datatype.split("/")
    return f"{pkg}/msg/{name}"
