"""Scripted robots: robots that follow waypoints at a set speed and avoid nobody.

People and robots on another stack, as a team's planners meet them. Pure numpy: the world asks
each `WaypointFollower` for its robot's command and executes it like any other (clamped,
disturbed by the scenario's actuation noise from the world's generator).
"""

import numpy as np


class WaypointFollower:
    """The command of one scripted robot: towards each waypoint in turn at `speed`.

    A waypoint is passed once the step that reaches it (the command `distance / dt`, at most
    `speed`) has been executed; after the last waypoint the robot heads for the first again if
    `loop`, else it holds the last one (command zero when it is there).
    """

    def __init__(self, path):
        self.waypoints = np.asarray(path.waypoints, dtype=float)
        self.speed = float(path.speed)
        self.loop = bool(path.loop)
        self.target = 0

    def command(self, position, dt):
        """Return the world-frame velocity (2,) from POSITION for the next DT; advance target."""
        offset = self.waypoints[self.target] - np.asarray(position, dtype=float)
        distance = float(np.hypot(*offset))
        if distance <= self.speed * dt:
            velocity = offset / dt
            if self.target + 1 < len(self.waypoints):
                self.target += 1
            elif self.loop:
                self.target = 0
            return velocity
        return offset * (self.speed / distance)


def followers_of(robots):
    """Return {index: WaypointFollower} of the scripted robots among ROBOTS (RobotSpecs)."""
    return {index: WaypointFollower(robot.scripted) for index, robot in enumerate(robots)
            if robot.scripted is not None}


def scripted_commands(followers, commands, positions, dt):
    """Return COMMANDS (N, 2) with each scripted robot's row replaced by its follower's command."""
    commands = np.array(commands, dtype=float)
    for index, follower in followers.items():
        commands[index] = follower.command(positions[index], dt)
    return commands
