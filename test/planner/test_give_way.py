"""Give way (prvo_planner.give_way), alone: where a robot at its goal steps for a passing route."""

import numpy as np
from planner_testing import Odometry
import pytest

from prvo_planner.agent import AgentSettings, PlannerAgent
from prvo_planner.core import PlannerConfig
from prvo_planner.give_way import GAP, RANGE, give_way_spot, spot_beside, way_ahead

RADIUS = 0.25
NEEDED = 2 * RADIUS + GAP
# A route along y = 0 from x = -3 to x = 3.
ROUTE = np.array([[-3.0, 0.0], [0.0, 0.0], [3.0, 0.0]])


def distance_to_route(point, route=ROUTE):
    """Return the distance [m] of POINT (2,) from the polyline ROUTE, by dense sampling."""
    samples = np.concatenate([np.linspace(a, b, 2001)
                              for a, b in zip(route[:-1], route[1:], strict=True)])
    return np.min(np.hypot(*(samples - point).T))


def below(limit):
    """Return a room test that lets a robot go only where y <= LIMIT."""
    return lambda start, end: end[1] <= limit + 1e-12


def test_a_goal_on_the_route_steps_off_it_to_the_route_s_right_by_the_radii_and_the_gap():
    spot = spot_beside(ROUTE, np.array([1.0, 0.0]), RADIUS, RADIUS, None)
    np.testing.assert_allclose(spot, [1.0, -NEEDED])


@pytest.mark.parametrize('offset', [0.05, 0.3, -0.3, NEEDED - 0.01])
def test_a_goal_beside_the_route_steps_away_on_its_own_side_to_the_needed_distance(offset):
    goal = np.array([-1.5, offset])
    spot = spot_beside(ROUTE, goal, RADIUS, RADIUS, None)
    assert spot[0] == pytest.approx(-1.5)
    assert np.sign(spot[1]) == np.sign(offset)
    assert distance_to_route(spot) == pytest.approx(NEEDED, abs=1e-3)


def test_a_goal_far_enough_from_the_route_stays():
    assert spot_beside(ROUTE, np.array([0.0, NEEDED + 0.01]), RADIUS, RADIUS, None) is None


def test_with_little_room_the_robot_steps_as_far_as_it_can_down_to_the_two_radii():
    goal = np.array([0.0, -0.2])
    # Room down to y = -0.55: between the two radii (0.5) and the needed distance (0.6).
    spot = spot_beside(ROUTE, goal, RADIUS, RADIUS, lambda start, end: end[1] >= -0.55)
    assert -0.55 <= spot[1] < -0.5
    # No room on its side below the two radii: the other side.
    spot = spot_beside(ROUTE, goal, RADIUS, RADIUS, lambda start, end: end[1] >= -0.45)
    assert spot[1] == pytest.approx(NEEDED)
    assert spot_beside(ROUTE, goal, RADIUS, RADIUS, lambda start, end: False) is None


def test_the_nearest_neighbour_whose_way_passes_by_the_goal_decides():
    goal = np.array([0.0, 0.0])
    near = ([-1.0, 0.0], RADIUS, np.array([[-1.0, 0.0], [2.0, 0.0]]))
    # Farther, on a way that passes the goal diagonally, with a larger radius.
    far = ([-2.0, -2.0], 0.5, np.array([[-2.0, -2.0], [2.0, 2.0]]))
    np.testing.assert_allclose(give_way_spot(goal, RADIUS, [far, near], None), [0.0, -NEEDED])
    spot = give_way_spot(goal, RADIUS, [far], None)
    assert distance_to_route(spot, far[2]) == pytest.approx(RADIUS + 0.5 + GAP, abs=1e-3)


@pytest.mark.parametrize('neighbour', [
    ([-1.0, 0.0], RADIUS, None),  # publishes no route
    ([-1.0, 0.0], RADIUS, np.array([[-1.0, 0.0]])),  # a route of one point
    ([-1.01 * RANGE, 0.0], RADIUS, ROUTE),  # beyond the range
    ([1.0, 0.0], RADIUS, ROUTE),  # went by: the goal is behind it on its route
    ([3.0, 0.0], RADIUS, ROUTE),  # at the end of its route: arrived
])
def test_no_route_one_too_far_one_that_went_by_or_arrived_claims_nothing(neighbour):
    assert give_way_spot(np.array([0.0, 0.0]), RADIUS, [neighbour], None) is None


def test_the_way_ahead_starts_where_the_robot_is_on_its_route():
    np.testing.assert_allclose(way_ahead(ROUTE, np.array([1.0, 0.2])),
                               [[1.0, 0.0], [3.0, 0.0]])
    np.testing.assert_allclose(way_ahead(ROUTE, np.array([-5.0, 0.0])), ROUTE)


def test_a_robot_giving_way_longer_than_the_stall_window_is_not_stalled():
    # A robot at its goal, then beside it for 15 s while a neighbour stands 1.5 m off with its
    # route through the goal: it gives way the whole time, and its monitor does not call that a
    # stall (the neighbour, not it, is held).
    goal = np.array([0.0, 0.0])
    agent = PlannerAgent('self', PlannerConfig(actuation_cov=0.0025 * np.eye(2)),
                         AgentSettings(radius=RADIUS, goal_tolerance=0.2), goal)
    agent.receive_route('other', np.array([[-1.5, 0.0], [3.0, 0.0]]), 0.0)
    agent.receive_footprint('other', RADIUS, 0.0)
    covariance = 0.0025 * np.eye(4)
    commands = []
    for step in range(160):
        stamp = round(0.1 * step, 9)
        own = goal if step < 10 else goal + [0.0, -NEEDED]
        agent.receive_neighbour('other', Odometry(stamp, np.array([-1.5, 0.0]), np.zeros(2),
                                                  covariance), 0.0)
        agent.receive_own(Odometry(stamp, own, np.zeros(2), covariance), 0.0)
        commands.append(agent.plan())
    # Beside its goal it does not head back to it (it would at 1 m/s without giving way).
    assert commands[-1].velocity[1] < 0.1
    assert all(command.stall is not None for command in commands)
    assert not any(command.stall.stalled for command in commands)
    assert commands[-1].stall.stalls == 0
