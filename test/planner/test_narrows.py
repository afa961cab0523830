"""One-way passages from a grid (issue 39, step 1), against geometry built or measured apart.

Every grid here is drawn cell by cell, so the doors' and corridors' free widths, their places and
lengths are known exactly; the waiting spots are checked by brute force over every occupied cell.
"""

import numpy as np
import pytest

from prvo_planner import narrows
from prvo_planner.maps import OCCUPIED, GridMap, MapTooLargeError, occupied_cells
from prvo_planner.narrows import find_passages, passing_width
from prvo_sim.narrows_figure import main as figure_main
from prvo_sim.scenario import find_scenario, load_scenario

RESOLUTION = 0.05
RADIUS = 0.25
MARGIN = 0.25


def _grid(occupied, origin=(0.0, 0.0)):
    return GridMap(np.where(occupied, OCCUPIED, 0).astype(np.int8), RESOLUTION, origin)


def _box(height, width):
    """Free cells (height, width) inside a border one cell thick."""
    occupied = np.zeros((height, width), dtype=bool)
    occupied[[0, -1], :] = True
    occupied[:, [0, -1]] = True
    return occupied


def _door_grid(door_cells, door_row=40, wall_column=60, thickness=2):
    """Two rooms 6 x 4 m joined by a door DOOR_CELLS high in a wall THICKNESS cells thick."""
    occupied = _box(80, 120)
    occupied[:, wall_column:wall_column + thickness] = True
    occupied[door_row:door_row + door_cells, wall_column:wall_column + thickness] = False
    return occupied


def _centre(row, column):
    return RESOLUTION * np.array([column + 0.5, row + 0.5])


def _square_distances(grid, point):
    """Distances [m] from POINT to every occupied cell's square and to the map's outside."""
    rows, columns = np.nonzero(occupied_cells(grid))
    low = grid.origin + RESOLUTION * np.stack([columns, rows], axis=1)
    gaps = np.maximum(np.maximum(low - point, point - (low + RESOLUTION)), 0.0)
    height, width = grid.shape
    edges = np.concatenate([point - grid.origin,
                            grid.origin + RESOLUTION * np.array([width, height]) - point])
    return np.concatenate([np.hypot(*gaps.T), edges])


def _check_waiting_spots(grid, passages, radius=RADIUS, margin=MARGIN):
    """Each spot: free, clear of every occupied cell, outside every passage, off its axis."""
    spots = np.array([end.waiting_spot for passage in passages
                      for end in passage.ends]).reshape(-1, 2)
    gaps = np.linalg.norm(spots[:, None] - spots[None], axis=-1)
    assert np.all(gaps[~np.eye(len(spots), dtype=bool)] >= 2.0 * radius + margin - 1e-9)
    for passage in passages:
        for end in passage.ends:
            spot = end.waiting_spot
            assert spot is not None
            # Clear by the radius and the margin, to the rounding of a distance transform
            # (a cell centre's distance to a diagonal square is at most 0.21 cells less).
            assert _square_distances(grid, spot).min() >= radius + margin - 0.25 * RESOLUTION
            offset = spot - end.entrance
            assert offset @ end.outward >= 0.0
            assert abs(offset @ np.array([-end.outward[1], end.outward[0]])) >= (
                2.0 * radius + margin - 1e-9)
            for other in passages:
                centres = grid.origin + RESOLUTION * (other.cells[:, ::-1] + 0.5)
                assert np.hypot(*(centres - spot).T).min() >= 2.0 * radius + margin - 1e-9


@pytest.mark.parametrize('door_cells', [11, 16, 20, 25])
def test_a_door_is_one_passage_of_its_width_where_it_is(door_cells):
    rng = np.random.default_rng(door_cells)
    door_row = int(rng.integers(10, 70 - door_cells))
    occupied = _door_grid(door_cells, door_row=door_row)
    grid = _grid(occupied)
    passages = find_passages(grid, RADIUS, MARGIN)
    assert len(passages) == 1
    passage = passages[0]
    width = door_cells * RESOLUTION
    # Within a cell, never wider than the door: cell centres sample the clearance.
    assert width - RESOLUTION - 1e-9 <= passage.width <= width + 1e-9
    door_y = RESOLUTION * (door_row + 0.5 * door_cells)
    wall_x = 61 * RESOLUTION
    (first, second) = passage.ends
    assert first.entrance[0] < wall_x < second.entrance[0]
    for end in passage.ends:
        assert abs(end.entrance[1] - door_y) <= RESOLUTION
        # The ridge is narrow out to where a disc of the passing width fits before the door.
        assert abs(end.entrance[0] - wall_x) <= 0.5 * passing_width(RADIUS, MARGIN)
        assert end.outward @ [np.sign(end.entrance[0] - wall_x), 0.0] > 0.99
    assert abs(passage.axis @ [1.0, 0.0]) > 0.99
    # Every door cell a robot's centre fits in belongs to the passage.
    cells = {tuple(cell) for cell in passage.cells}
    for row in range(door_row, door_row + door_cells):
        if abs(RESOLUTION * (row + 0.5) - door_y) <= 0.5 * width - RADIUS:
            assert (row, 60) in cells and (row, 61) in cells
    _check_waiting_spots(grid, passages)


def test_a_door_in_a_slanted_wall_is_found_across_it():
    # Seeded walls at any angle through a room 8 m square, a door of 0.55-1.4 m in each: a
    # cell is occupied when its centre lies within 0.06 m of the wall's line outside the door.
    rng = np.random.default_rng(39)
    rows, columns = np.mgrid[0:160, 0:160]
    for _ in range(12):
        angle = rng.uniform(0.0, np.pi)
        door = rng.uniform(0.55, 1.4)
        centre = 4.0 + rng.uniform(-0.5, 0.5, 2)
        along_wall = np.array([np.cos(angle), np.sin(angle)])
        normal = np.array([-along_wall[1], along_wall[0]])
        points = RESOLUTION * (np.stack([columns, rows], axis=-1) + 0.5) - centre
        occupied = _box(160, 160) | ((np.abs(points @ normal) <= 0.06)
                                     & (np.abs(points @ along_wall) >= 0.5 * door))
        grid = _grid(occupied)
        (passage,) = find_passages(grid, RADIUS, MARGIN)
        # Cells are occupied by their centres: the jambs' cells move by up to a cell.
        assert door - 2.0 * RESOLUTION <= passage.width <= door + RESOLUTION
        assert abs(passage.axis @ normal) > 0.99
        sides = [(end.entrance - centre) @ normal for end in passage.ends]
        assert min(sides) < 0.0 < max(sides)
        # Mid-door, to the cells' rounding of the jambs.
        for end in passage.ends:
            assert abs((end.entrance - centre) @ along_wall) <= 1.5 * RESOLUTION
        _check_waiting_spots(grid, (passage,))


def test_a_corridor_one_robot_wide_is_one_passage_along_it():
    occupied = _box(80, 160)
    # A corridor 14 cells (0.7 m) wide and 60 cells (3 m) long joins two rooms.
    occupied[:, 50:110] = True
    occupied[33:47, 50:110] = False
    grid = _grid(occupied)
    (passage,) = find_passages(grid, RADIUS, MARGIN)
    assert 0.7 - RESOLUTION - 1e-9 <= passage.width <= 0.7 + 1e-9
    assert abs(passage.axis @ [1.0, 0.0]) > 0.99
    first, second = passage.ends
    assert first.entrance[0] <= 50 * RESOLUTION and second.entrance[0] >= 110 * RESOLUTION
    # It spans the corridor, and a disc's radius of the passing width at most beyond each end.
    assert 3.0 <= passage.length <= 3.0 + passing_width(RADIUS, MARGIN) + 2 * RESOLUTION
    for line in passage.centre_lines:
        assert np.all(np.abs(line[:, 1] - 2.0) <= RESOLUTION)
    _check_waiting_spots(grid, (passage,))


def test_an_l_corridor_is_one_passage_whose_centre_line_turns():
    occupied = _box(140, 140)
    # Room A bottom left (to x 2 m), room B top right (from y 5 m); the corridor 0.7 m wide
    # runs east along y 1-1.7 m from A to x 5.3 m, then north to B.
    occupied[:100, 40:] = True
    occupied[20:34, 40:106] = False
    occupied[20:100, 92:106] = False
    grid = _grid(occupied)
    (passage,) = find_passages(grid, RADIUS, MARGIN)
    assert 0.7 - RESOLUTION - 1e-9 <= passage.width <= 0.7 + 1e-9
    first, second = passage.ends
    assert first.entrance[0] <= 2.0 and abs(first.entrance[1] - 1.35) <= RESOLUTION
    assert second.entrance[1] >= 5.0 and abs(second.entrance[0] - 4.95) <= RESOLUTION
    assert first.outward @ [-1.0, 0.0] > 0.99 and second.outward @ [0.0, 1.0] > 0.99
    (line,) = passage.centre_lines
    # Along the corridor's middle: the turn cuts its inner corner by less than a corridor width.
    along_x = line[line[:, 0] < 4.6]
    along_y = line[line[:, 1] > 1.7]
    assert np.all(np.abs(along_x[:, 1] - 1.35) <= RESOLUTION)
    assert np.all(np.abs(along_y[:, 0] - 4.95) <= RESOLUTION)
    legs = (4.95 - 2.0) + (5.0 - 1.35)
    assert legs <= passage.length <= legs + passing_width(RADIUS, MARGIN) + 2 * RESOLUTION
    _check_waiting_spots(grid, (passage,))


def test_open_space_a_wide_door_a_dead_end_and_a_door_too_narrow_make_no_passage():
    assert find_passages(_grid(_box(80, 120)), RADIUS, MARGIN) == ()
    # Two robots pass each other in a door of the passing width and more.
    wide = int(np.ceil(passing_width(RADIUS, MARGIN) / RESOLUTION)) + 1
    assert find_passages(_grid(_door_grid(wide)), RADIUS, MARGIN) == ()
    # A robot does not fit a door narrower than its diameter: no route passes it.
    assert find_passages(_grid(_door_grid(9)), RADIUS, MARGIN) == ()
    # An alcove one robot wide, closed at its end: nothing passes through it.
    alcove = _box(80, 120)
    alcove[:, 60:] = True
    alcove[33:47, 60:100] = False
    assert find_passages(_grid(alcove), RADIUS, MARGIN) == ()


def test_a_larger_margin_makes_a_door_a_passage():
    occupied = _door_grid(30)
    assert find_passages(_grid(occupied), RADIUS, 0.1) == ()
    (passage,) = find_passages(_grid(occupied), RADIUS, 0.3)
    assert abs(passage.width - 1.5) <= RESOLUTION


def test_a_mirrored_and_shifted_map_gives_the_mirrored_passage():
    occupied = _door_grid(16, door_row=22)
    origin = np.array([-3.3, 1.7])
    (passage,) = find_passages(_grid(occupied), RADIUS, MARGIN)
    (mirrored,) = find_passages(_grid(occupied[::-1], origin), RADIUS, MARGIN)
    # Rows flip about the middle of the 4 m map: y -> 4 - y, then the origin shifts it.
    flip = np.array([1.0, -1.0])
    assert mirrored.width == pytest.approx(passage.width)
    assert mirrored.length == pytest.approx(passage.length)
    for end, image in zip(passage.ends, mirrored.ends, strict=True):
        assert image.entrance == pytest.approx(origin + [0.0, 4.0] + flip * end.entrance)
        assert image.outward == pytest.approx(flip * end.outward)
    # The spots are mirrored too, but for ties broken to the right of the way out.
    for end, image in zip(passage.ends, mirrored.ends, strict=True):
        assert image.waiting_spot[0] == pytest.approx(origin[0] + end.waiting_spot[0])


def test_bad_input_is_refused_and_the_work_is_bounded(monkeypatch):
    grid = _grid(_door_grid(16))
    for radius, margin in ((0.0, 0.2), (np.nan, 0.2), (0.25, -0.1), (0.25, np.inf)):
        with pytest.raises(ValueError, match='radius|margin'):
            find_passages(grid, radius, margin)
    monkeypatch.setattr(narrows, 'MAX_CELLS', 80 * 120 - 1)
    with pytest.raises(MapTooLargeError, match='cells'):
        find_passages(grid, RADIUS, MARGIN)
    monkeypatch.setattr(narrows, 'MAX_CELLS', 80 * 120)
    monkeypatch.setattr(narrows, 'MAX_LOCAL_CELLS', 100)
    with pytest.raises(MapTooLargeError, match='span'):
        find_passages(grid, RADIUS, MARGIN)


def _shipped(name):
    scenario = load_scenario(find_scenario(name))
    return scenario.static_world.grid, max(robot.radius for robot in scenario.robots)


def _free_run(grid, point, axis):
    """Return the free width [m] of the run of free cells through POINT along AXIS (0: x)."""
    occupied = occupied_cells(grid)
    column, row = np.floor((point - grid.origin) / grid.resolution).astype(int)
    line = occupied[row] if axis == 0 else occupied[:, column]
    index = column if axis == 0 else row
    assert not line[index]
    blocked = np.flatnonzero(line)
    return grid.resolution * (blocked[blocked > index].min() - blocked[blocked < index].max()
                              - 1)


def test_doorway8_has_one_passage_its_door():
    grid, radius = _shipped('doorway8')
    (passage,) = find_passages(grid, radius, MARGIN)
    middle = 0.5 * (passage.ends[0].entrance + passage.ends[1].entrance)
    assert np.abs(middle) == pytest.approx([0.0, 0.0], abs=RESOLUTION)
    # The door is 1.2 m between the walls' capsules; the grid marks every cell they touch.
    gap = _free_run(grid, middle, axis=1)
    assert 1.2 - 2 * RESOLUTION - 1e-9 <= gap <= 1.2
    assert gap - RESOLUTION - 1e-9 <= passage.width <= gap + 1e-9
    assert abs(passage.axis @ [1.0, 0.0]) > 0.99
    # Each room's spot is on that room's side of the wall.
    assert passage.ends[0].waiting_spot[0] < 0.0 < passage.ends[1].waiting_spot[0]
    _check_waiting_spots(grid, (passage,), radius)


def test_every_passage_of_a_generated_office_joins_its_mouths():
    # map_bench's seeded office, 30 m square: 83 passages; some mouths are not reached through
    # the ridge's cells at the bottleneck's clearance (the search ended in an IndexError).
    from prvo_planner.map_bench import CLEARANCE, office

    passages = find_passages(office(30.0, RESOLUTION), CLEARANCE, 0.3)
    assert len(passages) > 50
    for passage in passages:
        assert len(passage.centre_lines) == len(passage.ends) - 1
        for line in passage.centre_lines:
            assert len(line) >= 2 and np.all(np.isfinite(line))


def test_office_has_a_passage_at_each_of_its_eight_doors():
    grid, radius = _shipped('office')
    passages = find_passages(grid, radius, MARGIN)
    doors = set()
    for passage in passages:
        middle = 0.5 * (passage.ends[0].entrance + passage.ends[1].entrance)
        doors.add((round(float(middle[0]), 1), int(np.sign(middle[1]))))
        # 1 m doors in the walls along the corridor: the way through them runs along y.
        gap = _free_run(grid, middle, axis=0)
        assert 1.0 - 2 * RESOLUTION - 1e-9 <= gap <= 1.0
        assert gap - RESOLUTION - 1e-9 <= passage.width <= gap + 1e-9
        assert abs(passage.axis @ [0.0, 1.0]) > 0.99
    assert doors == {(x, side) for x in (-7.5, -2.5, 2.5, 7.5) for side in (-1, 1)}
    _check_waiting_spots(grid, passages, radius)


def test_the_pictures_are_written(tmp_path):
    assert figure_main(['--scenarios', 'doorway8', '--folder', str(tmp_path)]) == 0
    picture = tmp_path / 'narrows_doorway8.png'
    assert picture.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    assert picture.stat().st_size < 200_000
    assert figure_main(['--scenarios', 'doorway8', '--margin', '-1']) == 2
    assert figure_main(['--scenarios', 'no_such_scenario']) == 2


@pytest.mark.parametrize('name', ['corridor8', 'doorway8', 'office', 'pillars12', 'u_trap'])
def test_every_shipped_map_has_its_waiting_spots_apart_and_clear(name):
    # u_trap's two passages open side by side into the trap: their spots must not overlap.
    grid, radius = _shipped(name)
    _check_waiting_spots(grid, find_passages(grid, radius, MARGIN), radius)
