"""A team fixture: the simulator and one planner per robot, as real processes."""

import copy
import os
import threading

from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Odometry
import numpy as np
import pytest
from rosgraph_msgs.msg import Clock

from prvo_msgs_util import (
    CLOCK,
    CLOCK_QOS,
    DIAGNOSTICS,
    DIAGNOSTICS_QOS,
    GROUND_TRUTH,
    ODOM_QOS,
    diagnostic_values,
    robot_topic,
    stamp_to_seconds,
)
from prvo_sim.scenario import find_scenario, load_scenario

OBSERVER_QUEUE_DEPTH = 2000


class TeamObserver:
    """What the probe sees of a running team: ground truth and the simulator's status."""

    def __init__(self, probe, robot_names):
        self._lock = threading.Lock()
        self.ground_truth = {name: {} for name in robot_names}
        self.sim_status = {}
        self.robot_status = {name: {} for name in robot_names}
        self.planner_status = {name: {} for name in robot_names}
        # A deep queue: a lockstep team can publish faster than a loaded probe takes messages.
        deep = copy.copy(ODOM_QOS)
        deep.depth = OBSERVER_QUEUE_DEPTH
        for name in robot_names:
            probe.node.create_subscription(
                Odometry, robot_topic(name, GROUND_TRUTH),
                lambda msg, name=name: self._on_ground_truth(name, msg), deep)
        probe.node.create_subscription(
            DiagnosticArray, DIAGNOSTICS, self._on_diagnostics, DIAGNOSTICS_QOS)
        # The simulator's observers listen to /clock too; the team's clock is not needed here.
        probe.node.create_subscription(Clock, CLOCK, lambda msg: None, CLOCK_QOS)

    def _on_ground_truth(self, name, msg):
        position = msg.pose.pose.position
        with self._lock:
            self.ground_truth[name][round(stamp_to_seconds(msg.header.stamp), 6)] = (
                position.x, position.y)

    def _on_diagnostics(self, msg):
        with self._lock:
            for status in msg.status:
                values = diagnostic_values(status)
                if status.name == 'prvo_sim':
                    self.sim_status = values
                elif status.name.startswith('prvo_sim/'):
                    self.robot_status.setdefault(status.name[len('prvo_sim/'):], {}).update(
                        values)
                elif status.name.startswith('prvo_planner/'):
                    self.planner_status.setdefault(
                        status.name[len('prvo_planner/'):], {}).update(values)

    def sim_time(self):
        return float(self.sim_status.get('sim_time', '-1'))

    def all_arrived(self):
        return bool(self.robot_status) and all(
            status.get('arrived') == 'true' for status in self.robot_status.values())

    def deadline_misses(self, name):
        return int(self.robot_status.get(name, {}).get('deadline_misses', '0'))

    def trajectories(self):
        """Return {robot: (stamps (T,), positions (T, 2))} sorted by stamp."""
        with self._lock:
            copies = {name: dict(samples) for name, samples in self.ground_truth.items()}
        result = {}
        for name, samples in copies.items():
            stamps = np.array(sorted(samples))
            result[name] = (stamps, np.array([samples[s] for s in stamps]).reshape(-1, 2))
        return result

    def min_clearance(self, scenario):
        """Smallest distance minus the sum of radii over robot pairs at common stamps."""
        trajectories = self.trajectories()
        clearance = np.inf
        robots = scenario.robots
        for a in range(len(robots)):
            for b in range(a + 1, len(robots)):
                stamps_a, positions_a = trajectories[robots[a].name]
                stamps_b, positions_b = trajectories[robots[b].name]
                common, index_a, index_b = np.intersect1d(
                    stamps_a, stamps_b, return_indices=True)
                if common.size:
                    distance = np.linalg.norm(positions_a[index_a] - positions_b[index_b], axis=1)
                    clearance = min(clearance, float(distance.min()) - robots[a].radius
                                    - robots[b].radius)
        return clearance


class Team:
    """Start the simulator and planners of a scenario through the `children` fixture."""

    def __init__(self, children, ros2_executable, scenario_name, tmp_path):
        self.children = children
        self.scenario = load_scenario(find_scenario(scenario_name))
        self._ros2_executable = ros2_executable
        self._tmp_path = tmp_path
        self.planners = {}
        self.sim = None
        # Nodes the simulator waits for before its first step (see `observe`).
        self.observers = []

    def start_sim(self, seed=None, step_timeout=2.0, mode='lockstep', label='sim'):
        argv = [self._ros2_executable('prvo_sim', 'sim'), '--ros-args',
                '-p', f'scenario:={self.scenario.path}', '-p', f'mode:={mode}',
                '-p', f'step_timeout:={float(step_timeout)}']
        if seed is not None:
            argv += ['-p', f'seed:={int(seed)}']
        if self.observers:
            argv += ['-p', 'observers:=[' + ', '.join(
                f"'{name}'" for name in self.observers) + ']']
        self.sim = self.children.start(label, argv)
        return self.sim

    def start_planner(self, robot, label=None, **parameters):
        spec = next(r for r in self.scenario.robots if r.name == robot)
        values = {
            'use_sim_time': True, 'goal': [float(v) for v in spec.goal],
            'radius': spec.radius, 'max_speed': spec.max_speed,
            'actuation_std': spec.noise.actuation_std,
            'goal_tolerance': 0.5 * self.scenario.goal_tolerance,
            'neighbors': [r.name for r in self.scenario.robots if r.name != robot],
            # Lockstep waits, as the runner sets them: reproducible however loaded the host.
            'sync_timeout': 1.0, 'neighbor_timeout': 5.0}
        values.update(spec.planner)
        values.update(parameters)
        argv = [self._ros2_executable('prvo_planner', 'planner'), '--ros-args',
                '-r', f'__ns:=/{robot}']
        for name, value in values.items():
            text = str(value).lower() if isinstance(value, bool) else str(value)
            argv += ['-p', f'{name}:={text}']
        process = self.children.start(label or f'planner_{robot}', argv)
        self.planners[robot] = process
        return process

    def start_planners(self, **parameters):
        for spec in self.scenario.robots:
            self.start_planner(spec.name, **parameters)


@pytest.fixture
def make_team(children, ros2_executable, tmp_path):
    """Return a factory of `Team`s by scenario name (processes not started yet)."""
    return lambda scenario_name: Team(children, ros2_executable, scenario_name, tmp_path)


def observe_through(probe, team):
    """Return a `TeamObserver` of TEAM subscribed through PROBE, which the simulator awaits."""
    observer = TeamObserver(probe, [spec.name for spec in team.scenario.robots])
    # The simulator takes no step before the probe listens (its `observers` parameter).
    team.observers.append(probe.node.get_fully_qualified_name())
    return observer


@pytest.fixture
def observe(probe):
    """Return a factory of `TeamObserver`s of a team, subscribed through the probe."""
    return lambda team: observe_through(probe, team)


@pytest.fixture(scope='module')
def module_team(module_domains, ros2_executable, tmp_path_factory):
    """Return a factory of (`Team`, its `TeamObserver`, the probe), each on a domain of its own.

    For the tests of one module that share a team (see `module_domains`).
    """
    def make(scenario_name):
        group, ros_probe = module_domains()
        team = Team(group, ros2_executable, scenario_name, tmp_path_factory.mktemp('team'))
        return team, observe_through(ros_probe, team), ros_probe

    return make


@pytest.fixture(autouse=True)
def _integration_environment(ros_env):
    """Integration tests need the installed executables (run through ./run.sh test)."""
    if 'AMENT_PREFIX_PATH' not in os.environ:
        pytest.fail('AMENT_PREFIX_PATH is not set: run the tests with ./run.sh test')
