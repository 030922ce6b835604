"""Launch the constraint_dynamics node suite (docs/nodes.md) for users who have ROS 2.

    ros2 launch launch/suite.launch.py                       # all nodes, params/default.yaml
    ros2 launch launch/suite.launch.py node:=predictor namespace:=robot1 \
        params_file:=/path/to/my_params.yaml

The suite is a pure-Rust program (ros2-client), not an ament package: build it first with
`cargo build --release -p constraint_dynamics_nodes` (the binary lands in target/release/, or
give `binary:=`). It speaks to rclcpp/rclpy nodes over DDS like any ROS 2 node: ROS_DOMAIN_ID
is honoured, and it runs on all network interfaces only when `network.allow_external: true` is
set in the parameter file (or CD_ALLOW_EXTERNAL_NETWORK=1) -- see docs/nodes.md, "Network".

Arguments:
  params_file  ROS parameter file (default: params/default.yaml of this repository)
  binary       the suite binary (default: target/release/constraint_dynamics_suite)
  node         '' for every enabled node, or one of predictor, forces, projection, prediction
  namespace    ROS namespace of the nodes ('' = root)
  log_level    debug, info, warn, error
  allow_external  'true' to allow DDS on non-loopback interfaces (a robot network)
"""

import os

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, ExecuteProcess, OpaqueFunction
from launch.substitutions import LaunchConfiguration

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _suite(context, *args, **kwargs):
    get = lambda name: LaunchConfiguration(name).perform(context)  # noqa: E731
    cmd = [get('binary')]
    if get('node'):
        cmd += ['--node', get('node')]
    cmd += ['--ros-args', '--params-file', get('params_file'), '--log-level', get('log_level')]
    namespace = get('namespace').strip('/')
    if namespace:
        cmd += ['-r', '__ns:=/' + namespace]
    if get('allow_external').lower() == 'true':
        cmd += ['-p', 'network.allow_external:=true']
    return [ExecuteProcess(cmd=cmd, cwd=REPO, output='screen', sigterm_timeout='5')]


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument('params_file',
                              default_value=os.path.join(REPO, 'params', 'default.yaml')),
        DeclareLaunchArgument('binary', default_value=os.path.join(
            REPO, 'target', 'release', 'constraint_dynamics_suite')),
        DeclareLaunchArgument('node', default_value=''),
        DeclareLaunchArgument('namespace', default_value=''),
        DeclareLaunchArgument('log_level', default_value='info'),
        DeclareLaunchArgument('allow_external', default_value='false'),
        OpaqueFunction(function=_suite),
    ])
