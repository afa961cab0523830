"""A planner node reads and builds its map beside its plans: no plan waits for it or sees half.

A PlannerNode runs in this process (its own ROS domain); its callbacks are called directly.
The map's read and build are held on events the test releases, so that "the callback returned
while the map was still being read or built" is shown by the order of events, never by a clock.
"""

import threading

import numpy as np
import pytest
from rclpy.parameter import Parameter
from rclpy.serialization import serialize_message

from prvo_msgs_util import make_occupancy_grid, make_odometry, occupancy_grid_to_parts
from prvo_planner import planner_node as planner_node_module
from prvo_planner.agent import build_map
from prvo_planner.detours import way_round
from prvo_planner.maps import GridMap
from prvo_planner.reports import AWAITING_MAP
from prvo_planner.right_of_way import Decision

COVARIANCE = 1e-6 * np.eye(2)
WAIT = 30.0


def _room(wall_row):
    """Return the cells of a 6 m x 6 m room (0.1 m cells) with a wall along row WALL_ROW."""
    cells = np.zeros((60, 60), dtype=np.int8)
    cells[wall_row, 10:50] = 100
    return cells


class HeldBuilds:
    """`build_map` made to wait for `release` (each build in turn), counting the builds."""

    def __init__(self):
        self.release = threading.Event()
        self.started = threading.Event()
        self.grids = []

    def __call__(self, grid, built_for, goal=None):
        self.grids.append(grid)
        self.started.set()
        assert self.release.wait(WAIT), 'the test never released the build'
        return build_map(grid, built_for, goal)


@pytest.fixture
def held(monkeypatch):
    builds = HeldBuilds()
    monkeypatch.setattr(planner_node_module, 'build_map', builds)
    yield builds
    # Never leave a worker waiting.
    builds.release.set()


@pytest.fixture
def map_node(ros_domain):
    """Yield a PlannerNode in /robot_0 heading for (3, 5) that waits for the map."""
    import rclpy

    from prvo_planner.planner_node import PlannerNode

    rclpy.init(domain_id=ros_domain, args=[
        '--ros-args', '-r', '__ns:=/robot_0', '-p', 'goal:=[3.0, 5.0]', '-p', 'neighbors:=[""]',
        '-p', 'wait_for_map:=true', '-p', 'neighbor_timeout:=0.01', '-p', 'status_period:=0.0'])
    node = PlannerNode()
    yield node
    node.destroy_node()
    rclpy.try_shutdown()


def _spin_until(node, condition):
    import rclpy

    for _ in range(int(WAIT / 0.01)):
        if condition():
            return
        rclpy.spin_once(node, timeout_sec=0.01)
    raise AssertionError('timed out')


def _send_map(node, wall_row):
    """Hand NODE's map callback the serialized room with a wall along row WALL_ROW."""
    node._on_map(serialize_message(make_occupancy_grid(0.0, _room(wall_row), 0.1, [0.0, 0.0])))


def _own_odometry(node, stamp, position=(3.0, 1.0)):
    node._on_own_odometry(serialize_message(make_odometry(
        stamp, position, [0.0, 0.0], COVARIANCE, COVARIANCE,
        child_frame_id='robot_0/base_link')))


def test_the_map_callback_returns_while_the_map_is_built_and_the_robot_holds_saying_so(
        map_node, held, monkeypatch):
    node, agent = map_node, map_node._agent
    commands, warnings, statuses = [], [], []
    monkeypatch.setattr(node._commands, 'publish',
                        lambda message, announced: commands.append(message))
    monkeypatch.setattr(node.get_logger(), 'warning', warnings.append)
    monkeypatch.setattr(node._reporter.diagnostics_publisher, 'publish',
                        lambda array: statuses.append(array.status[0]))
    _send_map(node, 30)
    # The worker reads the message; the next look at it has the map built, in another thread.
    _spin_until(node, held.started.is_set)
    assert agent.grid_map is None and agent.map_pending and agent.awaiting_map
    # With wait_for_map the first plan waits neighbor_timeout for the map, as for neighbours;
    # then, the map still being built, each odometry is answered by zero, and the log says so
    # once (the status at every plan).
    _own_odometry(node, 0.1)
    _spin_until(node, lambda: commands)
    for stamp in (0.2, 0.3):
        _own_odometry(node, stamp)
    assert len(commands) == 3 and agent.tally.plans == 0
    assert all(message.twist.linear.x == message.twist.linear.y == 0.0 for message in commands)
    assert [message.header.stamp.nanosec for message in commands] == [1e8, 2e8, 3e8]
    assert warnings == [AWAITING_MAP]
    assert [status.message for status in statuses] == [AWAITING_MAP] * 3
    assert {value.value for status in statuses for value in status.values
            if value.key == 'awaiting_map'} == {'true'}
    held.release.set()
    _spin_until(node, lambda: agent.grid_map is not None)
    assert not agent.map_pending and not agent.awaiting_map
    _own_odometry(node, 0.4)
    assert len(commands) == 4 and agent.tally.plans == 1
    assert np.linalg.norm([commands[-1].twist.linear.x, commands[-1].twist.linear.y]) > 0.0
    assert warnings == [AWAITING_MAP]


def test_plans_go_on_with_the_map_in_force_until_the_new_one_is_built(map_node, held):
    node, agent = map_node, map_node._agent
    held.release.set()
    _send_map(node, 30)
    _spin_until(node, lambda: agent.grid_map is not None)
    in_force = agent.grid_map
    held.release.clear()
    held.started.clear()
    _send_map(node, 40)
    _spin_until(node, held.started.is_set)
    for stamp in (0.1, 0.2):
        _own_odometry(node, stamp)
        assert agent.pending_stamp is None, 'planned on the map in force'
        assert agent.grid_map is in_force
    held.release.set()
    _spin_until(node, lambda: agent.grid_map is not in_force)
    assert np.array_equal(agent.grid_map.cells, _room(40))
    # A map equal to the one in force is not built again.
    builds = len(held.grids)
    _send_map(node, 40)
    _spin_until(node, lambda: not node._map_reads)
    assert len(held.grids) == builds and node._map_build is None


def test_a_map_message_is_read_beside_the_plans_and_a_bad_one_named(map_node, held,
                                                                     monkeypatch):
    # A 4000 x 4000 grid takes as long to deserialize and check as a control period: the
    # callback only hands the bytes on, and the worker reads them while the plans go on.
    node, agent = map_node, map_node._agent
    held.release.set()
    _send_map(node, 30)
    _spin_until(node, lambda: agent.grid_map is not None)
    in_force = agent.grid_map
    reading, release, readers = threading.Event(), threading.Event(), []

    def held_read(msg, expected_frame):
        readers.append(threading.current_thread())
        reading.set()
        assert release.wait(WAIT), 'the test never released the read'
        return occupancy_grid_to_parts(msg, expected_frame=expected_frame)

    monkeypatch.setattr(planner_node_module, 'occupancy_grid_to_parts', held_read)
    try:
        _send_map(node, 40)
        # Returned with the message still being read, on the worker's thread.
        assert reading.wait(WAIT) and readers == [node._map_builder._thread]
        for stamp in (0.1, 0.2):
            _own_odometry(node, stamp)
            assert agent.pending_stamp is None, 'planned on the map in force'
        assert agent.tally.plans == 2 and agent.grid_map is in_force
    finally:
        release.set()
    _spin_until(node, lambda: agent.grid_map is not in_force)
    assert np.array_equal(agent.grid_map.cells, _room(40))
    # A bad map read on the worker is named as before, once, and the map in force is kept.
    warned = []
    monkeypatch.setattr(node._warnings, 'warn', lambda key, text: warned.append(text))
    in_force = agent.grid_map
    node._on_map(serialize_message(make_occupancy_grid(0.0, _room(30), 0.1, [0.0, 0.0],
                                                       frame_id='odom')))
    _spin_until(node, lambda: not node._map_reads)
    assert warned == ["ignoring map on /map (keeping the map in force): header.frame_id is "
                      "'odom', expected 'map'"]
    assert agent.grid_map is in_force and not agent.map_pending and node._map_build is None


def test_new_settings_rebuild_the_map_beside_the_plans(map_node, held):
    node, agent = map_node, map_node._agent
    held.release.set()
    _send_map(node, 30)
    _spin_until(node, lambda: agent.grid_map is not None)
    before = agent.map_key
    held.release.clear()
    held.started.clear()
    node.set_parameters([Parameter('obstacle_distance', Parameter.Type.DOUBLE, 1.0)])
    assert held.started.wait(WAIT)
    # The parameter callback returned; the map made for the settings before is in force.
    assert agent.map_outdated and agent._map_built_for == before
    _own_odometry(node, 0.1)
    assert agent.pending_stamp is None
    held.release.set()
    _spin_until(node, lambda: not agent.map_outdated)
    assert agent.map_key[1] == 1.0


def test_a_built_map_plans_as_one_built_in_place():
    """The worker's result is what `set_map` makes: same obstacles, same route."""
    from prvo_planner.agent import AgentSettings, PlannerAgent
    from prvo_planner.core import PlannerConfig

    grid = GridMap(_room(30), 0.1, [0.0, 0.0])
    here = PlannerAgent('robot_0', PlannerConfig(), AgentSettings(), [3.0, 5.0])
    there = PlannerAgent('robot_0', PlannerConfig(), AgentSettings(), [3.0, 5.0])
    here.set_map(grid)
    there.install_map(build_map(grid, there.map_key, there.route_goal()))
    routes = [agent._route_at(np.array([3.0, 1.0]), 1.0) for agent in (here, there)]
    np.testing.assert_array_equal(*routes)
    assert routes[0][:, 0].min() < 1.0 or routes[0][:, 0].max() > 5.0  # round the wall
    near = [agent._obstacle_index.near(np.array([3.0, 2.5]), 1.0).segments
            for agent in (here, there)]
    np.testing.assert_array_equal(*near)


def test_a_new_goal_waits_for_its_ways_while_the_goal_before_holds(map_node, held):
    node, agent = map_node, map_node._agent
    held.release.set()
    _send_map(node, 30)
    _spin_until(node, lambda: agent.grid_map is not None)
    searching, release = threading.Event(), threading.Event()
    search = agent.route_map.tree_to

    def held_search(goal):
        searching.set()
        assert release.wait(WAIT), 'the test never released the search'
        return search(goal)

    agent.route_map.tree_to = held_search
    try:
        node.set_parameters([Parameter('goal', Parameter.Type.DOUBLE_ARRAY, [1.0, 5.0])])
        assert searching.wait(WAIT)
        # The parameter callback returned while the ways are searched; the goal before holds
        # and the plans go on toward it.
        np.testing.assert_array_equal(agent.goal, [3.0, 5.0])
        _own_odometry(node, 0.1)
        assert agent.pending_stamp is None
    finally:
        release.set()
    _spin_until(node, lambda: np.array_equal(agent.goal, [1.0, 5.0]))
    tree = agent._route_tree
    assert tree is not None and np.array_equal(tree.goal, [1.0, 5.0])
    _own_odometry(node, 0.2)
    # The plan took the ways the worker searched: it did not search again.
    assert agent.pending_stamp is None and agent._route_tree is tree


def _waiting_at_a_passage(node, held, position):
    """Give NODE its map and make its robot at POSITION (2,) wait at the passage on its route.

    Return the robot's `PassageUse`. Its plan then wants the way round, and does not search it.
    """
    agent = node._agent
    held.release.set()
    # A wall across the room leaves a gap 1 m wide at each end: two passages, one way round the
    # other.
    _send_map(node, 30)
    _spin_until(node, lambda: agent.grid_map is not None)
    assert len(agent.passage_map.passages) == 2
    _own_odometry(node, 0.1)
    use = agent.passage_map.use_of('robot_0', position, agent._route)
    end = agent.passage_map.passages[use.passage].ends[use.entry]
    # As a neighbour coming through would make it.
    agent._detours.update(0.1, Decision(use, False, end.waiting_spot, None, end.entrance),
                          position, 4.0, 1.0, agent.route_map, agent.passage_map, agent.goal,
                          search=agent.search_ways_round)
    return use


def test_a_way_round_a_passage_is_searched_beside_the_plans(map_node, held, monkeypatch):
    node, agent = map_node, map_node._agent
    position = np.array([3.0, 1.0])
    use = _waiting_at_a_passage(node, held, position)
    wanted = agent.way_round_wanted
    assert wanted is not None and wanted[0] == {use.passage}
    searching, release = threading.Event(), threading.Event()

    def held_way_round(*arguments):
        searching.set()
        assert release.wait(WAIT), 'the test never released the search'
        return way_round(*arguments)

    monkeypatch.setattr(planner_node_module, 'way_round', held_way_round)
    try:
        _own_odometry(node, 0.2)
        # The plan callback handed the search to the worker and returned while it runs.
        assert searching.wait(WAIT)
        assert agent.pending_stamp is None and agent.way_round_wanted is not None
    finally:
        release.set()
    _spin_until(node, lambda: agent.way_round_wanted is None)
    tree = agent._detours._trees[wanted[0]]
    route = tree.route_from(position)
    np.testing.assert_array_equal(route, way_round(*wanted).route_from(position))
    points = np.concatenate([np.linspace(a, b, 40)
                             for a, b in zip(route[:-1], route[1:], strict=True)])
    assert (agent.passage_map.passage_at(points) != use.passage).all()


def test_a_way_round_that_cannot_be_searched_is_none_and_asked_for_no_more(map_node, held,
                                                                           monkeypatch):
    node, agent = map_node, map_node._agent
    use = _waiting_at_a_passage(node, held, np.array([3.0, 1.0]))
    warnings = []
    monkeypatch.setattr(node.get_logger(), 'warning', warnings.append)

    def failing(*arguments):
        raise MemoryError('no room for the search')

    monkeypatch.setattr(planner_node_module, 'way_round', failing)
    _own_odometry(node, 0.2)
    _spin_until(node, lambda: agent.way_round_wanted is None)
    assert agent._detours._trees[frozenset({use.passage})] is None
    assert any('cannot search a way round a passage' in warning for warning in warnings)
