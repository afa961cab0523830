"""The way to the goal on a grid: clearance kept, shortest, around a U-shaped wall, or none."""

import heapq
import itertools
import math

import numpy as np
import pytest

from prvo_planner.path_following import carrot
from prvo_planner.route import MARGIN_COST, RouteMap, admissible_cells, path_length

RESOLUTION = 0.1
ORIGIN = np.array([2.0, -1.0])


def brute_distances(occupied):
    """Distances [m] from free cells' centres to the nearest occupied cell or the outside."""
    height, width = occupied.shape
    result = np.zeros(occupied.shape)
    blocked = np.argwhere(occupied)
    for row in range(height):
        for column in range(width):
            if occupied[row, column]:
                continue
            x, y = column + 0.5, row + 0.5
            nearest = min(x, width - x, y, height - y)
            for other_row, other_column in blocked:
                dx = max(other_column - x, 0.0, x - other_column - 1.0)
                dy = max(other_row - y, 0.0, y - other_row - 1.0)
                nearest = min(nearest, math.hypot(dx, dy))
            result[row, column] = nearest * RESOLUTION
    return result


def brute_admissible(occupied, clearance):
    """Cells whose centre keeps CLEARANCE [m] from every occupied cell and the map's outside."""
    return ~occupied & (brute_distances(occupied) >= clearance)


def step_cost(closeness, here, there):
    """Return the cost of the step between cells HERE and THERE (row, column) of CLOSENESS."""
    length = RESOLUTION * math.hypot(there[0] - here[0], there[1] - here[1])
    return length * (1.0 + MARGIN_COST * 0.5 * (closeness[here] + closeness[there]))


def brute_shortest(admissible, start, goal, closeness=None):
    """Return the least cost by own Dijkstra: 8-connected, diagonals beside free cells.

    CLOSENESS (height, width), if given, makes a step cost more near obstacles (`step_cost`).
    """
    height, width = admissible.shape
    closeness = np.zeros(admissible.shape) if closeness is None else closeness

    def ok(row, column):
        return 0 <= row < height and 0 <= column < width and admissible[row, column]

    best = {start: 0.0}
    queue = [(0.0, start)]
    while queue:
        cost, (row, column) = heapq.heappop(queue)
        if (row, column) == goal:
            return cost
        if cost > best[(row, column)]:
            continue
        for step_row in (-1, 0, 1):
            for step_column in (-1, 0, 1):
                if (step_row, step_column) == (0, 0):
                    continue
                there = (row + step_row, column + step_column)
                if not ok(*there):
                    continue
                if step_row and step_column and not (
                        ok(row + step_row, column) and ok(row, column + step_column)):
                    continue
                new = cost + step_cost(closeness, (row, column), there)
                if new < best.get(there, math.inf) - 1e-12:
                    best[there] = new
                    heapq.heappush(queue, (new, there))
    return None


def centre(cell):
    row, column = cell
    return ORIGIN + RESOLUTION * np.array([column + 0.5, row + 0.5])


def cell_of(point):
    column, row = np.floor((point - ORIGIN) / RESOLUTION + 1e-9).astype(int)
    return int(row), int(column)


def seen_along_admissible(admissible, start, end):
    """Whether points every 1/8 cell from START to END all lie in admissible cells."""
    count = int(np.ceil(8.0 * np.linalg.norm(end - start) / RESOLUTION)) + 1
    for fraction in np.linspace(0.0, 1.0, count):
        point = start + fraction * (end - start)
        # A point on a cell edge belongs to the cells of both sides: one admissible suffices.
        cells = {cell_of(point + offset) for offset in
                 itertools.product((-1e-7, 1e-7), repeat=2)}
        if not any(admissible[cell] for cell in cells if min(cell) >= 0 and
                   cell[0] < admissible.shape[0] and cell[1] < admissible.shape[1]):
            return False
    return True


def test_a_taut_route_across_a_free_room_is_the_straight_way():
    route_map = RouteMap(np.zeros((40, 60), dtype=bool), RESOLUTION, ORIGIN, 0.3)
    start, goal = ORIGIN + [0.55, 0.45], ORIGIN + [5.25, 3.35]
    route = route_map.tree_to(goal).route_from(start)
    np.testing.assert_allclose(route, [start, goal])
    grid = route_map.tree_to(goal).route_from(start, taut=False)
    assert path_length(grid) > path_length(route) + 0.3


def route_cells(route):
    """Every cell a route of cell centres passes through at its 8-connected steps."""
    cells = []
    for start, end in zip(route[:-1], route[1:], strict=True):
        steps = int(round(np.max(np.abs(end - start)) / RESOLUTION))
        direction = (end - start) / steps
        assert np.allclose(np.abs(direction[np.abs(direction) > 1e-9]), RESOLUTION), \
            'a route runs along the 8 grid directions'
        cells += [cell_of(start + k * direction) for k in range(steps + 1)]
    return cells


@pytest.mark.parametrize('seed', range(10))
def test_routes_are_shortest_and_keep_the_clearance(seed):
    rng = np.random.default_rng(seed)
    height, width = 10 + seed % 3, 13 - seed % 3
    occupied = rng.random((height, width)) < 0.2
    clearance = [0.0, 0.04, 0.05, 0.1, 0.12][seed % 5]
    admissible = brute_admissible(occupied, clearance)
    np.testing.assert_array_equal(admissible_cells(occupied, RESOLUTION, clearance), admissible)
    route_map = RouteMap(occupied, RESOLUTION, ORIGIN, clearance)
    cells = [tuple(cell) for cell in np.argwhere(admissible)]
    for _ in range(6):
        start, goal = (cells[index] for index in rng.choice(len(cells), 2, replace=False))
        expected = brute_shortest(admissible, start, goal)
        tree = route_map.tree_to(centre(goal))
        route = tree.route_from(centre(start), taut=False)
        if expected is None:
            assert route is None and tree.route_from(centre(start)) is None
            continue
        assert route is not None
        np.testing.assert_allclose(route[0], centre(start))
        np.testing.assert_allclose(route[-1], centre(goal))
        assert path_length(route) == pytest.approx(expected, abs=1e-9)
        passed = route_cells(route)
        assert all(admissible[cell] for cell in passed)
        taut = tree.route_from(centre(start))
        np.testing.assert_allclose(taut[[0, -1]], route[[0, -1]])
        assert path_length(taut) <= expected + 1e-9
        assert all(seen_along_admissible(admissible, a, b)
                   for a, b in zip(taut[:-1], taut[1:], strict=True))


@pytest.mark.parametrize('seed', range(6))
def test_a_map_without_some_cells_routes_round_them_and_shortest(seed):
    rng = np.random.default_rng(100 + seed)
    occupied = rng.random((11, 12)) < 0.15
    route_map = RouteMap(occupied, RESOLUTION, ORIGIN, 0.05)
    admissible = brute_admissible(occupied, 0.05)
    closed = np.argwhere(admissible)[rng.choice(int(admissible.sum()), 12, replace=False)]
    without = route_map.without(closed)
    left = admissible.copy()
    left[tuple(closed.T)] = False
    np.testing.assert_array_equal(without.admissible, left)
    # The map it was made from is unchanged.
    np.testing.assert_array_equal(route_map.admissible, admissible)
    cells = [tuple(cell) for cell in np.argwhere(left)]
    for _ in range(6):
        start, goal = (cells[index] for index in rng.choice(len(cells), 2, replace=False))
        expected = brute_shortest(left, start, goal)
        route = without.tree_to(centre(goal)).route_from(centre(start), taut=False)
        if expected is None:
            assert route is None
            continue
        assert path_length(route) == pytest.approx(expected, abs=1e-9)
        assert all(left[cell] for cell in route_cells(route))


@pytest.mark.parametrize('seed', range(6))
def test_with_a_margin_the_grid_path_costs_the_least(seed):
    """The search over the grid's steps finds the least cost: as a plain Dijkstra does."""
    rng = np.random.default_rng(100 + seed)
    occupied = rng.random((11, 12)) < 0.15
    clearance, margin = 0.05, [0.1, 0.25, 0.4][seed % 3]
    distances = brute_distances(occupied)
    admissible = ~occupied & (distances >= clearance)
    closeness = np.clip((clearance + margin - distances) / margin, 0.0, 1.0)
    route_map = RouteMap(occupied, RESOLUTION, ORIGIN, clearance, margin)
    cells = [tuple(cell) for cell in np.argwhere(admissible)]
    for _ in range(6):
        start, goal = (cells[index] for index in rng.choice(len(cells), 2, replace=False))
        expected = brute_shortest(admissible, start, goal, closeness)
        path = route_map.tree_to(centre(goal)).cells_from(centre(start))
        if expected is None:
            assert path is None
            continue
        steps = [divmod(int(cell), occupied.shape[1]) for cell in path]
        assert steps[0] == start and steps[-1] == goal
        assert all(max(abs(a[0] - b[0]), abs(a[1] - b[1])) == 1
                   for a, b in zip(steps[:-1], steps[1:], strict=True))
        cost = sum(step_cost(closeness, a, b) for a, b in zip(steps[:-1], steps[1:], strict=True))
        # Float32 costs near obstacles: equal to rounding.
        assert cost == pytest.approx(expected, rel=1e-6)


def test_start_and_goal_snap_to_the_nearest_admissible_cell_and_the_goal_ends_the_route():
    occupied = np.zeros((10, 10), dtype=bool)
    route_map = RouteMap(occupied, RESOLUTION, ORIGIN, 0.2)
    # 0.2 m from the outside: the two outer rings of cells are not admissible.
    start = ORIGIN + [0.01, 0.01]
    goal = ORIGIN + [0.62, 0.48]
    route = route_map.tree_to(goal).route_from(start, taut=False)
    np.testing.assert_allclose(route[0], ORIGIN + [0.25, 0.25])
    np.testing.assert_allclose(route[-2], ORIGIN + [0.65, 0.45])
    np.testing.assert_array_equal(route[-1], goal)


def u_trap():
    """Return a 6 m x 6 m room with a U open to the left around (3.5, 3) m of the room."""
    occupied = np.zeros((60, 60), dtype=bool)
    occupied[15:45, 40:42] = True        # the U's bottom, right of the robot
    occupied[15:17, 20:42] = True        # its arms, open to the left
    occupied[43:45, 20:42] = True
    return occupied


def test_a_u_shaped_wall_is_left_by_its_opening():
    occupied = u_trap()
    route_map = RouteMap(occupied, RESOLUTION, ORIGIN, 0.3)
    start = ORIGIN + [3.5, 3.0]
    goal = ORIGIN + [5.0, 3.0]
    route = route_map.tree_to(goal).route_from(start, taut=False)
    assert route is not None
    # Out of the U on the left (x < 2.0 m of the room), around an arm, to the goal.
    assert (route[:, 0] - ORIGIN[0]).min() < 2.0
    assert path_length(route) > 2.0 * 1.5 + 2.0
    admissible = route_map.admissible
    assert all(admissible[cell] for cell in route_cells(route[:-1]))


def test_no_route_to_a_closed_room_an_obstacle_or_off_the_map():
    occupied = np.zeros((20, 20), dtype=bool)
    occupied[:, 10] = True
    route_map = RouteMap(occupied, RESOLUTION, ORIGIN, 0.1)
    assert route_map.tree_to(ORIGIN + [1.5, 1.0]).route_from(ORIGIN + [0.5, 1.0]) is None
    assert route_map.tree_to(ORIGIN + [1.05, 1.0]).route_from(ORIGIN + [0.5, 1.0]) is None
    assert route_map.tree_to(ORIGIN + [5.0, 1.0]).route_from(ORIGIN + [0.5, 1.0]) is None
    assert route_map.blocked(ORIGIN + [1.05, 1.0]) and route_map.blocked(ORIGIN - 0.1)
    assert not route_map.blocked(ORIGIN + [0.5, 1.0])
    nowhere = RouteMap(np.ones((5, 5), dtype=bool), RESOLUTION, ORIGIN, 0.1)
    assert nowhere.tree_to(ORIGIN + 0.25).route_from(ORIGIN + 0.25) is None


def own_carrot(path, position, lookahead):
    """Pure pursuit's carrot, found by the test itself.

    The closest point by projection on each segment (the first on ties); then walking the path
    in small steps from it, the first point at least LOOKAHEAD away, refined by bisection.
    """
    best = (math.inf, 0, 0.0)
    for index in range(len(path) - 1):
        a, b = path[index], path[index + 1]
        t = float(np.clip((position - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0))
        distance = float(np.linalg.norm(a + t * (b - a) - position))
        if distance < best[0]:
            best = (distance, index, t)
    distance, index, t = best
    if distance >= lookahead:
        a, b = path[index], path[index + 1]
        return a + t * (b - a)
    for segment in range(index, len(path) - 1):
        a, b = path[segment], path[segment + 1]
        ts = np.linspace(t if segment == index else 0.0, 1.0, 2001)
        outside = np.linalg.norm(a + ts[:, None] * (b - a) - position, axis=1) >= lookahead
        if outside.any():
            first = int(np.argmax(outside))
            low, high = ts[max(first - 1, 0)], ts[first]
            for _ in range(60):
                middle = 0.5 * (low + high)
                if np.linalg.norm(a + middle * (b - a) - position) >= lookahead:
                    high = middle
                else:
                    low = middle
            return a + high * (b - a)
    return path[-1]


@pytest.mark.parametrize('seed', range(20))
def test_the_carrot_is_where_the_path_leaves_the_lookahead_circle(seed):
    rng = np.random.default_rng(300 + seed)
    path = np.cumsum(rng.uniform(-1.0, 1.0, size=(6, 2)), axis=0)
    for _ in range(10):
        position = path[rng.integers(0, 5)] + rng.normal(scale=0.4, size=2)
        lookahead = rng.uniform(0.2, 2.0)
        point, _ = carrot(path, position, lookahead)
        np.testing.assert_allclose(point, own_carrot(path, position, lookahead), atol=1e-6)


@pytest.mark.parametrize('seed', range(4))
def test_snapping_finds_the_nearest_admissible_centre(seed):
    rng = np.random.default_rng(500 + seed)
    occupied = rng.random((30, 40)) < 0.35
    route_map = RouteMap(occupied, RESOLUTION, ORIGIN, 0.1)
    cells = np.argwhere(route_map.admissible)
    centres = ORIGIN + RESOLUTION * (cells[:, ::-1] + 0.5)
    for position in ORIGIN + rng.uniform(-0.5, 4.5, size=(200, 2)):
        distances = np.linalg.norm(centres - position, axis=1)
        snapped = route_map.snapped(position)
        row, column = divmod(snapped, 40)
        assert route_map.admissible[row, column]
        chosen = np.linalg.norm(ORIGIN + RESOLUTION * np.array([column + 0.5, row + 0.5])
                                - position)
        assert chosen == pytest.approx(distances.min(), abs=1e-12)


def test_with_a_margin_the_route_keeps_room_where_there_is_some_and_squeezes_where_not():
    # A wall 1 m thick across a 6 m x 6 m room at x = 3 m with a 0.7 m gap about
    # y = 1.95 m, then a 0.2 m stub, then an opening above y = 2.5 m.
    occupied = np.zeros((60, 60), dtype=bool)
    occupied[:16, 25:35] = True
    occupied[23:25, 25:35] = True
    start, goal = ORIGIN + [1.0, 1.95], ORIGIN + [5.0, 1.95]
    hugging = RouteMap(occupied, RESOLUTION, ORIGIN, 0.3).tree_to(goal).route_from(start)
    assert np.abs(hugging[:, 1] - ORIGIN[1] - 1.95).max() < 0.1
    roomy = RouteMap(occupied, RESOLUTION, ORIGIN, 0.3, margin=0.3)
    assert (roomy.tree_to(goal).route_from(start)[:, 1] - ORIGIN[1]).max() > 2.7
    # With the opening closed the narrow gap is the only way: taken all the same.
    occupied[25:, 25:35] = True
    squeezed = RouteMap(occupied, RESOLUTION, ORIGIN, 0.3, margin=0.3)
    route = squeezed.tree_to(goal).route_from(start)
    assert route is not None and np.abs(route[:, 1] - ORIGIN[1] - 1.95).max() < 0.1
