"""
Benchmark of the map pieces: a grid's obstacles, the index near a robot, routes.

Usage: ``python -m prvo_planner.map_bench [--json PATH] [--sizes 20 40 100]
[--resolution 0.05] [--callbacks]``. Each size is a seeded office of that many metres square:
4 m rooms joined by 1 m doors, 0.1 m walls, boxes of furniture. Times are process CPU time
(insensitive to other processes sharing the cores), the best of three: once per map (segments,
index, route graph), once per goal (the shortest paths to it from every cell), per plan (the
obstacles within 3 m; a route from a new position).

A second table gives what a planner's whole map costs (`agent.build_map`, with a goal): its CPU
time, and the memory that tracemalloc traces while it is built (the peak) and after (kept, the
grid itself not counted), in bytes per cell of the grid.

With ``--callbacks`` a planner node in this process (on ROS_DOMAIN_ID, or 0) is handed each map
as a serialized OccupancyGrid message, and a second table gives wall times [ms]: the node's map
callback, what that callback took when it built the map itself (reading the message, then
``PlannerAgent.set_map``), and how long after the message the built map was in force.
"""

import argparse
import json
import sys
import time
import tracemalloc

import numpy as np

from prvo_planner.agent import build_map
from prvo_planner.maps import GridMap, ObstacleIndex, grid_obstacles, occupied_cells
from prvo_planner.route import RouteMap

ROOM = 4.0
DOOR = 1.0
WALL = 0.1
QUERY_DISTANCE = 3.0
CLEARANCE = 0.3
QUERIES = 200
# The map key of the whole map's build (`agent.map_key_of`): unknown cells occupied, obstacles
# within QUERY_DISTANCE, a robot of CLEARANCE with the default route margin, right of way (its
# passages).
BUILT_FOR = (True, QUERY_DISTANCE, CLEARANCE, 0.3, True)


def office(size, resolution, seed=0):
    """Return the seeded office GridMap SIZE [m] square, cells of RESOLUTION [m]."""
    rng = np.random.default_rng(seed)
    count = int(round(size / resolution))
    cells = np.zeros((count, count), dtype=np.int8)
    room, door = int(round(ROOM / resolution)), int(round(DOOR / resolution))
    wall = max(1, int(round(WALL / resolution)))
    for line in range(room, count, room):
        cells[line:line + wall, :] = 100
        cells[:, line:line + wall] = 100
        for start in range(0, count, room):
            opening = start + int(rng.integers(wall, room - door - wall))
            cells[line:line + wall, opening:opening + door] = 0
            cells[opening:opening + door, line:line + wall] = 0
    for _ in range(int(size * size / 8.0)):
        row, column = rng.integers(0, count - 10, size=2)
        height, width = rng.integers(2, 10, size=2)
        cells[row:row + height, column:column + width] = 100
    return GridMap(cells, resolution, [0.0, 0.0])


def cpu_ms(work, repeats=3):
    """Return (best CPU time [ms] of REPEATS calls of WORK, its last value)."""
    best, value = np.inf, None
    for _ in range(repeats):
        started = time.process_time()
        value = work()
        best = min(best, time.process_time() - started)
    return best * 1e3, value


def bench_map(size, resolution):
    """Return the row of one office map."""
    grid = office(size, resolution)
    segments_ms, obstacles = cpu_ms(lambda: grid_obstacles(grid))
    index_ms, index = cpu_ms(lambda: ObstacleIndex(obstacles, QUERY_DISTANCE))
    positions = np.random.default_rng(1).uniform(0.5, size - 0.5, size=(QUERIES, 2))
    started = time.process_time()
    found = [len(index.near(position, QUERY_DISTANCE)) for position in positions]
    near_us = (time.process_time() - started) / QUERIES * 1e6
    occupied = occupied_cells(grid)
    route_map_ms, route_map = cpu_ms(
        lambda: RouteMap(occupied, grid.resolution, grid.origin, CLEARANCE), repeats=1)
    tree_ms, tree = cpu_ms(lambda: route_map.tree_to([size - 1.5, size - 1.5]), repeats=1)
    started = time.process_time()
    routes = [tree.route_from(position) for position in positions[:20]]
    route_ms = (time.process_time() - started) / 20 * 1e3
    return {'size_m': size, 'resolution_m': resolution, 'cells': int(grid.cells.size),
            'segments': len(obstacles.segments), 'segments_ms': segments_ms,
            'index_ms': index_ms, 'near_us': near_us, 'near_found': float(np.mean(found)),
            'route_map_ms': route_map_ms, 'tree_ms': tree_ms, 'route_from_ms': route_ms,
            'routes_found': sum(route is not None for route in routes)}


def build_memory(grid):
    """
    Return what building the whole map of GRID costs: CPU time and traced memory.

    Returns
    -------
    dict
        ``build_ms`` (CPU, untraced), ``peak_bytes_per_cell`` and ``kept_bytes_per_cell``
        (tracemalloc's peak during `agent.build_map` and what the result holds, above what
        was traced before, per cell of GRID). The goal is the free cell nearest the map's
        middle.

    """
    height, width = grid.shape
    free = np.argwhere(~occupied_cells(grid))
    row, column = free[np.argmin(np.hypot(*(free - [height / 2.0, width / 2.0]).T))]
    goal = grid.origin + grid.resolution * (np.array([column, row]) + 0.5)
    build_ms, _ = cpu_ms(lambda: build_map(grid, BUILT_FOR, goal), repeats=1)
    tracing = tracemalloc.is_tracing()
    if not tracing:
        tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        tracemalloc.reset_peak()
        built = build_map(grid, BUILT_FOR, goal)
        kept, peak = tracemalloc.get_traced_memory()
    finally:
        if not tracing:
            tracemalloc.stop()
    assert built.route_tree is not None
    return {'build_ms': build_ms, 'peak_bytes_per_cell': (peak - before) / grid.cells.size,
            'kept_bytes_per_cell': (kept - before) / grid.cells.size}


def bench_callback(node, size, resolution):
    """Return the callback row of one office map handed to planner NODE as a message."""
    import rclpy
    from rclpy.serialization import serialize_message

    from prvo_msgs_util import WORLD_FRAME, make_occupancy_grid, occupancy_grid_to_parts
    from prvo_planner.agent import PlannerAgent

    grid = office(size, resolution)
    message = make_occupancy_grid(0.0, grid.cells, grid.resolution, grid.origin, WORLD_FRAME)
    agent = PlannerAgent('robot_0', node._agent.config, node._agent.settings)
    started = time.perf_counter()
    agent.set_map(GridMap(*occupancy_grid_to_parts(message, expected_frame=WORLD_FRAME)))
    inline_ms = (time.perf_counter() - started) * 1e3
    data = serialize_message(message)
    started = time.perf_counter()
    node._on_map(data)
    callback_ms = (time.perf_counter() - started) * 1e3
    # The message carries the resolution as float32: the map in force is known by its shape.
    while node._agent.grid_map is None or node._agent.grid_map.shape != grid.shape:
        rclpy.spin_once(node, timeout_sec=0.01)
    in_force_ms = (time.perf_counter() - started) * 1e3
    return {'size_m': size, 'resolution_m': resolution, 'callback_ms': callback_ms,
            'callback_building_ms': inline_ms, 'in_force_after_ms': in_force_ms}


def callback_rows(sizes, resolution):
    """Return the callback rows of SIZES, measured on one planner node in this process."""
    import rclpy

    from prvo_planner.planner_node import PlannerNode

    rclpy.init(args=['--ros-args', '-r', '__ns:=/robot_0', '-p', 'goal:=[1.5, 1.5]',
                     '-p', 'neighbors:=[""]'])
    node = PlannerNode()
    try:
        return [bench_callback(node, size, resolution) for size in sizes]
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


def main(argv=None):
    """Print the table (and write JSON if asked)."""
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--sizes', type=float, nargs='+', default=[20.0, 40.0, 100.0])
    parser.add_argument('--resolution', type=float, default=0.05)
    parser.add_argument('--json', help='write the rows to this file')
    parser.add_argument('--callbacks', action='store_true',
                        help="also time a planner node's map callback (starts rclpy)")
    arguments = parser.parse_args(argv)
    print('| map | cells | segments | segments [ms] | index [ms] | near 3 m [us] (found) | '
          'route graph [ms] | paths to a goal [ms] | route from [ms] |')
    print('|---|---|---|---|---|---|---|---|---|')
    rows = []
    for size in arguments.sizes:
        row = bench_map(size, arguments.resolution)
        rows.append(row)
        print(f"| {size:g} m at {arguments.resolution:g} m | {row['cells']} | "
              f"{row['segments']} | {row['segments_ms']:.1f} | {row['index_ms']:.1f} | "
              f"{row['near_us']:.0f} ({row['near_found']:.0f}) | {row['route_map_ms']:.0f} | "
              f"{row['tree_ms']:.0f} | {row['route_from_ms']:.2f} |", flush=True)
    print('\n| map | cells | whole map built [ms] | peak while built [B/cell] | kept [B/cell] |')
    print('|---|---|---|---|---|')
    for row in rows:
        row.update(build_memory(office(row['size_m'], arguments.resolution)))
        print(f"| {row['size_m']:g} m at {arguments.resolution:g} m | {row['cells']} | "
              f"{row['build_ms']:.0f} | {row['peak_bytes_per_cell']:.1f} | "
              f"{row['kept_bytes_per_cell']:.1f} |", flush=True)
    if arguments.callbacks:
        print('\n| map | map callback [ms] | callback building the map [ms] | '
              'map in force after [ms] |')
        print('|---|---|---|---|')
        for row in callback_rows(arguments.sizes, arguments.resolution):
            print(f"| {row['size_m']:g} m at {arguments.resolution:g} m | "
                  f"{row['callback_ms']:.1f} | {row['callback_building_ms']:.0f} | "
                  f"{row['in_force_after_ms']:.0f} |", flush=True)
            next(own for own in rows if own['size_m'] == row['size_m']).update(
                {key: row[key] for key in ('callback_ms', 'callback_building_ms',
                                           'in_force_after_ms')})
    if arguments.json:
        with open(arguments.json, 'w') as output:
            json.dump(rows, output, indent=2)
    return 0


if __name__ == '__main__':
    sys.exit(main())
