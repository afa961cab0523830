"""Per-robot PRVO planner node: neighbour odometry in, chance-constrained `cmd_vel` out.

Run one per robot, in the robot's namespace:

    ros2 run prvo_planner planner --ros-args -r __ns:=/robot_0 -p goal:="[4.0, 0.0]"

The node is a thin shell: it declares parameters, converts messages through prvo_msgs_util,
tracks every robot with `prvo_planner.estimation`, plans with `prvo_planner.core.plan_velocity`
and publishes.
"""

import dataclasses
import math
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseStamped, Twist, TwistStamped
from nav_msgs.msg import Odometry
import numpy as np
from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    SetParametersResult,
)
import rclpy
from rclpy.clock import Clock, ClockType
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter
from visualization_msgs.msg import MarkerArray

from prvo_msgs_util import (
    CMD_VEL,
    CMD_VEL_QOS,
    DIAGNOSTICS,
    DIAGNOSTICS_QOS,
    GOAL_POSE,
    GOAL_QOS,
    MARKER_QOS,
    MARKERS,
    ODOM,
    ODOM_LATEST_QOS,
    MessageFault,
    QosWatch,
    SigintRecorder,
    freeze_startup_objects,
    make_belief_markers,
    make_diagnostic_array,
    make_diagnostic_status,
    make_twist,
    make_twist_stamped,
    pose_stamped_to_goal,
    quiet_publisher_events,
    quiet_subscription_events,
    robot_from_topic,
    robot_topic,
    serialized_odometry_to_measurement,
    spin_events,
    validate_robot_name,
)
from prvo_planner.core import AgentBelief, plan_velocity
from prvo_planner.estimation import ConstantVelocityTracker
from prvo_planner.parameters import (
    BOOL,
    FLOAT,
    FLOAT_ARRAY,
    INTEGER,
    PARAMETERS,
    STRING,
    STRING_ARRAY,
    ParameterError,
    check_parameter,
    checked_parameters,
    planner_config_from,
)

# A stamp this far behind a track's last one means its source restarted (e.g. the simulator):
# the track starts over instead of rejecting every message from then on.
_TIME_RESET_SECONDS = 1.0
# Plans for a made-up encounter before spinning (see PlannerNode.warm_up).
_WARM_UP_PLANS = 3
_WARN_PERIOD_SECONDS = 2.0
_ODOMETRY_TYPE = 'nav_msgs/msg/Odometry'


_ROS_TYPES = {BOOL: Parameter.Type.BOOL, INTEGER: Parameter.Type.INTEGER,
              FLOAT: Parameter.Type.DOUBLE, STRING: Parameter.Type.STRING,
              FLOAT_ARRAY: Parameter.Type.DOUBLE_ARRAY, STRING_ARRAY: Parameter.Type.STRING_ARRAY}


def _descriptor(spec):
    """Return the ParameterDescriptor of the parameter SPEC: type, range, description.

    A parameter without a default (goal, neighbors) is dynamically typed, so that it can stay
    unset and take integers as well as doubles; its rules are checked on every set.
    """
    descriptor = ParameterDescriptor(
        description=spec.description, read_only=spec.read_only,
        dynamic_typing=spec.default is None, type=_ROS_TYPES[spec.kind].value)
    if spec.bounds is not None and spec.kind == FLOAT:
        descriptor.floating_point_range = [FloatingPointRange(
            from_value=float(spec.bounds[0]), to_value=float(spec.bounds[1]), step=0.0)]
    if spec.bounds is not None and spec.kind == INTEGER:
        descriptor.integer_range = [IntegerRange(
            from_value=spec.bounds[0], to_value=spec.bounds[1], step=1)]
    return descriptor


# name: (default, descriptor), in declaration order.
_PARAMETERS = {name: (spec.default, _descriptor(spec)) for name, spec in PARAMETERS.items()}


def _goal_from_parameter(value):
    """Return the goal (2,) from the `goal` parameter, None when unset; raise ParameterError."""
    goal = check_parameter('goal', value)
    return None if goal is None else np.array(goal, dtype=float)


def _neighbour_list(value):
    """Return the `neighbors` parameter as a list of names, None to discover them."""
    names = check_parameter('neighbors', value)
    if names is None:
        return None
    for name in names:
        if name:
            try:
                validate_robot_name(name)
            except ValueError as error:
                raise ParameterError('neighbors', str(error)) from None
    return [name for name in names if name]


def preferred_velocity(position, goal, max_speed, approach_time, goal_tolerance):
    """Return (v_pref (2,), arrived): straight to the goal, slowing over the last stretch."""
    if goal is None:
        return np.zeros(2), False
    offset = goal - position
    distance = float(np.hypot(*offset))
    if distance <= goal_tolerance:
        return np.zeros(2), True
    speed = min(max_speed, distance / approach_time)
    return offset * (speed / distance), False


def goal_horizon(distance_to_goal, max_speed, approach_time, time_horizon):
    """Return the time horizon of one plan [s]: no longer than the way to the goal takes.

    A robot that stops at its goal in about distance / max_speed, plus approach_time of slowing
    down, cannot collide later on the straight line it is planned on; without this cap, robots
    standing beyond a goal would forbid approaching it.
    """
    return min(time_horizon, distance_to_goal / max_speed + approach_time)


class _Track:
    """One tracked robot: its filter and when (wall time) it last spoke."""

    def __init__(self, acceleration_std):
        self.tracker = ConstantVelocityTracker(acceleration_std)
        self.last_heard = time.monotonic()


class PlannerNode(Node):
    """PRVO planner of one robot: tracks itself and its neighbours, publishes `cmd_vel`."""

    def __init__(self):
        super().__init__('planner')
        for name, (default, descriptor) in _PARAMETERS.items():
            self.declare_parameter(name, default, descriptor)
        self._values = checked_parameters(
            {name: self.get_parameter(name).value for name in _PARAMETERS})
        self._config = planner_config_from(self._values)
        self._goal = _goal_from_parameter(self._values['goal'])
        self._neighbours_listed = _neighbour_list(self._values['neighbors'])
        self.add_on_set_parameters_callback(self._on_set_parameters)

        self._robot = self.get_namespace().strip('/')
        if not self._robot or '/' in self._robot:
            raise ParameterError(
                '__ns', f'run the planner in a robot namespace (-r __ns:=/robot_0), '
                f'got namespace {self.get_namespace()!r}')
        self._steady_clock = Clock(clock_type=ClockType.STEADY_TIME)
        self._own_track = None
        self._neighbour_tracks = {}
        self._neighbour_subscriptions = {}
        self._pending_stamp = None
        self._own_yaw = 0.0
        self._arrived = False
        self._last_command = None
        self._last_command_stamp = None
        # The last planned velocity in the world frame, for the inertia term; None after a stop.
        self._previous_velocity = None
        self._warned_at = {}
        self._status_published_at = -math.inf
        # Listed neighbours are waited for from the first own odometry on, not from start-up:
        # a team's processes start at different speeds, and a run begins with all of them.
        self._first_odometry_at = None

        self._stamped = self._values['stamped_cmd_vel']
        # Endpoints without rclpy's QoS event handlers (each would cost every executor wake-up);
        # the watch reports incompatible QoS from the graph instead.
        self._qos_watch = QosWatch(self)
        self._cmd_vel_publisher = self.create_publisher(
            TwistStamped if self._stamped else Twist, CMD_VEL, CMD_VEL_QOS,
            event_callbacks=quiet_publisher_events())
        self._diagnostics_publisher = self.create_publisher(
            DiagnosticArray, DIAGNOSTICS, DIAGNOSTICS_QOS,
            event_callbacks=quiet_publisher_events())
        self._marker_publisher = self.create_publisher(
            MarkerArray, MARKERS, MARKER_QOS, event_callbacks=quiet_publisher_events())
        self._own_odom_topic = robot_topic(self._robot, ODOM)
        # Odometry arrives serialized (raw): eight messages a step in an 8-robot team, and
        # reading the few fields needed from the bytes costs a fraction of deserializing them.
        own_odometry = self.create_subscription(
            Odometry, ODOM, self._on_own_odometry, ODOM_LATEST_QOS,
            event_callbacks=quiet_subscription_events(), raw=True)
        goal = self.create_subscription(
            PoseStamped, GOAL_POSE, self._on_goal_pose, GOAL_QOS,
            event_callbacks=quiet_subscription_events())
        for endpoint in (self._cmd_vel_publisher, self._diagnostics_publisher,
                         self._marker_publisher, own_odometry, goal):
            self._qos_watch.watch(endpoint)

        # Wall-clock timers: under use_sim_time the simulator waits for us, so sim time would
        # never advance to fire them.
        self._sync_timer = self.create_timer(
            max(self._values['sync_timeout'], 1e-3), self._on_sync_timeout,
            clock=self._steady_clock, autostart=False)
        self.create_timer(0.5, self._maintain_neighbours, clock=self._steady_clock)
        self._maintain_neighbours()
        self.get_logger().info(
            f'planning for {self._robot}: model={self._config.model} '
            f'method={self._config.method} k={self._config.effective_k:.3f} '
            f'goal={None if self._goal is None else self._goal.tolist()}')

    # Parameters -------------------------------------------------------------------------------

    def _on_set_parameters(self, parameters):
        """Accept a parameter change only if the whole configuration stays valid."""
        values = dict(self._values)
        try:
            for parameter in parameters:
                if parameter.name in values:
                    values[parameter.name] = check_parameter(parameter.name, parameter.value)
            config = planner_config_from(values)
            goal = _goal_from_parameter(values['goal'])
        except ParameterError as error:
            return SetParametersResult(successful=False, reason=str(error))
        self._values, self._config, self._goal = values, config, goal
        if any(parameter.name == 'sync_timeout' for parameter in parameters):
            self._sync_timer.timer_period_ns = int(max(values['sync_timeout'], 1e-3) * 1e9)
        return SetParametersResult(successful=True)

    def warm_up(self):
        """Plan for a made-up encounter a few times, before the first real plan.

        A process's first plans pay one-off costs (numpy's first calls into its linear algebra,
        the planner's caches). When a team starts together on few cores, that is enough to
        miss the first realtime deadlines. The planner is pure: nothing here reaches a real plan.
        """
        radius = self._values['radius']
        own = AgentBelief([0.0, 0.0], [0.5, 0.0], 0.01 * np.eye(4), radius)
        neighbours = [AgentBelief([2.0, 0.2], [-0.5, 0.0], 0.01 * np.eye(4), radius),
                      AgentBelief([1.0, -1.5], [0.0, 0.5], 0.01 * np.eye(4), radius)]
        previous = None
        for _ in range(_WARM_UP_PLANS):
            previous = plan_velocity(own, neighbours, np.array([1.0, 0.0]), self._config,
                                     previous=previous).velocity

    # Inputs -----------------------------------------------------------------------------------

    def _warn(self, kind, message):
        """Log a warning at most once per period for each KIND, so one fault hides no other."""
        now = time.monotonic()
        if now - self._warned_at.get(kind, -math.inf) >= _WARN_PERIOD_SECONDS:
            self._warned_at[kind] = now
            self.get_logger().warning(message)

    def _measure(self, data, topic):
        """Return the OdometryMeasurement of serialized odometry, or None (warned) if bad."""
        try:
            return serialized_odometry_to_measurement(
                data, expected_frame=self._values['frame_id'])
        except MessageFault as fault:
            # Values sit in parentheses at the end: the text before them names the fault.
            self._warn((topic, str(fault).split('(')[0]),
                       f'skipping odometry on {topic}: {fault}')
            return None

    def _fuse(self, track, measurement, topic):
        """Feed MEASUREMENT to TRACK (None: a new one).

        Returns (the track to keep, 'fused' | 'duplicate' | 'stale'). A stamp far behind the
        last one starts a new track: its source restarted.
        """
        if track is None:
            track = _Track(self._values['acceleration_std'])
        last = track.tracker.stamp
        if last is not None and measurement.stamp == last:
            return track, 'duplicate'
        if last is not None and measurement.stamp < last:
            if last - measurement.stamp <= _TIME_RESET_SECONDS:
                self._warn((topic, 'stale'),
                           f'skipping odometry on {topic}: stamp {measurement.stamp:.3f} s '
                           f'is not after the last one ({last:.3f} s)')
                return track, 'stale'
            self.get_logger().info(
                f'time on {topic} jumped back from {last:.3f} s to {measurement.stamp:.3f} s: '
                f'restarting its track')
            track = _Track(self._values['acceleration_std'])
        track.tracker.update(measurement.stamp, measurement.position, measurement.velocity,
                             measurement.covariance)
        track.last_heard = time.monotonic()
        return track, 'fused'

    def _on_own_odometry(self, data):
        measurement = self._measure(data, self._own_odom_topic)
        if measurement is None:
            return
        self._own_track, outcome = self._fuse(
            self._own_track, measurement, self._own_odom_topic)
        if outcome == 'duplicate' and self._last_command_stamp == measurement.stamp:
            # The simulator re-sends odometry it has no answer to: the answer may have been lost.
            self._cmd_vel_publisher.publish(self._last_command)
        if outcome != 'fused':
            return
        if self._first_odometry_at is None:
            self._first_odometry_at = time.monotonic()
        self._pending_stamp = measurement.stamp
        self._own_yaw = measurement.yaw
        if self._neighbours_caught_up():
            self._plan()
        else:
            self._sync_timer.reset()

    def _on_neighbour_odometry(self, data, robot, topic):
        measurement = self._measure(data, topic)
        if measurement is None:
            return
        self._neighbour_tracks[robot], _ = self._fuse(
            self._neighbour_tracks.get(robot), measurement, topic)
        if self._pending_stamp is not None and self._neighbours_caught_up():
            self._plan()

    def _on_goal_pose(self, msg):
        try:
            goal = pose_stamped_to_goal(msg, expected_frame=self._values['frame_id'])
        except MessageFault as fault:
            self._warn('goal', f'ignoring goal on {robot_topic(self._robot, GOAL_POSE)}: {fault}')
            return
        self._goal = goal
        self._arrived = False
        self._previous_velocity = None
        self.get_logger().info(f'new goal {goal.tolist()}')

    def _awaiting_listed_neighbours(self):
        """Whether a listed neighbour has not been heard yet and may still turn up."""
        if (self._neighbours_listed is None or self._first_odometry_at is None
                or time.monotonic() - self._first_odometry_at > self._values['neighbor_timeout']):
            return False
        return any(name not in self._neighbour_tracks for name in self._neighbour_names())

    def _neighbours_caught_up(self):
        return not self._awaiting_listed_neighbours() and all(
            track.tracker.stamp >= self._pending_stamp
            for track in self._neighbour_tracks.values())

    def _on_sync_timeout(self):
        if self._pending_stamp is None or self._awaiting_listed_neighbours():
            return
        self._sync_timer.cancel()
        self._plan()

    # Neighbours -------------------------------------------------------------------------------

    def _neighbour_names(self):
        """Robots to avoid: the `neighbors` list, or every other /<name>/odom in the graph."""
        listed = self._neighbours_listed
        if listed is not None:
            return set(listed) - {self._robot}
        names = set()
        for topic, types in self.get_topic_names_and_types():
            robot = robot_from_topic(topic, ODOM)
            if robot and robot != self._robot and _ODOMETRY_TYPE in types:
                names.add(robot)
        return names

    def _maintain_neighbours(self):
        """Subscribe to robots that appeared, forget robots that went silent or vanished."""
        wanted = self._neighbour_names()
        for robot in wanted - set(self._neighbour_subscriptions):
            topic = robot_topic(robot, ODOM)
            self._neighbour_subscriptions[robot] = self.create_subscription(
                Odometry, topic,
                lambda data, robot=robot, topic=topic: self._on_neighbour_odometry(
                    data, robot, topic),
                ODOM_LATEST_QOS, event_callbacks=quiet_subscription_events(), raw=True)
            self._qos_watch.watch(self._neighbour_subscriptions[robot])
            self.get_logger().info(f'tracking neighbour {robot}')
        for robot in set(self._neighbour_subscriptions) - wanted:
            subscription = self._neighbour_subscriptions.pop(robot)
            self._qos_watch.forget(subscription)
            self.destroy_subscription(subscription)
        self._qos_watch.check()
        now = time.monotonic()
        for robot, track in list(self._neighbour_tracks.items()):
            silent = now - track.last_heard
            if robot not in wanted or silent > self._values['neighbor_timeout']:
                del self._neighbour_tracks[robot]
                self.get_logger().info(f'dropped neighbour {robot}: silent for {silent:.1f} s')

    # Planning ---------------------------------------------------------------------------------

    def _plan(self):
        """Plan for the pending stamp and publish the command, diagnostics and markers."""
        self._sync_timer.cancel()
        stamp, self._pending_stamp = self._pending_stamp, None
        started = time.perf_counter()
        own = self._own_track.tracker.belief_at(stamp)
        radius = self._values['radius']
        neighbour_radius = self._values['neighbor_radius']
        if neighbour_radius < 0.0:
            neighbour_radius = radius
        v_pref, arrived = preferred_velocity(
            own.mean[:2], self._goal, self._values['max_speed'], self._values['approach_time'],
            self._values['goal_tolerance'])
        if arrived and not self._arrived:
            self.get_logger().info(f'arrived at {self._goal.tolist()}')
        self._arrived = arrived
        neighbour_beliefs = [
            track.tracker.belief_at(stamp) for track in self._neighbour_tracks.values()]
        if arrived or self._goal is None:
            velocity, result = np.zeros(2), None
        else:
            horizon = goal_horizon(
                float(np.hypot(*(self._goal - own.mean[:2]))), self._values['max_speed'],
                self._values['approach_time'], self._config.time_horizon)
            result = plan_velocity(
                AgentBelief(own.mean[:2], own.mean[2:], own.covariance, radius),
                [AgentBelief(belief.mean[:2], belief.mean[2:], belief.covariance,
                             neighbour_radius) for belief in neighbour_beliefs],
                v_pref, dataclasses.replace(self._config, time_horizon=horizon),
                previous=self._previous_velocity)
            velocity = result.velocity
        self._previous_velocity = None if result is None else velocity
        plan_time_ms = (time.perf_counter() - started) * 1e3

        # cmd_vel is in the body frame: rotate the world-frame plan by minus the robot's yaw.
        cos_yaw, sin_yaw = math.cos(self._own_yaw), math.sin(self._own_yaw)
        body_velocity = np.array([cos_yaw * velocity[0] + sin_yaw * velocity[1],
                                  -sin_yaw * velocity[0] + cos_yaw * velocity[1]])
        if self._stamped:
            command = make_twist_stamped(stamp, body_velocity, f'{self._robot}/base_link')
        else:
            command = make_twist(body_velocity)
        self._cmd_vel_publisher.publish(command)
        self._last_command, self._last_command_stamp = command, stamp
        if result is not None and not result.feasible:
            self._warn('infeasible',
                       f'no velocity meets k={self._config.effective_k:.2f}; best achieves '
                       f'k={result.achieved_k:.2f} (P >= {result.eta_bound:.2f})')
        # Diagnostics and markers are for people and tools: a few per second, off the hot path.
        now = time.monotonic()
        if now - self._status_published_at < self._values['status_period']:
            return
        self._status_published_at = now
        self._publish_diagnostics(stamp, result, len(neighbour_beliefs), plan_time_ms)
        if self._marker_publisher.get_subscription_count() == 0:
            # Markers take about 0.6 ms to build: only for a listener (RViz).
            return
        self._marker_publisher.publish(make_belief_markers(
            stamp, self._values['frame_id'], self._robot, own.mean[:2], velocity,
            np.array([belief.mean[:2] for belief in neighbour_beliefs]).reshape(-1, 2),
            np.array([belief.covariance[:2, :2] for belief in neighbour_beliefs]).reshape(
                -1, 2, 2),
            np.full(len(neighbour_beliefs), neighbour_radius),
            confidence=self._config.eta))

    def _publish_diagnostics(self, stamp, result, neighbours_tracked, plan_time_ms):
        feasible = True if result is None else bool(result.feasible)
        achieved_k = math.inf if result is None else result.achieved_k
        eta_bound = 1.0 if result is None else result.eta_bound
        status = make_diagnostic_status(
            f'prvo_planner/{self._robot}',
            'ok' if feasible else 'no velocity meets the chance constraint',
            {'achieved_k': achieved_k, 'eta_bound': eta_bound, 'feasible': feasible,
             'neighbours_tracked': neighbours_tracked, 'plan_time_ms': plan_time_ms,
             'arrived': self._arrived, 'model': self._config.model},
            level=DiagnosticStatus.OK if feasible else DiagnosticStatus.WARN,
            hardware_id=self._robot)
        self._diagnostics_publisher.publish(make_diagnostic_array(stamp, [status]))


def main(args=None):
    """Run one planner until Ctrl-C; exit 2 with a clear message on an invalid parameter."""
    sigint = SigintRecorder().install()
    rclpy.init(args=args)
    node = None
    try:
        node = PlannerNode()
        node.warm_up()
        freeze_startup_objects()
        spin_events(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except RuntimeError:
        # A message take in flight when Ctrl-C lands can fail with a RuntimeError. That is the
        # shutdown asked for; anything else is not.
        if rclpy.ok() and not sigint.received:
            raise
    except (ParameterError, InvalidParameterTypeException,
            InvalidParameterValueException) as error:
        rclpy.logging.get_logger('planner').fatal(f'invalid parameter: {error}')
        return 2
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
