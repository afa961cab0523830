"""The agent with a map: it goes round a wall, plans against what is near, holds if it must."""

import dataclasses
import inspect

import numpy as np
from planner_testing import Odometry
import pytest

from prvo_msgs_util import diagnostic_values
from prvo_planner import agent as agent_module
from prvo_planner import narrows
from prvo_planner.agent import (
    ROUTE_FOUND,
    ROUTE_NONE,
    ROUTE_UNREACHABLE,
    AgentSettings,
    PlannerAgent,
    route_preferred_velocity,
)
from prvo_planner.core import PlannerConfig, plan_velocity
from prvo_planner.detours import way_round
from prvo_planner.maps import GridMap, occupied_at, way_out
from prvo_planner.reports import plan_status
from prvo_planner.right_of_way import IDLE_INSIDE
from prvo_planner.route import path_length

SETTINGS = AgentSettings(radius=0.3, goal_tolerance=0.15, obstacle_distance=1.5,
                         lookahead_dist=0.8)
CONFIG = PlannerConfig(eta=0.8, max_speed=1.0, actuation_cov=0.0025 * np.eye(2))
RESOLUTION = 0.1
# Does the core take the map's obstacles yet? Until it does, the agent's calls are checked and
# passed on without them.
CORE_TAKES_OBSTACLES = 'obstacles' in inspect.signature(plan_velocity).parameters


def walled_room():
    """Return an 8 m x 6 m room split at y = 3 m by a wall open only at x > 6 m."""
    cells = np.zeros((60, 80), dtype=np.int8)
    cells[29:31, :60] = 100
    cells[0, 70] = -1
    return GridMap(cells, RESOLUTION, [0.0, 0.0])


def in_obstacle(grid, position):
    column, row = np.floor((position - grid.origin) / grid.resolution).astype(int)
    height, width = grid.cells.shape
    return not (0 <= row < height and 0 <= column < width) or grid.cells[row, column] != 0


def distance_to_segment(point, a, b):
    """Return the distance from POINT to the segment [A, B], computed by the test."""
    ab = b - a
    t = min(max(float((point - a) @ ab) / float(ab @ ab), 0.0), 1.0)
    return float(np.linalg.norm(a + t * ab - point))


@pytest.fixture
def planned_obstacles(monkeypatch):
    """Record what the agent gives the core: (ego position, obstacles) per plan."""
    seen = []

    def recording(*problem, obstacles=None):
        if problem[3].model != 'rvo':
            # Not the check whether anybody comes to a robot standing still.
            seen.append((problem[0].position, obstacles))
        if CORE_TAKES_OBSTACLES:
            return plan_velocity(*problem, obstacles=obstacles)
        return plan_velocity(*problem)

    monkeypatch.setattr(agent_module, 'plan_velocity', recording)
    return seen


def drive(agent, start, steps, dt=0.1, t0=0.0):
    """Move a noise-free robot by its commands from T0; return its positions, last command."""
    position, velocity = np.array(start, dtype=float), np.zeros(2)
    positions, command = [position], None
    for step in range(steps):
        agent.receive_own(Odometry(round(t0 + step * dt, 9), position, velocity,
                                      1e-4 * np.eye(4)), 0.0)
        command = agent.plan()
        velocity = command.velocity
        position = position + dt * velocity
        positions.append(position)
        if command.arrived:
            break
    return np.array(positions), command


def stand(agent, position, steps, dt=0.1, t0=0.0):
    """Measure the robot at POSITION, standing, STEPS times from T0; return the last command."""
    for step in range(steps):
        agent.receive_own(Odometry(round(t0 + step * dt, 9), np.array(position, dtype=float),
                                      np.zeros(2), 1e-4 * np.eye(4)), 0.0)
        command = agent.plan()
    return command


def test_a_map_whose_passages_are_beyond_their_bounds_is_planned_on_without_turns(
        monkeypatch):
    # The room's gap at x > 6 m is a passage; with the passages' work bounded below it, the map
    # keeps its route and obstacles, without right of way, and says why.
    key = agent_module.map_key_of(SETTINGS, 0.0)
    assert key[-1] is True
    assert agent_module.build_map(walled_room(), key).passage_map is not None
    monkeypatch.setattr(narrows, 'MAX_LOCAL_CELLS', 10)
    built = agent_module.build_map(walled_room(), key, [1.0, 5.0])
    assert built.passage_map is None and built.route_tree is not None
    assert built.passages_refused.endswith('(at most 10)')


def test_a_goal_behind_a_wall_is_reached_by_the_way_around(planned_obstacles):
    grid = walled_room()
    goal = np.array([2.0, 4.5])
    agent = PlannerAgent('self', CONFIG, SETTINGS, goal)
    agent.set_map(grid)
    positions, command = drive(agent, [2.0, 1.5], 400)
    assert command.arrived and np.linalg.norm(positions[-1] - goal) <= SETTINGS.goal_tolerance
    assert not any(in_obstacle(grid, position) for position in positions)
    # Heading for carrots in sight, it keeps clear of the wall's end even before the planner
    # plans against the wall.
    wall_end = [np.array([6.0, 2.9]), np.array([6.0, 3.1])]
    assert min(distance_to_segment(position, *wall_end) for position in positions) > 0.2
    # It went round the wall's end at x = 6 m.
    assert positions[:, 0].max() > 6.0
    assert planned_obstacles
    for position, obstacles in planned_obstacles:
        for segment in () if obstacles is None else obstacles.segments:
            assert distance_to_segment(position, *segment) <= SETTINGS.obstacle_distance
    # Beside the wall the wall's faces count.
    beside = [obstacles for position, obstacles in planned_obstacles if 1.8 < position[1] < 4.2]
    assert beside and all(obstacles is not None and len(obstacles) > 0 for obstacles in beside)


def test_without_a_map_the_robot_heads_straight_and_plans_without_obstacles(planned_obstacles):
    agent = PlannerAgent('self', CONFIG, SETTINGS, np.array([2.0, 4.5]))
    agent.receive_own(Odometry(0.0, np.array([2.0, 1.5]), np.zeros(2), 1e-4 * np.eye(4)), 0.0)
    command = agent.plan()
    assert command.route is None and command.route_status == ROUTE_NONE
    assert planned_obstacles[-1][1] is None
    np.testing.assert_allclose(command.velocity / np.linalg.norm(command.velocity), [0.0, 1.0],
                               atol=0.05)


def test_far_from_every_obstacle_the_plan_is_that_of_an_empty_plane(planned_obstacles):
    for position in ([5.0, 5.0], [1.0, 5.0]):
        agent = PlannerAgent('self', CONFIG, SETTINGS, np.array([6.0, 4.0]))
        agent.set_map(GridMap(np.zeros((100, 100), dtype=np.int8), RESOLUTION, [0.0, 0.0]))
        stand(agent, position, 1)
    assert planned_obstacles[0][1] is None
    assert len(planned_obstacles[1][1].segments) == 1


def test_a_goal_no_way_reaches_is_reported_and_the_robot_holds(planned_obstacles):
    grid = walled_room()
    closed = np.array(grid.cells)
    closed[29:31, :] = 100
    agent = PlannerAgent('self', CONFIG, SETTINGS, np.array([2.0, 4.5]))
    agent.set_map(GridMap(closed, RESOLUTION, grid.origin))
    positions, command = drive(agent, [2.0, 1.5], 5)
    assert command.route_status == ROUTE_UNREACHABLE and command.route is None
    assert not command.arrived
    np.testing.assert_array_equal(positions[-1], [2.0, 1.5])
    # The map opens: a way is found.
    agent.set_map(grid)
    _, command = drive(agent, positions[-1], 1, t0=1.0)
    assert command.route_status == ROUTE_FOUND
    assert agent.goal_blocked([3.0, 3.0]) and agent.goal_blocked([-1.0, 3.0])
    assert not agent.goal_blocked([2.0, 4.5])


def test_the_route_is_taken_anew_for_a_new_goal_or_when_the_robot_strays(planned_obstacles):
    agent = PlannerAgent('self', CONFIG, SETTINGS, np.array([2.0, 4.5]))
    agent.set_map(walled_room())
    _, first = drive(agent, [2.0, 1.5], 1)
    # The same map again (a map server publishing it anew) changes nothing.
    agent.set_map(walled_room())
    _, same = drive(agent, [2.3, 1.5], 1, t0=0.1)
    assert same.route is first.route
    strayed = stand(agent, [2.0, 0.4], 20, t0=0.2)
    assert strayed.route is not first.route
    # Taken from where the robot was when it strayed farther than the lookahead.
    assert strayed.route[0][1] < first.route[0][1] - SETTINGS.lookahead_dist + RESOLUTION
    agent.set_goal(np.array([7.0, 1.0]))
    new_goal = stand(agent, [2.0, 0.4], 1, t0=3.0)
    np.testing.assert_array_equal(new_goal.route[-1], [7.0, 1.0])
    assert path_length(new_goal.route) < 1.1 * np.linalg.norm(new_goal.route[0] - [7.0, 1.0])


def test_unknown_cells_block_the_way_unless_the_settings_say_otherwise(planned_obstacles):
    grid = walled_room()
    unknown = np.array(grid.cells)
    unknown[29:31, 60:] = -1
    agent = PlannerAgent('self', CONFIG, SETTINGS, np.array([2.0, 4.5]))
    agent.set_map(GridMap(unknown, RESOLUTION, grid.origin))
    assert stand(agent, [2.0, 1.5], 1).route_status == ROUTE_UNREACHABLE
    agent.reconfigure(CONFIG, dataclasses.replace(SETTINGS, unknown_is_occupied=False),
                      agent.goal)
    assert stand(agent, [2.0, 1.5], 1, t0=0.1).route_status == ROUTE_FOUND


def test_a_robot_in_a_u_shaped_trap_leaves_it_by_its_opening(planned_obstacles):
    cells = np.zeros((80, 80), dtype=np.int8)
    cells[20:62, 50:52] = 100      # the U's bottom, between the robot and its goal
    cells[20:22, 20:52] = 100      # its arms, open to the left
    cells[60:62, 20:52] = 100
    grid = GridMap(cells, RESOLUTION, [0.0, 0.0])
    goal = np.array([7.0, 4.0])
    agent = PlannerAgent('self', CONFIG, SETTINGS, goal)
    agent.set_map(grid)
    positions, command = drive(agent, [4.0, 4.0], 600)
    assert command.arrived and np.linalg.norm(positions[-1] - goal) <= SETTINGS.goal_tolerance
    assert not any(in_obstacle(grid, position) for position in positions)
    assert positions[:, 0].min() < 2.0


def test_with_wait_for_map_the_first_plan_waits_for_the_map_as_long_as_for_neighbours():
    settings = dataclasses.replace(SETTINGS, wait_for_map=True, neighbor_timeout=2.0)
    agent = PlannerAgent('self', CONFIG, settings, np.array([2.0, 4.5]))
    agent.receive_own(Odometry(0.0, np.array([2.0, 1.5]), np.zeros(2), 1e-4 * np.eye(4)),
                      10.0)
    assert agent.awaiting_listed(10.5) and not agent.ready(10.5)
    # Not for ever: after neighbor_timeout the robot plans without.
    assert not agent.awaiting_listed(12.5) and agent.ready(12.5)
    agent.set_map(walled_room())
    assert not agent.awaiting_listed(10.5) and agent.ready(10.5)
    without = PlannerAgent('self', CONFIG, SETTINGS, np.array([2.0, 4.5]))
    without.receive_own(Odometry(0.0, np.array([2.0, 1.5]), np.zeros(2), 1e-4 * np.eye(4)),
                        10.0)
    assert without.ready(10.0)


def test_with_wait_for_map_a_robot_whose_map_is_being_built_holds_with_zero_commands():
    settings = dataclasses.replace(SETTINGS, wait_for_map=True, neighbor_timeout=2.0)
    agent = PlannerAgent('self', CONFIG, settings, np.array([2.0, 4.5]))
    agent.map_pending = True
    agent.receive_own(Odometry(0.0, np.array([2.0, 1.5]), np.zeros(2), 1e-4 * np.eye(4)),
                      10.0)
    # Waited for as a map not yet arrived is; then held for, by zero commands, not planned
    # without (the robot would head into the walls of the map coming) nor left unanswered.
    assert agent.awaiting_listed(10.5) and not agent.ready(10.5)
    assert agent.ready(12.5)
    command = agent.plan()
    assert command.awaiting_map and command.result is None
    np.testing.assert_array_equal(command.velocity, [0.0, 0.0])
    agent.set_map(walled_room())
    assert not agent.awaiting_map
    agent.receive_own(Odometry(0.1, np.array([2.0, 1.5]), np.zeros(2), 1e-4 * np.eye(4)),
                      12.6)
    command = agent.plan()
    assert not command.awaiting_map and np.linalg.norm(command.velocity) > 0.0


def test_the_carrot_moves_on_to_the_farthest_waypoint_in_sight():
    route = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [8.0, 4.0]])
    position = np.array([1.0, 0.5])
    everything = route_preferred_velocity(position, route[-1], route, 0, 1.0, 1.0, 0.5, 0.2,
                                          in_sight=lambda a, b: True)[0]
    np.testing.assert_allclose(everything / np.linalg.norm(everything),
                               (route[-1] - position) / np.linalg.norm(route[-1] - position))
    # The corner (4, 0) in sight, the next one not: head for the corner.
    corner = route_preferred_velocity(position, route[-1], route, 0, 1.0, 1.0, 0.5, 0.2,
                                      in_sight=lambda a, b: b[1] < 1.0)[0]
    np.testing.assert_allclose(corner / np.linalg.norm(corner),
                               (route[1] - position) / np.linalg.norm(route[1] - position))
    # Nothing in sight beyond the lookahead: the carrot 1 m ahead (the circle meets the route
    # at x = 1 + sqrt(0.75)).
    near = route_preferred_velocity(position, route[-1], route, 0, 1.0, 1.0, 0.5, 0.2,
                                    in_sight=lambda a, b: np.hypot(*(b - a)) <= 1.0 + 1e-9)[0]
    carrot_point = np.array([1.0 + np.sqrt(0.75), 0.0])
    np.testing.assert_allclose(near / np.linalg.norm(near),
                               (carrot_point - position) / np.linalg.norm(carrot_point - position))


def block_room():
    """Return an 8 m x 6 m room, empty but for a 0.6 m block from (2.0, 2.0) to (2.6, 2.6)."""
    cells = np.zeros((60, 80), dtype=np.int8)
    cells[20:26, 20:26] = 100
    return GridMap(cells, RESOLUTION, [0.0, 0.0])


def test_a_robot_inside_an_obstacle_on_its_map_says_so_and_leaves_by_the_nearest_free_cell():
    """A map marking the robot's own cells: it was holding, infeasible, forever (issue 36)."""
    grid = block_room()
    start = np.array([2.25, 2.32])
    agent = PlannerAgent('robot_0', CONFIG, SETTINGS, goal=np.array([6.0, 2.3]))
    agent.set_map(grid)
    agent.receive_own(Odometry(0.0, start, np.zeros(2), 1e-4 * np.eye(4)), 0.0)
    command = agent.plan()
    # The nearest free cell, by brute force over every cell: the one left of x = 2.0.
    rows, columns = np.nonzero(grid.cells == 0)
    centres = RESOLUTION * (np.stack([columns, rows], axis=1) + 0.5)
    nearest = centres[np.argmin(np.hypot(*(centres - start).T))]
    position, exit_point = command.inside_obstacle
    np.testing.assert_array_equal(position, start)
    np.testing.assert_allclose(exit_point, nearest)
    assert np.dot(command.velocity, nearest - start) > 0.0 and command.result.feasible
    status = plan_status('robot_0', command, 1.0, 'prvo', 0.3)
    assert status.level == status.WARN and status.message.startswith(
        'the robot is inside an obstacle on the map at (2.25, 2.32): leaving it by the nearest '
        f'free cell, ({nearest[0]:.2f}, {nearest[1]:.2f})')
    # Out of the block it follows its route to the goal, as any robot.
    positions, command = drive(agent, start, 200, t0=0.1)
    assert command.arrived and command.inside_obstacle is None
    assert not any(occupied_at(grid.cells != 0, RESOLUTION, grid.origin, point)
                   for point in positions[10:])


def test_the_way_out_is_none_beyond_reach_and_a_free_cell_is_not_inside():
    cells = np.ones((40, 40), dtype=bool)
    cells[:, :2] = False
    origin = np.zeros(2)
    assert not occupied_at(cells, RESOLUTION, origin, [0.1, 2.0])
    assert not occupied_at(cells, RESOLUTION, origin, [-1.0, 2.0])
    assert occupied_at(cells, RESOLUTION, origin, [3.0, 2.0])
    np.testing.assert_allclose(way_out(cells, RESOLUTION, origin, [3.0, 2.02], 3.0), [0.15, 2.05])
    assert way_out(cells, RESOLUTION, origin, [3.0, 2.0], 2.0) is None


def test_a_filter_inside_an_obstacle_passes_its_controller_s_command_on():
    """The controller's command is its way out: a filter does not replace it by its own."""
    from prvo_planner.preferred import UpstreamCommand

    agent = PlannerAgent('robot_0', CONFIG, dataclasses.replace(
        SETTINGS, preferred_source='velocity'))
    agent.set_map(block_room())
    agent.receive_own(Odometry(0.0, np.array([2.25, 2.32]), np.zeros(2),
                                  1e-4 * np.eye(4)), 0.0)
    agent.receive_upstream(UpstreamCommand((0.0, 0.4), 0.0), 0.0)
    command = agent.plan()
    assert command.inside_obstacle is not None and command.passed_through
    np.testing.assert_array_equal(command.velocity, [0.0, 0.4])


def door_room():
    """Two rooms 6 x 4 m, a wall 0.1 m thick at x = 3 with a 1.2 m door about y = 2."""
    cells = np.zeros((80, 120), dtype=np.int8)
    cells[[0, -1], :] = 100
    cells[:, [0, -1]] = 100
    cells[:, 59:61] = 100
    cells[28:52, 59:61] = 0
    return GridMap(cells, 0.05, [0.0, 0.0])


def test_a_neighbour_standing_in_the_door_is_named_once_it_claims_nothing():
    # 'broken' stands in the door on its way west: the robot bound east waits for it until
    # it has stood there IDLE_INSIDE, then goes, its status naming the neighbour.
    agent = PlannerAgent('self', CONFIG, dataclasses.replace(SETTINGS, radius=0.25),
                         np.array([5.0, 2.0]))
    agent.set_map(door_room())
    agent.receive_route('broken', np.array([[3.0, 2.0], [1.0, 2.0]]), 0.0)
    idle, goes = [], []
    for step in range(int(IDLE_INSIDE / 0.1) + 5):
        stamp = round(0.1 * step, 9)
        agent.receive_neighbour('broken', Odometry(stamp, np.array([3.0, 2.0]), np.zeros(2),
                                                      1e-4 * np.eye(4)), 0.0)
        command = stand(agent, [1.0, 2.0], 1, t0=stamp)
        idle.append(command.idle_in_passage)
        goes.append(command.right_of_way.goes)
    settled = int(IDLE_INSIDE / 0.1) + 1
    assert set(idle[:settled]) == {()} and set(idle[settled:]) == {('broken',)}
    assert not any(goes[:settled]) and all(goes[settled:])
    status = plan_status('self', command, 1.0, 'prvo', 0.25)
    assert diagnostic_values(status)['idle_in_passage'] == 'broken'
    assert 'neighbour broken stood in a passage' in status.message


def test_at_a_passage_its_order_leads_and_the_robot_does_not_keep_right():
    # Bound east through the door, 0.2 m below its middle, a robot meets one coming west in
    # the far room (it publishes no route: it claims nothing). In open space it would lean
    # right (test_lanes); here it heads for the door's middle, as the right of way aims it.
    settings = dataclasses.replace(SETTINGS, radius=0.25)
    position = np.array([2.0, 1.8])
    preferences = {}
    for keep_right in (0.0, 0.3):
        agent = PlannerAgent('self', CONFIG, dataclasses.replace(settings, keep_right=keep_right),
                             np.array([5.0, 2.0]))
        agent.set_map(door_room())
        for step in range(3):
            stamp = round(0.1 * step, 9)
            agent.receive_neighbour('coming', Odometry(
                stamp, np.array([5.0 - 0.1 * step, 2.0]), np.array([-1.0, 0.0]),
                1e-4 * np.eye(4)), 0.0)
            agent.receive_own(Odometry(stamp, position, np.zeros(2), 1e-4 * np.eye(4)), 0.0)
            request = agent.plan_request()
        assert agent.passage_decision is not None and agent.passage_decision.goes
        preferences[keep_right] = request.problem[2]
    np.testing.assert_allclose(preferences[0.3], preferences[0.0], atol=1e-12)
    # It heads up toward the middle (y = 2) of the door, not down along the wall on its right.
    assert preferences[0.3][1] > 0.0


def test_a_robot_waiting_where_no_spot_fits_says_so_and_holds_its_place(monkeypatch):
    # The door's west end without waiting spots (as where the room beside it is too small):
    # the robot bound east waits for 'other', inside going west, where it is, and says so.
    def without_west_spots(*args, **kwargs):
        return tuple(dataclasses.replace(passage, ends=(
            dataclasses.replace(passage.ends[0], waiting_spot=None), *passage.ends[1:]))
            for passage in narrows.find_passages(*args, **kwargs))

    monkeypatch.setattr(agent_module, 'find_passages', without_west_spots)
    agent = PlannerAgent('self', CONFIG, dataclasses.replace(SETTINGS, radius=0.25),
                         np.array([5.0, 2.0]))
    agent.set_map(door_room())
    agent.receive_route('other', np.array([[3.0, 2.0], [1.0, 2.0]]), 0.0)
    position = np.array([1.5, 2.0])
    for step in range(3):
        stamp = round(0.1 * step, 9)
        agent.receive_neighbour('other', Odometry(stamp, np.array([3.0, 2.0]), np.zeros(2),
                                                     1e-4 * np.eye(4)), 0.0)
        agent.receive_own(Odometry(stamp, position, np.zeros(2), 1e-4 * np.eye(4)), 0.0)
        request = agent.plan_request()
    decision = agent.passage_decision
    west = agent.passage_map.passages[0].ends[0]
    assert not decision.goes and decision.without_spot and decision.waiting_spot is None
    np.testing.assert_array_equal(decision.entrance, west.entrance)
    np.testing.assert_array_equal(request.problem[2], np.zeros(2))
    agent.receive_own(Odometry(0.3, position, np.zeros(2), 1e-4 * np.eye(4)), 0.0)
    command = agent.plan()
    status = plan_status('self', command, 1.0, 'prvo', 0.25)
    assert (f'self waits at passage 0, whose end at ({west.entrance[0]:.2f}, '
            f'{west.entrance[1]:.2f}) has no waiting spot') in status.message
    assert 'it holds its place' in status.message


def test_a_neighbour_waiting_at_the_door_before_the_robot_came_goes_first():
    # 'waiter' stands at the west end's waiting spot, bound east, from t = 0. 'self' stays in
    # the east room until t = 5, then heads west, and comes nearer the door than the waiter's
    # way to it: first come, first served, it waits (it watched the waiter come, though it
    # used no passage then).
    agent = PlannerAgent('self', CONFIG, dataclasses.replace(SETTINGS, radius=0.25),
                         np.array([5.0, 3.5]))
    agent.set_map(door_room())
    west, east = agent.passage_map.passages[0].ends
    spot = west.waiting_spot
    agent.receive_route('waiter', np.array([spot, west.entrance, [5.0, 2.0]]), 0.0)
    position = east.entrance + [1.0, 0.0]
    decisions = []
    for step in range(60):
        stamp = round(0.1 * step, 9)
        if stamp == 5.0:
            agent.set_goal(np.array([1.0, 2.0]))
        agent.receive_neighbour('waiter', Odometry(stamp, spot, np.zeros(2),
                                                      1e-4 * np.eye(4)), 0.0)
        agent.receive_own(Odometry(stamp, position, np.zeros(2), 1e-4 * np.eye(4)), 0.0)
        agent.plan_request()
        decisions.append(agent.passage_decision)
    assert all(decision is None for decision in decisions[:50])
    mine = decisions[-1]
    assert mine.use.entry == 1 and not mine.goes


def two_door_room():
    """Two rooms 6 x 4 m, a wall 0.1 m thick at x = 3, 1.2 m doors about y = 0.9 and 3.1."""
    cells = np.zeros((80, 120), dtype=np.int8)
    cells[[0, -1], :] = 100
    cells[:, [0, -1]] = 100
    cells[:, 59:61] = 100
    cells[6:30, 59:61] = 0
    cells[50:74, 59:61] = 0
    return GridMap(cells, 0.05, [0.0, 0.0])


def _kept_waiting(search_here, install):
    """Run the robot of the test below; return its decisions and routes (each step's)."""
    agent = PlannerAgent('self', CONFIG, dataclasses.replace(SETTINGS, radius=0.25),
                         np.array([5.0, 0.9]))
    agent.search_ways_round = search_here
    agent.set_map(two_door_room())
    agent.receive_route('broken', np.array([[3.0, 0.9], [1.0, 0.9]]), 0.0)
    routes, decisions, wanted = [], [], []
    for step in range(40):
        stamp = round(0.1 * step, 9)
        agent.receive_neighbour('broken', Odometry(stamp, np.array([3.0, 0.9]), np.zeros(2),
                                                      1e-4 * np.eye(4)), 0.0)
        command = stand(agent, [1.6, 0.9], 1, t0=stamp)
        routes.append(command.route)
        decisions.append(agent.passage_decision)
        wanted.append(agent.way_round_wanted)
        if install and wanted[-1] is not None:
            # Searched elsewhere (a node's map worker) before the next plan.
            assert agent.install_way_round(wanted[-1], way_round(*wanted[-1]))
    return agent, decisions, routes, wanted


def test_a_robot_kept_waiting_at_one_door_goes_round_by_the_other():
    # 'broken' stands in the lower door on its way west: the robot bound east waits for it as
    # long as the way by the upper door adds at full speed (about 1.4 m: 1.4 s), then takes
    # that way, long before the neighbour stops claiming the door (IDLE_INSIDE).
    agent, decisions, routes, wanted = _kept_waiting(True, False)
    lower = int(agent.passage_map.passage_at(np.array([[3.0, 0.9]]))[0])
    assert decisions[0].use.passage == lower and not decisions[0].goes
    assert not any(wanted)
    way_round = [step for step, decision in enumerate(decisions)
                 if decision is not None and decision.use.passage != lower]
    assert way_round and 10 <= way_round[0] <= 25
    # From then on its route keeps out of the lower door and goes through the upper one, where
    # nobody comes: it goes.
    for route in routes[way_round[0]:]:
        points = np.concatenate([np.linspace(a, b, 40)
                                 for a, b in zip(route[:-1], route[1:], strict=True)])
        assert (agent.passage_map.passage_at(points) != lower).all()
        assert max(points[:, 1]) > 2.5
    assert decisions[-1].goes
    # Searched elsewhere and handed over before the next plan, the same way round at the same
    # step; never handed over, the robot waits and keeps asking for it.
    _, elsewhere, elsewhere_routes, asked = _kept_waiting(False, True)
    assert [str(decision) for decision in elsewhere] == [str(decision) for decision in decisions]
    for route, other in zip(routes, elsewhere_routes, strict=True):
        np.testing.assert_array_equal(route, other)
    assert asked[0][0] == {lower} and not any(asked[1:])
    _, waiting, _, asked = _kept_waiting(False, False)
    assert all(decision.use.passage == lower and not decision.goes for decision in waiting)
    assert all(wanted[0] == {lower} for wanted in asked)
