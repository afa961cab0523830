"""The nodes of a scenario for `ros2 launch prvo_sim scenario.launch.py`: the runner's.

`scenario_nodes` returns the simulator and one planner per planned robot with the parameters
the runner gives them (prvo_sim.runner.session), as plain data: the executable, the node name
and namespace and the `-p` arguments. `launch_actions` turns them into launch actions:
launch_ros `Node`s in a ROS 2 install, `ExecuteProcess` actions of the same command lines where
only `launch` is installed. Nothing here imports launch until actions are asked for.
"""

import dataclasses

from prvo_sim.runner.processes import package_command
from prvo_sim.runner.session import (
    METHODS,
    PLANNER_NODE,
    SIM_NODE,
    planned_robots,
    planner_parameters,
    sim_parameters,
)
from prvo_sim.scenario import find_scenario, load_scenario
from prvo_sim.step_timing import MODES

# Launch arguments: name -> (default, description). An empty default means "not given".
LAUNCH_ARGUMENTS = {
    'scenario': ('circle8', 'Scenario name (a shipped one) or YAML file.'),
    'method': ('prvo', f"Planner variant: {', '.join(METHODS)}."),
    'eta': ('', "Collision-avoidance probability in (0, 1) for every robot (default: each "
                "robot's planner eta)."),
    'mode': ('lockstep', f"Simulator stepping: {', '.join(MODES)}."),
    'seed': ('', "Random seed (default: the scenario's)."),
}


class LaunchArgumentError(ValueError):
    """A launch argument that cannot be used: '<name>: <reason>'."""


@dataclasses.dataclass(frozen=True)
class LaunchedNode:
    """One node of a launched scenario: `ros2 run PACKAGE EXECUTABLE` with these ROS arguments.

    `parameters` maps each parameter name to its `-p` value, formatted as the runner does.
    """

    package: str
    executable: str
    module: str
    name: str
    namespace: str
    parameters: dict

    def parameter_arguments(self):
        """Return the `-p name:=value` arguments of the node's parameters."""
        arguments = []
        for key, value in self.parameters.items():
            arguments += ['-p', f'{key}:={value}']
        return arguments

    def command(self):
        """Return the node's whole command line, as the runner starts it."""
        remaps = ['-r', f'__ns:=/{self.namespace}'] if self.namespace else []
        return [*package_command(self.package, self.executable, self.module), '--ros-args',
                *remaps, '-r', f'__node:={self.name}', *self.parameter_arguments()]


def scenario_nodes(scenario='circle8', method='prvo', eta='', mode='lockstep', seed=''):
    """Return the `LaunchedNode`s of a scenario run: the simulator first, then the planners.

    Arguments are the launch arguments as text (see LAUNCH_ARGUMENTS); an empty ETA or SEED
    is not given. Raises LaunchArgumentError or prvo_sim.scenario.ScenarioError naming the
    value that cannot be used.
    """
    if method not in METHODS:
        raise LaunchArgumentError(f"method: must be one of {', '.join(METHODS)}, got {method!r}")
    if mode not in MODES:
        raise LaunchArgumentError(f"mode: must be one of {', '.join(MODES)}, got {mode!r}")
    planner_eta = _number('eta', eta, float)
    if planner_eta is not None and not 0.0 < planner_eta < 1.0:
        raise LaunchArgumentError(f'eta: must be in (0, 1), got {eta!r}')
    loaded = load_scenario(find_scenario(scenario), seed=_number('seed', seed, int))
    nodes = [LaunchedNode('prvo_sim', 'sim', 'prvo_sim.sim_main', SIM_NODE, '',
                          sim_parameters(loaded, mode, loaded.seed))]
    # A scripted robot follows its script in the simulator: it has no planner.
    for robot in planned_robots(loaded):
        nodes.append(LaunchedNode(
            'prvo_planner', 'planner', 'prvo_planner.planner_node', PLANNER_NODE, robot.name,
            planner_parameters(robot, loaded, method, planner_eta, mode)))
    return nodes


def _number(name, text, kind):
    """Return TEXT as a KIND number, None when empty; raise LaunchArgumentError if not one."""
    if text == '':
        return None
    try:
        return kind(text)
    except ValueError:
        raise LaunchArgumentError(f'{name}: expected {kind.__name__}, got {text!r}') from None


def node_actions(nodes):
    """Return launch_ros `Node` actions of NODES (needs launch_ros, as in a ROS 2 install)."""
    from launch_ros.actions import Node

    return [Node(package=node.package, executable=node.executable, name=node.name,
                 namespace=node.namespace or None, ros_arguments=node.parameter_arguments(),
                 output='screen') for node in nodes]


def process_actions(nodes):
    """Return `ExecuteProcess` actions running the command lines of NODES (needs launch)."""
    from launch.actions import ExecuteProcess

    return [ExecuteProcess(cmd=node.command(), name=node.namespace or node.name,
                           output='screen') for node in nodes]


def launch_actions(nodes):
    """Return launch_ros `Node` actions of NODES if launch_ros is installed, else processes."""
    try:
        import launch_ros  # noqa: F401
    except ImportError:
        return process_actions(nodes)
    return node_actions(nodes)
