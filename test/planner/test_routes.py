"""Routes: what a robot publishes of its way, and its neighbours' routes in the agent's plans."""

import types

import numpy as np
import pytest
from test_agent import CONFIG, GOAL, SETTINGS, run, team

from prvo_msgs_util import MAX_PATH_POSES
from prvo_planner.agent import (
    DEPARTURE_TOLERANCES,
    MAX_KEPT_ANNOUNCEMENTS,
    ROUTE_FOUND,
    ROUTE_NONE,
    ROUTE_UNREACHABLE,
    PlannerAgent,
)
from prvo_planner.routes import (
    FLIP_CHANGES,
    FLIP_WINDOW,
    MAX_ROUTE_POINTS,
    NeighbourRoute,
    RouteFlips,
    RouteIntent,
    checked_route,
    route_stamp,
)

ROUTE_A = np.array([[3.0, 0.2], [-3.0, 0.2]])
ROUTE_B = np.array([[1.5, -2.0], [1.5, 2.0], [2.0, 3.0]])


def test_a_route_is_bounded_and_finite_and_shared_read_only():
    route = checked_route([[0.0, 1.0], [2.0, 3.0]])
    assert route.dtype == float and route.shape == (2, 2)
    with pytest.raises(ValueError):
        route[0, 0] = 5.0
    assert MAX_ROUTE_POINTS == MAX_PATH_POSES
    assert len(checked_route(np.zeros((MAX_ROUTE_POINTS, 2)))) == MAX_ROUTE_POINTS
    for points, fault in (
            (np.empty((0, 2)), 'the route is empty'),
            ([[0.0, 0.0], [np.nan, 1.0]], r'not finite: points\[1\] = \[nan, 1.0\]'),
            ([[np.inf, 0.0]], r'not finite: points\[0\]'),
            ([1.0, 2.0], r'\(K, 2\) points, got shape \(2,\)'),
            (np.zeros((MAX_ROUTE_POINTS + 1, 2)), f'more than {MAX_ROUTE_POINTS}')):
        with pytest.raises(ValueError, match=fault):
            checked_route(points)


def test_a_route_that_flips_every_step_is_refused_until_it_changes_less_often():
    flips = RouteFlips()
    ways = (ROUTE_A, ROUTE_B)
    for step in range(FLIP_CHANGES):
        flips.check('x', ways[step % 2], 0.1 * step)
    with pytest.raises(ValueError, match=f'changed {FLIP_CHANGES + 1} times within '
                       f'{FLIP_WINDOW:g} s.*flips, and claims nothing'):
        flips.check('x', ways[FLIP_CHANGES % 2], 0.1 * FLIP_CHANGES)
    # Another neighbour is counted apart; the same route sent again is no change.
    flips.check('y', ROUTE_A, 1.0)
    with pytest.raises(ValueError):
        flips.check('x', ways[FLIP_CHANGES % 2], 1.2)
    # Its changes out of the window: a route is a claim again.
    flips.check('x', ROUTE_B, 1.0 + FLIP_WINDOW + 0.1)
    # A planner re-planning once a second (Nav2's planner_server), or sending one route every
    # step, never flips.
    steady = RouteFlips()
    for step in range(200):
        steady.check('nav2', ROUTE_A + 0.01 * (step // 10), 0.1 * step)
        steady.check('same', ROUTE_A, 0.1 * step)
    # A neighbour dropped and heard anew starts afresh.
    flips.forget('x')
    flips.check('x', ROUTE_A, 1.0 + FLIP_WINDOW + 0.2)


def test_a_neighbour_whose_route_flips_claims_nothing():
    agent = PlannerAgent('self', CONFIG, SETTINGS, GOAL)
    for step in range(FLIP_CHANGES):
        agent.receive_route('a', (ROUTE_A, ROUTE_B)[step % 2], 0.1 * step)
    assert agent.route_of('a', 1.05) is not None
    with pytest.raises(ValueError, match='flips'):
        agent.receive_route('a', ROUTE_A, 0.1 * FLIP_CHANGES)
    assert agent.route_of('a', 1.05) is None


def test_a_plan_of_stamp_zero_stamps_its_route_after_the_start():
    assert route_stamp(0.0) == 1e-9
    assert route_stamp(0.3) == 0.3


def command(position, arrived=False, route=None, route_status=ROUTE_NONE):
    """Return the fields of an agent Command a RouteIntent reads."""
    return types.SimpleNamespace(own=types.SimpleNamespace(mean=np.array([*position, 0.0, 0.0])),
                                 arrived=arrived, route=route, route_status=route_status)


def test_without_a_map_the_straight_way_is_published_once_per_goal_and_arrival():
    intent = RouteIntent(DEPARTURE_TOLERANCES)
    goal, tolerance = np.array([4.0, 0.0]), 0.2
    # No goal, nothing published before: nothing to say.
    assert intent.update(command([0.0, 0.0]), None, tolerance) is None
    np.testing.assert_array_equal(intent.update(command([0.0, 0.0]), goal, tolerance),
                                  [[0.0, 0.0], [4.0, 0.0]])
    assert intent.update(command([1.0, 0.1]), goal, tolerance) is None
    np.testing.assert_array_equal(intent.update(command([3.9, 0.0], arrived=True), goal,
                                                tolerance), [[4.0, 0.0]])
    # Noise carries it out of the tolerance and back: it stays at its goal, saying so once.
    for position, arrived in (([3.75, 0.0], False), ([3.9, 0.0], True), ([3.65, 0.0], False)):
        assert intent.update(command(position, arrived), goal, tolerance) is None
    # Pushed farther than DEPARTURE_TOLERANCES tolerances: on its way again.
    np.testing.assert_array_equal(intent.update(command([3.5, 0.0]), goal, tolerance),
                                  [[3.5, 0.0], [4.0, 0.0]])
    other = np.array([0.0, 4.0])
    np.testing.assert_array_equal(intent.update(command([3.5, 0.1]), other, tolerance),
                                  [[3.5, 0.1], [0.0, 4.0]])
    # Its goal taken away: the route is withdrawn, once.
    assert intent.update(command([3.5, 0.1]), None, tolerance).shape == (0, 2)
    assert intent.update(command([3.5, 0.1]), None, tolerance) is None


def test_on_a_map_the_route_is_published_when_taken_anew_and_a_robot_that_holds_says_so():
    intent = RouteIntent(DEPARTURE_TOLERANCES)
    goal, tolerance = np.array([4.0, 0.0]), 0.2
    route = np.array([[0.0, 0.0], [2.0, 1.0], [4.0, 0.0]])
    assert intent.update(command([0.0, 0.0], route=route, route_status=ROUTE_FOUND), goal,
                         tolerance) is route
    assert intent.update(command([0.5, 0.2], route=route, route_status=ROUTE_FOUND), goal,
                         tolerance) is None
    # The robot strayed and took the route anew from where it is: equal or not, it is new.
    again = route.copy()
    assert intent.update(command([0.5, 0.2], route=again, route_status=ROUTE_FOUND), goal,
                         tolerance) is again
    holding = intent.update(command([0.6, 0.2], route_status=ROUTE_UNREACHABLE), goal,
                            tolerance)
    np.testing.assert_array_equal(holding, [[0.6, 0.2]])
    assert intent.update(command([0.7, 0.2], route_status=ROUTE_UNREACHABLE), goal,
                         tolerance) is None
    assert intent.update(command([0.7, 0.2], route=again, route_status=ROUTE_FOUND), goal,
                         tolerance) is again


def routed_plans(deliveries, steps=8):
    """Return (agent, its Commands) of the crossing given DELIVERIES {step: [(robot, route, s)]}.

    Each step's deliveries reach the agent after its own odometry, before the plan.
    """
    data = team(steps)
    agent = PlannerAgent('self', CONFIG, SETTINGS, GOAL)
    commands = []
    for step in range(steps):
        for robot in ('a', 'b'):
            assert agent.receive_neighbour(robot, data[robot][step], 0.0).accepted
        assert agent.receive_own(data['self'][step], 0.0).accepted
        for robot, route, stamp in deliveries.get(step, ()):
            agent.receive_route(robot, route, stamp)
        commands.append(agent.plan())
    return agent, commands


def routes_held(command):
    """Return {neighbour: (its route's points as a list, stamp) or None} of COMMAND's plan."""
    return {robot: None if route is None else (route.points.tolist(), route.stamp)
            for robot, route in zip(command.neighbour_names, command.neighbour_routes,
                                    strict=True)}


def test_a_route_holds_for_the_plans_after_its_stamp_whenever_it_arrives():
    # Stamped with step 2's stamp, as the neighbour's plan of step 2 publishes it; it reaches
    # the agent before the agent plans step 2 (a faster neighbour) and counts from step 3.
    stamp_2 = team()['a'][2].stamp
    _, commands = routed_plans({0: [('b', ROUTE_B, 0.0)], 2: [('a', ROUTE_A, stamp_2)]})
    for step, command in enumerate(commands):
        held = routes_held(command)
        # From the start (stamp 0): from the first plan on.
        assert held['b'] == (ROUTE_B.tolist(), 0.0)
        assert held['a'] == (None if step <= 2 else (ROUTE_A.tolist(), stamp_2)), step
        assert command.route_values()['neighbour.a.route_points'] == (0 if step <= 2 else 2)
    assert commands[0].route_values() == {
        'neighbour.a.route_points': 0, 'neighbour.a.route_stamp': 'none',
        'neighbour.b.route_points': 3, 'neighbour.b.route_stamp': 0.0}


def test_routes_change_no_command():
    data = team()
    plain = run(PlannerAgent('self', CONFIG, SETTINGS, GOAL), data, 12)
    _, routed = routed_plans({0: [('a', ROUTE_A, 0.0), ('b', ROUTE_B, 0.0)]}, steps=12)
    for command, other in zip(plain, routed, strict=True):
        np.testing.assert_array_equal(command.velocity, other.velocity)
        assert other.neighbour_routes[0] is not None


@pytest.mark.parametrize('points, stamp', [
    (np.empty((0, 2)), 0.5), ([[0.0, np.nan]], 0.5), (ROUTE_A, float('nan')), (ROUTE_A, -1.0)])
def test_a_bad_route_is_refused_by_name_and_its_robot_claims_nothing(points, stamp):
    agent, _ = routed_plans({0: [('a', ROUTE_A, 0.0)]}, steps=1)
    with pytest.raises(ValueError):
        agent.receive_route('a', points, stamp)
    assert agent.route_of('a', 1.0) is None


def test_routes_are_forgotten_with_their_robot_and_kept_bounded():
    agent, _ = routed_plans({0: [('a', ROUTE_A, 0.0), ('b', ROUTE_B, 0.0)]}, steps=2)
    agent.forget_announcements('a')
    assert agent.route_of('a', 1.0) is None and agent.route_of('b', 1.0) is not None
    # A route that came before its robot's odometry stays (a latched route reaches a planner
    # as soon as it subscribes); a tracked robot that went silent takes its route with it.
    agent.receive_route('c', ROUTE_A, 0.0)
    assert [robot for robot, _ in agent.forget_neighbours(10.0)] == ['a', 'b']
    assert agent.route_of('b', 1.0) is None
    assert isinstance(agent.route_of('c', 1.0), NeighbourRoute)
    # A neighbour flooding routes faster than the agent plans: the newest are kept.
    for index in range(3 * MAX_KEPT_ANNOUNCEMENTS):
        agent.receive_route('c', ROUTE_A + index, 1.0 + index)
    assert len(agent._announced_route['c']) == MAX_KEPT_ANNOUNCEMENTS
    assert agent.route_of('c', 1e6).stamp == 3 * MAX_KEPT_ANNOUNCEMENTS


def test_a_new_goal_near_the_old_one_is_set_off_for():
    intent = RouteIntent(DEPARTURE_TOLERANCES)
    goal, near, tolerance = np.array([4.0, 0.0]), np.array([4.3, 0.0]), 0.2
    intent.update(command([3.9, 0.0], arrived=True), goal, tolerance)
    np.testing.assert_array_equal(intent.update(command([3.95, 0.0]), near, tolerance),
                                  [[3.95, 0.0], [4.3, 0.0]])
