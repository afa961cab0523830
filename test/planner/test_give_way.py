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
    # Walls on both sides, and no room on its side down to the two radii: the other side.
    spot = spot_beside(ROUTE, goal, RADIUS, RADIUS, lambda start, end: -0.45 <= end[1] <= 0.55)
    assert spot[1] == pytest.approx(0.55)
    assert spot_beside(ROUTE, goal, RADIUS, RADIUS, lambda start, end: False) is None


def between(low, high):
    """Return a room test that lets a robot go only where LOW <= y <= HIGH."""
    return lambda start, end: low - 1e-12 <= end[1] <= high + 1e-12


@pytest.mark.parametrize('goal_y', [0.02, 0.0, -0.02, -0.2])
def test_a_goal_on_the_route_steps_toward_a_near_wall_and_leaves_the_open_side_whole(goal_y):
    # A wall 0.3 below the route, open above: against the wall, though the goal lies above the
    # route or on it (where the route's right would be the wall's side by chance).
    spot = spot_beside(ROUTE, np.array([1.0, goal_y]), RADIUS, RADIUS, between(-0.3, 5.0))
    np.testing.assert_allclose(spot, [1.0, -0.3], atol=1e-9)
    # The same with the wall above: the side is the wall's, not the route's right.
    spot = spot_beside(ROUTE, np.array([1.0, -goal_y]), RADIUS, RADIUS, between(-5.0, 0.3))
    np.testing.assert_allclose(spot, [1.0, 0.3], atol=1e-9)


def test_a_goal_clearly_on_the_open_side_does_not_cross_the_route_to_a_wall():
    # 0.3 above the route, a wall 0.3 below it: away from the route on its own side, as without
    # a wall (crossing, it would stand in the passer's way on the other side).
    spot = spot_beside(ROUTE, np.array([1.0, 0.3]), RADIUS, RADIUS, between(-0.3, 5.0))
    np.testing.assert_allclose(spot, [1.0, NEEDED], atol=1e-9)


def test_a_goal_against_its_wall_already_stays():
    assert spot_beside(ROUTE, np.array([1.0, -0.3]), RADIUS, RADIUS, between(-0.3, 5.0)) is None


def test_a_goal_beyond_the_needed_distance_steps_away_for_one_going_round_a_robot_on_the_route():
    # The passer may go round a robot standing on its route, up to NEEDED off it, and then
    # needs NEEDED and GAP from this one: a goal within 2 NEEDED and GAP of the route steps away
    # to that distance, as far as walls and other robots let it.
    beyond = 2 * NEEDED + GAP
    goal = np.array([1.0, -(NEEDED + 0.3)])
    spot = spot_beside(ROUTE, goal, RADIUS, RADIUS, between(-5.0, 5.0))
    np.testing.assert_allclose(spot, [1.0, -beyond], atol=1e-9)
    spot = spot_beside(ROUTE, goal, RADIUS, RADIUS, between(-(NEEDED + 0.5), 5.0))
    np.testing.assert_allclose(spot, [1.0, -(NEEDED + 0.5)], atol=1e-9)
    # Another robot below it: the two radii and GAP from it.
    other = np.array([1.0, -(beyond + 0.4)])
    spot = spot_beside(ROUTE, goal, RADIUS, RADIUS, between(-5.0, 5.0), [(other, RADIUS)])
    assert np.hypot(*(spot - other)) >= NEEDED - 1e-9
    assert spot[1] == pytest.approx(other[1] + NEEDED, abs=0.05)
    # A way that ends beside the goal (a neighbour going back to its own goal) has nobody to
    # pass: two robots stepped aside would otherwise keep each other aside for good.
    ending = np.array([[-3.0, 0.0], [1.0, 0.0]])
    assert spot_beside(ending, goal, RADIUS, RADIUS, between(-5.0, 5.0)) is None
    # Without a map, or farther off: it stays.
    assert spot_beside(ROUTE, goal, RADIUS, RADIUS, None) is None
    far = np.array([1.0, -(beyond + 0.01)])
    assert spot_beside(ROUTE, far, RADIUS, RADIUS, between(-5.0, 5.0)) is None


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
