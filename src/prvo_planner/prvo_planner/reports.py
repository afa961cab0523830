"""What a planner sends of one plan: its cmd_vel, diagnostic status and belief markers.

The planner node publishes these; the in-process engine's recording builds the same messages.
"""

import math

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
import numpy as np
from visualization_msgs.msg import MarkerArray

from prvo_msgs_util import (
    DIAGNOSTICS,
    DIAGNOSTICS_QOS,
    MARKER_QOS,
    MARKERS,
    make_belief_markers,
    make_diagnostic_array,
    make_diagnostic_status,
    make_twist,
    make_twist_stamped,
    quiet_publisher_events,
    world_to_body,
)
from prvo_planner.core.probability import confidence_ellipse_scale
from prvo_planner.right_of_way import IDLE_INSIDE, IDLE_MOVE

# What a robot holding for its map says (`PlannerAgent.awaiting_map`), in its status and log.
AWAITING_MAP = ('holding with zero commands: no map in force yet, and the one that arrived is '
                'still being built (wait_for_map)')


def command_message(robot, command, stamped):
    """Return the cmd_vel of COMMAND (an agent `Command`): a TwistStamped if STAMPED, else Twist.

    cmd_vel is in the body frame: the world-frame plan is rotated by minus the robot's yaw; a
    unicycle drives forward and turns (its tracking controller's command), nothing else.
    """
    if command.drive is None:
        velocity, turn_rate = world_to_body(command.velocity, command.yaw), 0.0
    else:
        velocity, turn_rate = (command.drive[0], 0.0), command.drive[1]
    if stamped:
        return make_twist_stamped(command.stamp, velocity, f'{robot}/base_link', turn_rate)
    return make_twist(velocity, turn_rate)


def plan_status(robot, command, plan_time_ms, model, planning_radius, cpu_ms=None):
    """Return the `prvo_planner/<ROBOT>` DiagnosticStatus of COMMAND (an agent `Command`).

    PLANNING_RADIUS [m] is the ego radius the plan used (grown by a unicycle's tracking error):
    the eta bound holds for it. The tally's keys count every plan since the planner started:
    `min_achieved_eta` and `tally_stamp` are 'none' before the first. `certificate` is the
    plan's mode and `min_certified_probability` the lowest of its neighbours' bounds that are
    certified ('none' without one). `obstacle_clearance` [m] is the mean's distance from the
    nearest static obstacle grown by the planning radius (inf without obstacles) and
    `obstacle_probability` the probability certified against static obstacles (1 without).
    `route` is the way to the goal: 'none' without a map, 'ok' or 'unreachable' (the robot
    holds its place); the neighbours' routes the plan held are `Command.route_values`. The
    stall keys are `stall_values`'; a stalled robot's status is a WARN, as is that of a robot
    whose centre is inside an obstacle on its map (`inside_message`). `awaiting_map` is true
    while the robot holds for a map still being built (`AWAITING_MAP`, the message then).
    The right of way keys are `right_of_way_values`'; a robot waiting for its turn says so, and
    where no waiting spot fits at its end, that it holds its place (`no_spot_message`).
    `idle_in_passage` names the neighbours that stood in the passage on the robot's route too
    long and claim nothing (comma-separated; 'none'), and the message says so of each
    (`idle_message`). CPU_MS, a planner node's (plan, node) CPU times [ms], gives `plan_cpu_ms`,
    the plan's own, and `node_cpu_ms`, the whole process's since the plan before (every
    callback, the middleware's threads, the map worker); 'none' without (the in-process engine,
    a node's first plan).
    """
    result = command.result
    feasible = True if result is None else bool(result.feasible)
    achieved_k = math.inf if result is None else result.achieved_k
    eta_bound = 1.0 if result is None else result.eta_bound
    certified = [] if result is None else [
        bound for bound, kind in zip(result.neighbour_bounds, result.bound_kinds, strict=True)
        if kind == 'certified']
    tally = command.tally
    stalled = command.stall is not None and command.stall.stalled
    inside = command.inside_obstacle
    messages = [] if inside is None else [inside_message(inside)]
    if command.awaiting_map:
        messages.append(AWAITING_MAP)
    if not feasible:
        messages.append('no velocity meets the chance constraint')
    decision = command.right_of_way
    if decision is not None and not decision.goes:
        messages.append(f'waits for its turn at passage {decision.use.passage}')
        if decision.without_spot:
            messages.append(no_spot_message(robot, decision))
    messages.extend(idle_message(robot) for robot in command.idle_in_passage)
    if stalled:
        messages.append(stall_message(command.stall))
        if command.narrow_passage is not None:
            messages.append(passage_message(command.narrow_passage))
    return make_diagnostic_status(
        f'prvo_planner/{robot}', '; '.join(messages) or 'ok',
        {'achieved_k': achieved_k, 'eta_bound': eta_bound, 'feasible': feasible,
         'neighbours_tracked': len(command.neighbours), 'plan_time_ms': plan_time_ms,
         'arrived': command.arrived, 'model': model, 'planning_radius': planning_radius,
         'route': command.route_status, 'awaiting_map': command.awaiting_map,
         'certificate': 'cantelli' if result is None else result.certificate,
         'min_certified_probability': _or_none(min(certified, default=None)),
         'obstacle_clearance': math.inf if result is None else result.obstacle_clearance,
         'obstacle_probability': 1.0 if result is None else result.obstacle_probability,
         'plans': tally.plans, 'infeasible_plans': tally.infeasible,
         'min_achieved_eta': _or_none(tally.min_achieved_eta),
         'tally_stamp': _or_none(tally.last_stamp), **stall_values(command),
         **command.announcement_values(), **command.route_values(),
         **right_of_way_values(decision),
         'idle_in_passage': ','.join(command.idle_in_passage) or 'none',
         'plan_cpu_ms': 'none' if cpu_ms is None else cpu_ms[0],
         'node_cpu_ms': 'none' if cpu_ms is None else cpu_ms[1]},
        level=(DiagnosticStatus.OK if feasible and not stalled and inside is None
               else DiagnosticStatus.WARN),
        hardware_id=robot)


def stall_message(stall):
    """Return the status message of STALL, a stalled robot's `stalls.StallStatus`."""
    return (f'stalled for {stall.duration:.1f} s at ({stall.position[0]:.2f}, '
            f'{stall.position[1]:.2f}), {stall.distance_to_goal:.2f} m from the goal')


def inside_message(inside):
    """Return the line of a robot inside an obstacle: INSIDE is (position, way out or None)."""
    (x, y), exit_point = inside
    text = f'the robot is inside an obstacle on the map at ({x:.2f}, {y:.2f}): '
    if exit_point is None:
        return text + 'no free cell within obstacle_distance (holding)'
    return text + ('leaving it by the nearest free cell, '
                   f'({exit_point[0]:.2f}, {exit_point[1]:.2f})')


def passage_message(passage):
    """Return the line that names PASSAGE, a `passages.NarrowPassage` a robot holds before."""
    return (f'the way at ({passage.point[0]:.2f}, {passage.point[1]:.2f}) is '
            f'{passage.width:.2f} m wide; certifying it needs at least {passage.needed:.2f} m '
            '(holding)')


def no_spot_message(robot, decision):
    """Return the line of ROBOT waiting by DECISION at a passage end where no spot fits."""
    x, y = decision.entrance
    return (f'{robot} waits at passage {decision.use.passage}, whose end at ({x:.2f}, {y:.2f}) '
            'has no waiting spot (none fits beside it): it holds its place')


def idle_message(robot):
    """Return the line of neighbour ROBOT that stood in a passage too long: it claims nothing."""
    return (f'neighbour {robot} stood in a passage, moving less than {IDLE_MOVE:g} m in '
            f'{IDLE_INSIDE:g} s: it claims nothing (avoided as any neighbour)')


def right_of_way_values(decision):
    """Return the right of way keys of a `right_of_way.Decision` DECISION (None: none).

    `right_of_way`: 'none' (no passage on the route, or the rule off), 'goes' or 'waits';
    with a passage `right_of_way_passage` (its index on the map), `right_of_way_entry` and
    `right_of_way_exit` (the ends the robot comes in and leaves by, 'none' inside or where its
    route ends in it) and `right_of_way_distance` [m] (its way to the passage, inside the way
    left through it); while it
    waits, `waiting_spot_x`, `waiting_spot_y` [m] where it waits ('none': it holds its place).
    """
    if decision is None:
        return {'right_of_way': 'none'}
    use = decision.use
    values = {'right_of_way': 'goes' if decision.goes else 'waits',
              'right_of_way_passage': use.passage, 'right_of_way_entry': _end_or_none(use.entry),
              'right_of_way_exit': _end_or_none(use.exit), 'right_of_way_distance': use.distance}
    if not decision.goes:
        spot = decision.waiting_spot
        values['waiting_spot_x'] = _or_none(None if spot is None else float(spot[0]))
        values['waiting_spot_y'] = _or_none(None if spot is None else float(spot[1]))
    return values


def _end_or_none(end):
    return 'none' if end is None else end


def stall_values(command):
    """Return the stall keys of COMMAND's status (`prvo_planner.stalls`).

    `stalled` (true or false), `stalls` (since the planner started), `longest_stall` [s],
    `longest_dwell` [s] (the longest time within SPOT_RADIUS of one spot away from the goal);
    while stalled also `stall_since` [s, the plan stamps' clock], `stall_duration` [s],
    `stall_x`, `stall_y` [m], `stall_distance_to_goal` [m], `stall_gained` [m over the window]
    and the conditions that bind most: `stall.binding.<i>.neighbour`, `.gap` [m], `.bound`
    and `.kind`, lowest bound first (the wall's are `obstacle_clearance` and
    `obstacle_probability`); in front of a passage too narrow to certify also `passage_x`,
    `passage_y` [m], `passage_width` [m] and `passage_needed` [m] (`passages`).
    """
    stall = command.stall
    if stall is None:
        return {'stalled': False, 'stalls': 0, 'longest_stall': 0.0, 'longest_dwell': 0.0}
    values = {'stalled': stall.stalled, 'stalls': stall.stalls,
              'longest_stall': float(stall.longest_stall),
              'longest_dwell': float(stall.longest_dwell)}
    if stall.stalled:
        values.update({'stall_since': float(stall.since), 'stall_duration': stall.duration,
                       'stall_x': float(stall.position[0]), 'stall_y': float(stall.position[1]),
                       'stall_distance_to_goal': float(stall.distance_to_goal),
                       'stall_gained': float(stall.gained)})
        for index, item in enumerate(command.binding):
            values.update({f'stall.binding.{index}.neighbour': item['neighbour'],
                           f'stall.binding.{index}.gap': item['gap_m'],
                           f'stall.binding.{index}.bound': item['bound'],
                           f'stall.binding.{index}.kind': item['kind']})
        passage = command.narrow_passage
        if passage is not None:
            values.update({'passage_x': float(passage.point[0]),
                           'passage_y': float(passage.point[1]),
                           'passage_width': passage.width, 'passage_needed': passage.needed})
    return values


def _or_none(value):
    return 'none' if value is None else float(value)


def plan_markers(robot, command, frame_id, effective_k):
    """Return the MarkerArray of COMMAND: its velocity and every neighbour's confidence ellipse.

    EFFECTIVE_K is the planner's chance-constraint margin, which sizes the ellipses.
    """
    neighbours = command.neighbours
    return make_belief_markers(
        command.stamp, frame_id, robot, command.own.mean[:2], command.velocity,
        np.array([belief.mean[:2] for belief in neighbours]).reshape(-1, 2),
        np.array([belief.covariance[:2, :2] for belief in neighbours]).reshape(-1, 2, 2),
        [announcement.radius for announcement in command.announcements],
        confidence_ellipse_scale(effective_k),
        [announcement.avoidance_share for announcement in command.announcements])


class PlanReporter:
    """A planner node's diagnostics and marker publishers, for people and tools (RViz).

    Reports are few, off the hot path: at most one per period, and markers only while someone
    subscribes to them.
    """

    def __init__(self, node, robot):
        self._robot = robot
        self.diagnostics_publisher = node.create_publisher(
            DiagnosticArray, DIAGNOSTICS, DIAGNOSTICS_QOS,
            event_callbacks=quiet_publisher_events())
        self.marker_publisher = node.create_publisher(
            MarkerArray, MARKERS, MARKER_QOS, event_callbacks=quiet_publisher_events())
        self._reported_at = -math.inf

    def report(self, now, period, command, plan_time_ms, config, planning_radius, frame_id,
               cpu_ms=None):
        """Publish COMMAND's status and markers unless the last report is under PERIOD old.

        NOW and PERIOD are in seconds of one clock; CONFIG is the planner's PlannerConfig;
        CPU_MS as for `plan_status`.
        """
        if now - self._reported_at < period:
            return
        self._reported_at = now
        status = plan_status(self._robot, command, plan_time_ms, config.model, planning_radius,
                             cpu_ms)
        self.diagnostics_publisher.publish(make_diagnostic_array(command.stamp, [status]))
        if self.marker_publisher.get_subscription_count() == 0:
            # Markers take about 0.6 ms to build: only for a listener.
            return
        self.marker_publisher.publish(
            plan_markers(self._robot, command, frame_id, config.effective_k))
