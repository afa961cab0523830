"""What a planner reports of one plan: its diagnostic status and its belief markers.

The planner node publishes these; the in-process engine's recording builds the same messages.
"""

import math

from diagnostic_msgs.msg import DiagnosticStatus
import numpy as np

from prvo_msgs_util import make_belief_markers, make_diagnostic_status
from prvo_planner.core.probability import confidence_ellipse_scale


def plan_status(robot, command, plan_time_ms, model, planning_radius):
    """Return the `prvo_planner/<ROBOT>` DiagnosticStatus of COMMAND (an agent `Command`).

    PLANNING_RADIUS [m] is the ego radius the plan used (grown by a unicycle's tracking error):
    the eta bound holds for it.
    """
    result = command.result
    feasible = True if result is None else bool(result.feasible)
    achieved_k = math.inf if result is None else result.achieved_k
    eta_bound = 1.0 if result is None else result.eta_bound
    return make_diagnostic_status(
        f'prvo_planner/{robot}',
        'ok' if feasible else 'no velocity meets the chance constraint',
        {'achieved_k': achieved_k, 'eta_bound': eta_bound, 'feasible': feasible,
         'neighbours_tracked': len(command.neighbours), 'plan_time_ms': plan_time_ms,
         'arrived': command.arrived, 'model': model, 'planning_radius': planning_radius,
         **command.announcement_values()},
        level=DiagnosticStatus.OK if feasible else DiagnosticStatus.WARN,
        hardware_id=robot)


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
