"""A simulated robot's cmd_vel as the command it executes, or why it is refused.

A holonomic robot executes a world-frame velocity (`command_velocity`), a unicycle its forward
speed and turn rate (`unicycle_command`).
"""

import math

from geometry_msgs.msg import TwistStamped

from prvo_msgs_util import (
    WORLD_FRAME,
    MessageFault,
    body_to_world,
    stamp_to_seconds,
    twist_to_velocity,
)
from prvo_sim.world import YAW_HISTORY

# A commanded speed above this [m/s] is a corrupt message, not a fast robot.
MAX_COMMAND_SPEED = 1e3


def command_velocity(msg, index, base_frame, world):
    """Return cmd_vel MSG of robot INDEX of WORLD as a world-frame velocity (2,).

    A TwistStamped is in its header's frame, `map` (or empty) or BASE_FRAME, rotated by the
    robot's heading at the step of its stamp; a plain Twist is in BASE_FRAME, as cmd_vel
    conventionally is. Raises MessageFault naming the fault: a NaN or infinite component, a
    speed above MAX_COMMAND_SPEED, another frame, or a stamp after the world's time or
    YAW_HISTORY steps or more before it.
    """
    velocity = twist_to_velocity(msg)
    speed = math.hypot(*velocity)
    if speed > MAX_COMMAND_SPEED:
        raise MessageFault(f'speed {speed:.3f} m/s is above {MAX_COMMAND_SPEED:g} m/s')
    if not isinstance(msg, TwistStamped):
        return body_to_world(velocity, world.yaws[index])
    step = _stamp_step(msg, world)
    frame_id = msg.header.frame_id
    if frame_id in ('', WORLD_FRAME):
        return velocity
    if frame_id != base_frame:
        raise MessageFault(
            f'header.frame_id is {frame_id!r}, expected {WORLD_FRAME!r} or {base_frame!r}')
    return body_to_world(velocity, world.yaws_at(step)[index])



def unicycle_command(msg, base_frame, world):
    """Return (command (forward speed, turn rate), dropped sideways speed) of cmd_vel MSG.

    A unicycle takes `linear.x` and `angular.z` in BASE_FRAME (a TwistStamped's frame may also
    be empty); it cannot move sideways, so a `linear.y` is dropped and returned for a warning
    (0.0 when there is none). Raises MessageFault as `command_velocity` does, and for a turn
    rate that is not finite.
    """
    velocity = twist_to_velocity(msg)
    twist = msg.twist if isinstance(msg, TwistStamped) else msg
    turn = twist.angular.z
    if not math.isfinite(turn):
        raise MessageFault(f'twist.angular.z is {turn}')
    if abs(velocity[0]) > MAX_COMMAND_SPEED:
        raise MessageFault(f'speed {abs(velocity[0]):.3f} m/s is above {MAX_COMMAND_SPEED:g} m/s')
    if isinstance(msg, TwistStamped):
        _stamp_step(msg, world)
        if msg.header.frame_id not in ('', base_frame):
            raise MessageFault(f'header.frame_id is {msg.header.frame_id!r}, expected '
                               f'{base_frame!r}: a unicycle takes body-frame commands')
    return (float(velocity[0]), float(turn)), float(velocity[1])


def _stamp_step(msg, world):
    """Return the step of a TwistStamped's stamp; MessageFault if it is not a recent one."""
    stamp = stamp_to_seconds(msg.header.stamp)
    step = round(stamp / world.scenario.dt)
    if not world.step_count - YAW_HISTORY < step <= world.step_count:
        relation = 'after' if step > world.step_count else (
            f'{YAW_HISTORY} steps or more before')
        raise MessageFault(f'stamp {stamp:.3f} s is {relation} the sim time {world.time:.3f} s')
    return step
