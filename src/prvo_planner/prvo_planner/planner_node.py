"""Per-robot PRVO planner node: neighbour odometry in, chance-constrained `cmd_vel` out.

Run one per robot, in the robot's namespace:

    ros2 run prvo_planner planner --ros-args -r __ns:=/robot_0 -p goal:="[4.0, 0.0]"

The node is a thin shell around `prvo_planner.agent.PlannerAgent`: it declares parameters,
converts messages through prvo_msgs_util, feeds the agent, waits at most `sync_timeout` for
neighbours and publishes the agent's commands and its announcements (footprint, share). With
an occupancy grid on `map_topic` (latched, as map_server publishes it) it plans against the
grid's obstacles. Heading for a goal, it publishes the way it means to take on `<robot>/plan`
(`prvo_planner.routes.RouteIntent`: its route on the map, else the straight way), and it reads
its neighbours' on theirs.
"""

import collections
import concurrent.futures
import dataclasses
import importlib
import sys
import threading
import time

from geometry_msgs.msg import PointStamped, PoseStamped, Twist, TwistStamped
from nav_msgs.msg import OccupancyGrid, Odometry, Path
import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.impl.implementation_singleton import rclpy_implementation
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message

from prvo_msgs_util import (
    CMD_VEL,
    CMD_VEL_QOS,
    GOAL_POSE,
    GOAL_QOS,
    MAP_QOS,
    ODOM_LATEST_QOS,
    PLAN,
    PLAN_QOS,
    Announcer,
    CommandsAfterAnnouncements,
    MessageFault,
    QosWatch,
    SerializedPathReader,
    ThrottledWarnings,
    declare_parameters,
    filtered_twist,
    make_path,
    make_point_stamped,
    occupancy_grid_to_parts,
    parameter_descriptor,
    pose_stamped_to_goal,
    quiet_after_shutdown,
    quiet_publisher_events,
    quiet_subscription_events,
    robot_topic,
    robots_with_topic,
    run_node,
    serialized_odometry_to_measurement,
    stamp_to_seconds,
    subscribe_announcements,
    subscribe_route,
    twist_components,
    world_to_body,
)
from prvo_planner.agent import (
    DEPARTURE_TOLERANCES,
    ROUTE_UNREACHABLE,
    AgentSettings,
    PlannerAgent,
    build_map,
    same_grid,
)
from prvo_planner.background import BackgroundWorker
from prvo_planner.detours import way_round
from prvo_planner.heap import keep_freed_heap
from prvo_planner.maps import GridMap, MapTooLargeError
from prvo_planner.parameters import (
    PARAMETERS,
    ParameterError,
    check_parameter_update,
    checked_parameters,
    goal_array,
    is_dumped_unset,
    neighbour_names,
    planner_config_from,
)
from prvo_planner.preferred import GOAL, PATH, VELOCITY, UpstreamCommand
from prvo_planner.reports import (
    AWAITING_MAP,
    PlanReporter,
    command_message,
    idle_message,
    inside_message,
    no_spot_message,
    passage_message,
)
from prvo_planner.routes import RouteIntent, route_stamp
from prvo_planner.stalls import STALL_WINDOW

RCLError = rclpy_implementation.RCLError
_WARN_PERIOD_SECONDS = 2.0
_ODOMETRY_TYPE = 'nav_msgs/msg/Odometry'
_TWIST_TYPES = {Twist: 'geometry_msgs/msg/Twist', TwistStamped: 'geometry_msgs/msg/TwistStamped'}
LOOKAHEAD_POINT = 'lookahead_point'
# How often [s, wall] a map being built is looked at: the plans go on meanwhile.
MAP_POLL_PERIOD = 0.02
# name: (default, descriptor), in declaration order. A parameter without a default (goal,
# neighbors) is dynamically typed, so that it can stay unset and take integers as well as
# doubles; its rules are checked on every set.
_PARAMETERS = {name: (spec.default, parameter_descriptor(
    spec.description, spec.kind, spec.bounds, spec.read_only,
    dynamic_typing=spec.default is None)) for name, spec in PARAMETERS.items()}


@dataclasses.dataclass(frozen=True)
class _MapBuild:
    """What the worker makes: a `BuiltMap`, the ways to a goal or round a passage (`RouteTree`).

    `future` gives it; `grid` is what it is made of (the `GridMap`, the goal (2,), or the
    agent's `way_round_wanted`), `started` when it began [s, monotonic].
    """

    future: concurrent.futures.Future
    grid: object
    started: float


class PlannerNode(Node):
    """PRVO planner of one robot: feeds a `PlannerAgent` odometry, publishes its `cmd_vel`."""

    def __init__(self):
        super().__init__('planner')
        try:
            self._declare_parameters()
        except (ParameterError, InvalidParameterTypeException,
                InvalidParameterValueException) as error:
            # Logged here, under the node's logger: the caller has no node to name.
            self.get_logger().fatal(f'invalid parameter: {error}')
            raise
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self._agent = PlannerAgent(
            self._robot, self._config, AgentSettings.from_parameters(self._values),
            self._goal if self._values['preferred_source'] == GOAL else None,
            self._neighbours_listed)
        # A way round a passage is searched by the map worker too, never in a plan.
        self._agent.search_ways_round = False
        self._steady_clock = Clock(clock_type=ClockType.STEADY_TIME)
        self._neighbour_subscriptions = {}
        self._last_command = None
        self._last_command_stamp = None
        # The stamp whose command was re-sent: once per stamp is enough for a lost answer.
        self._resent_stamp = None
        # Whether the log said the robot holds for its map (`AWAITING_MAP`) in this wait.
        self._told_awaiting_map = False
        self._warnings = ThrottledWarnings(self.get_logger(), _WARN_PERIOD_SECONDS)

        self._source = self._values['preferred_source']
        filtering = self._source == VELOCITY
        self._stamped = self._values[
            'enable_stamped_cmd_vel' if filtering else 'stamped_cmd_vel']
        self._twist_type = TwistStamped if self._stamped else Twist
        # Endpoints without rclpy's QoS event handlers (each would cost every executor wake-up);
        # the watch reports incompatible QoS from the graph instead.
        self._qos_watch = QosWatch(self)
        self._cmd_vel_topic = self._values['cmd_vel_out_topic'] if filtering else CMD_VEL
        self._cmd_vel_publisher = self.create_publisher(
            self._twist_type, self._cmd_vel_topic, CMD_VEL_QOS,
            event_callbacks=quiet_publisher_events())
        self._reporter = PlanReporter(self, self._robot)
        # The process's CPU time [s] at the plan before (`PlanReporter`'s node CPU), None before
        # the first.
        self._process_cpu = None
        # The passage ends without a waiting spot this robot has waited at (reported once).
        self._ends_without_spot = set()
        self._announcer = Announcer(self, self._robot)
        self._announce()
        self._commands = CommandsAfterAnnouncements(
            self, self._cmd_vel_publisher, self._steady_clock,
            lambda text: self._warnings.warn('acknowledgement', text))
        self._state_topic = self._values['state_topic']
        self._own_odom_topic = robot_topic(self._robot, self._state_topic)
        # Odometry arrives serialized (raw): eight messages a step in an 8-robot team, and
        # reading the few fields needed from the bytes costs a fraction of deserializing them.
        own_odometry = self.create_subscription(
            Odometry, self._state_topic, self._on_own_odometry, ODOM_LATEST_QOS,
            event_callbacks=quiet_subscription_events(), raw=True)
        self._qos_watch.watch(
            self._cmd_vel_publisher, self._reporter.diagnostics_publisher,
            self._reporter.marker_publisher, self._announcer.footprint_publisher,
            self._announcer.share_publisher, own_odometry, *self._source_endpoints(),
            *self._map_endpoints())

        # Wall-clock timers: under use_sim_time sim time waits for us and would never fire them.
        self._sync_timer = self.create_timer(
            max(self._values['sync_timeout'], 1e-3), self._on_sync_timeout,
            clock=self._steady_clock, autostart=False)
        self.create_timer(0.5, self._maintain_neighbours, clock=self._steady_clock)
        self._maintain_neighbours()
        self.get_logger().info(
            f'planning for {self._robot}: model={self._config.model} '
            f'method={self._config.method} k={self._config.effective_k:.3f} '
            f'preferred_source={self._source} '
            f'goal={None if self._agent.goal is None else self._agent.goal.tolist()}')

    def destroy_node(self):
        """Destroy the node; a map being built is let go (its thread ends with it)."""
        self._map_builder.shutdown()
        super().destroy_node()

    def _source_endpoints(self):
        """Create the endpoints of the preferred velocity's source; return them.

        goal: goal_pose; path: path_topic and the carrot on lookahead_point; velocity: the
        upstream command on cmd_vel_in_topic (answered on cmd_vel_out_topic).
        """
        quiet = quiet_subscription_events
        self._lookahead_publisher = None
        if self._source == GOAL:
            return [self.create_subscription(PoseStamped, GOAL_POSE, self._on_goal_pose,
                                             GOAL_QOS, event_callbacks=quiet())]
        if self._source == PATH:
            self._lookahead_publisher = self.create_publisher(
                PointStamped, LOOKAHEAD_POINT, CMD_VEL_QOS,
                event_callbacks=quiet_publisher_events())
            # Serialized (raw): a path's length is read before its poses, and the same path
            # again is one comparison of bytes (`SerializedPathReader`).
            self._path_reader = SerializedPathReader(self._values['frame_id'])
            return [self._subscribe_parameter_topic('path_topic', Path, self._on_path, GOAL_QOS,
                                                    raw=True),
                    self._lookahead_publisher]
        return [self.create_subscription(
            self._twist_type, self._values['cmd_vel_in_topic'], self._on_upstream, CMD_VEL_QOS,
            event_callbacks=quiet())]

    def _subscribe_parameter_topic(self, parameter, msg_type, callback, qos, raw=False):
        """Subscribe to the topic PARAMETER names; return the subscription.

        A topic the node itself has an endpoint of with another type (the planner's own
        odometry, say) raises ParameterError, logged: rcl cannot subscribe with another type to
        a topic of the process's own, and fails with an 'invalid allocator' error. The check
        reads the node's own endpoints, not the graph: it waits for nothing.
        """
        topic = self._values[parameter]
        name = self._resolved(topic)
        known = sorted({_type_name(endpoint.msg_type)
                        for endpoint in (*self.subscriptions, *self.publishers)
                        if endpoint.topic_name == name and endpoint.msg_type is not msg_type})
        wanted = _type_name(msg_type)
        if known:
            named = name if topic == name else f'{topic!r} is {name}, which'
            self._refuse(parameter, f'{named} carries {", ".join(known)}, not {wanted}')
        try:
            return self.create_subscription(msg_type, topic, callback, qos, raw=raw,
                                            event_callbacks=quiet_subscription_events())
        except RCLError as error:
            # Whatever else rcl refuses (a conflict the graph did not list): one line, exit 2.
            self._refuse(parameter, f'cannot subscribe to {name} as {wanted}: '
                         f'{str(error).split(", at ")[0]}')

    def _refuse(self, parameter, reason):
        """Log PARAMETER's REASON as the fatal 'invalid parameter: ...'; raise ParameterError."""
        error = ParameterError(parameter, reason)
        self.get_logger().fatal(f'invalid parameter: {error}')
        raise error

    def _resolved(self, topic):
        """Return TOPIC as the graph names it (resolved in the node's namespace)."""
        return self.resolve_topic_name(topic)

    def _check_topic_types(self):
        """Warn about a filter topic that carries another Twist type than the filter's."""
        if self._source != VELOCITY:
            return
        wanted = _TWIST_TYPES[self._twist_type]
        for topic, endpoints in (
                (self._values['cmd_vel_in_topic'], self.get_publishers_info_by_topic),
                (self._cmd_vel_topic, self.get_subscriptions_info_by_topic)):
            name = self._resolved(topic)
            other = sorted({info.topic_type for info in endpoints(name)} - {wanted})
            if other:
                self._warnings.warn((name, 'type'), f'{name} carries {", ".join(other)}, the '
                                    f'filter {wanted} (enable_stamped_cmd_vel '
                                    f'{str(self._stamped).lower()}): they do not connect')

    # Parameters -------------------------------------------------------------------------------

    def _declare_parameters(self):
        """Declare every parameter and check its start-up value; raise ParameterError."""
        self._values = checked_parameters(declare_parameters(self, _PARAMETERS, is_dumped_unset))
        self._config = planner_config_from(self._values)
        self._goal = goal_array(self._values['goal'])
        self._neighbours_listed = neighbour_names(self._values['neighbors'])
        self._robot = self.get_namespace().strip('/')
        if not self._robot or '/' in self._robot:
            raise ParameterError(
                '__ns', f'run the planner in a robot namespace (-r __ns:=/robot_0), '
                f'got namespace {self.get_namespace()!r}')
        if self._values['preferred_source'] == VELOCITY:
            # Compared as the graph names them: after the namespace and any remapping.
            names = [self._values[name] for name in ('cmd_vel_in_topic', 'cmd_vel_out_topic')]
            upstream, output = (self.resolve_topic_name(name) for name in names)
            if upstream == output:
                raise ParameterError(
                    'cmd_vel_out_topic', f'{names[1]!r} and cmd_vel_in_topic {names[0]!r} are '
                    f'both {output}: the filter would take its own commands as its input')

    def _on_set_parameters(self, parameters):
        """Accept a parameter change only if the whole configuration stays valid."""
        values = dict(self._values)
        try:
            for parameter in parameters:
                if parameter.name in values:
                    values[parameter.name] = check_parameter_update(parameter.name,
                                                                    parameter.value)
            config = planner_config_from(values, {parameter.name for parameter in parameters})
            goal = goal_array(values['goal'])
        except ParameterError as error:
            return SetParametersResult(successful=False, reason=str(error))
        self._values, self._config, self._goal = values, config, goal
        # The goal parameter is the goal_pose's; a path brings its own goal, a filter none.
        # A map made for other settings is made anew beside the plans (it is not made here),
        # and so are the ways to a new goal on the map: until they are, the goal before holds.
        agent = self._agent
        routed = (self._source == GOAL and goal is not None and agent.grid_map is not None
                  and (agent.goal is None or not np.array_equal(goal, agent.goal)))
        agent.reconfigure(config, AgentSettings.from_parameters(values), (
            goal if self._source == GOAL and not routed else agent.goal), rebuild_map=False)
        if routed and (self._route_build is None
                       or not np.array_equal(self._route_build.grid, goal)):
            self._build_route(goal)
        elif self._source == GOAL:
            self._route_build = None
        if agent.map_outdated and self._map_build is None:
            self._build_map(agent.grid_map)
        self._announce()
        if any(parameter.name == 'sync_timeout' for parameter in parameters):
            self._sync_timer.timer_period_ns = int(max(values['sync_timeout'], 1e-3) * 1e9)
        return SetParametersResult(successful=True)

    def _announce(self):
        """Publish the footprint and share (latched) where they changed; return the publishers."""
        return self._announcer.announce(*dataclasses.astuple(self._agent.own_announcement),
                                        self._agent.own_announcement_stamp)

    def warm_up(self):
        """
        Pay the first plans' one-off costs before spinning (see PlannerAgent.warm_up).

        The walls' compiled kernels (`core.wall_kernels`) are loaded here too, by their import:
        a map or walls can reach the planner at any time, and the load in a callback would be
        late. A Monte Carlo planner never plans beside walls.
        """
        self._agent.warm_up()
        if self._agent.config.model != 'mc':
            importlib.import_module('prvo_planner.core.wall_kernels')

    # Inputs -----------------------------------------------------------------------------------

    def _measure(self, data, topic):
        """Return the OdometryMeasurement of serialized odometry, or None (warned) if bad."""
        try:
            return serialized_odometry_to_measurement(
                data, expected_frame=self._values['frame_id'])
        except MessageFault as fault:
            # Values sit in parentheses at the end: the text before them names the fault.
            self._warnings.warn((topic, str(fault).split('(')[0]),
                                f'skipping odometry on {topic}: {fault}')
            return None

    def _report(self, fusion, topic):
        """Log what a fused measurement's outcome tells: faults throttled, restarts once."""
        if fusion.status in ('restarted', 'resumed'):
            self.get_logger().info(f'odometry on {topic}: {fusion.detail}')
        elif fusion.status in ('stale', 'refused'):
            self._warnings.warn((topic, fusion.status),
                                f'skipping odometry on {topic}: {fusion.detail}')

    @quiet_after_shutdown
    def _on_own_odometry(self, data):
        measurement = self._measure(data, self._own_odom_topic)
        if measurement is None:
            return
        fusion = self._agent.receive_own(measurement, time.monotonic())
        self._report(fusion, self._own_odom_topic)
        if fusion.status == 'duplicate':
            if (self._source != VELOCITY and self._last_command_stamp == measurement.stamp
                    and self._resent_stamp != measurement.stamp and not self._commands.holding):
                # The simulator re-sends odometry it has no answer to: the answer may be lost.
                self._resent_stamp = measurement.stamp
                self._cmd_vel_publisher.publish(self._last_command)
            return
        if not fusion.accepted:
            return
        if self._agent.ready(time.monotonic()):
            self._plan()
        elif self._sync_timer.is_canceled() and (
                self._source != VELOCITY or self._agent.upstream_waiting):
            # Armed once per wait: re-arming it on every own odometry would postpone the plan
            # for as long as odometry comes faster than sync_timeout and a neighbour is silent.
            self._sync_timer.reset()

    @quiet_after_shutdown
    def _on_neighbour_odometry(self, data, robot, topic):
        measurement = self._measure(data, topic)
        if measurement is None:
            return
        self._report(self._agent.receive_neighbour(robot, measurement, time.monotonic()), topic)
        if self._agent.ready(time.monotonic()):
            self._plan()

    @quiet_after_shutdown
    def _on_goal_pose(self, msg):
        try:
            goal = pose_stamped_to_goal(msg, expected_frame=self._values['frame_id'])
        except MessageFault as fault:
            self._warnings.warn(
                'goal', f'ignoring goal on {robot_topic(self._robot, GOAL_POSE)}: {fault}')
            return
        if self._agent.goal_blocked(goal):
            self._warnings.warn(
                'goal', f'ignoring goal on {robot_topic(self._robot, GOAL_POSE)}: '
                f'{goal.tolist()} lies in an obstacle of the map, or off it')
            return
        # Through the parameter: `goal` shows the goal in force, and other changes keep it. The
        # parameter's rules hold: pose_stamped_to_goal checked the same coordinate bound.
        self.set_parameters([Parameter('goal', Parameter.Type.DOUBLE_ARRAY, goal.tolist())])
        self.get_logger().info(f'new goal {goal.tolist()}')

    @quiet_after_shutdown
    def _on_path(self, data):
        topic = self._resolved(self._values['path_topic'])
        try:
            waypoints = self._path_reader.read(data)
            if waypoints is None:
                # The path in force, sent again.
                return
            self._agent.set_path(waypoints)
        except ValueError as fault:
            self._warnings.warn((topic, 'path'), f'ignoring path on {topic} (keeping the path '
                                f'in force): {fault}')
            return
        self._announce()
        self.get_logger().info(f'following a path of {len(waypoints)} poses' if len(waypoints)
                               else 'empty path: stopped following')
        if self._agent.ready(time.monotonic()):
            # A plan waiting for the path (wait_for_path) goes ahead now.
            self._plan()

    @quiet_after_shutdown
    def _on_upstream(self, msg):
        topic = self._resolved(self._values['cmd_vel_in_topic'])
        try:
            linear, angular = twist_components(msg)
        except MessageFault as fault:
            self._warnings.warn((topic, 'upstream'), f'ignoring command on {topic}: {fault}')
            return
        now = time.monotonic()
        agent = self._agent
        stamp = stamp_to_seconds(msg.header.stamp) if self._stamped else None
        if agent.upstream_superseded(stamp, now):
            # One output per input: the one still waiting is answered before it is replaced.
            agent.repeat_last_stamp()
            self._plan()
        agent.receive_upstream(UpstreamCommand(linear, angular, msg, stamp), now)
        answer = agent.upstream_answer(now)
        if answer == 'stale':
            self._warnings.warn('stale', f'no state on {self._own_odom_topic} within '
                                f"state_timeout {self._values['state_timeout']:g} s: stopping")
            if agent.stale_answer() is not None:
                self._commands.publish(
                    filtered_twist(msg, (0.0, 0.0), 0.0), self._announce())
        elif answer == 'repeat':
            if self._last_command is not None and not self._commands.holding:
                self._cmd_vel_publisher.publish(self._last_command)
        elif answer == 'plan':
            self._plan()
        elif self._sync_timer.is_canceled():
            self._sync_timer.reset()

    @quiet_after_shutdown
    def _on_sync_timeout(self):
        agent = self._agent
        if self._source == VELOCITY:
            if not agent.upstream_waiting:
                self._sync_timer.cancel()
                return
            # No newer own state came: the command is answered from the last one.
            agent.repeat_last_stamp()
        # While a listed neighbour may still turn up, the timer keeps firing: plan then.
        if agent.pending_stamp is None or agent.awaiting_listed(time.monotonic()):
            return
        self._plan()

    def _on_bad_announcement(self, topic, error):
        # The agent keeps the neighbour's last valid announcement, else its default.
        self._warnings.warn((topic, 'announcement'), f'ignoring announcement on {topic}: {error}')

    def _on_bad_route(self, robot, topic, error):
        # Whatever is wrong with it, the neighbour is one without a route: it claims nothing.
        self._agent.forget_route(robot)
        self._warnings.warn((topic, 'route'), f'ignoring route on {topic} (the robot claims '
                            f'nothing): {error}')

    # Map and route ----------------------------------------------------------------------------

    def _map_endpoints(self):
        """Subscribe the map (QoS as map_server's), advertise the route; return them.

        A map is built (`agent.build_map`: its obstacles, their index, its route graph, the
        paths to the goal; seconds for a large map) by a worker thread, never in a callback;
        the plans go on with the map in force until the new one is built whole and swapped in.

        Only a robot heading for a goal has a route of its own: one following a path has the
        path (on `plan` too, by default), a filter none. It publishes its route with or
        without a map.
        """
        self._map_topic = self._values['map_topic']
        # A daemon thread: a planner stopped while it builds a large map does not wait for it.
        self._map_builder = BackgroundWorker('map_builder')
        # The newest map message not yet taken by the worker (bytes), under its lock: one
        # message waits at most, however fast maps come.
        self._map_lock = threading.Lock()
        self._map_data = None
        # The worker's reads of map messages (Futures of a GridMap), oldest first.
        self._map_reads = collections.deque()
        # The newest map being built, the newest goal's ways and the way round a passage the
        # robot waits at (`_MapBuild`), None when none.
        self._map_build = None
        self._route_build = None
        self._way_round_search = None
        self._map_poll = self.create_timer(MAP_POLL_PERIOD, self._on_map_poll,
                                           clock=self._steady_clock, autostart=False)
        # What the robot published of its way, to publish it once per change.
        self._route_intent = RouteIntent(DEPARTURE_TOLERANCES)
        self._plan_publisher = None if self._source != GOAL else self.create_publisher(
            Path, PLAN, PLAN_QOS, event_callbacks=quiet_publisher_events())
        # Serialized (raw): a 4000 x 4000 grid takes 40 ms to deserialize and as long again to
        # check; the worker does both, and the callback only hands it the bytes.
        subscription = self._subscribe_parameter_topic('map_topic', OccupancyGrid, self._on_map,
                                                       MAP_QOS, raw=True)
        return [subscription] + ([] if self._plan_publisher is None else [self._plan_publisher])

    @quiet_after_shutdown
    def _on_map(self, data):
        with self._map_lock:
            queued = self._map_data is not None
            self._map_data = data
        if not queued:
            self._map_reads.append(self._map_builder.submit(self._read_map))
        # A map on its way: with wait_for_map the first plan waits for it.
        self._agent.map_pending = True
        self._map_poll.reset()

    def _read_map(self):
        """Return the `GridMap` of the newest map message (on the worker's thread).

        Raises MessageFault or ValueError for a message that is not a map in frame_id.
        """
        with self._map_lock:
            data, self._map_data = self._map_data, None
        msg = deserialize_message(data, OccupancyGrid)
        return GridMap(*occupancy_grid_to_parts(msg, expected_frame=self._values['frame_id']))

    def _take_read_maps(self):
        """Have the maps the worker read built, unless in force or being built; warn on faults."""
        while self._map_reads and self._map_reads[0].done():
            try:
                grid = self._map_reads.popleft().result()
            except (MessageFault, ValueError) as fault:
                # Values sit in parentheses at the end: the text before them names the fault.
                self._warnings.warn((self._map_topic, str(fault).split('(')[0]),
                                    f'ignoring map on {self._map_topic} (keeping the map in '
                                    f'force): {fault}')
                continue
            building = self._map_build is not None and same_grid(self._map_build.grid, grid)
            if not building and not (self._map_build is None and self._agent.has_map(grid)):
                self._build_map(grid)
        # A map on its way is one read or built; nothing else keeps a plan waiting for it.
        self._agent.map_pending = bool(self._map_reads) or self._map_build is not None
        self._stop_polling_when_idle()

    def _build_map(self, grid):
        """Have the worker build GRID for the settings in force; it replaces any build before."""
        agent = self._agent
        self._map_build = _MapBuild(self._map_builder.submit(
            build_map, grid, agent.map_key, agent.route_goal()), grid, time.monotonic())
        agent.map_pending = True
        self._map_poll.reset()

    def _build_route(self, goal):
        """Have the worker search the ways to GOAL (2,) on the map in force; the goal waits."""
        route_map = self._agent.route_map
        self._route_build = _MapBuild(self._map_builder.submit(route_map.tree_to, goal), goal,
                                      time.monotonic())
        self._map_poll.reset()

    def _search_way_round(self):
        """Have the worker search the way round the agent wants, unless it searches it now."""
        wanted = self._agent.way_round_wanted
        search = self._way_round_search
        if wanted is None or (search is not None and search.grid[0] == wanted[0]
                              and search.grid[1] is wanted[1]):
            return
        self._way_round_search = _MapBuild(self._map_builder.submit(way_round, *wanted),
                                           wanted, time.monotonic())
        self._map_poll.reset()

    def _take_way_round(self):
        """Hand the agent the way round the worker searched, if done."""
        search = self._way_round_search
        if search is None or not search.future.done():
            return
        self._way_round_search = None
        self._stop_polling_when_idle()
        try:
            tree = search.future.result()
        except Exception as error:
            # Counted as no way round: the robot waits its turn, and asks no more.
            self._warnings.warn('way round', f'cannot search a way round a passage: {error!r}')
            tree = None
        self._agent.install_way_round(search.grid, tree)

    @quiet_after_shutdown
    def _on_map_poll(self):
        self._take_read_maps()
        self._take_way_round()
        taken = self._take_built_map()
        taken = self._take_route() or taken
        if taken and self._agent.ready(time.monotonic()):
            # A plan waiting for the map (wait_for_map) goes ahead now.
            self._plan()

    def _stop_polling_when_idle(self):
        """Stop looking at the worker once it has nothing of ours to read, build or search."""
        if (not self._map_reads and self._map_build is None and self._route_build is None
                and self._way_round_search is None):
            self._map_poll.cancel()

    def _take_route(self):
        """Head for the goal whose ways the worker searched, if done; return whether it did."""
        build = self._route_build
        if build is None or not build.future.done():
            return False
        self._route_build = None
        self._stop_polling_when_idle()
        agent = self._agent
        agent.set_goal(build.grid)
        try:
            tree = build.future.result()
        except Exception as error:
            # The plans search the ways themselves.
            self._warnings.warn('route build', f'cannot search the ways to the goal: {error!r}')
            return True
        if not agent.install_route_tree(tree):
            # Searched on a map since replaced: the plans search on the one in force.
            return True
        self.get_logger().info(f'ways to the goal {build.grid.tolist()} searched in '
                               f'{time.monotonic() - build.started:.2f} s')
        return True

    def _take_built_map(self):
        """Swap in the map the worker built, if it is done; return whether a map came in."""
        build = self._map_build
        if build is None or not build.future.done():
            return False
        self._map_build = None
        self._stop_polling_when_idle()
        agent = self._agent
        try:
            built = build.future.result()
        except Exception as error:
            # Whatever failed (a map beyond the bounds, memory), the plans go on with the map in
            # force. The type tells what else failed (a MemoryError's text may be empty).
            agent.map_pending = bool(self._map_reads)
            reason = str(error) if isinstance(error, MapTooLargeError) else repr(error)
            self._warnings.warn((self._map_topic, 'build'), f'cannot use the map on '
                                f'{self._map_topic} (keeping the map in force): {reason}')
            return False
        if built.built_for != agent.map_key:
            # The settings changed while it was built: build it again for them.
            self._build_map(built.grid)
            return False
        agent.install_map(built)
        if built.passages_refused is not None:
            self._warnings.warn((self._map_topic, 'passages'), f'no right of way on the map on '
                                f'{self._map_topic} (planning without turns at its passages): '
                                f'{built.passages_refused}')
        height, width = built.grid.shape
        self.get_logger().info(
            f'map {width} x {height} cells of {built.grid.resolution:g} m from '
            f'{self._map_topic} (built in {time.monotonic() - build.started:.2f} s)')
        return True

    def _publish_route(self, command):
        """Publish the way after COMMAND on <robot>/plan where it changed; warn while none is.

        Returns the publishers that published (the command waits until the neighbours hold
        the route, as it does for announcements: they plan the next step with it).
        """
        if self._plan_publisher is None:
            return []
        agent = self._agent
        if command.route_status == ROUTE_UNREACHABLE:
            self._warnings.warn('route', f'no way on the map reaches the goal '
                                f'{agent.goal.tolist()}: holding the place')
        route = self._route_intent.update(command, agent.goal, agent.settings.goal_tolerance)
        if route is None:
            return []
        self._plan_publisher.publish(make_path(route_stamp(command.stamp), route,
                                               self._values['frame_id']))
        return [self._plan_publisher]

    # Neighbours -------------------------------------------------------------------------------

    @quiet_after_shutdown
    def _maintain_neighbours(self):
        """Subscribe to robots that appeared, forget robots that went silent or vanished.

        The robots to avoid are the `neighbors` list, or every other /<name>/odom in the graph.
        """
        listed = self._neighbours_listed
        wanted = (robots_with_topic(self, self._state_topic, _ODOMETRY_TYPE) if listed is None
                  else set(listed)) - {self._robot}
        agent = self._agent
        for robot in wanted - set(self._neighbour_subscriptions):
            topic = robot_topic(robot, self._state_topic)
            self._neighbour_subscriptions[robot] = [self.create_subscription(
                Odometry, topic,
                lambda data, robot=robot, topic=topic: self._on_neighbour_odometry(
                    data, robot, topic),
                ODOM_LATEST_QOS, event_callbacks=quiet_subscription_events(), raw=True)
            ] + subscribe_announcements(self, robot, agent.receive_footprint,
                                        agent.receive_share, self._on_bad_announcement) + [
                subscribe_route(self, robot, agent.receive_route, self._on_bad_route,
                                self._values['frame_id'])]
            self._qos_watch.watch(*self._neighbour_subscriptions[robot])
            self.get_logger().info(f'tracking neighbour {robot}')
        for robot in set(self._neighbour_subscriptions) - wanted:
            for subscription in self._neighbour_subscriptions.pop(robot):
                self._qos_watch.forget(subscription)
                self.destroy_subscription(subscription)
            agent.forget_announcements(robot)
        self._qos_watch.check()
        self._check_topic_types()
        for robot, silent in self._agent.forget_neighbours(time.monotonic(), wanted):
            self.get_logger().info(f'dropped neighbour {robot}: silent for {silent:.1f} s')

    # Planning ---------------------------------------------------------------------------------

    def _plan(self):
        """Plan for the pending stamp and publish the command, diagnostics and markers."""
        self._sync_timer.cancel()
        self._take_built_map()
        self._take_route()
        self._take_way_round()
        unheard = self._agent.unheard_listed() if self._last_command_stamp is None else []
        if unheard:
            self.get_logger().warning(
                f"first plan without {', '.join(unheard)}: not heard in full (odometry, "
                f"footprint, share) within neighbor_timeout "
                f"{self._values['neighbor_timeout']:g} s")
        started, plan_cpu = time.perf_counter(), time.thread_time()
        command = self._agent.plan()
        plan_time_ms = (time.perf_counter() - started) * 1e3
        # CPU of the plan itself and of the whole process since the plan before: every
        # callback, DDS's threads and the map worker (a step's worth in lockstep).
        process_cpu = time.process_time()
        cpu_ms = None if self._process_cpu is None else (
            (time.thread_time() - plan_cpu) * 1e3, (process_cpu - self._process_cpu) * 1e3)
        self._process_cpu = process_cpu
        self._search_way_round()
        if command.arrival:
            self.get_logger().info(f'arrived at {self._agent.goal.tolist()}')
        if command.awaiting_map and not self._told_awaiting_map:
            self.get_logger().warning(AWAITING_MAP)
        # Once per wait: the status says so at every plan.
        self._told_awaiting_map = command.awaiting_map
        # Once neighbours hold a changed announcement: in lockstep they plan the next step with it.
        message = self._command_message(command)
        announced = self._announce() + self._publish_route(command)
        if command.published:
            self._commands.publish(message, announced)
        self._last_command, self._last_command_stamp = message, command.stamp
        if self._lookahead_publisher is not None and self._agent.path is not None and (
                self._agent.path.last_carrot is not None):
            self._lookahead_publisher.publish(make_point_stamped(
                command.stamp, self._agent.path.last_carrot, self._values['frame_id']))
        result = command.result
        if result is not None and not result.feasible:
            self._warnings.warn(
                'infeasible', f'no velocity meets k={self._config.effective_k:.2f}; best '
                f'achieves k={result.achieved_k:.2f} (P >= {result.eta_bound:.2f})')
        stall = command.stall
        if stall is not None and stall.began:
            self._warnings.warn('stalled', f'stalled at ({stall.position[0]:.2f}, '
                                f'{stall.position[1]:.2f}), {stall.distance_to_goal:.2f} m from '
                                f'the goal: gained {stall.gained:.2f} m in {STALL_WINDOW:g} s')
            if command.narrow_passage is not None:
                self._warnings.warn('narrow', passage_message(command.narrow_passage))
        if command.inside_obstacle is not None:
            self._warnings.warn('inside', inside_message(command.inside_obstacle))
        for robot in command.idle_in_passage:
            self._warnings.warn(('idle', robot), idle_message(robot))
        decision = command.right_of_way
        if decision is not None and decision.without_spot:
            # Once per end: the map's geometry does not change while the robot waits there.
            end = (decision.use.passage, *np.round(decision.entrance, 3))
            if end not in self._ends_without_spot:
                self._ends_without_spot.add(end)
                self.get_logger().warning(no_spot_message(self._robot, decision))
        self._reporter.report(
            time.monotonic(), self._values['status_period'], command, plan_time_ms,
            self._config, self._agent.settings.planning_radius, self._values['frame_id'],
            cpu_ms)


    def _command_message(self, command):
        """Return the cmd_vel of COMMAND; a filter's answers its upstream message."""
        upstream = command.upstream
        if upstream is None:
            return command_message(self._robot, command, self._stamped)
        if command.passed_through:
            return upstream.message
        if command.drive is not None:
            return filtered_twist(upstream.message, (command.drive[0], 0.0), command.drive[1])
        # A holonomic robot turns as it was told: turning does not move its disc.
        return filtered_twist(upstream.message, world_to_body(command.velocity, command.yaw),
                              upstream.angular)


def warmed_up_planner():
    """Return a PlannerNode whose first plan has been computed once (`PlannerNode.warm_up`)."""
    node = PlannerNode()
    node.warm_up()
    return node


def _type_name(msg_type):
    """Return a message class's ROS type name, 'package/msg/Name'."""
    return f'{msg_type.__module__.split(".")[0]}/msg/{msg_type.__name__}'


def main(args=None):
    """Run one planner until Ctrl-C; exit 2 with a clear message on an invalid parameter."""
    keep_freed_heap()
    # PlannerNode logs an invalid parameter under its own name.
    return run_node(warmed_up_planner, 'planner', (
        ParameterError, InvalidParameterTypeException, InvalidParameterValueException), args,
        bad_input_logged=True)


if __name__ == '__main__':
    sys.exit(main())
