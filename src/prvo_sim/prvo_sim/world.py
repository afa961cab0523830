"""The world of a scenario without ROS: every robot's state, its noise and its contacts.

`TeamWorld` is what the `sim` node steps; it draws from one seeded generator in a fixed order
(the t_0 odometry, then per step the actuation noise and the odometry of the new state), so a
seed gives the same trajectories whoever drives it.
"""

from dataclasses import dataclass
import math

import numpy as np

from prvo_sim import kinematics, scripted

# Below this executed speed [m/s] the heading is noise, so the last heading is kept.
HEADING_MIN_SPEED = 1e-3
# Headings of this many recent steps are kept (see `TeamWorld.yaws_at`).
YAW_HISTORY = 32


@dataclass(frozen=True)
class Contact:
    """Two robots that came into contact: indices first < second, sim time, centre distance."""

    first: int
    second: int
    time: float
    distance: float


class TeamWorld:
    """Every robot of SCENARIO, stepped with single-integrator kinematics and seeded noise.

    Attributes (arrays over robots, in the scenario's order): `positions`, `velocities` (the
    executed velocities of the last step), `yaws` (ground truth), `measured_positions`,
    `measured_velocities` (the noisy odometry of the current state), `radii`, `max_speeds`,
    `goals`, `position_std`, `velocity_std`, `actuation_std`; `step_count`, `contact_count`;
    `followers`, {index: `scripted.WaypointFollower`} of the scripted robots, whose commands the
    world makes itself.
    """

    def __init__(self, scenario, seed=None):
        self.scenario = scenario
        self.seed = scenario.seed if seed is None else int(seed)
        self.rng = np.random.default_rng(self.seed)
        specs = scenario.robots
        self.names = tuple(spec.name for spec in specs)
        self.radii = np.array([spec.radius for spec in specs])
        self.max_speeds = np.array([spec.max_speed for spec in specs])
        self.goals = np.array([spec.goal for spec in specs])
        self.actuation_std = np.array([spec.noise.actuation_std for spec in specs])
        self.position_std = np.array([spec.noise.position_std for spec in specs])
        self.velocity_std = np.array([spec.noise.velocity_std for spec in specs])
        self.positions = np.array([spec.start for spec in specs], dtype=float)
        self.velocities = np.zeros_like(self.positions)
        self.followers = scripted.followers_of(specs)
        # A robot placed at its start faces its goal (a scripted one its first waypoint) until
        # it first moves.
        to_goal = np.array([spec.goal if spec.scripted is None else spec.scripted.waypoints[0]
                            for spec in specs]) - self.positions
        self.yaws = np.arctan2(to_goal[:, 1], to_goal[:, 0])
        self.final_step = math.ceil(scenario.duration / scenario.dt - 1e-9)
        self.step_count = 0
        self.contact_count = 0
        self._in_contact = set()
        self._yaw_history = {}
        self._record_state()

    @property
    def time(self):
        """Sim time of the current state [s]."""
        return self.step_count * self.scenario.dt

    @property
    def finished(self):
        """Whether the scenario's duration has been reached."""
        return self.step_count >= self.final_step

    def step(self, commands):
        """Execute COMMANDS (N, 2), world-frame velocities, for one dt; return new `Contact`s.

        Each command is clamped to its robot's max speed and disturbed by actuation noise, the
        heading follows the executed velocity, and the odometry of the new state is drawn. A
        scripted robot's row is ignored: it executes its follower's command.
        """
        commands = np.asarray(commands, dtype=float)
        if commands.shape != self.positions.shape or not np.all(np.isfinite(commands)):
            raise ValueError(
                f'commands must be finite, of shape {self.positions.shape}, got {commands!r}')
        commands = scripted.scripted_commands(self.followers, commands, self.positions,
                                              self.scenario.dt)
        self.positions, self.velocities = kinematics.step(
            self.positions, commands, self.max_speeds, self.actuation_std, self.scenario.dt,
            self.rng)
        self.step_count += 1
        moving = np.linalg.norm(self.velocities, axis=1) > HEADING_MIN_SPEED
        self.yaws[moving] = np.arctan2(self.velocities[moving, 1], self.velocities[moving, 0])
        contacts = self._new_contacts()
        self._record_state()
        return contacts

    def yaws_at(self, step):
        """Return the headings at STEP (one of the last `YAW_HISTORY`), else the current ones."""
        return self._yaw_history.get(step, self.yaws)

    def arrived(self):
        """Return, per robot, whether its ground truth is within the goal tolerance."""
        distances = np.linalg.norm(self.positions - self.goals, axis=1)
        return distances <= self.scenario.goal_tolerance

    def _record_state(self):
        self._yaw_history[self.step_count] = self.yaws.copy()
        self._yaw_history.pop(self.step_count - YAW_HISTORY, None)
        self.measured_positions, self.measured_velocities = kinematics.noisy_odometry(
            self.positions, self.velocities, self.position_std, self.velocity_std, self.rng)

    def _new_contacts(self):
        pairs = kinematics.contact_pairs(self.positions, self.radii)
        new_pairs = sorted(pairs - self._in_contact)
        self._in_contact = pairs
        self.contact_count += len(new_pairs)
        return [Contact(first, second, self.time,
                        float(np.linalg.norm(self.positions[first] - self.positions[second])))
                for first, second in new_pairs]
