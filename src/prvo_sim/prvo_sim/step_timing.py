"""When the simulator steps: the answers it waits for, missed deadlines, silent robots (no ROS).

Times are seconds of one wall clock (the simulator node passes `time.monotonic()`). The rules
are those of docs/interfaces.md: in lockstep a step waits for every planned robot's cmd_vel, at
most `step_timeout` (`startup_timeout` for the first step, re-sending the t_0 odometry meanwhile);
a robot silent for longer than `cmd_timeout` executes zero velocity.
"""

from dataclasses import dataclass

MODES = ('lockstep', 'realtime')
# How often the t_0 odometry is re-sent while waiting for planners [s].
REPUBLISH_PERIOD = 0.5
# What `StepTiming.due` asks of the simulator.
STEP = 'step'
REPUBLISH = 'republish'


@dataclass
class RobotTiming:
    """One robot's answers: whether it answered the current step, and its deadline record.

    `commanded_at` is the time of its last accepted command and, in lockstep, `missed_since` of
    the first deadline it missed since; `stopped` once it executes zero for lack of commands.
    """

    answered: bool = False
    deadline_misses: int = 0
    commanded_at: float = None
    missed_since: float = None
    stopped: bool = False


class StepTiming:
    """The timing of a simulation of ROBOT_COUNT robots whose PLANNED indices answer each step.

    The other robots (scripted) are moved by the world: they miss no deadline. REALTIME counts a
    silence from the last command; lockstep from the first deadline missed since.
    """

    def __init__(self, robot_count, planned, realtime, step_timeout, cmd_timeout,
                 startup_timeout, now):
        self.robots = [RobotTiming() for _ in range(robot_count)]
        self._planned = list(planned)
        self.realtime = realtime
        self.step_timeout = step_timeout
        self.cmd_timeout = cmd_timeout
        self.startup_timeout = startup_timeout
        self.started = False
        # When the last state went out, and when the t_0 state was last sent again.
        self.published_at = now
        self.republished_at = now

    @property
    def deadline_misses(self):
        """Every robot's number of missed deadlines, in order."""
        return [robot.deadline_misses for robot in self.robots]

    def all_answered(self):
        """Whether every planned robot answered the current step."""
        return all(self.robots[index].answered for index in self._planned)

    def command_received(self, index, answers_step, now):
        """Record an accepted command of robot INDEX at NOW; ANSWERS_STEP: the current one."""
        robot = self.robots[index]
        robot.commanded_at = now
        robot.missed_since = None
        robot.stopped = False
        if answers_step:
            robot.answered = True

    def republish_due(self, now):
        """Whether the t_0 state is to be sent again at NOW; if so, it counts as sent."""
        if now - self.republished_at < REPUBLISH_PERIOD:
            return False
        self.republished_at = now
        return True

    def start(self, now):
        """Start stepping at NOW: the t_0 state goes out once more, the first wait begins."""
        self.started = True
        self.republished_at = self.published_at = now

    def due(self, now, first_step):
        """Return STEP, REPUBLISH or None: what is due at NOW while a step waits for answers.

        FIRST_STEP: the step from t_0, which waits `startup_timeout` and re-sends t_0 meanwhile
        so that whoever is not subscribed yet gets it (a run starts with everyone in it, which
        is what makes a seed reproduce its run).
        """
        if self.all_answered():
            return STEP
        if first_step:
            if now - self.published_at >= self.startup_timeout:
                return STEP
            return REPUBLISH if self.republish_due(now) else None
        return STEP if now - self.published_at >= self.step_timeout else None

    def close_step(self, now):
        """Close the current step at NOW; return (late, stopped) as robot indices.

        The late robots did not answer: each misses a deadline. The stopped ones were silent
        for longer than `cmd_timeout` and are to execute zero velocity until their next command;
        `stopped` is a list of (index, seconds since its last command).
        """
        late = [index for index in self._planned if not self.robots[index].answered]
        for index in late:
            robot = self.robots[index]
            robot.deadline_misses += 1
            if robot.missed_since is None:
                robot.missed_since = now
        stopped = []
        for index in self._planned:
            robot = self.robots[index]
            if self._silent(robot, now):
                robot.stopped = True
                stopped.append((index, now - robot.commanded_at))
        return late, stopped

    def deadline_miss_message(self, late, names, sim_time):
        """Return the warning for the LATE robots (indices) of the step closed at SIM_TIME [s].

        NAMES are every robot's, in order. It says what each late robot executes, as
        `close_step` decided: its last command again while within `cmd_timeout`, zero velocity
        once stopped or before its first command.
        """
        reusing, stopped, never = [], [], []
        for index in late:
            robot = self.robots[index]
            group = never if robot.commanded_at is None else stopped if robot.stopped else reusing
            group.append(names[index])
        timeout = f'cmd_timeout {self.cmd_timeout:g} s'
        parts = ((reusing, f'reusing the last command (within {timeout})'),
                 (stopped, f'executing zero velocity (past {timeout})'),
                 (never, 'executing zero velocity (no command yet)'))
        return f'deadline miss at t={sim_time:.3f}: no cmd_vel from ' + '; '.join(
            f'{", ".join(robots)}: {what}' for robots, what in parts if robots)

    def _silent(self, robot, now):
        if robot.stopped or robot.commanded_at is None:
            return False
        since = robot.commanded_at if self.realtime else robot.missed_since
        return since is not None and now - since > self.cmd_timeout

    def step_published(self, now):
        """Record that the next step's state went out at NOW: every answer is awaited anew."""
        for robot in self.robots:
            robot.answered = False
        self.published_at = now
