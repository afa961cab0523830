"""The pure-pursuit carrot against an independent path-circle intersection, and path following.

The independent computation walks the path by arc length on a fine grid and bisects the first
sign change of |p(s) - x| - L after the robot's closest point: no quadratic, no segment logic
shared with the implementation.
"""

import dataclasses

import numpy as np
import pytest

from prvo_planner.agent import AgentSettings, PlannerAgent
from prvo_planner.core import PlannerConfig
from prvo_planner.path_following import carrot, closest_on_path
from prvo_planner.preferred import LookaheadSettings, PathFollower

# An L-shaped corridor route: 4 m east, then 3 m north.
L_ROUTE = np.array([[0.0, 0.0], [2.0, 0.0], [4.0, 0.0], [4.0, 1.5], [4.0, 3.0]])


def _points_at(path, s):
    """Return the points (S, 2) at arc lengths S [m] along PATH (K, 2), and its length."""
    lengths = np.linalg.norm(np.diff(path, axis=0), axis=1)
    ends = np.concatenate([[0.0], np.cumsum(lengths)])
    s = np.clip(np.atleast_1d(s), 0.0, ends[-1])
    index = np.minimum(np.searchsorted(ends, s, side='right') - 1, len(lengths) - 1)
    fraction = (s - ends[index]) / lengths[index]
    return path[index] + fraction[:, None] * (path[index + 1] - path[index]), ends[-1]


def _independent_carrot(path, position, lookahead):
    """Return the first point past the closest one where the path leaves the circle."""
    total = _points_at(path, 0.0)[1]
    ends = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
    grid = np.unique(np.concatenate([np.linspace(0.0, total, 200001), ends]))
    distances = np.hypot(*(_points_at(path, grid)[0] - position).T)
    start = int(np.argmin(distances))
    if distances[start] >= lookahead:
        return _points_at(path, grid[start])[0][0]
    outside = np.nonzero(distances[start:] >= lookahead)[0]
    if len(outside) == 0:
        return path[-1]
    low, high = grid[start + outside[0] - 1], grid[start + outside[0]]
    for _ in range(60):
        middle = 0.5 * (low + high)
        if np.hypot(*(_points_at(path, middle)[0][0] - position)) >= lookahead:
            high = middle
        else:
            low = middle
    return _points_at(path, high)[0][0]


def test_carrot_is_the_path_circle_intersection():
    rng = np.random.default_rng(25)
    for _ in range(200):
        # Paths heading east with turns up to 60 degrees: no loop back, one closest point.
        count = rng.integers(2, 7)
        headings = rng.uniform(-np.pi / 3.0, np.pi / 3.0, count)
        steps = rng.uniform(0.2, 1.5, count)[:, None] * np.stack(
            [np.cos(headings), np.sin(headings)], axis=1)
        path = np.concatenate([[[0.0, 0.0]], np.cumsum(steps, axis=0)])
        position = path[rng.integers(0, count)] + rng.uniform(-0.8, 0.8, 2)
        lookahead = rng.uniform(0.2, 1.5)
        point, _ = carrot(path, position, lookahead)
        np.testing.assert_allclose(point, _independent_carrot(path, position, lookahead),
                                   atol=2e-5, err_msg=f'{path.tolist()} {position} {lookahead}')


def test_carrot_on_the_l_route_turns_the_corner():
    # At (3.5, 0) with a 1 m lookahead the circle meets the second leg at (4, sqrt(0.75)).
    point, segment = carrot(L_ROUTE, [3.5, 0.0], 1.0)
    np.testing.assert_allclose(point, [4.0, np.sqrt(1.0 - 0.25)], atol=1e-12)
    assert segment == 1
    # Off the path by more than the lookahead: back to the closest point first.
    point, _ = carrot(L_ROUTE, [1.0, -2.0], 1.0)
    np.testing.assert_allclose(point, [1.0, 0.0], atol=1e-12)
    # Near the end: the last waypoint.
    point, _ = carrot(L_ROUTE, [4.0, 2.8], 1.0)
    np.testing.assert_allclose(point, [4.0, 3.0])


def test_progress_never_goes_back():
    segment, point = closest_on_path(L_ROUTE, [3.9, 1.0], start_segment=3)
    assert segment == 3
    np.testing.assert_allclose(point, [4.0, 1.5])


def test_way_left_is_the_length_to_the_end():
    follower = PathFollower(L_ROUTE)
    _, left = follower.advance([1.0, 0.0], 0.5)
    assert left == pytest.approx(3.0 + 3.0)
    _, left = follower.advance([4.2, 2.0], 0.5)
    assert left == pytest.approx(1.0 + 0.2)


def test_velocity_scaled_lookahead_is_clamped():
    settings = LookaheadSettings(0.6, True, 0.3, 0.9, 1.5)
    assert settings.distance(0.0) == 0.3
    assert settings.distance(0.4) == pytest.approx(0.6)
    assert settings.distance(2.0) == 0.9
    assert LookaheadSettings().distance(2.0) == 1.0


@dataclasses.dataclass(frozen=True)
class _Measurement:
    stamp: float
    position: np.ndarray
    velocity: np.ndarray
    covariance: np.ndarray
    yaw: float = 0.0


@pytest.mark.parametrize('scaled', [False, True])
def test_path_mode_follows_the_l_route_to_its_end(scaled):
    settings = AgentSettings(preferred_source='path', goal_tolerance=0.1,
                             use_velocity_scaled_lookahead_dist=scaled)
    agent = PlannerAgent('robot_0', PlannerConfig(max_speed=0.8), settings)
    agent.set_path(L_ROUTE)
    np.testing.assert_array_equal(agent.goal, L_ROUTE[-1])
    assert agent.own_announcement.avoidance_share == 0.5
    dt, position, velocity = 0.1, np.array([0.0, -0.1]), np.zeros(2)
    worst = 0.0
    for step in range(400):
        agent.receive_own(_Measurement(round(step * dt, 9), position.copy(), velocity.copy(),
                                       1e-4 * np.eye(4)), step * dt)
        command = agent.plan()
        if command.arrived:
            break
        velocity = command.velocity
        position = position + dt * velocity
        # Distance to the corridor's centre line.
        worst = max(worst, min(abs(position[1]) if position[0] <= 4.0 else np.inf,
                               abs(position[0] - 4.0) if position[1] >= 0.0 else np.inf))
    assert command.arrived
    assert np.hypot(*(position - L_ROUTE[-1])) <= 0.1
    # A chord to a carrot within the lookahead L cuts the right-angled corner by at most L / 2.
    assert worst <= 0.5 * (settings.max_lookahead_dist if scaled else settings.lookahead_dist)
    assert agent.own_announcement.avoidance_share == 0.0


def test_empty_path_cancels():
    agent = PlannerAgent('robot_0', PlannerConfig(), AgentSettings(preferred_source='path'))
    agent.set_path(L_ROUTE)
    agent.set_path(np.zeros((0, 2)))
    assert agent.goal is None and agent.path is None
    agent.receive_own(_Measurement(0.0, np.zeros(2), np.zeros(2), 1e-4 * np.eye(4)), 0.0)
    np.testing.assert_array_equal(agent.plan().velocity, [0.0, 0.0])
    with pytest.raises(ValueError, match='finite'):
        PathFollower([[0.0, 0.0], [np.nan, 1.0]])


@pytest.fixture
def path_node(ros_domain):
    """Yield (PlannerNode in /robot_0 following paths, published carrots)."""
    import rclpy

    from prvo_planner.planner_node import PlannerNode

    rclpy.init(domain_id=ros_domain, args=[
        '--ros-args', '-r', '__ns:=/robot_0', '-p', 'preferred_source:=path',
        '-p', 'neighbors:=[""]', '-p', 'lookahead_dist:=1.0'])
    node = PlannerNode()
    carrots = []
    node._lookahead_publisher.publish = carrots.append
    node._cmd_vel_publisher.publish = lambda message: None
    yield node, carrots
    node.destroy_node()
    rclpy.try_shutdown()


def test_node_follows_a_path_message_and_publishes_the_carrot(path_node):
    from rclpy.serialization import serialize_message

    from prvo_msgs_util import make_path, serialize_odometry

    node, carrots = path_node
    assert node.count_subscribers('/robot_0/goal_pose') == 0
    node._on_path(serialize_message(make_path(0.0, L_ROUTE)))
    np.testing.assert_array_equal(node._agent.goal, L_ROUTE[-1])
    node._on_own_odometry(serialize_odometry(0.1, [3.5, 0.0], [0.0, 0.0], 1e-4 * np.eye(2),
                                             1e-4 * np.eye(2)))
    assert len(carrots) == 1 and carrots[0].header.frame_id == 'map'
    np.testing.assert_allclose([carrots[0].point.x, carrots[0].point.y],
                               [4.0, np.sqrt(0.75)], atol=1e-9)
    # A path in another frame is refused; an empty one cancels.
    node._on_path(serialize_message(make_path(0.0, L_ROUTE, frame_id='odom')))
    np.testing.assert_array_equal(node._agent.goal, L_ROUTE[-1])
    node._on_path(serialize_message(make_path(0.0, np.zeros((0, 2)))))
    assert node._agent.goal is None
