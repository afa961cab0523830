"""Keep right (prvo_planner.lanes), alone: who is met, where the way is wide, how far it leans."""

import math

import numpy as np
import pytest

from prvo_planner.core.beliefs import AgentBelief
from prvo_planner.core.config import PlannerConfig
from prvo_planner.core.obstacles import StaticObstacles
from prvo_planner.core.walls import certifiable_width
from prvo_planner.lanes import (
    ABREAST_AHEAD,
    AHEAD,
    CONE,
    FADE,
    FALL_BACK,
    LANE_LENGTH,
    LANE_SLACK,
    LANES,
    ONCOMING_SPEED,
    RANGE,
    WALL_LEAN,
    keep_right,
    meets_oncoming,
    wide_enough,
)

NOISE = np.diag([0.05 ** 2] * 4)
CONFIG = PlannerConfig(eta=0.95, certificate='certified', actuation_cov=0.05 ** 2 * np.eye(2))
EGO = AgentBelief([0.0, 0.0], [1.0, 0.0], NOISE, 0.25)


def neighbour(position, velocity):
    """Return a neighbour's belief at POSITION (2,) moving at VELOCITY (2,)."""
    return AgentBelief(position, velocity, NOISE, 0.25)


def walls(segments):
    """Return the walls without thickness along SEGMENTS (N, 2, 2)."""
    segments = np.asarray(segments, dtype=float)
    return StaticObstacles(segments, np.zeros(len(segments)), np.zeros((0, 2)), np.zeros(0))


def corridor(width, length=20.0):
    """Return the two walls of a corridor along x of clear WIDTH [m]."""
    half = 0.5 * width
    return walls([[[-length, half], [length, half]], [[-length, -half], [length, -half]]])


def angle_to_right(before, after):
    """Return the clockwise angle [rad] from BEFORE (2,) to AFTER (2,)."""
    return math.atan2(before[0] * after[1] - before[1] * after[0], before @ after) * -1.0


def test_a_neighbour_coming_toward_the_robot_ahead_is_met():
    assert meets_oncoming(EGO.position, [1.0, 0.0], [neighbour([3.0, 0.5], [-0.5, 0.0])])
    # Just inside the range and the cone.
    inside = 0.99 * RANGE * np.array([math.cos(0.99 * CONE), math.sin(0.99 * CONE)])
    assert meets_oncoming(EGO.position, [1.0, 0.0], [neighbour(inside, [-0.5, 0.0])])


@pytest.mark.parametrize('position, velocity', [
    ([-3.0, 0.0], [1.0, 0.0]),  # behind, coming after the robot
    ([3.0, 0.0], [1.0, 0.0]),  # ahead, going the same way
    ([3.0, 0.0], [-0.9 * ONCOMING_SPEED, 0.0]),  # ahead, about standing
    ([1.01 * RANGE, 0.0], [-1.0, 0.0]),  # beyond the range
    ([2.0, 2.0 * math.tan(1.01 * CONE)], [-1.0, 0.0]),  # outside the cone
    ([0.0, 1.0], [0.0, -1.0]),  # beside, not ahead
])
def test_a_neighbour_behind_aside_far_or_not_coming_is_not_met(position, velocity):
    assert not meets_oncoming(EGO.position, [1.0, 0.0], [neighbour(position, velocity)])


def test_meeting_someone_the_preference_turns_right_by_the_angle_at_the_same_speed():
    v_pref = np.array([0.6, 0.8])
    coming = neighbour(3.0 * v_pref, -v_pref)
    turned, lean = keep_right(v_pref, 0.2, EGO, [coming], 5.0, None, CONFIG)
    assert lean == 0.2
    assert angle_to_right(v_pref, turned) == pytest.approx(0.2)
    assert np.hypot(*turned) == pytest.approx(1.0)


def test_alone_standing_or_off_the_preference_stays_as_it_is():
    v_pref = np.array([1.0, 0.0])
    coming = neighbour([3.0, 0.0], [-1.0, 0.0])
    for args in ((v_pref, 0.2, EGO, [], 5.0, None, CONFIG),
                 (np.zeros(2), 0.2, EGO, [coming], 5.0, None, CONFIG),
                 (v_pref, 0.0, EGO, [coming], 5.0, None, CONFIG)):
        turned, lean = keep_right(*args)
        assert lean == 0.0
        assert turned is args[0]


@pytest.mark.parametrize('distance', [0.0, 0.25 * FADE, 0.5 * FADE, FADE, 3.0 * FADE])
def test_the_lean_fades_over_the_last_stretch_to_the_goal(distance):
    v_pref = np.array([1.0, 0.0])
    turned, lean = keep_right(v_pref, 0.3, EGO, [neighbour([3.0, 0.0], [-1.0, 0.0])], distance,
                              None, CONFIG)
    expected = 0.3 * min(1.0, distance / FADE)
    assert lean == pytest.approx(expected)
    assert angle_to_right(v_pref, turned) == pytest.approx(expected, abs=1e-12)


def test_a_corridor_is_wide_enough_from_twice_the_certifiable_width():
    needed = 2.0 * certifiable_width(EGO, CONFIG)
    # Walls without thickness are found to within the clear width's step (2 cm).
    assert wide_enough(corridor(needed + 0.05), EGO, CONFIG, [1.0, 0.0])
    assert not wide_enough(corridor(needed - 0.05), EGO, CONFIG, [1.0, 0.0])
    assert wide_enough(None, EGO, CONFIG, [1.0, 0.0])


def test_a_door_in_a_thin_wall_ahead_is_not_wide_enough():
    # A wall 0.1 thick across the way 0.4 AHEAD in front, its door one robot wide: the way at
    # the robot and at AHEAD is open to both sides, the door between them is not.
    half = 0.5 * certifiable_width(EGO, CONFIG) + 0.05
    across = 0.4 * AHEAD
    wall = StaticObstacles(np.array([[[across, half], [across, 5.0]],
                                     [[across, -half], [across, -5.0]]]),
                           np.array([0.05, 0.05]), np.zeros((0, 2)), np.zeros(0))
    assert not wide_enough(wall, EGO, CONFIG, [1.0, 0.0])
    coming = neighbour([3.0, 0.0], [-1.0, 0.0])
    v_pref = np.array([1.0, 0.0])
    turned, lean = keep_right(v_pref, 0.2, EGO, [coming], 5.0, wall, CONFIG)
    assert lean == 0.0 and turned is v_pref


def test_a_narrowing_ahead_straightens_the_robot_up_before_it():
    needed = 2.0 * certifiable_width(EGO, CONFIG)
    # A wide hall to x = 0.5 AHEAD, then a door one robot wide.
    half = 0.5 * certifiable_width(EGO, CONFIG) + 0.05
    edge = 0.5 * AHEAD
    door = walls([[[edge, half], [edge + 2.0, half]], [[edge, -half], [edge + 2.0, -half]],
                  [[-10.0, 5.0], [10.0, 5.0]], [[-10.0, -5.0], [10.0, -5.0]]])
    assert 2.0 * half < needed
    assert not wide_enough(door, EGO, CONFIG, [1.0, 0.0])
    coming = neighbour([3.0, 0.0], [-1.0, 0.0])
    v_pref = np.array([1.0, 0.0])
    turned, lean = keep_right(v_pref, 0.2, EGO, [coming], 5.0, door, CONFIG)
    assert lean == 0.0 and turned is v_pref
    turned, lean = keep_right(v_pref, 0.2, EGO, [coming], 5.0, corridor(needed + 0.1), CONFIG)
    assert lean == 0.2


def test_among_walls_the_lean_is_at_most_the_wall_lean_in_open_space_the_whole_angle():
    coming = neighbour([3.0, 0.0], [-1.0, 0.0])
    v_pref = np.array([1.0, 0.0])
    # A hall: wider than a corridor of two lanes.
    wide = corridor(LANES * certifiable_width(EGO, CONFIG) + 1.0)
    angle = WALL_LEAN + 0.2
    turned, lean = keep_right(v_pref, angle, EGO, [coming], 5.0, None, CONFIG)
    assert lean == angle
    assert angle_to_right(v_pref, turned) == pytest.approx(angle, abs=1e-12)
    turned, lean = keep_right(v_pref, angle, EGO, [coming], 5.0, wide, CONFIG)
    assert lean == WALL_LEAN
    assert angle_to_right(v_pref, turned) == pytest.approx(WALL_LEAN, abs=1e-12)
    # A smaller angle is taken as it is among walls too.
    assert keep_right(v_pref, 0.5 * WALL_LEAN, EGO, [coming], 5.0, wide, CONFIG)[1] == (
        0.5 * WALL_LEAN)


def lane_lean(width, across, angle):
    """Return the lean [rad] toward its lane of a robot ACROSS [m] left of a corridor's middle.

    The corridor along x is WIDTH [m] clear; the robot (EGO's radius) heads along +x. Its
    centre can be within the radius of either wall; its lane's middle is halfway between the
    corridor's middle and the farthest right its centre can be.
    """
    lane_middle = 0.5 * (-(0.5 * width - EGO.radius))
    return min(angle, math.atan2(max(across - lane_middle, 0.0), AHEAD))


@pytest.mark.parametrize('across', [0.6, 0.0, -0.3, -0.5])
def test_in_a_corridor_of_two_lanes_the_robot_leans_toward_the_middle_of_its_lane(across):
    width = 3.0 * certifiable_width(EGO, CONFIG)
    ego = AgentBelief([0.0, across], [1.0, 0.0], NOISE, 0.25)
    coming = neighbour([3.0, 0.0], [-1.0, 0.0])
    v_pref = np.array([1.0, 0.0])
    turned, lean = keep_right(v_pref, 0.5, ego, [coming], 5.0, corridor(width), CONFIG)
    assert lean == pytest.approx(lane_lean(width, across, 0.5), abs=1e-12)
    assert angle_to_right(v_pref, turned) == pytest.approx(lean, abs=1e-12)
    assert np.hypot(*turned) == pytest.approx(1.0)
    # Farther from its lane than the angle reaches, the whole angle; in it or right of it, none.
    assert (lean == 0.5) is (across == 0.6)
    assert (lean == 0.0) is (across == -0.5)
    # Meeting nobody, as it is.
    turned, lean = keep_right(v_pref, 0.5, ego, [], 5.0, corridor(width), CONFIG)
    assert lean == 0.0 and turned is v_pref


@pytest.mark.parametrize('position, velocity, across, falls_back', [
    ([0.1, -0.3], [1.0, 0.0], 0.3, True),  # abreast on its right, going its way
    ([-0.45, -0.3], [1.0, 0.0], 0.3, True),  # just behind, abreast still
    ([0.5 + ABREAST_AHEAD + 0.05, -0.3], [1.0, 0.0], 0.3, False),  # ahead: it follows
    ([-0.55, -0.3], [1.0, 0.0], 0.3, False),  # behind: it goes first
    ([0.1, -0.3], [-1.0, 0.0], 0.3, False),  # abreast, coming the other way
    ([0.1, -0.3], [0.5 * ONCOMING_SPEED, 0.0], 0.3, False),  # abreast, standing
    ([0.1, 0.8], [1.0, 0.0], 0.3, False),  # abreast on its left
    ([0.1, -0.3], [1.0, 0.0], -0.3, False),  # within the slack of its lane itself
])
def test_out_of_its_lane_beside_one_going_its_way_the_robot_falls_in_behind(
        position, velocity, across, falls_back):
    width = 3.0 * certifiable_width(EGO, CONFIG)
    ego = AgentBelief([0.0, across], [1.0, 0.0], NOISE, 0.25)
    beside = neighbour(np.array(position) + [0.0, across], velocity)
    coming = neighbour([3.0, 0.0], [-1.0, 0.0])
    v_pref = np.array([1.0, 0.0])
    turned, lean = keep_right(v_pref, 0.5, ego, [coming, beside], 5.0, corridor(width), CONFIG)
    assert lean == pytest.approx(lane_lean(width, across, 0.5), abs=1e-12)
    # Out of its lane by more than the slack where it falls back.
    assert (across - 0.5 * (-(0.5 * width - EGO.radius)) > LANE_SLACK) is (across == 0.3)
    assert np.hypot(*turned) == pytest.approx(FALL_BACK if falls_back else 1.0)


def test_a_corridor_of_two_lanes_is_from_two_to_lanes_widths():
    needed = certifiable_width(EGO, CONFIG)
    ego = AgentBelief([0.0, 0.3], [1.0, 0.0], NOISE, 0.25)
    coming = neighbour([3.0, 0.0], [-1.0, 0.0])
    v_pref = np.array([1.0, 0.0])
    for width, lean in ((2.0 * needed + 0.05, lane_lean(2.0 * needed + 0.05, 0.3, 0.5)),
                        (LANES * needed - 0.05, lane_lean(LANES * needed - 0.05, 0.3, 0.5)),
                        (LANES * needed + 0.05, WALL_LEAN)):
        assert keep_right(v_pref, 0.5, ego, [coming], 5.0, corridor(width), CONFIG)[1] == (
            pytest.approx(lean, abs=1e-12))
    # Its end, a wall across it, within LANE_LENGTH ahead (a door across it, a turn): the lean
    # of open space among walls.
    width = 3.0 * needed
    end = 0.9 * LANE_LENGTH
    ending = walls([[[-20.0, 0.5 * width], [end, 0.5 * width]],
                    [[-20.0, -0.5 * width], [end, -0.5 * width]],
                    [[end, -0.5 * width], [end, 0.5 * width]]])
    assert keep_right(v_pref, 0.5, ego, [coming], 5.0, ending, CONFIG)[1] == WALL_LEAN


def met_one_by_one(position, direction, neighbours):
    """Return `meets_oncoming` of NEIGHBOURS judged one at a time, as it was written first."""
    unit = np.asarray(direction, dtype=float) / math.hypot(*direction)
    for other in neighbours:
        offset = other.position - position
        # Products of 2-vectors component by component: a BLAS dot product may fuse them
        # (OpenBLAS's AVX-512 kernels do), and an edge neighbour would round otherwise.
        ahead = float(offset[0] * unit[0] + offset[1] * unit[1])
        across = abs(float(offset[0] * unit[1] - offset[1] * unit[0]))
        if (0.0 < ahead <= RANGE and across <= ahead * math.tan(CONE)
                and math.hypot(ahead, across) <= RANGE
                and float(other.velocity[0] * unit[0] + other.velocity[1] * unit[1])
                < -ONCOMING_SPEED):
            return True
    return False


def test_neighbours_are_met_as_when_judged_one_at_a_time():
    # Crowds of 1-12 around a robot, some on the cone's and the range's edges: the same answer
    # as each neighbour judged alone, and so the same lean.
    rng = np.random.default_rng(38)
    answers = []
    for _ in range(400):
        count = int(rng.integers(1, 13))
        angle = rng.uniform(-1.2 * CONE, 1.2 * CONE, count)
        distance = rng.uniform(0.0, 1.2 * RANGE, count)
        edge = rng.random(count) < 0.3
        angle[edge] = rng.choice([-CONE, CONE], int(edge.sum()))
        distance[rng.random(count) < 0.2] = RANGE
        heading = rng.uniform(0.0, 2.0 * np.pi)
        direction = rng.uniform(0.2, 1.0) * np.array([math.cos(heading), math.sin(heading)])
        bearing = heading + angle
        position = EGO.position + distance[:, None] * np.stack(
            [np.cos(bearing), np.sin(bearing)], axis=1)
        speed = rng.choice([-ONCOMING_SPEED, -1.0, 0.0, 0.5], count)
        velocity = speed[:, None] * direction / np.hypot(*direction) + rng.normal(0.0, 0.05, (
            count, 2)) * (rng.random((count, 1)) < 0.5)
        crowd = [neighbour(position[index], velocity[index]) for index in range(count)]
        answer = meets_oncoming(EGO.position, direction, crowd)
        assert answer == met_one_by_one(EGO.position, direction, crowd)
        answers.append(answer)
    assert 0.2 < np.mean(answers) < 0.8
    assert not meets_oncoming(EGO.position, [1.0, 0.0], [])
