"""The simulator's messages built from a TeamWorld: odometry, ground truth, diagnostics, map."""

from dataclasses import dataclass

from diagnostic_msgs.msg import DiagnosticStatus
import numpy as np

from prvo_msgs_util import (
    WORLD_FRAME,
    diagnostic_values,
    make_diagnostic_array,
    make_diagnostic_status,
    make_occupancy_grid,
    make_static_world_markers,
    serialize_odometry,
)


def serialized_odometry(world):
    """Return [(noisy odometry, ground truth)] of every robot of WORLD, serialized.

    Serialized messages are sent as they are, without rclpy converting a Python message. A
    unicycle's twist is its forward speed and turn rate, each with variance velocity_std^2;
    its sideways speed is exactly zero, and so is its variance.
    """
    messages = []
    for index, name in enumerate(world.names):
        yaw = float(world.yaws[index])
        frames = {'frame_id': WORLD_FRAME, 'child_frame_id': f'{name}/base_link', 'yaw': yaw}
        variance = world.velocity_std[index] ** 2
        if world.unicycle[index]:
            heading = np.array([np.cos(yaw), np.sin(yaw)])
            velocity_cov = variance * np.outer(heading, heading)
            turn = {'turn_rate_variance': variance}
        else:
            velocity_cov = variance * np.eye(2)
            turn = {}
        odometry = serialize_odometry(
            world.time, world.measured_positions[index], world.measured_velocities[index],
            world.position_std[index] ** 2 * np.eye(2), velocity_cov,
            turn_rate=float(world.measured_turn_rates[index]), **turn, **frames)
        ground_truth = serialize_odometry(
            world.time, world.positions[index], world.velocities[index], np.zeros((2, 2)),
            np.zeros((2, 2)), turn_rate=float(world.turn_rates[index]), **frames)
        messages.append((odometry, ground_truth))
    return messages


def status_array(world, message, mode, deadline_misses):
    """Return the DiagnosticArray of statuses `prvo_sim` (MESSAGE) and `prvo_sim/<robot>`.

    DEADLINE_MISSES gives each robot's count; the keys are those of docs/interfaces.md.
    """
    total_misses = sum(deadline_misses)
    warn = world.contact_count or world.wall_contact_count or total_misses
    statuses = [make_diagnostic_status(
        'prvo_sim', message,
        {'sim_time': world.time, 'step': world.step_count, 'finished': world.finished,
         'contacts': world.contact_count, 'wall_contacts': world.wall_contact_count,
         'deadline_misses': total_misses, 'mode': mode},
        level=DiagnosticStatus.WARN if warn else DiagnosticStatus.OK)]
    arrived = world.arrived()
    for index, name in enumerate(world.names):
        values = {'deadline_misses': deadline_misses[index], 'arrived': bool(arrived[index]),
                  'x': float(world.positions[index, 0]), 'y': float(world.positions[index, 1]),
                  'scripted': index in world.followers}
        message = 'arrived' if arrived[index] else 'driving'
        if index in world.followers:
            # A scripted robot's goal is its last waypoint; which one it heads for says more.
            values['waypoint'] = world.followers[index].target
            message = f'scripted, heading for waypoint {values["waypoint"]}'
        statuses.append(make_diagnostic_status(
            f'prvo_sim/{name}', message, values,
            level=DiagnosticStatus.WARN if deadline_misses[index] else DiagnosticStatus.OK))
    return make_diagnostic_array(world.time, statuses)


@dataclass(frozen=True)
class SimStatus:
    """The simulator's `prvo_sim` status as a reader needs it (see `status_array`)."""

    step: int
    finished: bool
    deadline_misses: int
    contacts: int


def sim_status_of(status):
    """Return the SimStatus of a DiagnosticStatus named `prvo_sim`, None for any other."""
    if status.name != 'prvo_sim':
        return None
    values = diagnostic_values(status)
    return SimStatus(step=int(values['step']), finished=values['finished'] == 'true',
                     deadline_misses=int(values['deadline_misses']),
                     contacts=int(values['contacts']))


def contact_array(world, contact):
    """Return the DiagnosticArray of one `contact` status for CONTACT (a world.Contact)."""
    first, second = world.names[contact.first], world.names[contact.second]
    return make_diagnostic_array(contact.time, [make_diagnostic_status(
        'contact', f'{first} and {second} in contact',
        {'robot_a': first, 'robot_b': second, 'time': contact.time,
         'distance': contact.distance}, level=DiagnosticStatus.WARN)])


def wall_contact_array(world, contact):
    """Return the DiagnosticArray of one `wall_contact` status for CONTACT (world.WallContact)."""
    name = world.names[contact.robot]
    return make_diagnostic_array(contact.time, [make_diagnostic_status(
        'wall_contact', f'{name} in contact with a wall or obstacle',
        {'robot': name, 'time': contact.time, 'clearance': contact.clearance},
        level=DiagnosticStatus.WARN)])


def map_message(world):
    """Return the nav_msgs/OccupancyGrid of WORLD's static shapes (its rasterised grid).

    None for a world without walls, obstacles or map. Stamped at t = 0, in the world frame.
    """
    grid = world.static_world.grid
    if grid is None:
        return None
    return make_occupancy_grid(0.0, grid.cells, grid.resolution, grid.origin, WORLD_FRAME)


def static_world_markers(world):
    """Return the MarkerArray of WORLD's walls and obstacles (the map shows on /map)."""
    static = world.static_world
    return make_static_world_markers(0.0, WORLD_FRAME, static.walls, static.discs,
                                     static.polygons)
