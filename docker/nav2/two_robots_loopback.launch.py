"""Two robots on Nav2 (Jazzy) and its loopback simulator, each filtered by prvo (layout B).

Per robot, in its namespace: Nav2's navigation stack (nav2_bringup's navigation_launch.py),
a map server, the loopback simulator, a relay of its odometry into the map frame
(odom_in_map.py, standing in for robot_localization) and prvo's filter between
velocity_smoother and collision_monitor:

    controller -> cmd_vel_nav -> velocity_smoother -> cmd_vel_smoothed -> prvo_filter
        -> cmd_vel_prvo -> collision_monitor -> cmd_vel -> loopback simulator

The robots start facing each other on one line and are sent to each other's start: their
paths coincide, and only the filters keep them apart. The poses suit the TB3 sandbox map;
change ROBOTS for another map. Not built or run where this file was written (no Nav2 there).
"""

import math
import os
import sys
import tempfile

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import ExecuteProcess, IncludeLaunchDescription, TimerAction
from launch.launch_description_sources import PythonLaunchDescriptionSource
from launch_ros.actions import Node
from launch_ros.descriptions import ParameterFile
from nav2_common.launch import RewrittenYaml
import yaml

# name, start (x, y, yaw), goal (x, y)
ROBOTS = (('robot_0', (-2.0, -0.5, 0.0), (0.5, -0.5)),
          ('robot_1', (0.5, -0.5, math.pi), (-2.0, -0.5)))
REMAPPINGS = [('/tf', 'tf'), ('/tf_static', 'tf_static')]
HERE = os.path.dirname(os.path.abspath(__file__))


def _parameter_file(robot):
    """Return nav2_params.yaml with prvo's filter block, rewired for layout B, as a file."""
    bringup = get_package_share_directory('nav2_bringup')
    with open(os.path.join(bringup, 'params', 'nav2_params.yaml')) as source:
        params = yaml.safe_load(source)
    with open(os.path.join(get_package_share_directory('prvo_planner'), 'config',
                           'nav2_prvo_params.yaml')) as source:
        params.update(yaml.safe_load(source))
    filter_params = params['prvo_filter']['ros__parameters']
    filter_params['use_sim_time'] = True
    filter_params['neighbors'] = [name for name, _, _ in ROBOTS if name != robot]
    params['collision_monitor']['ros__parameters']['cmd_vel_in_topic'] = 'cmd_vel_prvo'
    # One clock for both robots: robot_0's simulator publishes it.
    params.setdefault('loopback_simulator', {}).setdefault('ros__parameters', {})[
        'publish_clock'] = robot == ROBOTS[0][0]
    handle, path = tempfile.mkstemp(prefix=f'{robot}_', suffix='.yaml')
    with os.fdopen(handle, 'w') as target:
        yaml.safe_dump(params, target)
    return path


def _quaternion(yaw):
    return f'{{z: {math.sin(0.5 * yaw)}, w: {math.cos(0.5 * yaw)}}}'


def _robot_actions(robot, start, goal):
    bringup = get_package_share_directory('nav2_bringup')
    source = _parameter_file(robot)
    params = ParameterFile(RewrittenYaml(source_file=source, root_key=robot, param_rewrites={},
                                         convert_types=True), allow_substs=True)
    x, y, yaw = start
    return [
        IncludeLaunchDescription(
            PythonLaunchDescriptionSource(
                os.path.join(bringup, 'launch', 'navigation_launch.py')),
            launch_arguments={'namespace': robot, 'use_sim_time': 'True',
                              'params_file': source, 'autostart': 'True',
                              'use_composition': 'False'}.items()),
        Node(package='nav2_map_server', executable='map_server', name='map_server',
             namespace=robot, parameters=[params, {
                 'yaml_filename': os.path.join(bringup, 'maps', 'tb3_sandbox.yaml'),
                 'use_sim_time': True}], remappings=REMAPPINGS),
        Node(package='nav2_lifecycle_manager', executable='lifecycle_manager',
             name='lifecycle_manager_map_server', namespace=robot,
             parameters=[{'autostart': True, 'node_names': ['map_server'],
                          'use_sim_time': True}]),
        Node(package='nav2_loopback_sim', executable='loopback_simulator',
             name='loopback_simulator', namespace=robot, parameters=[params],
             remappings=REMAPPINGS),
        # Beside the lifecycle managers, not under them: prvo's planner is a plain node.
        Node(package='prvo_planner', executable='planner', name='prvo_filter',
             namespace=robot, parameters=[params], remappings=REMAPPINGS),
        ExecuteProcess(cmd=[sys.executable, os.path.join(HERE, 'odom_in_map.py'),
                            '--ros-args', '-r', f'__ns:=/{robot}', '-r', '/tf:=tf',
                            '-r', '/tf_static:=tf_static', '-p', 'use_sim_time:=true']),
        TimerAction(period=3.0, actions=[ExecuteProcess(cmd=[
            'ros2', 'topic', 'pub', '--once', f'/{robot}/initialpose',
            'geometry_msgs/msg/PoseWithCovarianceStamped',
            f'{{header: {{frame_id: map}}, pose: {{pose: {{position: {{x: {x}, y: {y}}}, '
            f'orientation: {_quaternion(yaw)}}}}}}}'])]),
        TimerAction(period=20.0, actions=[ExecuteProcess(cmd=[
            'ros2', 'topic', 'pub', '--once', f'/{robot}/goal_pose',
            'geometry_msgs/msg/PoseStamped',
            f'{{header: {{frame_id: map}}, pose: {{position: {{x: {goal[0]}, y: {goal[1]}}}, '
            f'orientation: {_quaternion(yaw)}}}}}'])]),
    ]


def generate_launch_description():
    """Both robots' stacks."""
    return LaunchDescription(
        [action for robot in ROBOTS for action in _robot_actions(*robot)])
