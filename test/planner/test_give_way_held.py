"""Give way when held short of the goal (prvo_planner.give_way): who yields, and where to."""

import numpy as np
from planner_testing import Odometry
import pytest

from prvo_planner.agent import AgentSettings, PlannerAgent
from prvo_planner.core import PlannerConfig
from prvo_planner.give_way import (
    GAP,
    HELD_PROGRESS,
    HELD_WINDOW,
    NEAR_GOAL,
    RANGE,
    STEP,
    TIE,
    held_short,
    held_spot,
    way_left,
    yields_to,
)
from prvo_planner.stalls import StallMonitor

RADIUS = 0.25
NEEDED = 2 * RADIUS + GAP
# A neighbour at (-1.5, 0) on its way east along y = 0, 9.5 m to go.
OTHER = np.array([-1.5, 0.0])
LONG_WAY = np.array([[-1.5, 0.0], [8.0, 0.0]])


def test_the_way_left_runs_along_the_route_from_its_point_nearest_the_robot():
    route = np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 4.0]])
    assert way_left(route, np.array([1.0, 0.5])) == pytest.approx(2.0 + 4.0)
    assert way_left(route, np.array([3.5, 4.0])) == pytest.approx(0.0)
    assert way_left(route, np.array([2.5, 1.0])) == pytest.approx(3.0)  # nearest: (3, 1)
    assert way_left(np.array([[1.0, 1.0]]), np.array([4.0, 5.0])) == pytest.approx(5.0)


def test_of_a_pair_exactly_one_yields_the_one_with_less_to_go_unless_a_tie():
    generator = np.random.default_rng(38)
    for _ in range(2000):
        left = generator.uniform(0.0, 3.0, 2)
        # Ways within the tie often enough for the names to decide.
        left[1] = left[0] + generator.choice([-1, 1]) * generator.uniform(0.0, 2 * TIE)
        first, second = generator.permutation(['robot_0', 'robot_1', 'robot_10'])[:2]
        one = yields_to(left[0], first, left[1], second)
        other = yields_to(left[1], second, left[0], first)
        assert one != other
        if abs(left[0] - left[1]) > TIE:
            assert one == (left[0] < left[1])
        else:
            # A tie: the name that sorts later yields.
            assert one == (first > second)


@pytest.mark.parametrize('stalled, distance, gained, expected', [
    (True, 9.0, 1.0, True),  # stalled anywhere
    (False, NEAR_GOAL, HELD_PROGRESS - 0.01, True),  # near its goal, hardly gaining
    (False, NEAR_GOAL + 0.01, 0.0, False),  # too far to be held before it stalls
    (False, 1.0, HELD_PROGRESS, False),  # gaining
    (False, 1.0, float('nan'), False),  # not a full window, or at its goal within it
])
def test_held_short_is_stalled_or_near_the_goal_and_hardly_gaining(stalled, distance, gained,
                                                                 expected):
    assert held_short(stalled, distance, gained) is expected


def test_a_held_robot_steps_beside_the_way_of_one_with_farther_to_go():
    position = np.array([0.0, 0.1])
    spot, _ = held_spot(position, 1.0, 'robot_9', RADIUS,
                     [('robot_1', OTHER, RADIUS, LONG_WAY)], None)
    # On its own side of the way, the two radii and the gap off it, abreast of where it stood.
    np.testing.assert_allclose(spot, [0.0, NEEDED])
    # The way's end on it: to the way's right.
    spot, _ = held_spot(np.array([0.0, 0.0]), 1.0, 'robot_9', RADIUS,
                     [('robot_1', OTHER, RADIUS, LONG_WAY)], None)
    np.testing.assert_allclose(spot, [0.0, -NEEDED])


def _nearest_clear_spot(route_y, position, standing, side):
    """Return the clear spot nearest POSITION at NEEDED on SIDE of y = ROUTE_Y, on a 1 mm grid.

    Independent of `clear_spot_beside`: a brute-force search along the whole line.
    """
    xs = np.arange(-1.5, 8.0, 0.001)
    spots = np.column_stack([xs, np.full_like(xs, route_y + side * NEEDED)])
    clear = np.all(np.hypot(*(spots[:, None, :] - standing[None, :, :]).transpose(2, 0, 1))
                   >= NEEDED, axis=1)
    spots = spots[clear]
    return spots[np.argmin(np.hypot(*(spots - position).T))]


@pytest.mark.parametrize('standing', [
    [[0.0, 0.9]],  # beside it, on its own side of the way: it slides along the way
    [[0.0, 0.9], [0.0, -0.9], [0.7, 0.5]],  # a pocket: robots at their goals all about it
])
def test_a_held_robot_steps_beside_the_way_where_no_other_robot_stands(standing):
    position = np.array([0.0, 0.1])
    standing = np.array(standing)
    neighbours = [('robot_1', OTHER, RADIUS, LONG_WAY)] + [
        (f'robot_{2 + index}', where, RADIUS, np.array([where])) for index, where
        in enumerate(standing)]
    spot, _ = held_spot(position, 1.0, 'robot_9', RADIUS, neighbours, None)
    # Where it would have stood, abreast of itself, a robot stands: not there.
    assert np.min(np.hypot(*(standing - [0.0, NEEDED]).T)) < NEEDED
    # Clear of every robot standing, off the way by the radii and the gap, on its own side,
    # and as near as such a spot lies (within the step the way is searched by).
    assert np.all(np.hypot(*(standing - spot).T) >= NEEDED - 1e-9)
    assert spot[1] == pytest.approx(NEEDED)
    nearest = _nearest_clear_spot(0.0, position, standing, 1.0)
    assert np.hypot(*(spot - position)) <= np.hypot(*(nearest - position)) + STEP


def test_a_held_robot_steps_aside_from_where_a_neighbour_off_its_route_goes():
    # The neighbour is 0.8 m to the right of its route (a lane), and goes from there straight
    # to the route's next point: through where the robot is, though the route passes it by.
    passer = np.array([-1.5, -0.8])
    position = np.array([0.0, -0.6])
    spot, _ = held_spot(position, 1.0, 'robot_9', RADIUS,
                     [('robot_1', passer, RADIUS, LONG_WAY)], None)
    assert spot is not None
    way = LONG_WAY[1] - passer
    across = (way[0] * (spot - passer)[1] - way[1] * (spot - passer)[0]) / np.hypot(*way)
    assert abs(across) == pytest.approx(NEEDED)


def test_a_held_robot_yields_to_one_with_farther_to_go_a_tie_by_name_and_then_until_it_passed():
    short_way = np.array([[-1.5, 0.0], [1.0, 0.0]])  # 2.5 m
    neighbour = [('robot_1', OTHER, RADIUS, short_way)]
    def spot(left, name, yielding=None):
        return held_spot(np.zeros(2), left, name, RADIUS, neighbour, None, (), yielding)

    assert spot(2.5 - 1.01 * TIE, 'robot_9') == (pytest.approx([0.0, -NEEDED]), 'robot_1')
    assert spot(2.5 + 1.01 * TIE, 'robot_9') == (None, None)
    assert spot(2.5, 'robot_9')[0] is not None
    assert spot(2.5, 'robot_0') == (None, None)
    # Yielding already, it goes on yielding, though the other now has less to go.
    assert spot(2.5 + 1.01 * TIE, 'robot_9', 'robot_1')[1] == 'robot_1'
    assert spot(2.5 + 1.01 * TIE, 'robot_9', 'robot_2') == (None, None)
    # It yields to none that waits its turn at its passage.
    assert held_spot(np.zeros(2), 1.0, 'robot_9', RADIUS, neighbour, None, ('robot_1',)) == (
        None, None)


@pytest.mark.parametrize('neighbour', [
    ('robot_1', OTHER, RADIUS, None),  # publishes no route
    ('robot_1', OTHER, RADIUS, np.array([[8.0, 0.0]])),  # at its goal
    ('robot_1', OTHER, RADIUS, np.array([[-1.5, 0.0], [-1.5, 5.0]])),  # its way goes elsewhere
    ('robot_1', np.array([-1.01 * RANGE, 0.0]), RADIUS, LONG_WAY),  # too far
    ('robot_1', np.array([1.0, 0.0]), RADIUS, LONG_WAY),  # went by
    ('robot_1', np.array([0.3, -0.5]), RADIUS, LONG_WAY),  # off its route, going away
    ('robot_1', np.array([0.0, -0.5]), RADIUS, LONG_WAY - [0.0, 0.5]),  # abreast, passing now
])
def test_a_held_robot_stays_for_a_way_that_does_not_pass_by_it(neighbour):
    assert held_spot(np.zeros(2), 1.0, 'robot_9', RADIUS, [neighbour], None) == (None, None)


def test_the_monitor_s_gain_over_a_few_seconds_is_the_distance_lost_since():
    monitor = StallMonitor()
    goal = np.array([10.0, 0.0])
    for step in range(31):
        monitor.update(0.1 * step, [0.01 * step, 0.0], goal, 0.2)
        if step < 30:
            assert np.isnan(monitor.gained_over(HELD_WINDOW))
    assert monitor.gained_over(HELD_WINDOW) == pytest.approx(0.3)
    assert monitor.gained_over(1.0) == pytest.approx(0.1)
    # Within the tolerance inside the window: no gain to judge by.
    monitor.update(3.1, [9.9, 0.0], goal, 0.2)
    assert np.isnan(monitor.gained_over(HELD_WINDOW))


def run_agent(goal, route, seconds, own=lambda step: np.zeros(2), give_way=True,
              later=None, share=0.5, moving=(0.0, 0.0)):
    """Plan SECONDS of a robot 'robot_9' at OWN(step) heading for GOAL, a neighbour at OTHER.

    The neighbour 'robot_1' stands on its ROUTE (from 4 s on on LATER if given), its odometry
    saying it moves at MOVING, and announces SHARE; return the commands and the announced
    shares.
    """
    settings = AgentSettings(radius=RADIUS, goal_tolerance=0.2, give_way=give_way)
    agent = PlannerAgent('robot_9', PlannerConfig(actuation_cov=0.0025 * np.eye(2)), settings,
                         np.asarray(goal))
    agent.receive_route('robot_1', route, 0.0)
    agent.receive_footprint('robot_1', RADIUS, 0.0)
    agent.receive_share('robot_1', share, 0.0)
    covariance = 0.0025 * np.eye(4)
    commands, shares = [], []
    for step in range(int(round(seconds / 0.1))):
        stamp = round(0.1 * step, 9)
        if later is not None and step == 40:
            agent.receive_route('robot_1', later, stamp)
        agent.receive_neighbour('robot_1', Odometry(stamp, OTHER, np.asarray(moving), covariance),
                                0.0)
        agent.receive_own(Odometry(stamp, own(step), np.zeros(2), covariance), 0.0)
        commands.append(agent.plan())
        shares.append(agent.own_announcement.avoidance_share)
    return commands, shares


def test_a_robot_held_near_its_goal_steps_aside_after_the_window_and_announces_no_share():
    # Held at (0, 0), 2 m short of its goal; the neighbour's way (9.5 m) passes through it.
    # It stands at the spot once it gives way (its odometry says so from step 40 on; its
    # estimate follows within 1 s).
    commands, shares = run_agent([2.0, 0.0], LONG_WAY, 6.0,
                                 own=lambda step: np.zeros(2) if step < 40 else [0, -NEEDED])
    window = int(round(HELD_WINDOW / 0.1))
    # Toward its goal until the window is full, then toward the spot (the way's right).
    assert all(command.velocity[0] > 0.5 for command in commands[:window - 1])
    assert all(command.velocity[1] < -0.3 for command in commands[window + 1:40])
    # On its way it takes its share; standing at the spot it announces none, as at its goal.
    assert shares[window - 1] == 0.5
    assert shares[-1] == 0.0


def test_a_robot_giving_way_goes_on_while_the_one_it_yields_to_moves_though_it_has_less_to_go():
    # Yielding from 3 s on; at 4 s the neighbour has 1.6 m to go, 0.4 m less than the robot: it
    # would not have yielded to it, and goes on yielding, to the way's right, while it moves.
    later = np.array([[-1.5, 0.0], [0.1, 0.0]])
    commands, _ = run_agent([2.0, 0.0], LONG_WAY, 6.0, later=later, moving=np.array([0.5, 0.0]))
    assert all(command.velocity[1] < -0.3 for command in commands[41:50])
    # One that stands passes nobody: the robot goes on to its goal.
    commands, _ = run_agent([2.0, 0.0], LONG_WAY, 6.0, later=later)
    assert all(command.velocity[0] > 0.5 for command in commands[45:60])


@pytest.mark.parametrize('goal, route', [
    ([2.0, 0.0], np.array([[-1.5, 0.0], [-0.5, 0.0]])),  # the neighbour has less to go
    ([2.0, 0.0], np.array([[-1.5, 0.0], [-1.5, 5.0]])),  # its way does not pass by
    ([NEAR_GOAL + 1.0, 0.0], LONG_WAY),  # too far from its goal to be held within 5 s
])
def test_a_robot_not_held_or_not_passed_by_one_with_farther_to_go_keeps_its_way(goal, route):
    commands, shares = run_agent(goal, route, 5.0)
    assert all(command.velocity[0] > 0.5 for command in commands)
    assert all(share == 0.5 for share in shares)


def test_a_held_robot_does_not_yield_to_one_that_announces_no_share():
    # It stands (at its goal, or aside for another): yielding to it, both would stand.
    commands, _ = run_agent([2.0, 0.0], LONG_WAY, 5.0, share=0.0)
    assert all(command.velocity[0] > 0.5 for command in commands)


def test_give_way_off_keeps_a_held_robot_on_its_way():
    commands, _ = run_agent([2.0, 0.0], LONG_WAY, 5.0, give_way=False)
    assert all(command.velocity[0] > 0.5 for command in commands)
