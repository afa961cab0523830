"""Run a scenario: the simulator and one planner per robot, as `prvo-run` starts them.

    ros2 launch prvo_sim scenario.launch.py scenario:=headon2 [method:=prvo] [eta:=0.9]
        [mode:=lockstep|realtime] [seed:=7]

Nothing is recorded (that is `prvo-run`'s job); watch with RViz2
(`rviz2 -d $(ros2 pkg prefix prvo_sim)/share/prvo_sim/rviz/prvo.rviz`). Ctrl-C stops it.
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration

from prvo_sim.launching import LAUNCH_ARGUMENTS, launch_actions, scenario_nodes


def _scenario_actions(context):
    arguments = {name: LaunchConfiguration(name).perform(context) for name in LAUNCH_ARGUMENTS}
    return launch_actions(scenario_nodes(**arguments))


def generate_launch_description():
    """Return the launch description: the arguments, then the scenario's nodes."""
    return LaunchDescription([
        *(DeclareLaunchArgument(name, default_value=default, description=description)
          for name, (default, description) in LAUNCH_ARGUMENTS.items()),
        OpaqueFunction(function=_scenario_actions),
    ])
