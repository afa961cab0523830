"""Occupancy grids as the planner sees them: exact boundary segments and the index near a robot."""

import itertools
import re

import numpy as np
import pytest

from prvo_planner.core.obstacles import StaticObstacles
from prvo_planner.maps import (
    GridMap,
    MapTooLargeError,
    ObstacleIndex,
    check_route_work,
    grid_obstacles,
)

VALUES = np.array([-1, 0, 30, 64, 65, 100], dtype=np.int8)


def random_grid(seed, height, width, resolution=0.1, origin=(-1.3, 0.7)):
    rng = np.random.default_rng(seed)
    cells = VALUES[rng.integers(0, len(VALUES), size=(height, width))]
    # Mostly free, so that there are runs of several edges to merge.
    cells[rng.random((height, width)) < 0.5] = 0
    return GridMap(cells, resolution, np.array(origin))


def boundary_edges(cells, unknown_is_occupied):
    """Return the unit cell edges between an obstacle and a free cell, by brute force.

    An edge is ('h', j, c): the horizontal edge on line y = j (cells) from x = c to c + 1, or
    ('v', i, r): the vertical edge on line x = i from y = r to r + 1. Outside the map is an
    obstacle.
    """
    height, width = cells.shape

    def blocked(row, column):
        if not (0 <= row < height and 0 <= column < width):
            return True
        value = int(cells[row, column])
        return value >= 65 or (value == -1 and unknown_is_occupied)

    edges = set()
    for j in range(height + 1):
        for c in range(width):
            if blocked(j - 1, c) != blocked(j, c):
                edges.add(('h', j, c))
    for i in range(width + 1):
        for r in range(height):
            if blocked(r, i - 1) != blocked(r, i):
                edges.add(('v', i, r))
    return edges


def unit_edges(segment, grid):
    """Return the unit edges of an axis-aligned SEGMENT (2, 2) [m] of GRID, in cell units."""
    (ax, ay), (bx, by) = (np.asarray(segment) - grid.origin) / grid.resolution
    assert all(abs(value - round(value)) < 1e-9 for value in (ax, ay, bx, by))
    ax, ay, bx, by = (round(value) for value in (ax, ay, bx, by))
    if ay == by:
        return [('h', ay, c) for c in range(min(ax, bx), max(ax, bx))]
    assert ax == bx, 'a segment of a grid is axis-aligned'
    return [('v', ax, r) for r in range(min(ay, by), max(ay, by))]


@pytest.mark.parametrize('seed', range(12))
@pytest.mark.parametrize('unknown_is_occupied', [True, False])
def test_grid_segments_cover_every_obstacle_edge_once_and_merge_maximally(
        seed, unknown_is_occupied):
    grid = random_grid(seed, 9 + seed % 4, 7 + seed % 5)
    obstacles = grid_obstacles(grid, unknown_is_occupied)
    assert isinstance(obstacles, StaticObstacles)
    assert (obstacles.half_widths == 0.0).all() and len(obstacles.disc_radii) == 0
    covered = [edge for segment in obstacles.segments for edge in unit_edges(segment, grid)]
    # Exactly once each, and nothing between two free cells (or two obstacles).
    assert len(covered) == len(set(covered))
    assert set(covered) == boundary_edges(grid.cells, unknown_is_occupied)
    # Maximal: no two segments on one line share an end.
    for first, second in itertools.combinations(obstacles.segments, 2):
        same_line = ((first[0, 1] == first[1, 1] == second[0, 1] == second[1, 1])
                     or (first[0, 0] == first[1, 0] == second[0, 0] == second[1, 0]))
        if same_line:
            ends = [tuple(point) for point in first] + [tuple(point) for point in second]
            assert len(set(ends)) == 4, (first, second)


def test_a_free_grid_is_its_border_and_a_full_grid_has_no_boundary():
    free = GridMap(np.zeros((3, 4), dtype=np.int8), 0.5, [1.0, 2.0])
    segments = grid_obstacles(free).segments
    assert sorted(map(tuple, segments.reshape(-1, 4).tolist())) == sorted([
        (1.0, 2.0, 3.0, 2.0), (1.0, 3.5, 3.0, 3.5), (1.0, 2.0, 1.0, 3.5), (3.0, 2.0, 3.0, 3.5)])
    full = GridMap(np.full((3, 4), 100, dtype=np.int8), 0.5, [1.0, 2.0])
    assert len(grid_obstacles(full)) == 0
    unknown = GridMap(np.full((3, 4), -1, dtype=np.int8), 0.5, [1.0, 2.0])
    assert len(grid_obstacles(unknown)) == 0
    assert len(grid_obstacles(unknown, unknown_is_occupied=False)) == 4


def distance_to_segment(point, a, b):
    """Return the distance from POINT to the segment [A, B], computed by the test."""
    ab, ap = b - a, point - a
    t = min(max(float(ab @ ap) / float(ab @ ab), 0.0), 1.0)
    return float(np.linalg.norm(a + t * ab - point))


@pytest.mark.parametrize('seed', range(6))
@pytest.mark.parametrize('bucket_size', [0.3, 1.0, 4.0])
def test_obstacles_near_are_those_within_the_distance(seed, bucket_size):
    rng = np.random.default_rng(100 + seed)
    starts = rng.uniform(-10.0, 10.0, size=(60, 2))
    ends = starts + rng.uniform(-3.0, 3.0, size=(60, 2))
    half_widths = rng.uniform(0.0, 0.3, size=60)
    centres = rng.uniform(-10.0, 10.0, size=(15, 2))
    radii = rng.uniform(0.1, 1.0, size=15)
    obstacles = StaticObstacles(np.stack([starts, ends], axis=1), half_widths, centres, radii)
    index = ObstacleIndex(obstacles, bucket_size)
    for _ in range(30):
        position = rng.uniform(-14.0, 14.0, size=2)
        distance = rng.uniform(0.1, 5.0)
        near = index.near(position, distance)
        expected_segments = [i for i in range(60) if distance_to_segment(
            position, starts[i], ends[i]) - half_widths[i] <= distance]
        expected_discs = [i for i in range(15)
                          if np.linalg.norm(centres[i] - position) - radii[i] <= distance]
        np.testing.assert_array_equal(near.segments, obstacles.segments[expected_segments])
        np.testing.assert_array_equal(near.half_widths, half_widths[expected_segments])
        np.testing.assert_array_equal(near.disc_centres, centres[expected_discs])
        np.testing.assert_array_equal(near.disc_radii, radii[expected_discs])
        # The frames the subset carries are the ones its segments give (a unit vector along,
        # one across, and the ends' coordinates along it), from the test's own arithmetic.
        along = ends[expected_segments] - starts[expected_segments]
        unit = along / np.linalg.norm(along, axis=1, keepdims=True)
        np.testing.assert_allclose(near.frames, np.column_stack([
            unit, -unit[:, 1], unit[:, 0], np.sum(unit * starts[expected_segments], axis=1),
            np.sum(unit * ends[expected_segments], axis=1)]).reshape(-1, 6), atol=1e-12)


def test_an_index_of_nothing_and_a_query_far_away_find_nothing():
    assert len(ObstacleIndex(StaticObstacles.empty(), 1.0).near([0.0, 0.0], 5.0)) == 0
    grid = GridMap(np.zeros((20, 20), dtype=np.int8), 0.1, [0.0, 0.0])
    index = ObstacleIndex(grid_obstacles(grid), 1.0)
    assert len(index.near([50.0, 50.0], 3.0)) == 0
    assert len(index.near([-50.0, 1.0], 3.0)) == 0
    assert len(index.near([1.0, 1.0], 0.9)) == 0
    assert len(index.near([1.0, 1.0], 1.01)) == 4
    assert len(index.near([0.5, 1.0], 0.6)) == 1
    with pytest.raises(ValueError, match='bucket_size'):
        ObstacleIndex(StaticObstacles.empty(), 0.0)


def test_an_index_asked_for_tiny_buckets_stays_small_and_exact():
    grid = GridMap(np.zeros((2000, 2000), dtype=np.int8), 0.05, [0.0, 0.0])
    obstacles = grid_obstacles(grid)
    index = ObstacleIndex(obstacles, 1e-3)
    assert index.bucket_size > 1e-3
    np.testing.assert_array_equal(index.near([0.5, 50.0], 0.6).segments, [[[0.0, 0.0],
                                                                          [0.0, 100.0]]])


@pytest.mark.parametrize('shape, resolution, reach, refused', [
    # A large map of usual cells passes; tiny cells, however few, do not.
    ((4000, 4000), 0.05, 1.0, None),
    ((160, 160), 0.05, 0.6, None),
    ((160, 160), 1e-4, 0.6, '1.48e+08 cells padded'),
    ((160, 160), 1e-9, 0.6, '1.44e+18 cells padded'),
    ((160, 160), 5e-324, 0.6, 'inf cells padded'),
    # Within the padding bound, beyond the visits: a reach of 200 cells over 2000 x 2000.
    ((2000, 2000), 0.005, 1.0, '3.53e+09 cell visits'),
])
def test_the_route_work_of_a_map_is_bounded_before_anything_is_built(shape, resolution, reach,
                                                                      refused):
    if refused is None:
        check_route_work(shape, resolution, reach)
        return
    with pytest.raises(MapTooLargeError, match=re.escape(refused)):
        check_route_work(shape, resolution, reach)
