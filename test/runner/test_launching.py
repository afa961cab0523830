"""The nodes `ros2 launch prvo_sim scenario.launch.py` starts: the runner's, same parameters."""

import pathlib

from ament_index_python.packages import get_package_share_directory
import pytest

from prvo_sim.launching import LaunchArgumentError, scenario_nodes
from prvo_sim.run_scenario import build_parser
from prvo_sim.runner.session import RunSpec, run_eta, start_planners, start_sim
from prvo_sim.scenario import ScenarioError, find_scenario, load_scenario


class _StartedCommands:
    """Stands in for the runner's Children: keeps each command line it is asked to start."""

    def __init__(self):
        self.argv = {}

    def start(self, label, argv):
        self.argv[label] = argv


def _runner_commands(argv, tmp_path):
    """Return the command lines the runner starts for ARGV (its command line), by label."""
    options = build_parser().parse_args(argv)
    scenario = load_scenario(find_scenario(options.scenario), seed=options.seed)
    spec = RunSpec(options, scenario, run_eta(options, scenario), scenario.seed, tmp_path)
    started = _StartedCommands()
    start_planners(started, spec)
    start_sim(started, spec, 'recorder')
    return started.argv


@pytest.mark.parametrize('runner_argv, launch_arguments', [
    (['headon2'], {'scenario': 'headon2'}),
    (['circle8', '--method', 'rvo', '--eta', '0.9', '--mode', 'realtime', '--seed', '7'],
     {'scenario': 'circle8', 'method': 'rvo', 'eta': '0.9', 'mode': 'realtime', 'seed': '7'}),
    (['paper3', '--method', 'prvo-no-ego'], {'scenario': 'paper3', 'method': 'prvo-no-ego'}),
])
def test_launched_nodes_run_the_runners_command_lines(tmp_path, runner_argv, launch_arguments):
    runner = _runner_commands(runner_argv, tmp_path)
    nodes = scenario_nodes(**launch_arguments)
    assert [node.name for node in nodes[1:]] == ['planner'] * (len(runner) - 1)
    for node in nodes[1:]:
        assert node.command() == runner[f'planner_{node.namespace}']
    sim = nodes[0]
    # The runner's simulator also waits for its recorder; a launched one has none to wait for.
    assert sim.command() + ['-p', "observers:=['recorder']"] == runner['sim']
    assert sim.name == 'prvo_sim' and sim.namespace == ''


def test_scripted_robots_get_no_planner():
    scenario = load_scenario(find_scenario('walkers'))
    nodes = scenario_nodes('walkers')
    planned = [robot.name for robot in scenario.robots if robot.scripted is None]
    assert len(planned) < len(scenario.robots)
    assert [node.namespace for node in nodes[1:]] == planned


@pytest.mark.parametrize('arguments, named', [
    ({'method': 'magic'}, 'method'), ({'mode': 'fast'}, 'mode'), ({'eta': '1.5'}, 'eta'),
    ({'eta': 'high'}, 'eta'), ({'eta': 'nan'}, 'eta'), ({'seed': '1.5'}, 'seed'),
])
def test_bad_launch_arguments_are_refused_naming_them(arguments, named):
    with pytest.raises(LaunchArgumentError, match=f'^{named}: .*'):
        scenario_nodes('headon2', **arguments)


def test_an_unknown_scenario_is_refused_naming_it():
    with pytest.raises(ScenarioError, match='no_such_scenario'):
        scenario_nodes('no_such_scenario')


def test_launch_file_and_rviz_config_are_installed():
    share = pathlib.Path(get_package_share_directory('prvo_sim'))
    assert 'def generate_launch_description' in (
        share / 'launch' / 'scenario.launch.py').read_text()
    rviz = (share / 'rviz' / 'prvo.rviz').read_text()
    assert 'Fixed Frame: map' in rviz and '/robot_0/prvo_markers' in rviz


def test_launch_description_declares_the_arguments_and_runs_processes():
    """Where only `launch` is installed, the description runs the nodes as processes."""
    launch = pytest.importorskip('launch')
    from launch.actions import DeclareLaunchArgument, ExecuteProcess, OpaqueFunction
    from launch.launch_description_sources import PythonLaunchDescriptionSource

    from prvo_sim.launching import LAUNCH_ARGUMENTS, process_actions

    path = pathlib.Path(get_package_share_directory('prvo_sim')) / 'launch' / 'scenario.launch.py'
    description = PythonLaunchDescriptionSource(str(path)).get_launch_description(
        launch.LaunchContext())
    declared = [entity.name for entity in description.entities
                if isinstance(entity, DeclareLaunchArgument)]
    assert declared == list(LAUNCH_ARGUMENTS)
    assert isinstance(description.entities[-1], OpaqueFunction)
    nodes = scenario_nodes('headon2')
    actions = process_actions(nodes)
    assert all(isinstance(action, ExecuteProcess) for action in actions)
    assert len(actions) == len(nodes) == 3
