"""Pass beside: a robot aims beside a neighbour standing on its way, at the two radii and GAP."""

import math

import numpy as np
from planner_testing import Odometry
import pytest

from prvo_planner.agent import AgentSettings, PlannerAgent
from prvo_planner.core import PlannerConfig
from prvo_planner.give_way import GAP
from prvo_planner.passing import AT_GOAL, RANGE, at_goal, pass_beside
from prvo_planner.routes import NeighbourRoute

RADIUS = 0.3
# The robot at the origin heads along +x, its way 6 m long.
POSITION = np.zeros(2)
WAY = np.array([[0.0, 0.0], [6.0, 0.0]])
V_PREF = np.array([0.8, 0.0])
NEEDED = RADIUS + 0.25 + GAP


def aimed_at(velocity):
    """Return the unit direction of VELOCITY (2,)."""
    return velocity / math.hypot(*velocity)


def toward(point):
    """Return the unit direction from POSITION to POINT (2,)."""
    return aimed_at(np.asarray(point, dtype=float) - POSITION)


@pytest.mark.parametrize('lateral, side', [(0.0, -1.0), (0.04, -1.0), (-0.04, -1.0),
                                           (0.3, -1.0), (-0.3, 1.0), (NEEDED - 0.01, -1.0)])
def test_a_standing_neighbour_on_the_way_is_passed_at_the_needed_distance_away_from_it(
        lateral, side):
    # Away from its side of the way; to the way's right (-y) where it stands on it (GAP).
    other = np.array([2.0, lateral])
    velocity = pass_beside(POSITION, V_PREF, WAY, RADIUS, [(other, 0.25)], None)
    assert math.hypot(*velocity) == pytest.approx(0.8, abs=1e-12)
    np.testing.assert_allclose(aimed_at(velocity), toward([2.0, lateral + side * NEEDED]),
                               atol=1e-12)


def test_where_the_map_leaves_no_room_on_one_side_it_passes_on_the_other():
    # A wall 0.2 m right of the way: the standing one steps toward it (`give_way`), the robot
    # passes on the open side.
    def room(start, end):
        return min(start[1], end[1]) >= -0.2
    other = np.array([2.0, 0.0])
    velocity = pass_beside(POSITION, V_PREF, WAY, RADIUS, [(other, 0.25)], room)
    np.testing.assert_allclose(aimed_at(velocity), toward([2.0, NEEDED]), atol=1e-12)


def test_with_no_room_on_either_side_the_route_leads():
    def room(start, end):
        return abs(start[1]) <= 0.2 and abs(end[1]) <= 0.2
    velocity = pass_beside(POSITION, V_PREF, WAY, RADIUS, [(np.array([2.0, 0.0]), 0.25)], room)
    np.testing.assert_array_equal(velocity, V_PREF)


@pytest.mark.parametrize('other', [
    [2.0, NEEDED + 0.01],       # clear of the way
    [2.0, -(NEEDED + 0.01)],
    [-0.5, 0.0],                # behind the robot
    [0.0, 0.3],                 # abreast of it
    [RANGE + 0.1, 0.0],         # too far ahead yet
    [6.2, 0.0],                 # where the way ends: the robot's goal is beside it
])
def test_a_neighbour_clear_of_the_way_behind_abreast_far_or_at_its_end_changes_nothing(other):
    velocity = pass_beside(POSITION, V_PREF, WAY, RADIUS, [(np.array(other), 0.25)], None)
    np.testing.assert_array_equal(velocity, V_PREF)


def test_the_nearest_standing_neighbour_along_the_way_decides():
    first = np.array([1.0, 0.1])
    second = np.array([2.0, -0.1])
    for standing in ([(first, 0.25), (second, 0.25)], [(second, 0.25), (first, 0.25)]):
        velocity = pass_beside(POSITION, V_PREF, WAY, RADIUS, standing, None)
        np.testing.assert_allclose(aimed_at(velocity), toward(first - [0.0, NEEDED]), atol=1e-12)


def test_on_a_way_that_turns_the_side_is_the_way_s_where_the_neighbour_stands():
    # Heading +y after the turn, the neighbour stands 0.1 right of the way (+x): the robot
    # passes on its left (-x).
    way = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 5.0]])
    other = np.array([1.1, 2.0])
    velocity = pass_beside(POSITION, V_PREF, way, RADIUS, [(other, 0.25)], None)
    np.testing.assert_allclose(aimed_at(velocity), toward(other - [NEEDED, 0.0]), atol=1e-12)


def test_a_robot_that_stands_still_is_left_still():
    velocity = pass_beside(POSITION, np.zeros(2), WAY, RADIUS, [(np.array([2.0, 0.0]), 0.25)],
                           None)
    np.testing.assert_array_equal(velocity, np.zeros(2))


def test_a_neighbour_near_the_end_of_the_route_it_publishes_stands():
    route = NeighbourRoute(points=np.array([[0.0, 0.0], [4.0, 0.0]]), stamp=0.0)
    assert at_goal(np.array([4.0, AT_GOAL - 0.01]), route)
    assert not at_goal(np.array([4.0 - AT_GOAL - 0.01, 0.0]), route)
    assert not at_goal(np.array([4.0, 0.0]), None)


@pytest.mark.parametrize('share, at, goal, oncoming', [
    (0.5, [3.0, 0.2], [-1.0, 0.2], True),   # on its way toward the robot: met, it leans right
    (0.0, [3.0, 0.2], [-1.0, 0.2], False),  # announcing no share: it stands, whatever it seems
    (0.5, [5.8, 0.2], [5.5, 0.2], False),   # within AT_GOAL of its goal: arriving, or aside
])
def test_keep_right_meets_a_neighbour_on_its_way_and_not_one_that_stands(share, at, goal,
                                                                          oncoming):
    settings = AgentSettings(radius=0.3, unknown_neighbor_radius=0.4, approach_time=0.5,
                             goal_tolerance=0.2, acceleration_std=1.0, neighbor_timeout=2.0)
    config = PlannerConfig(eta=0.8, max_speed=1.0, actuation_cov=0.0025 * np.eye(2))
    agent = PlannerAgent('self', config, settings, [6.0, 0.0])
    agent.receive_footprint('a', 0.3, 0.0)
    agent.receive_share('a', share, 0.0)
    agent.receive_route('a', [at, goal], 0.0)
    covariance = 0.0001 * np.eye(4)
    agent.receive_neighbour('a', Odometry(0.0, np.array(at), np.array([-0.3, 0.0]),
                                             covariance), 0.0)
    agent.receive_own(Odometry(0.0, np.zeros(2), np.zeros(2), covariance), 0.0)
    v_pref = agent.plan_request().problem[2]
    assert (v_pref[1] < -0.1) == oncoming
