"""Robots following the Paths of a planner_server stand-in: the poses, the scenario key, a team.

The team runs on the in-process engine (the same agents and stand-in logic as the ROS lockstep
run, whose agreement test/runner/test_runner_nav2.py checks), ten seeds.
"""

import dataclasses
import re

import numpy as np
import pytest

from prvo_planner.agent import AgentSettings, PlannerAgent
from prvo_planner.core import PlannerConfig
from prvo_sim.engine import InProcessTeam
from prvo_sim.planned_path import PlannedPath, path_poses, pose_count
from prvo_sim.runner.session import planner_values
from prvo_sim.scenario import ScenarioError, find_scenario, load_scenario

SEEDS = range(10)
HEADER = """name: paths
seed: 1
dt: 0.1
duration: 10.0
goal_tolerance: 0.2
robots:
  - name: robot_0
    start: [0.0, 0.0]
    radius: 0.3
    max_speed: 1.0
"""


@dataclasses.dataclass(frozen=True)
class _Measurement:
    stamp: float
    position: np.ndarray
    velocity: np.ndarray
    covariance: np.ndarray
    yaw: float = 0.0


def _distance_to_polyline(point, waypoints):
    """Return the distance from POINT to the polyline WAYPOINTS, the test's own arithmetic."""
    best = np.inf
    for a, b in zip(waypoints[:-1], waypoints[1:], strict=True):
        ab = b - a
        t = 0.0 if not ab.any() else min(max(float((point - a) @ ab) / float(ab @ ab), 0.0),
                                         1.0)
        best = min(best, float(np.hypot(*(a + t * ab - point))))
    return best


def test_poses_lie_on_the_route_at_most_spacing_apart_through_every_waypoint():
    rng = np.random.default_rng(3)
    for _ in range(50):
        waypoints = rng.uniform(-5.0, 5.0, (int(rng.integers(2, 6)), 2))
        waypoints[2:3] = waypoints[1:2]  # a repeated waypoint adds no pose
        spacing = float(rng.uniform(0.01, 0.5))
        poses = path_poses(waypoints, spacing)
        steps = np.hypot(*np.diff(poses, axis=0).T)
        assert np.all(steps <= spacing + 1e-12) and np.all(steps > 0.0)
        assert max(_distance_to_polyline(pose, waypoints) for pose in poses) <= 1e-9
        for waypoint in waypoints:
            assert np.min(np.hypot(*(poses - waypoint).T)) <= 1e-12
        np.testing.assert_array_equal(poses[[0, -1]], waypoints[[0, -1]])
    np.testing.assert_array_equal(path_poses([[1.0, 2.0]]), [[1.0, 2.0]])


def test_the_pose_count_is_that_of_the_poses():
    rng = np.random.default_rng(8)
    for count in (1, 2, 5, 12):
        waypoints = rng.uniform(-3.0, 3.0, (count, 2))
        # A repeated waypoint adds no pose.
        waypoints = np.insert(waypoints, count // 2, waypoints[count // 2], axis=0)
        assert pose_count(waypoints) == len(path_poses(waypoints))


def test_a_route_is_published_again_only_when_it_changes():
    path = PlannedPath(0.5)
    first = path.replan([[0.0, 0.0], [1.0, 0.0]])
    np.testing.assert_allclose(first, [[0.0, 0.0], [0.5, 0.0], [1.0, 0.0]])
    assert path.replan([[0.0, 0.0], [1.0, 0.0]]) is None
    assert path.replan([[0.0, 0.0], [1.0, 1.0]]) is not None
    with pytest.raises(ValueError, match='finite'):
        path.replan([[0.0, 0.0], [np.inf, 1.0]])
    with pytest.raises(ValueError, match=re.escape('shape (K, 2), K >= 1, got shape (0,)')):
        path.replan([])
    np.testing.assert_array_equal(path.poses[-1], [1.0, 1.0])


def test_the_same_path_again_keeps_the_progress_and_wait_for_path_waits():
    settings = AgentSettings(preferred_source='path', wait_for_path=True, neighbor_timeout=2.0)
    agent = PlannerAgent('robot_0', PlannerConfig(), settings)
    agent.receive_own(_Measurement(0.0, np.array([3.0, 0.0]), np.zeros(2), 1e-4 * np.eye(4)),
                      10.0)
    assert agent.awaiting_listed(10.5) and not agent.ready(10.5)
    assert not agent.awaiting_listed(12.5)
    route = path_poses([[0.0, 0.0], [4.0, 0.0], [4.0, 4.0]])
    agent.set_path(route)
    assert agent.ready(10.5)
    agent.plan()
    follower = agent.path
    assert follower.segment > 0
    agent.set_path(route.copy())
    assert agent.path is follower
    agent.set_path(route[::-1])
    assert agent.path is not follower


@pytest.mark.parametrize(('block', 'key', 'reason'), [
    ('    goal: [1.0, 0.0]\n    path: {waypoints: [[1.0, 0.0]]}\n', 'robots[0].path',
     "robot 'robot_0' follows path.waypoints: it has no goal"),
    ('    upstream: {waypoints: [[1.0, 0.0]]}\n    path: {waypoints: [[1.0, 0.0]]}\n',
     'robots[0].path', "robot 'robot_0' follows path.waypoints: it has no upstream block"),
    ('    path: {waypoints: []}\n', 'robots[0].path.waypoints',
     "expected a non-empty list of [x, y], got [] (robot 'robot_0')"),
    ('    path: {waypoints: [[1.0, 0.0]], speed: 0.5}\n', 'robots[0].path.speed',
     'unknown key (allowed: waypoints)'),
    ('    path: {waypoints: [[1.0, .nan]]}\n', 'robots[0].path.waypoints[0][1]',
     'expected a finite number, got nan'),
    # 600 m at 5 cm a pose: the planner would ignore it (ROS) or follow it (in process).
    ('    path: {waypoints: [[300.0, 0.0], [-300.0, 0.0]]}\n', 'robots[0].path.waypoints',
     "the path of robot 'robot_0' is 12001 poses (one every 0.05 m), more than the 10000 a "
     'planner takes'),
])
def test_a_bad_path_block_is_named_in_one_line(tmp_path, block, key, reason):
    path = tmp_path / 'paths.yaml'
    path.write_text(HEADER + block)
    with pytest.raises(ScenarioError) as raised:
        load_scenario(path)
    message = str(raised.value)
    assert '\n' not in message and message.startswith(f'{path}: {key}: ') and reason in message


def _run(method, seed):
    """Return (contacts, arrived (N,)) of nav2_path_crossing4 on the in-process engine."""
    scenario = load_scenario(find_scenario('nav2_path_crossing4'), seed=seed)
    team = InProcessTeam(scenario, [planner_values(robot, scenario, method, None)
                                    for robot in scenario.robots], seed=seed)
    ends = np.array([robot.followed_path.waypoints[-1] for robot in scenario.robots])
    contacts, arrived = 0, np.zeros(len(ends), dtype=bool)
    while not team.finished and not arrived.all():
        step = team.do_step()
        contacts += len(step.contacts)
        arrived |= np.linalg.norm(step.states[:, :2] - ends, axis=1) <= scenario.goal_tolerance
    return contacts, arrived


def test_path_following_team_reaches_every_path_end_without_contact():
    assert _run('none', 0)[0] > 0
    for seed in SEEDS:
        contacts, arrived = _run('prvo', seed)
        assert contacts == 0, seed
        assert arrived.all(), seed
