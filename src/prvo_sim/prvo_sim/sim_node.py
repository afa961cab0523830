"""The `sim` node: one process simulates every robot of a scenario.

The world (`prvo_sim.world.TeamWorld`) executes each robot's cmd_vel with single-integrator
kinematics; this node gives it its ROS endpoints (noisy odometry, exact ground truth, /clock,
diagnostics and contact events) and its timing, lockstep or realtime, whose rules
`prvo_sim.step_timing.StepTiming` keeps. Topics, QoS, lockstep and diagnostics follow
docs/interfaces.md.
"""

import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Twist, TwistStamped
from nav_msgs.msg import OccupancyGrid, Odometry
import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.exceptions import ParameterException
from rclpy.node import Node
from rosgraph_msgs.msg import Clock as ClockMsg
from visualization_msgs.msg import MarkerArray

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
    MAP,
    MAP_QOS,
    ODOM,
    ODOM_QOS,
    WORLD_MARKERS,
    Announcer,
    MessageFault,
    QosWatch,
    declare_parameters,
    quiet_after_shutdown,
    quiet_publisher_events,
    quiet_subscription_events,
    robot_topic,
    run_node,
    seconds_to_stamp,
)
from prvo_planner.agent import ANNOUNCED_FROM_THE_START, UNANNOUNCED_SHARE
from prvo_sim.commands import command_velocity, unicycle_command
from prvo_sim.observers import ObserverGate
from prvo_sim.scenario import ScenarioError, find_scenario, load_scenario
from prvo_sim.sim_parameters import PARAMETERS, parameter_fault
from prvo_sim.step_timing import REPUBLISH, STEP, StepTiming
from prvo_sim.world import TeamWorld
from prvo_sim.world_messages import (
    contact_array,
    map_message,
    serialized_odometry,
    static_world_markers,
    status_array,
    wall_contact_array,
)

# How often timeouts, the cmd_vel publishers and the observers are checked [s]. Only timeouts
# are polled (answers step the simulation from their callback): each poll is a spin of the
# executor, which costs as much as a message.
_POLL_PERIOD = 0.02
# How often the status is published while idle.
_IDLE_STATUS_PERIOD = 1.0
# How often the graph is checked for endpoints with incompatible QoS (prvo_msgs_util.QosWatch).
_QOS_CHECK_PERIOD = 1.0
_WARNING_THROTTLE = 2.0


class _Robot:
    """One simulated robot's ROS side: its topics, publishers and command in force.

    A scripted robot (SCRIPTED) is moved by the world: it has no cmd_vel.
    """

    def __init__(self, name, scripted=False):
        self.name = name
        self.scripted = scripted
        self.cmd_vel_topic = robot_topic(name, CMD_VEL)
        self.base_frame = f'{name}/base_link'
        self.command = np.zeros(2)
        self.odom_publisher = None
        self.ground_truth_publisher = None
        self.logger = None


class SimNode(Node):
    """Simulator of a scenario's team, in lockstep with the planners or on a wall timer."""

    def __init__(self):
        super().__init__('prvo_sim')
        self.add_on_set_parameters_callback(self._validate_parameters)
        values = declare_parameters(self, PARAMETERS)
        self._mode, seed, observers = values['mode'], values['seed'], values['observers'] or []
        scenario = load_scenario(find_scenario(values['scenario']),
                                 seed=None if seed < 0 else seed)
        self._world = TeamWorld(scenario)
        self._robots = [_Robot(spec.name, spec.scripted is not None) for spec in scenario.robots]
        # The robots whose cmd_vel lockstep waits for.
        planned = [index for index, robot in enumerate(self._robots) if not robot.scripted]
        self._planned = [self._robots[index] for index in planned]
        self._stamp = seconds_to_stamp(0.0)
        self._waiting_for = 'every cmd_vel publisher'
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
        grid = map_message(self._world)
        if grid is not None:
            # The static world, once and latched, as map_server publishes a map.
            map_publisher = self.create_publisher(OccupancyGrid, MAP, MAP_QOS,
                                                  event_callbacks=quiet())
            markers_publisher = self.create_publisher(MarkerArray, WORLD_MARKERS, MAP_QOS,
                                                      event_callbacks=quiet())
            map_publisher.publish(grid)
            markers_publisher.publish(static_world_markers(self._world))
            endpoints += [map_publisher, markers_publisher]
        # What every observer must subscribe to: each robot's ground truth, /diagnostics and
        # /clock (a recording is complete from t_0).
        observed = [(DIAGNOSTICS, self._diagnostics_publisher), (CLOCK, self._clock_publisher)]
        command_type = TwistStamped if values['stamped_cmd_vel'] else Twist
        for index, robot in enumerate(self._robots):
            robot.odom_publisher = self.create_publisher(
                Odometry, robot_topic(robot.name, ODOM), ODOM_QOS, event_callbacks=quiet())
            ground_truth_topic = robot_topic(robot.name, GROUND_TRUTH)
            robot.ground_truth_publisher = self.create_publisher(
                Odometry, ground_truth_topic, ODOM_QOS, event_callbacks=quiet())
            observed.insert(index, (ground_truth_topic, robot.ground_truth_publisher))
            robot.logger = self.get_logger().get_child(robot.name)
            endpoints += [robot.odom_publisher, robot.ground_truth_publisher]
            if robot.scripted:
                # No planner speaks for a scripted robot: this node announces its size and that
                # it takes no share of the avoidance, latched, as a planner announces its own.
                announcer = Announcer(self, robot.name, in_robot_namespace=False)
                announcer.announce(scenario.robots[index].radius, UNANNOUNCED_SHARE,
                                   ANNOUNCED_FROM_THE_START)
                endpoints += [announcer.footprint_publisher, announcer.share_publisher]
                continue
            endpoints.append(self.create_subscription(
                command_type, robot.cmd_vel_topic,
                lambda msg, index=index: self._on_cmd_vel(index, msg), CMD_VEL_QOS,
                event_callbacks=quiet_subscription_events()))
        self._qos_watch.watch(*endpoints)
        self._observer_gate = ObserverGate(self, observers, observed)

        # Wall timers on a steady clock: they must run even when this node uses sim time.
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._poll_timer = self.create_timer(_POLL_PERIOD, self._poll, clock=steady)
        self.create_timer(_IDLE_STATUS_PERIOD, self._publish_idle_status, clock=steady)
        self.create_timer(_QOS_CHECK_PERIOD, self._check_qos, clock=steady)
        self._realtime_timer = None
        if self._mode == 'realtime':
            self._realtime_timer = self.create_timer(
                1.0 / (values['rate'] or 1.0 / scenario.dt), self._advance, clock=steady,
                autostart=False)
        self._timing = StepTiming(
            len(self._robots), planned, self._mode == 'realtime', values['step_timeout'],
            values['cmd_timeout'], values['startup_timeout'], time.monotonic())
        # Registered once declared: it applies changes to the timing.
        self.add_post_set_parameters_callback(self._apply_parameters)
        self._publish_state()
        observers = f' and observers {", ".join(observers)}' if observers else ''
        self.get_logger().info(
            f'simulating {scenario.name} ({len(self._robots)} robots, seed {self._world.seed}, '
            f'{self._mode}) from {scenario.path}; waiting for every cmd_vel publisher'
            f'{observers}')

    def _validate_parameters(self, parameters):
        for parameter in parameters:
            fault = parameter_fault(parameter.name, parameter.value)
            if fault:
                return SetParametersResult(successful=False, reason=fault)
        return SetParametersResult(successful=True)

    def _apply_parameters(self, parameters):
        for parameter in parameters:
            if parameter.name == 'step_timeout':
                self._timing.step_timeout = parameter.value
            elif parameter.name == 'cmd_timeout':
                self._timing.cmd_timeout = parameter.value

    @quiet_after_shutdown
    def _on_cmd_vel(self, index, msg):
        robot = self._robots[index]
        try:
            if self._world.unicycle[index]:
                command, sideways = unicycle_command(msg, robot.base_frame, self._world)
                if sideways != 0.0:
                    robot.logger.warning(
                        f'{robot.cmd_vel_topic}: linear.y {sideways:.3f} m/s dropped: '
                        f'{robot.name} is a unicycle (linear.x and angular.z only)',
                        throttle_duration_sec=_WARNING_THROTTLE)
            else:
                command = command_velocity(msg, index, robot.base_frame, self._world)
        except MessageFault as fault:
            robot.logger.warning(f'skipping {robot.cmd_vel_topic}: {fault}',
                                 throttle_duration_sec=_WARNING_THROTTLE)
            return
        stamped = isinstance(msg, TwistStamped)
        # In lockstep the answer to a step done (a planner's repeat that crossed the next
        # state) leaves the command in force: the current step's answer, or until it comes
        # the last step's, as an unanswered step executes.
        if not (self._mode == 'lockstep' and stamped
                and _stamp_key(msg.header.stamp) < _stamp_key(self._stamp)):
            robot.command = command
        # An unstamped Twist cannot say which odometry it answers: any after it counts. A
        # duplicate answer finds the robot answered already, or the step it answers done.
        timing = self._timing
        timing.command_received(
            index, not stamped or msg.header.stamp == self._stamp, time.monotonic())
        if (self._mode == 'lockstep' and timing.started and not self._world.finished
                and timing.all_answered()):
            self._advance()

    @quiet_after_shutdown
    def _poll(self):
        now, timing = time.monotonic(), self._timing
        if not timing.started:
            if not self._ready_to_start():
                if timing.republish_due(now):
                    self._send_last_state()
                return
            # The t_0 state once more, unchanged, so that a late subscriber gets the same draw.
            timing.start(now)
            self._send_last_state()
            self.get_logger().info('every cmd_vel has a publisher, every observer subscribes: '
                                   'stepping')
        if self._world.finished:
            return
        due = timing.due(now, first_step=self._world.step_count == 0)
        if due == STEP:
            self._advance()
        elif due == REPUBLISH:
            self._send_last_state()
        if self._realtime_timer is not None and self._world.step_count > 0:
            # Realtime: the first step waited for every answer, as in lockstep (a planner's
            # first plan includes its warm-up); from t_1 on a wall timer steps.
            self._poll_timer.cancel()
            self._realtime_timer.reset()

    def _ready_to_start(self):
        """Whether every cmd_vel has a publisher and every observer subscribes; else say why."""
        if any(self.count_publishers(robot.cmd_vel_topic) == 0 for robot in self._planned):
            self._waiting_for = 'every cmd_vel publisher'
            return False
        missing = self._observer_gate.missing()
        if not missing:
            return True
        self._waiting_for = 'observers: ' + ', '.join(self._observer_gate.observers)
        self.get_logger().info(
            f'waiting for observers: {ObserverGate.describe(missing)}',
            throttle_duration_sec=_WARNING_THROTTLE)
        return False

    @quiet_after_shutdown
    def _advance(self):
        """Execute every robot's command for one dt and publish the state at t_(k+1)."""
        world = self._world
        if world.finished:
            return
        late, stopped = self._timing.close_step(time.monotonic())
        if late:
            self.get_logger().warning(self._timing.deadline_miss_message(
                late, [robot.name for robot in self._robots], world.time),
                throttle_duration_sec=_WARNING_THROTTLE)
        for index, silence in stopped:
            robot = self._robots[index]
            robot.command = np.zeros(2)
            robot.logger.warning(
                f'no cmd_vel from {robot.name} for {silence:.2f} s (cmd_timeout '
                f'{self._timing.cmd_timeout:g} s): executing zero velocity until its next '
                'command')
        for contact in world.step([robot.command for robot in self._robots]):
            self._report_contact(contact)
        for contact in world.last_wall_contacts:
            self._report_wall_contact(contact)
        self._stamp = seconds_to_stamp(world.time)
        self._publish_state()
        self._timing.step_published(time.monotonic())
        if world.finished:
            self._poll_timer.cancel()
            if self._realtime_timer is not None:
                self._realtime_timer.cancel()
            self.get_logger().info(
                f'finished at t={world.time:.3f} s: {world.contact_count} contacts, '
                f'{world.wall_contact_count} with walls, '
                f'{sum(self._timing.deadline_misses)} deadline misses')

    def _report_contact(self, contact):
        first, second = self._robots[contact.first].name, self._robots[contact.second].name
        self.get_logger().warning(
            f'contact at t={contact.time:.3f} s: {first} and {second}, centre distance '
            f'{contact.distance:.3f} m')
        self._contacts_publisher.publish(contact_array(self._world, contact))

    def _report_wall_contact(self, contact):
        name = self._robots[contact.robot].name
        self.get_logger().warning(
            f'contact at t={contact.time:.3f} s: {name} and a wall or obstacle',
            throttle_duration_sec=_WARNING_THROTTLE)
        self._contacts_publisher.publish(wall_contact_array(self._world, contact))

    def _publish_state(self):
        """Publish /clock, every robot's odometry, then ground truth and diagnostics.

        Every message is built before the first is sent: each odometry message wakes planners
        that then compete with this process for the CPU, and a planner plans only once all its
        neighbours' odometry is in, so the odometry goes out back to back.
        """
        self._last_odometry = serialized_odometry(self._world)
        self._send_last_state()

    def _send_last_state(self):
        """Publish /clock, every robot's last odometry, every ground truth, then the status.

        The status goes with every state sent, also the first state sent again before and when
        stepping starts: a recording that holds a state holds the simulator's status with it.
        """
        self._clock_publisher.publish(ClockMsg(clock=self._stamp))
        for robot, (odometry, _) in zip(self._robots, self._last_odometry, strict=True):
            robot.odom_publisher.publish(odometry)
        for robot, (_, ground_truth) in zip(self._robots, self._last_odometry, strict=True):
            robot.ground_truth_publisher.publish(ground_truth)
        self._publish_status()

    @quiet_after_shutdown
    def _check_qos(self):
        self._qos_watch.check()

    @quiet_after_shutdown
    def _publish_idle_status(self):
        # Stepping publishes a status every step; before and after, this keeps it visible.
        if not self._timing.started or self._world.finished:
            self._publish_status()

    def _publish_status(self):
        if self._world.finished:
            message = 'finished'
        else:
            message = 'running' if self._timing.started else f'waiting for {self._waiting_for}'
        self._diagnostics_publisher.publish(status_array(
            self._world, message, self._mode, self._timing.deadline_misses))


def _stamp_key(stamp):
    """Return a builtin_interfaces/Time STAMP as (sec, nanosec), which orders stamps."""
    return stamp.sec, stamp.nanosec


def main(args=None):
    """Run the simulator until SIGINT or SIGTERM; exit 2 if the scenario or a parameter is bad."""
    return run_node(SimNode, 'prvo_sim', (ScenarioError, ParameterException), args)


if __name__ == '__main__':
    sys.exit(main())
