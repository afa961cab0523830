"""The `sim` executable: one process simulates every robot of a scenario.

Publishes each robot's noisy odometry and exact ground truth, /clock, diagnostics and contact
events; executes each robot's cmd_vel with single-integrator kinematics. Topics, QoS, lockstep
and diagnostics follow docs/interfaces.md.
"""

import math
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import Twist, TwistStamped
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
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rosgraph_msgs.msg import Clock as ClockMsg

from prvo_msgs_util import (
    CLOCK,
    CLOCK_QOS,
    CMD_VEL,
    CMD_VEL_QOS,
    CONTACT_QOS,
    CONTACTS,
    DIAGNOSTICS,
    DIAGNOSTICS_QOS,
    GROUND_TRUTH,
    ODOM,
    ODOM_QOS,
    MessageFault,
    QosWatch,
    SigintRecorder,
    freeze_startup_objects,
    make_diagnostic_array,
    make_diagnostic_status,
    quiet_publisher_events,
    quiet_subscription_events,
    robot_topic,
    seconds_to_stamp,
    serialize_odometry,
    spin_events,
    stamp_to_seconds,
    twist_to_velocity,
)
from prvo_sim import kinematics
from prvo_sim.scenario import ScenarioError, find_scenario, load_scenario

MODES = ('lockstep', 'realtime')
WORLD_FRAME = 'map'
# Exit code of a run rejected at startup (bad scenario or parameter).
EXIT_BAD_INPUT = 2
# Lockstep: how often the step timeout and the cmd_vel publishers are checked [s].
# Only timeouts are polled (answers step the simulation from their callback): each poll is a
# spin of the executor, which costs as much as a message.
_POLL_PERIOD = 0.02
# Headings of this many recent steps are kept to turn late body-frame commands into the world.
_YAW_HISTORY = 32
# How often the t_0 odometry is re-sent while waiting for planners, and the status while idle.
_REPUBLISH_PERIOD = 0.5
_IDLE_STATUS_PERIOD = 1.0
# How often the graph is checked for endpoints with incompatible QoS (prvo_msgs_util.QosWatch).
_QOS_CHECK_PERIOD = 1.0
# Below this executed speed [m/s] the heading is noise, so the last heading is kept.
_HEADING_MIN_SPEED = 1e-3
_WARNING_THROTTLE = 2.0


class _Robot:
    """One simulated robot's ROS side: its topics, last command and deadline record."""

    def __init__(self, spec):
        self.spec = spec
        self.cmd_vel_topic = robot_topic(spec.name, CMD_VEL)
        self.base_frame = f'{spec.name}/base_link'
        self.command = np.zeros(2)
        self.answered = False
        self.deadline_misses = 0
        self.odom_publisher = None
        self.ground_truth_publisher = None
        self.logger = None


class SimNode(Node):
    """Simulator of a scenario's team, in lockstep with the planners or on a wall timer."""

    def __init__(self):
        super().__init__('prvo_sim')
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)
        self._step_timeout = 1.0
        scenario_name = self.declare_parameter(
            'scenario', '', ParameterDescriptor(
                description='Scenario YAML path, or the name of a packaged scenario',
                read_only=True)).value
        self._mode = self.declare_parameter(
            'mode', 'lockstep', ParameterDescriptor(
                description='lockstep: step once every robot answered; realtime: wall timer',
                read_only=True)).value
        rate = self.declare_parameter(
            'rate', 0.0, ParameterDescriptor(
                description='Realtime step rate [Hz]; 0 means 1 / the scenario dt',
                floating_point_range=[FloatingPointRange(from_value=0.0, to_value=1000.0)],
                read_only=True)).value
        seed = self.declare_parameter(
            'seed', -1, ParameterDescriptor(
                description="Noise seed; -1 uses the scenario file's",
                integer_range=[IntegerRange(from_value=-1, to_value=2**31 - 1)],
                read_only=True)).value
        stamped = self.declare_parameter(
            'stamped_cmd_vel', True, ParameterDescriptor(
                description='Subscribe to TwistStamped cmd_vel (false: plain Twist)',
                read_only=True)).value
        self.declare_parameter(
            'step_timeout', 1.0, ParameterDescriptor(
                description='Lockstep: wall time [s] to wait for every cmd_vel before stepping',
                floating_point_range=[FloatingPointRange(from_value=0.001, to_value=3600.0)]))

        self._startup_timeout = self.declare_parameter(
            'startup_timeout', 10.0, ParameterDescriptor(
                description='Wall time [s] the first step waits for every cmd_vel (both modes), '
                            're-sending the t_0 odometry, so that late joiners are in from t_0',
                floating_point_range=[FloatingPointRange(from_value=0.001, to_value=3600.0)],
                read_only=True)).value

        self._scenario = load_scenario(
            find_scenario(scenario_name), seed=None if seed < 0 else seed)
        self._rng = np.random.default_rng(self._scenario.seed)
        self._robots = [_Robot(spec) for spec in self._scenario.robots]
        specs = self._scenario.robots
        self._radii = np.array([spec.radius for spec in specs])
        self._max_speeds = np.array([spec.max_speed for spec in specs])
        self._goals = np.array([spec.goal for spec in specs])
        self._actuation_std = np.array([spec.noise.actuation_std for spec in specs])
        self._position_std = np.array([spec.noise.position_std for spec in specs])
        self._velocity_std = np.array([spec.noise.velocity_std for spec in specs])
        self._positions = np.array([spec.start for spec in specs])
        self._velocities = np.zeros_like(self._positions)
        # A robot placed at its start faces its goal until it first moves.
        to_goal = self._goals - self._positions
        self._yaws = np.arctan2(to_goal[:, 1], to_goal[:, 0])
        self._yaws_at_step = {}
        self._final_step = math.ceil(self._scenario.duration / self._scenario.dt - 1e-9)
        self._step = 0
        self._stamp = seconds_to_stamp(0.0)
        self._started = False
        self._finished = False
        self._in_contact = set()
        self._contact_count = 0
        self._published_at = time.monotonic()
        self._last_odometry = []

        # Endpoints without rclpy's QoS event handlers (each would cost every executor wake-up);
        # the watch reports incompatible QoS from the graph instead.
        self._qos_watch = QosWatch(self)
        quiet = quiet_publisher_events
        self._clock_publisher = self.create_publisher(
            ClockMsg, CLOCK, CLOCK_QOS, event_callbacks=quiet())
        self._diagnostics_publisher = self.create_publisher(
            DiagnosticArray, DIAGNOSTICS, DIAGNOSTICS_QOS, event_callbacks=quiet())
        self._contacts_publisher = self.create_publisher(
            DiagnosticArray, CONTACTS, CONTACT_QOS, event_callbacks=quiet())
        endpoints = [self._clock_publisher, self._diagnostics_publisher, self._contacts_publisher]
        command_type = TwistStamped if stamped else Twist
        for index, robot in enumerate(self._robots):
            robot.odom_publisher = self.create_publisher(
                Odometry, robot_topic(robot.spec.name, ODOM), ODOM_QOS, event_callbacks=quiet())
            robot.ground_truth_publisher = self.create_publisher(
                Odometry, robot_topic(robot.spec.name, GROUND_TRUTH), ODOM_QOS,
                event_callbacks=quiet())
            robot.logger = self.get_logger().get_child(robot.spec.name)
            command_subscription = self.create_subscription(
                command_type, robot.cmd_vel_topic,
                lambda msg, index=index: self._on_cmd_vel(index, msg), CMD_VEL_QOS,
                event_callbacks=quiet_subscription_events())
            endpoints += [robot.odom_publisher, robot.ground_truth_publisher, command_subscription]
        for endpoint in endpoints:
            self._qos_watch.watch(endpoint)

        # Wall timers on a steady clock: they must run even when this node uses sim time.
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._poll_timer = self.create_timer(_POLL_PERIOD, self._poll, clock=steady)
        self._idle_timer = self.create_timer(
            _IDLE_STATUS_PERIOD, self._publish_idle_status, clock=steady)
        self.create_timer(_QOS_CHECK_PERIOD, self._qos_watch.check, clock=steady)
        self._realtime_timer = None
        if self._mode == 'realtime':
            self._realtime_timer = self.create_timer(
                1.0 / (rate or 1.0 / self._scenario.dt), self._advance, clock=steady,
                autostart=False)
        self._republished_at = time.monotonic()
        self._publish_state()
        self.get_logger().info(
            f'simulating {self._scenario.name} ({len(self._robots)} robots, seed '
            f'{self._scenario.seed}, {self._mode}) from {self._scenario.path}; waiting for '
            'every cmd_vel publisher')

    def _validate_parameters(self, parameters):
        for parameter in parameters:
            if parameter.name == 'mode' and parameter.value not in MODES:
                return SetParametersResult(
                    successful=False,
                    reason=f'mode must be one of {", ".join(MODES)}, got {parameter.value!r}')
            if parameter.name == 'scenario' and not parameter.value:
                return SetParametersResult(
                    successful=False, reason='scenario is required (a YAML path or a name)')
        return SetParametersResult(successful=True)

    def _apply_parameters(self, parameters):
        for parameter in parameters:
            if parameter.name == 'step_timeout':
                self._step_timeout = parameter.value

    def _on_cmd_vel(self, index, msg):
        robot = self._robots[index]
        try:
            # A plain Twist is in the robot's body frame, as cmd_vel conventionally is.
            if isinstance(msg, TwistStamped):
                # A command answers the odometry of its stamp: rotate by that step's heading.
                step = round(stamp_to_seconds(msg.header.stamp) / self._scenario.dt)
                yaws = self._yaws_at_step.get(step, self._yaws)
                velocity = self._to_world_frame(
                    index, msg.header.frame_id, twist_to_velocity(msg), yaws)
            else:
                velocity = self._to_world_frame(
                    index, robot.base_frame, twist_to_velocity(msg), self._yaws)
        except MessageFault as fault:
            robot.logger.warning(
                f'skipping {robot.cmd_vel_topic}: {fault}',
                throttle_duration_sec=_WARNING_THROTTLE)
            return
        robot.command = velocity
        # An unstamped Twist cannot say which odometry it answers: any after it counts.
        if not isinstance(msg, TwistStamped) or msg.header.stamp == self._stamp:
            robot.answered = True
        if (self._mode == 'lockstep' and self._started and not self._finished
                and all(other.answered for other in self._robots)):
            self._advance()

    def _to_world_frame(self, index, frame_id, velocity, yaws):
        robot = self._robots[index]
        if frame_id in ('', WORLD_FRAME):
            return velocity
        if frame_id != robot.base_frame:
            raise MessageFault(
                f'header.frame_id is {frame_id!r}, expected {WORLD_FRAME!r} or '
                f'{robot.base_frame!r}')
        cos_yaw, sin_yaw = math.cos(yaws[index]), math.sin(yaws[index])
        return np.array([cos_yaw * velocity[0] - sin_yaw * velocity[1],
                         sin_yaw * velocity[0] + cos_yaw * velocity[1]])

    def _poll(self):
        now = time.monotonic()
        if not self._started:
            waiting_for = [robot.spec.name for robot in self._robots
                           if self.count_publishers(robot.cmd_vel_topic) == 0]
            if waiting_for:
                if now - self._republished_at >= _REPUBLISH_PERIOD:
                    self._republish_initial_odometry(now)
                return
            self._started = True
            self._republish_initial_odometry(now)
            self._published_at = now
            self.get_logger().info('every cmd_vel has a publisher: stepping')
        if self._finished:
            return
        if all(robot.answered for robot in self._robots):
            self._advance()
        elif self._step == 0:
            # Whoever is not subscribed yet gets t_0 again: a run starts with everyone in it,
            # which is what makes a seed reproduce its run.
            if now - self._published_at >= self._startup_timeout:
                self._advance()
            elif now - self._republished_at >= _REPUBLISH_PERIOD:
                self._republish_initial_odometry(now)
        elif now - self._published_at >= self._step_timeout:
            self._advance()
        if self._realtime_timer is not None and self._step > 0:
            # Realtime: the first step waited for every answer, as in lockstep (a planner's
            # first plan includes its warm-up); from t_1 on a wall timer steps.
            self._poll_timer.cancel()
            self._realtime_timer.reset()

    def _republish_initial_odometry(self, now):
        """Send the t_0 messages again, unchanged, so a late subscriber gets the same draw."""
        self._republished_at = now
        self._send_last_state()

    def _advance(self):
        """Execute every robot's command for one dt and publish the state at t_(k+1)."""
        if self._finished:
            return
        late = [robot for robot in self._robots if not robot.answered]
        for robot in late:
            robot.deadline_misses += 1
        if late:
            self.get_logger().warning(
                f'deadline miss at t={self._step * self._scenario.dt:.3f}: no cmd_vel from '
                f'{", ".join(robot.spec.name for robot in late)}; reusing the last command',
                throttle_duration_sec=_WARNING_THROTTLE)
        commands = np.array([robot.command for robot in self._robots])
        self._positions, self._velocities = kinematics.step(
            self._positions, commands, self._max_speeds, self._actuation_std,
            self._scenario.dt, self._rng)
        self._step += 1
        self._stamp = seconds_to_stamp(self._step * self._scenario.dt)
        speeds = np.linalg.norm(self._velocities, axis=1)
        moving = speeds > _HEADING_MIN_SPEED
        self._yaws[moving] = np.arctan2(
            self._velocities[moving, 1], self._velocities[moving, 0])
        self._detect_contacts()
        self._finished = self._step >= self._final_step
        for robot in self._robots:
            robot.answered = False
        self._publish_state()
        self._published_at = time.monotonic()
        if self._finished:
            self._poll_timer.cancel()
            if self._realtime_timer is not None:
                self._realtime_timer.cancel()
            self.get_logger().info(
                f'finished at t={self._sim_time():.3f} s: {self._contact_count} contacts, '
                f'{self._total_deadline_misses()} deadline misses')

    def _detect_contacts(self):
        pairs = kinematics.contact_pairs(self._positions, self._radii)
        new_pairs = sorted(pairs - self._in_contact)
        self._in_contact = pairs
        if not new_pairs:
            return
        statuses = []
        for first, second in new_pairs:
            distance = float(np.linalg.norm(self._positions[first] - self._positions[second]))
            names = self._robots[first].spec.name, self._robots[second].spec.name
            self.get_logger().warning(
                f'contact at t={self._sim_time():.3f} s: {names[0]} and {names[1]}, centre '
                f'distance {distance:.3f} m')
            statuses.append(make_diagnostic_status(
                'contact', f'{names[0]} and {names[1]} in contact',
                {'robot_a': names[0], 'robot_b': names[1], 'time': self._sim_time(),
                 'distance': distance},
                level=DiagnosticStatus.WARN))
        self._contact_count += len(new_pairs)
        self._contacts_publisher.publish(make_diagnostic_array(self._sim_time(), statuses))

    def _sim_time(self):
        return self._step * self._scenario.dt

    def _total_deadline_misses(self):
        return sum(robot.deadline_misses for robot in self._robots)

    def _publish_state(self):
        """Publish /clock, every robot's odometry, then ground truth and diagnostics.

        Every message is built before the first is sent: each odometry message wakes planners
        that then compete with this process for the CPU, and a planner plans only once all its
        neighbours' odometry is in, so the odometry goes out back to back.
        """
        now = self._sim_time()
        self._yaws_at_step[self._step] = self._yaws.copy()
        self._yaws_at_step.pop(self._step - _YAW_HISTORY, None)
        noisy_positions, noisy_velocities = kinematics.noisy_odometry(
            self._positions, self._velocities, self._position_std, self._velocity_std,
            self._rng)
        self._last_odometry = []
        for index, robot in enumerate(self._robots):
            frames = {'frame_id': WORLD_FRAME, 'child_frame_id': robot.base_frame,
                      'yaw': float(self._yaws[index])}
            # Serialized: sent as they are, without rclpy converting a Python message.
            odometry = serialize_odometry(
                now, noisy_positions[index], noisy_velocities[index],
                self._position_std[index] ** 2 * np.eye(2),
                self._velocity_std[index] ** 2 * np.eye(2), **frames)
            ground_truth = serialize_odometry(
                now, self._positions[index], self._velocities[index], np.zeros((2, 2)),
                np.zeros((2, 2)), **frames)
            self._last_odometry.append((odometry, ground_truth))
        self._send_last_state()
        self._publish_status()

    def _send_last_state(self):
        """Publish /clock, then every robot's last odometry, then every ground truth."""
        self._clock_publisher.publish(ClockMsg(clock=self._stamp))
        for robot, (odometry, _) in zip(self._robots, self._last_odometry, strict=True):
            robot.odom_publisher.publish(odometry)
        for robot, (_, ground_truth) in zip(self._robots, self._last_odometry, strict=True):
            robot.ground_truth_publisher.publish(ground_truth)

    def _publish_idle_status(self):
        # Stepping publishes a status every step; before and after, this keeps it visible.
        if not self._started or self._finished:
            self._publish_status()

    def _publish_status(self):
        misses = self._total_deadline_misses()
        if self._finished:
            message = 'finished'
        elif self._started:
            message = 'running'
        else:
            message = 'waiting for every cmd_vel publisher'
        statuses = [make_diagnostic_status(
            'prvo_sim', message,
            {'sim_time': self._sim_time(), 'step': self._step, 'finished': self._finished,
             'contacts': self._contact_count, 'deadline_misses': misses, 'mode': self._mode},
            level=DiagnosticStatus.WARN if self._contact_count or misses else DiagnosticStatus.OK)]
        distances_to_goal = np.linalg.norm(self._positions - self._goals, axis=1)
        for index, robot in enumerate(self._robots):
            arrived = bool(distances_to_goal[index] <= self._scenario.goal_tolerance)
            statuses.append(make_diagnostic_status(
                f'prvo_sim/{robot.spec.name}', 'arrived' if arrived else 'driving',
                {'deadline_misses': robot.deadline_misses, 'arrived': arrived,
                 'x': float(self._positions[index, 0]), 'y': float(self._positions[index, 1])},
                level=DiagnosticStatus.WARN if robot.deadline_misses else DiagnosticStatus.OK))
        self._diagnostics_publisher.publish(make_diagnostic_array(self._sim_time(), statuses))


def main(args=None):
    """Run the simulator until SIGINT; exit 2 if the scenario or a parameter is invalid."""
    sigint = SigintRecorder().install()
    rclpy.init(args=args)
    try:
        node = SimNode()
    except (ScenarioError, ParameterException) as error:
        rclpy.logging.get_logger('prvo_sim').error(f'cannot start: {error}')
        rclpy.try_shutdown()
        return EXIT_BAD_INPUT
    freeze_startup_objects()
    try:
        spin_events(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except RuntimeError:
        # A message take in flight when Ctrl-C lands can fail with a RuntimeError. That is the
        # shutdown asked for; anything else is not.
        if rclpy.ok() and not sigint.received:
            raise
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
