"""The world of a scenario without ROS: every robot's state, its noise and its contacts.

Holonomic robots execute world-frame velocities; unicycle (differential-drive) robots execute a
forward speed and a turn rate along exact arcs. Either kind may have acceleration limits.
The scenario's walls, obstacles and map (`prvo_sim.static_world.StaticWorld`) are solid: a robot
whose step would take it into one stops at its surface, the part of its motion into it removed
and the rest along the surface kept (tested on the straight motion of the step, so no robot
passes through a thin wall; a unicycle's arc is taken by its chord), and the contact counts.

`TeamWorld` is what the `sim` node steps; it draws from one seeded generator in a fixed order
(the t_0 odometry, then per step the actuation noise and the odometry of the new state), so a
seed gives the same trajectories whoever drives it.
"""

from dataclasses import dataclass
import math

import numpy as np

from prvo_sim import kinematics, scripted
from prvo_sim.static_world import CONTACT_TOLERANCE

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


@dataclass(frozen=True)
class WallContact:
    """A robot that came into contact with a static shape: index, sim time, clearance [m].

    The clearance is 0 up to rounding: the world stops a robot at the surface.
    """

    robot: int
    time: float
    clearance: float


class TeamWorld:
    """Every robot of SCENARIO, stepped with its kinematics and seeded noise.

    Attributes (arrays over robots, in the scenario's order): `positions`, `velocities` (the
    executed world-frame velocities of the last step), `yaws` (ground truth), `turn_rates`
    (executed, 0 for holonomic robots), `unicycle` (bool), `measured_positions`,
    `measured_velocities`, `measured_turn_rates` (the noisy odometry of the current state),
    `radii`, `max_speeds`, `goals`, `position_std`, `velocity_std`, `actuation_std`;
    `step_count`, `contact_count`; `static_world`, the scenario's walls, obstacles and map
    (`StaticWorld`; its `grid`, the rasterised `GridMap` of them all, None without any);
    `wall_contact_count` and `last_wall_contacts` (the `WallContact`s of the last step);
    `followers`, {index: `scripted.WaypointFollower`} of the
    scripted robots, whose commands the world makes itself.
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
        # A robot placed at its start faces its goal (a scripted one its first waypoint, any
        # robot its start_yaw if given) until it first moves.
        to_goal = np.array([spec.goal if spec.scripted is None else spec.scripted.waypoints[0]
                            for spec in specs]) - self.positions
        self.yaws = np.arctan2(to_goal[:, 1], to_goal[:, 0])
        for index, spec in enumerate(specs):
            if spec.start_yaw is not None:
                self.yaws[index] = spec.start_yaw
        self.unicycle = np.array([spec.kinematics == 'unicycle' for spec in specs])
        self.max_accelerations = np.array([spec.max_acceleration for spec in specs])
        self.unicycle_limits = kinematics.UnicycleLimits(
            *(np.array([getattr(spec, name) for spec in specs])[self.unicycle] for name in (
                'max_speed', 'max_angular_speed', 'max_acceleration',
                'max_angular_acceleration')))
        self.turn_rates = np.zeros(len(specs))
        # What each robot executed last before noise, in its own command space (world-frame
        # velocity, or forward speed and turn rate): acceleration limits act on its change.
        self._last_commands = np.zeros_like(self.positions)
        self.final_step = math.ceil(scenario.duration / scenario.dt - 1e-9)
        self.step_count = 0
        self.contact_count = 0
        self._in_contact = set()
        self.static_world = scenario.static_world
        self.wall_contact_count = 0
        self.last_wall_contacts = []
        self._at_wall = np.zeros(len(specs), dtype=bool)
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
        """Execute COMMANDS (N, 2) for one dt; return new `Contact`s.

        A holonomic robot's row is a world-frame velocity: clamped to its max speed, its change
        limited by its max acceleration, disturbed by actuation noise; its heading follows the
        executed velocity. A unicycle's row is (forward speed, turn rate): clamped and rate
        limited likewise, disturbed on both, integrated along the arc. A scripted robot's row
        is ignored: it executes its follower's command. Then the odometry of the new state is
        drawn.
        """
        commands = np.asarray(commands, dtype=float)
        if commands.shape != self.positions.shape or not np.all(np.isfinite(commands)):
            raise ValueError(
                f'commands must be finite, of shape {self.positions.shape}, got {commands!r}')
        dt = self.scenario.dt
        commands = scripted.scripted_commands(self.followers, commands, self.positions, dt)
        limited = kinematics.rate_limited(commands, self._last_commands,
                                          np.where(self.unicycle, np.inf,
                                                   self.max_accelerations * dt))
        holonomic = ~self.unicycle
        limited[holonomic] = kinematics.clamp_speed(limited[holonomic],
                                                    self.max_speeds[holonomic])
        forward, turn = kinematics.unicycle_commands(
            commands[self.unicycle, 0], commands[self.unicycle, 1],
            self._last_commands[self.unicycle, 0], self._last_commands[self.unicycle, 1],
            self.unicycle_limits, dt)
        limited[self.unicycle, 0], limited[self.unicycle, 1] = forward, turn
        self._last_commands = limited
        noise = self.rng.standard_normal(self.positions.shape) * self.actuation_std[:, None]
        executed = limited + noise
        positions = self.positions + executed * dt
        (positions[self.unicycle], self.yaws[self.unicycle], executed_forward,
         self.turn_rates[self.unicycle]) = kinematics.unicycle_step(
            self.positions[self.unicycle], self.yaws[self.unicycle], forward, turn,
            noise[self.unicycle], dt)
        executed[self.unicycle] = executed_forward[:, None] * np.stack(
            [np.cos(self.yaws[self.unicycle]), np.sin(self.yaws[self.unicycle])], axis=1)
        if not self.static_world.empty:
            positions, executed = self._stopped_at_walls(positions, executed, dt)
        self.positions, self.velocities = positions, executed
        self.step_count += 1
        self.last_wall_contacts = self._new_wall_contacts()
        moving = holonomic & (np.linalg.norm(self.velocities, axis=1) > HEADING_MIN_SPEED)
        self.yaws[moving] = np.arctan2(self.velocities[moving, 1], self.velocities[moving, 0])
        contacts = self._new_contacts()
        self._record_state()
        return contacts

    def _stopped_at_walls(self, positions, executed, dt):
        """Return POSITIONS and EXECUTED velocities with every step into a static shape cut.

        A robot stopped or deflected moves by what it could; its velocity is that motion / dt.
        """
        positions, executed = positions.copy(), executed.copy()
        for index, (start, end) in enumerate(zip(self.positions, positions, strict=True)):
            moved, touched = self.static_world.move(start, end - start, self.radii[index])
            if touched:
                positions[index] = moved
                executed[index] = (moved - start) / dt
        return positions, executed

    def wall_clearances(self):
        """Return (N,) each robot's clearance to the nearest static shape [m] (inf: none)."""
        return self.static_world.clearance(self.positions) - self.radii

    def _new_wall_contacts(self):
        if self.static_world.empty:
            return []
        clearances = self.wall_clearances()
        at_wall = clearances <= CONTACT_TOLERANCE
        new = np.flatnonzero(at_wall & ~self._at_wall)
        self._at_wall = at_wall
        self.wall_contact_count += len(new)
        return [WallContact(int(index), self.time, float(clearances[index])) for index in new]

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
        self.measured_turn_rates = self.turn_rates.copy()
        if self.unicycle.any():
            # A unicycle's odometry errs along its heading and in its turn rate, never sideways:
            # the same draws, read in its body frame.
            body_noise = self.measured_velocities - self.velocities
            rows = self.unicycle
            cos_yaw, sin_yaw = np.cos(self.yaws[rows]), np.sin(self.yaws[rows])
            forward = (self.velocities[rows, 0] * cos_yaw + self.velocities[rows, 1] * sin_yaw
                       + body_noise[rows, 0])
            self.measured_velocities[rows] = forward[:, None] * np.stack([cos_yaw, sin_yaw],
                                                                         axis=1)
            self.measured_turn_rates[rows] += body_noise[rows, 1]

    def _new_contacts(self):
        pairs = kinematics.contact_pairs(self.positions, self.radii)
        new_pairs = sorted(pairs - self._in_contact)
        self._in_contact = pairs
        self.contact_count += len(new_pairs)
        return [Contact(first, second, self.time,
                        float(np.linalg.norm(self.positions[first] - self.positions[second])))
                for first, second in new_pairs]
