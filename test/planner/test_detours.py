"""A robot kept waiting at a passage goes round it once waiting has cost as much (issue 38)."""

import numpy as np
import pytest

from prvo_planner.detours import DetourWatch
from prvo_planner.maps import OCCUPIED, GridMap
from prvo_planner.narrows import find_passages
from prvo_planner.right_of_way import Decision, PassageMap, PassageUse
from prvo_planner.route import RouteMap, path_length

RESOLUTION = 0.05
RADIUS = 0.25
MARGIN = 0.3
SPEED = 0.8
# Rooms 6 m wide each side of a wall at x = 6 m, 8 m tall; doors 1.2 m wide about y = 1.5 m
# and y = 6.5 m.
DOORS = (1.5, 6.5)


def _grid(doors):
    occupied = np.zeros((160, 240), dtype=bool)
    occupied[[0, -1], :] = True
    occupied[:, [0, -1]] = True
    occupied[:, 119:121] = True
    for door in doors:
        middle = int(door / RESOLUTION)
        occupied[middle - 12:middle + 12, 119:121] = False
    return GridMap(np.where(occupied, OCCUPIED, 0).astype(np.int8), RESOLUTION, (0.0, 0.0))


def _maps(doors):
    grid = _grid(doors)
    route_map = RouteMap(grid.cells == OCCUPIED, RESOLUTION, grid.origin, RADIUS, MARGIN)
    return route_map, PassageMap(grid, find_passages(grid, RADIUS, MARGIN), RADIUS)


@pytest.fixture(scope='module')
def two_doors():
    return _maps(DOORS)


def _waiting(passage_map, passage, position):
    end = passage_map.passages[passage].ends[0]
    use = PassageUse('me', passage, 0, 1, float(np.hypot(*(end.entrance - position))), position)
    return Decision(use, False, end.waiting_spot, None, end.entrance)


def _lower_door(passage_map):
    return int(passage_map.passage_at(np.array([[6.0, DOORS[0]]]))[0])


def _remaining(route_map, goal, position):
    way = route_map.tree_to(goal).route_from(position)
    return path_length(way) + float(np.hypot(*(way[0] - position)))


def test_the_robot_waits_as_long_as_the_way_round_adds_then_takes_it(two_doors):
    route_map, passage_map = two_doors
    assert len(passage_map.passages) == 2
    door = _lower_door(passage_map)
    position, goal = np.array([4.5, 1.5]), np.array([9.0, 1.5])
    remaining = _remaining(route_map, goal, position)
    # Round by the upper door: at least the straight ways to its middle and on to the goal.
    upper = np.array([6.0, DOORS[1]])
    at_least = np.hypot(*(upper - position)) + np.hypot(*(goal - upper)) - remaining
    watch = DetourWatch()
    decision = _waiting(passage_map, door, position)
    taken = None
    for step in range(400):
        stamp = 10.0 + 0.1 * step
        tree = watch.update(stamp, decision, position, remaining, SPEED, route_map,
                            passage_map, goal)
        if tree is not None:
            taken = stamp - 10.0
            break
    assert taken is not None
    assert at_least / SPEED <= taken <= (at_least + 1.0) / SPEED
    way = tree.route_from(position)
    points = np.concatenate([np.linspace(a, b, 50)
                             for a, b in zip(way[:-1], way[1:], strict=True)])
    crossed = set(passage_map.passage_at(points).tolist()) - {-1}
    assert crossed == {1 - door}
    assert watch.avoided == {door}


def test_without_another_way_the_robot_waits_for_ever():
    route_map, passage_map = _maps(DOORS[:1])
    position, goal = np.array([4.5, 1.5]), np.array([9.0, 1.5])
    remaining = _remaining(route_map, goal, position)
    watch = DetourWatch()
    decision = _waiting(passage_map, 0, position)
    assert all(watch.update(stamp, decision, position, remaining, SPEED, route_map, passage_map,
                            goal) is None for stamp in np.arange(0.0, 600.0, 10.0))


def test_going_through_or_following_starts_the_wait_anew(two_doors):
    route_map, passage_map = two_doors
    door = _lower_door(passage_map)
    position, goal = np.array([4.5, 1.5]), np.array([9.0, 1.5])
    remaining = _remaining(route_map, goal, position)
    waiting = _waiting(passage_map, door, position)
    for pause in (Decision(waiting.use, True), Decision(waiting.use, False), None):
        watch = DetourWatch()
        assert watch.update(0.0, waiting, position, remaining, SPEED, route_map, passage_map,
                            goal) is None
        watch.update(3.0, pause, position, remaining, SPEED, route_map, passage_map, goal)
        # Waited since 3.1 s only: 99 s is a long wait, 3.2 s after it began is not.
        assert watch.update(3.1, waiting, position, remaining, SPEED, route_map, passage_map,
                            goal) is None
        assert watch.update(6.3, waiting, position, remaining, SPEED, route_map, passage_map,
                            goal) is None
        assert watch.update(99.0, waiting, position, remaining, SPEED, route_map, passage_map,
                            goal) is not None


def test_no_way_round_a_passage_the_goal_lies_in(two_doors):
    route_map, passage_map = two_doors
    door = _lower_door(passage_map)
    position, goal = np.array([4.5, 1.5]), np.array([6.0, DOORS[0]])
    watch = DetourWatch()
    decision = _waiting(passage_map, door, position)
    assert all(watch.update(stamp, decision, position, 1.5, SPEED, route_map, passage_map,
                            goal) is None for stamp in (0.0, 100.0, 1000.0))
    assert watch.avoided == frozenset()
