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
)
from prvo_planner.core import AgentBelief, PlannerConfig, plan_velocity
from prvo_planner.estimation import ConstantVelocityTracker

# A stamp this far behind a track's last one means its source restarted (e.g. the simulator):
# the track starts over instead of rejecting every message from then on.
_TIME_RESET_SECONDS = 1.0
# Plans for a made-up encounter before spinning (see PlannerNode.warm_up).
_WARM_UP_PLANS = 3
_WARN_PERIOD_SECONDS = 2.0
_ODOMETRY_TYPE = 'nav_msgs/msg/Odometry'


class ParameterError(ValueError):
    """A planner parameter has a value the planner cannot use."""


def _descriptor(description, floating=None, integer=None, read_only=False, dynamic=False):
    """Build a ParameterDescriptor with a description and an optional inclusive range."""
    descriptor = ParameterDescriptor(
        description=description, read_only=read_only, dynamic_typing=dynamic)
    if floating is not None:
        descriptor.floating_point_range = [
            FloatingPointRange(from_value=floating[0], to_value=floating[1], step=0.0)]
    if integer is not None:
        descriptor.integer_range = [
            IntegerRange(from_value=integer[0], to_value=integer[1], step=1)]
    return descriptor


# name: (default, descriptor). Float defaults are float literals so the types are doubles.
_PARAMETERS = {
    'eta': (0.8, _descriptor(
        'Required probability that the RVO condition holds for each neighbour, in (0, 1).',
        floating=(0.0, 1.0))),
    'k': (-1.0, _descriptor(
        'Surrogate margin k >= 0 (mean - k std >= 0); wins over eta when set. -1 = use eta.',
        floating=(-1.0, 1.0e3))),
    'radius': (0.3, _descriptor("This robot's radius [m], > 0.", floating=(1.0e-3, 100.0))),
    'neighbor_radius': (-1.0, _descriptor(
        'Radius assumed for every neighbour [m]; -1 = the same as radius.',
        floating=(-1.0, 100.0))),
    'max_speed': (1.0, _descriptor('Speed limit [m/s], > 0.', floating=(1.0e-3, 100.0))),
    'num_directions': (64, _descriptor(
        'Candidate headings evaluated per plan.', integer=(1, 4096))),
    'time_horizon': (5.0, _descriptor(
        'Collisions later than this many seconds do not constrain now; .inf for none.')),
    'neighbor_distance': (10.0, _descriptor(
        'Neighbours farther than this [m] are not considered.', floating=(0.0, 1.0e4))),
    'actuation_std': (0.0, _descriptor(
        "Std of this robot's velocity execution error per axis [m/s] (PRVO ego noise).",
        floating=(0.0, 10.0))),
    'safety_margin': (0.0, _descriptor(
        'Extra clearance added to the sum of radii [m].', floating=(0.0, 10.0))),
    'model': ('prvo', _descriptor('Planner model: prvo, rvo, inflate or mc.')),
    'method': ('exact', _descriptor('PRVO ray solver: exact (quartic) or taylor (paper).')),
    'risk': ('pairwise', _descriptor('Risk allocation over neighbours: pairwise or joint.')),
    'goal': (None, _descriptor(
        'Goal [x, y] in the map frame; unset = wait for a goal_pose message.', dynamic=True)),
    'goal_tolerance': (0.2, _descriptor(
        'Distance to the goal [m] under which the robot stops.', floating=(1.0e-3, 100.0))),
    'approach_time': (0.5, _descriptor(
        'Preferred speed is distance / approach_time near the goal [s].',
        floating=(1.0e-3, 100.0))),
    'stamped_cmd_vel': (True, _descriptor(
        'Publish geometry_msgs/TwistStamped (true) or Twist (false).', read_only=True)),
    'neighbors': (None, _descriptor(
        'Robot names to avoid; unset discovers every other /<name>/odom in the graph.',
        read_only=True, dynamic=True)),
    'neighbor_timeout': (2.0, _descriptor(
        'A neighbour silent this long [s, wall time] is dropped.', floating=(0.01, 3600.0))),
    'sync_timeout': (0.2, _descriptor(
        "Wall time [s] to wait for neighbours' odometry of the same stamp before planning.",
        floating=(0.0, 10.0))),
    'status_period': (0.2, _descriptor(
        'Diagnostics and markers are published at most this often [s, wall]; cmd_vel always.',
        floating=(0.0, 60.0))),
    'acceleration_std': (1.0, _descriptor(
        'Process noise of the constant-velocity tracker [m/s^2].', floating=(1.0e-3, 100.0))),
    'frame_id': ('map', _descriptor('World frame of odometry and goals.', read_only=True)),
    'seed': (-1, _descriptor(
        'Seed for the random rotation of candidate headings; -1 = fixed headings.',
        integer=(-1, 2 ** 31 - 1))),
    # Both only rank the velocities that meet the constraints (issue 5): without them,
    # the closest-to-v_pref choice flips side from one step to the next (the chosen
    # command turned by more than 90 degrees in 15% of the steps of circle8, PRVO eta 0.8).
    'inertia': (0.5, _descriptor(
        'Weight in [0, 1) of |v - previous command| in the choice cost |v - v_pref| + ...; '
        'damps side flips. 0 = closest to v_pref.', floating=(0.0, 0.99))),
    'passing_bias': (0.1, _descriptor(
        'Cost per m/s of velocity left of the preferred direction: every robot breaks the '
        'tie of a symmetric encounter the same way (pass on the right). 0 = none.',
        floating=(0.0, 10.0))),
}


def _goal_from_parameter(value):
    """Return the goal (2,) from the `goal` parameter, None when unset; raise ParameterError."""
    if value is None:
        return None
    if (not isinstance(value, (list, tuple)) or len(value) != 2
            or not all(isinstance(item, (int, float)) and not isinstance(item, bool)
                       and math.isfinite(item) for item in value)):
        raise ParameterError(f'goal must be [x, y] with finite numbers, got {value!r}')
    return np.array(value, dtype=float)


def _neighbour_list(value):
    """Return the `neighbors` parameter as a list of names, None to discover them."""
    if value is None:
        return None
    if not isinstance(value, (list, tuple)) or not all(isinstance(n, str) for n in value):
        raise ParameterError(f'neighbors must be a list of robot names, got {value!r}')
    return [name for name in value if name]


def planner_config_from(values):
    """Build the core's PlannerConfig from a name -> value mapping of parameters.

    Raises ParameterError naming the parameter and value when the planner cannot use it.
    """
    eta = values['eta']
    if not 0.0 < eta < 1.0:
        raise ParameterError(f'eta must be in (0, 1), got {eta}')
    k = values['k']
    if k != -1.0 and k < 0.0:
        raise ParameterError(f'k must be >= 0 (or -1 to use eta), got {k}')
    time_horizon = values['time_horizon']
    if not time_horizon > 0.0:
        raise ParameterError(f'time_horizon must be > 0 (.inf for none), got {time_horizon}')
    actuation_variance = values['actuation_std'] ** 2
    try:
        return PlannerConfig(
            eta=eta, k=None if k == -1.0 else k, max_speed=values['max_speed'],
            num_directions=values['num_directions'], time_horizon=time_horizon,
            neighbor_distance=values['neighbor_distance'],
            actuation_cov=actuation_variance * np.eye(2),
            safety_margin=values['safety_margin'], method=values['method'],
            model=values['model'], risk=values['risk'],
            seed=None if values['seed'] < 0 else values['seed'], inertia=values['inertia'],
            passing_bias=values['passing_bias'])
    except ValueError as error:
        raise ParameterError(str(error)) from error


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
        self._values = {name: self.get_parameter(name).value for name in _PARAMETERS}
        self._config = planner_config_from(self._values)
        self._goal = _goal_from_parameter(self._values['goal'])
        self._neighbours_listed = _neighbour_list(self._values['neighbors'])
        self.add_on_set_parameters_callback(self._on_set_parameters)

        self._robot = self.get_namespace().strip('/')
        if not self._robot or '/' in self._robot:
            raise ParameterError(
                f'run the planner in a robot namespace (-r __ns:=/robot_0), '
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
        for parameter in parameters:
            if parameter.name in values:
                values[parameter.name] = parameter.value
        try:
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
