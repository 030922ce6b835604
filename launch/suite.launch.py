"""Launch the constraint_dynamics node suite (docs/nodes.md) from its colcon install.

    colcon build --packages-up-to constraint_dynamics_nodes   # docs/nodes.md, "Installing with colcon"
    source install/setup.bash
    ros2 launch constraint_dynamics_nodes suite.launch.py                  # every enabled node
    ros2 launch constraint_dynamics_nodes suite.launch.py node:=predictor namespace:=robot1 \
        params_file:=/path/to/my_params.yaml use_sim_time:=true

The suite is one pure-Rust program (ros2-client) holding every enabled node; `node:=KIND` runs
one of them. It speaks to rclcpp/rclpy nodes over DDS like any ROS 2 node: ROS_DOMAIN_ID is
honoured, and it uses network interfaces other than loopback only when
`network.allow_external: true` is set (allow_external:=true here) -- docs/nodes.md, "Network".
Without a ROS install, run the binary directly (README: cargo run ... --ros-args ...).

Arguments:
  params_file     ROS parameter file (default: share/constraint_dynamics_nodes/params/default.yaml;
                  its relative scene and URDF paths resolve next to it)
  node            '' for every enabled node, or one of predictor, forces, projection, prediction
  namespace       ROS namespace of the nodes ('' = root); topics are relative and follow it
  use_sim_time    'true' to run every stamp, rate and timeout on /clock
  log_level       debug, info, warn, error
  allow_external  'true' to allow DDS on non-loopback interfaces (a robot network)
  exit_on_failure 'true' to end the process when a node fails to configure (default: that node
                  stays unconfigured and the others run)
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

PACKAGE = 'constraint_dynamics_nodes'


def _suite(context, *args, **kwargs):
    get = lambda name: LaunchConfiguration(name).perform(context)  # noqa: E731
    parameters = [get('params_file')]
    overrides = {}
    if get('use_sim_time').lower() == 'true':
        overrides['use_sim_time'] = True
    if get('allow_external').lower() == 'true':
        overrides['network.allow_external'] = True
    if overrides:
        # launch_ros writes these as a `/**:` parameter file after params_file: they win.
        parameters.append(overrides)
    return [Node(
        package=PACKAGE,
        executable='constraint_dynamics_suite',
        namespace=get('namespace').strip('/'),
        arguments=(['--node', get('node')] if get('node') else [])
        + (['--exit-on-failure'] if get('exit_on_failure').lower() == 'true' else []),
        parameters=parameters,
        ros_arguments=['--log-level', get('log_level')],
        output='screen',
        sigterm_timeout='5',
    )]


def generate_launch_description():
    share = get_package_share_directory(PACKAGE)
    return LaunchDescription([
        DeclareLaunchArgument('params_file',
                              default_value=os.path.join(share, 'params', 'default.yaml')),
        DeclareLaunchArgument('node', default_value=''),
        DeclareLaunchArgument('namespace', default_value=''),
        DeclareLaunchArgument('use_sim_time', default_value='false'),
        DeclareLaunchArgument('log_level', default_value='info'),
        DeclareLaunchArgument('allow_external', default_value='false'),
        DeclareLaunchArgument('exit_on_failure', default_value='false'),
        OpaqueFunction(function=_suite),
    ])
