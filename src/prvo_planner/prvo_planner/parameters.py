"""The planner's parameters, defined once for the planner node and for scenario files (no ROS).

Every parameter has a kind, a default, an inclusive range (what a ROS parameter descriptor can
state) and the further rules the planner needs. `check_parameter` applies them to one value,
`planner_config_from` to a whole mapping: the planner node validates its parameters with these
at start-up and on every change, and the scenario loader validates the planner blocks of a
scenario file with the same functions, so a file the loader accepts starts every planner.
"""

import array
from dataclasses import dataclass
import difflib
import math
import numbers

import numpy as np

from prvo_msgs_util import validate_robot_name
from prvo_planner.core import PlannerConfig
from prvo_planner.core.config import CERTIFICATES, METHODS, MODELS, RISKS
from prvo_planner.escalation import TURN_MAX, TURN_RATE
from prvo_planner.lanes import KEEP_RIGHT
from prvo_planner.preferred import SOURCES

BOOL = 'bool'
INTEGER = 'int'
FLOAT = 'float'
STRING = 'str'
FLOAT_ARRAY = 'float[]'
STRING_ARRAY = 'str[]'
KINEMATICS = ('holonomic', 'unicycle')
# The `model` that disables avoidance: the command is the preferred velocity, unchanged.
NO_AVOIDANCE = 'none'
# Goals (and the scenario's coordinates) are in metres of one shared map: 1000 km is plenty and
# keeps every product of coordinates far from floating-point trouble.
COORDINATE_LIMIT = 1.0e6
# A unicycle's slowest turn limits [rad/s, rad/s^2]. Slower, a half turn takes over 30 s (or
# reaching 1 rad/s over 10 s) while a plan looks 5 s ahead: the robot cannot follow its plans,
# and its tracking table would be all but empty.
MIN_ANGULAR_SPEED = 0.1
MIN_ANGULAR_ACCELERATION = 0.1


class ParameterError(ValueError):
    """A planner parameter value the planner cannot use: '<name>: <reason>'."""

    def __init__(self, name, reason):
        super().__init__(f'{name}: {reason}')
        self.name = name
        self.reason = reason


@dataclass(frozen=True)
class ParameterSpec:
    """One planner parameter.

    `bounds` is an inclusive (low, high) range of a scalar, as a ROS descriptor states it;
    `rule(value)` returns why a value is refused beyond that (None: accepted). A default of
    None means the parameter may be left unset.
    """

    name: str
    kind: str
    default: object
    description: str
    bounds: tuple = None
    choices: tuple = ()
    rule: object = None
    read_only: bool = False


def _positive(value):
    return None if value > 0.0 else f'must be > 0, got {_shown(value)}'


def _positive_up_to_100(value):
    return None if 0.0 < value <= 100.0 else f'must be in (0, 100], got {_shown(value)}'


def _open_unit_interval(value):
    return None if 0.0 < value < 1.0 else f'must be in (0, 1), got {_shown(value)}'


def _below_one(value):
    return None if value < 1.0 else f'must be in [0, 1), got {_shown(value)}'


def _k_rule(value):
    return None if value == -1.0 or value >= 0.0 else (
        f'must be >= 0 (or -1 to use eta), got {_shown(value)}')


def _retired_neighbour_radius(value):
    # Kept declared so that a launch file or `ros2 param set` still using it is told why it no
    # longer applies, instead of "unknown parameter".
    return None if value == -1.0 else (
        f'retired (got {_shown(value)}): neighbours announce their own footprints; set '
        'unknown_neighbor_radius for those that announce none')


def _at_least(low, why):
    """Return a rule that refuses a value below LOW, saying WHY."""
    def rule(value):
        return None if value >= low else f'must be >= {low:g} ({why}), got {_shown(value)}'
    return rule


def _goal_rule(value):
    if len(value) != 2:
        return f'must be [x, y], got {_shown(value)}'
    if any(abs(coordinate) > COORDINATE_LIMIT for coordinate in value):
        return f'coordinates must be in [{-COORDINATE_LIMIT:g}, {COORDINATE_LIMIT:g}], got ' \
            f'{_shown(value)}'
    return None


def _not_empty(value):
    return None if value else 'must not be empty'


def _topic_name(value):
    return None if value and ' ' not in value else f'must be a topic name, got {value!r}'


# Where the preferred velocity comes from, and the topics of each source. The names of the
# path and filter parameters are those of Nav2's Regulated Pure Pursuit and collision monitor.
_PREFERRED_SOURCE_SPECS = (
    ParameterSpec('preferred_source', STRING, 'goal', 'Source of the preferred velocity: goal '
                  '(straight to the goal parameter or goal_pose), path (follow a nav_msgs/Path '
                  'on path_topic) or velocity (filter the command on cmd_vel_in_topic).',
                  choices=SOURCES, read_only=True),
    ParameterSpec('path_topic', STRING, 'plan', 'preferred_source path: the nav_msgs/Path (map '
                  'frame) to follow; a new path replaces the old, an empty one cancels.',
                  read_only=True, rule=_topic_name),
    ParameterSpec('wait_for_path', BOOL, False, 'preferred_source path: plan only once a path '
                  'has arrived (for at most neighbor_timeout after the first own odometry), as '
                  'for listed neighbours: a run whose robots follow paths plans its first step '
                  'on them.'),
    ParameterSpec('lookahead_dist', FLOAT, 1.0, 'Distance [m] of the carrot on the path '
                  "followed: the path of preferred_source path, or with a map a goal's route "
                  '(which is taken anew when the robot strays farther from it).', (0.01, 100.0)),
    ParameterSpec('use_velocity_scaled_lookahead_dist', BOOL, False, 'The lookahead is speed * '
                  'lookahead_time within [min_lookahead_dist, max_lookahead_dist] instead of '
                  'lookahead_dist.'),
    ParameterSpec('min_lookahead_dist', FLOAT, 0.3, 'Smallest velocity-scaled lookahead [m].',
                  (0.01, 100.0)),
    ParameterSpec('max_lookahead_dist', FLOAT, 0.9, 'Largest velocity-scaled lookahead [m], >= '
                  'min_lookahead_dist.', (0.01, 100.0)),
    ParameterSpec('lookahead_time', FLOAT, 1.5, 'Velocity-scaled lookahead: seconds of travel '
                  'at the current speed [s].', (0.01, 100.0)),
    ParameterSpec('cmd_vel_in_topic', STRING, 'cmd_vel_smoothed', 'preferred_source velocity: '
                  'the upstream command filtered.', read_only=True, rule=_topic_name),
    ParameterSpec('cmd_vel_out_topic', STRING, 'cmd_vel', 'preferred_source velocity: where the '
                  'filtered command goes.', read_only=True, rule=_topic_name),
    ParameterSpec('enable_stamped_cmd_vel', BOOL, False, 'preferred_source velocity: both '
                  'topics carry geometry_msgs/TwistStamped (true) or Twist (false).',
                  read_only=True),
    ParameterSpec('stop_pub_timeout', FLOAT, 2.0, 'preferred_source velocity: once the output is '
                  'zero it is published this long [s], then not until it moves; .inf for ever.',
                  rule=_positive),
    # Nav2's per-robot odom is in each robot's own odom frame: robots can only compare states in
    # one shared frame, so the states read must come from localisation in frame_id.
    ParameterSpec('state_topic', STRING, 'odom', 'nav_msgs/Odometry (with covariance, in '
                  "frame_id) read for this robot and, under each neighbour's namespace, for "
                  'the neighbours: e.g. odometry/global of robot_localization.', read_only=True,
                  rule=_topic_name),
    ParameterSpec('state_timeout', FLOAT, 1.0, 'preferred_source velocity: the output is zero '
                  'while the own state is older than this [s, wall time].', (0.01, 3600.0)),
)


_SPECS = (
    # eta 0.95 by the certified bound: the shipped scenarios free of contacts over 10 seeds with
    # more clearance than Cantelli's 0.8 (which certifies about 0.99) at about its time to goal;
    # certified 0.8 touched in parked_large, 0.9 came within 9 mm (docs/results.md).
    ParameterSpec('eta', FLOAT, 0.95, 'Required probability that the RVO condition holds for '
                  'each neighbour, in (0, 1).', (0.0, 1.0), rule=_open_unit_interval),
    ParameterSpec('k', FLOAT, -1.0, 'Surrogate margin k >= 0 (mean - k std >= 0); wins over '
                  'eta when set. -1 = use eta.', (-1.0, 1.0e3), rule=_k_rule),
    ParameterSpec('radius', FLOAT, 0.3, "This robot's radius [m], in (0, 100].", (0.0, 100.0),
                  rule=_positive_up_to_100),
    ParameterSpec('unknown_neighbor_radius', FLOAT, 0.5, 'Radius assumed for a neighbour that '
                  'announces no footprint [m], in (0, 100]; choose it no smaller than the '
                  'largest robot expected.', (0.0, 100.0), rule=_positive_up_to_100),
    ParameterSpec('neighbor_radius', FLOAT, -1.0, 'Retired, must stay -1: neighbours announce '
                  'their footprints (/<robot>/footprint); unknown_neighbor_radius covers those '
                  'that do not.', (-1.0, 100.0), rule=_retired_neighbour_radius),
    ParameterSpec('max_speed', FLOAT, 1.0, 'Speed limit [m/s], in (0, 100].', (0.0, 100.0),
                  rule=_positive_up_to_100),
    ParameterSpec('num_directions', INTEGER, 64, 'Candidate headings evaluated per plan.',
                  (1, 4096)),
    # 2 s with the guard below: doorway8 at the default bound in 21 s on average over 10 seeds
    # (35 s at 5 s), the noisy 24-robot circle in 1.6-1.9x the straight-line time (2.2x), no
    # contact in any measured world (docs/results.md, section 3.6).
    ParameterSpec('time_horizon', FLOAT, 2.0, 'Collisions later than this many seconds do not '
                  'constrain now [s], > 0; .inf for none: longer yields earlier to distant '
                  'robots and, under noise, keeps further from near ones (slower in crowds and '
                  'doors); shorter reacts later and passes closer.', rule=_positive),
    # Without it a 2 s or 3 s horizon let two robots alternating out of phase touch (doorway8,
    # corridor8); 0.3 s removed both contacts (docs/results.md, section 3.6).
    ParameterSpec('guard_time', FLOAT, 0.3, 'A neighbour that avoids too and could touch '
                  'this robot within this time [s] is also avoided over it as if it kept its '
                  'velocity, in [0, 10]: safety near contact not resting on its reciprocating; '
                  'longer holds back sooner in crowds. 0 = off.', (0.0, 10.0)),
    # Off: on, the 24-robot circle took 1.78 / 1.72 / 1.71 times the straight line (1.83 / 1.88
    # / 1.58 off), but the shipped corridor8 left two robots short in one seed of ten and had a
    # contact in another (docs/results.md, section 3.8).
    ParameterSpec('approach_limit', BOOL, False, 'Near contact, close at most this '
                  "robot's share of the gap to each neighbour (half if it announces none) in "
                  'one control period: two robots that change course at once still cannot '
                  'meet within it. Binds only within about 0.2 m; costs speed there.'),
    # 1 s: at 2 s a robot slowed for every wall it headed at within 2 s, the end wall behind
    # its goal and the side walls it leaned towards to pass, and corridors took 1.1-1.7x as long
    # (corridor8 worst 18.7 s against 15.7 s, a 2 m corridor 22.4 against 13.4 s mean) with
    # as close a least wall clearance (docs/results.md, section 3.21).
    ParameterSpec('obstacle_horizon', FLOAT, 1.0, 'Walls and static obstacles constrain the '
                  'path over this many seconds [s], in [0.5, 10]: longer keeps further '
                  'from walls and slows earlier (before a wall ahead, to at most the gap over '
                  'the horizon), shorter passes closer; keep it above the time the base needs '
                  'to stop from max_speed.', (0.5, 10.0)),
    ParameterSpec('neighbor_distance', FLOAT, 10.0, 'Neighbours farther than this [m] are not '
                  'considered, > 0.', (0.0, 1.0e4), rule=_positive),
    ParameterSpec('actuation_std', FLOAT, 0.0, "Std of this robot's velocity execution error "
                  'per axis [m/s] (PRVO ego noise).', (0.0, 1.0e3)),
    ParameterSpec('safety_margin', FLOAT, 0.0, 'Extra clearance added to the sum of radii [m].',
                  (0.0, 10.0)),
    ParameterSpec('model', STRING, 'prvo', 'Planner model: prvo, rvo, inflate or mc; none '
                  'disables avoidance (the command is the preferred velocity).',
                  choices=(*MODELS, NO_AVOIDANCE)),
    ParameterSpec('method', STRING, 'exact', 'PRVO ray solver: exact (quartic) or taylor '
                  '(paper).', choices=METHODS),
    ParameterSpec('risk', STRING, 'pairwise', 'Risk allocation over neighbours: pairwise or '
                  'joint.', choices=RISKS),
    ParameterSpec('certificate', STRING, 'certified', 'Bound a velocity meets eta by: '
                  'certified (prvo: the Gaussian bound, smaller margins, less detour; Cantelli '
                  'kept where it falls short) or cantelli (any distribution, as in the paper; '
                  'cheaper per plan).', choices=CERTIFICATES),
    ParameterSpec('goal', FLOAT_ARRAY, None, 'Goal [x, y] in the map frame [m], |x|, |y| <= '
                  '1e6; unset = wait for a goal_pose message (preferred_source goal only).',
                  rule=_goal_rule),
    ParameterSpec('goal_tolerance', FLOAT, 0.2, 'Distance to the goal [m] under which the robot '
                  'stops, in (0, 100].', (0.0, 100.0), rule=_positive_up_to_100),
    ParameterSpec('approach_time', FLOAT, 0.5, 'Preferred speed is distance / approach_time '
                  'near the goal [s].', (1.0e-3, 100.0)),
    ParameterSpec('stamped_cmd_vel', BOOL, True, 'Publish geometry_msgs/TwistStamped (true) or '
                  'Twist (false).', read_only=True),
    ParameterSpec('neighbors', STRING_ARRAY, None, 'Robot names to avoid; unset discovers every '
                  'other /<name>/odom in the graph.', read_only=True),
    ParameterSpec('neighbor_timeout', FLOAT, 2.0, 'A neighbour silent this long [s, wall time] '
                  'is dropped.', (0.01, 3600.0)),
    ParameterSpec('sync_timeout', FLOAT, 0.2, "Wall time [s] to wait for neighbours' odometry "
                  'of the same stamp before planning.', (0.0, 60.0)),
    ParameterSpec('status_period', FLOAT, 0.2, 'Diagnostics and markers are published at most '
                  'this often [s, wall]; cmd_vel always.', (0.0, 60.0)),
    ParameterSpec('acceleration_std', FLOAT, 2.0, 'Process noise of the constant-velocity '
                  'tracker [m/s^2]: std of velocity change per second.', (1.0e-3, 100.0)),
    ParameterSpec('frame_id', STRING, 'map', 'World frame of odometry and goals.',
                  read_only=True, rule=_not_empty),
    ParameterSpec('seed', INTEGER, -1, 'Seed for the random rotation of candidate headings; '
                  '-1 = fixed headings.', (-1, 2 ** 31 - 1)),
    # Both only rank the velocities that meet the constraints: without them, the
    # closest-to-v_pref choice flips side from one step to the next (the chosen command turned
    # by more than 90 degrees in 15% of the steps of circle8, PRVO eta 0.8).
    ParameterSpec('inertia', FLOAT, 0.5, 'Weight in [0, 1) of |v - previous command| in the '
                  'choice cost |v - v_pref| + ...; damps side flips. 0 = closest to v_pref.',
                  (0.0, 0.99), rule=_below_one),
    ParameterSpec('passing_bias', FLOAT, 0.1, 'Cost per m/s of velocity left of the preferred '
                  'direction: every robot breaks the tie of a symmetric encounter the same way '
                  '(pass on the right). 0 = none.', (0.0, 10.0)),
    # Charging the speed lost towards the goal rather than |v - v_pref| alone: crowds pass at
    # speed instead of queueing (makespan of the noisy 24-robot 6 m circle 40.7 -> 27.6 s).
    ParameterSpec('progress_weight', FLOAT, 0.5, 'Share in [0, 1) of the goal term of the '
                  'choice cost charging only speed lost towards the goal, not sideways speed. '
                  '0 = |v - v_pref| alone.', (0.0, 0.99), rule=_below_one),
    ParameterSpec('kinematics', STRING, 'holonomic', 'Drive of the robot: holonomic (cmd_vel '
                  'linear x, y) or unicycle (differential drive: linear.x and angular.z).',
                  choices=KINEMATICS),
    ParameterSpec('max_angular_speed', FLOAT, 2.0, 'Turn rate limit of a unicycle [rad/s], in '
                  f'[{MIN_ANGULAR_SPEED:g}, 1000].', (MIN_ANGULAR_SPEED, 1.0e3),
                  rule=_at_least(MIN_ANGULAR_SPEED, 'slower, a half turn takes over 30 s')),
    # Unbounded ranges: .inf (the default) means no limit.
    ParameterSpec('max_acceleration', FLOAT, math.inf, 'Limit of the change of the commanded '
                  'velocity (unicycle: forward speed) [m/s^2], > 0; .inf for none.',
                  rule=_positive),
    ParameterSpec('max_angular_acceleration', FLOAT, math.inf, 'Limit of the change of a '
                  f"unicycle's turn rate [rad/s^2], >= {MIN_ANGULAR_ACCELERATION:g}; .inf for "
                  'none.', rule=_at_least(MIN_ANGULAR_ACCELERATION,
                                          'slower, reaching 1 rad/s takes over 10 s')),
    ParameterSpec('tracking_error', FLOAT, 0.1, 'Largest distance [m] a unicycle may stray from '
                  'the holonomic plan it tracks; its radius is grown by it, in (0, 10].',
                  (0.0, 10.0), rule=_positive),
    ParameterSpec('tracking_horizon', FLOAT, 0.5, 'A unicycle turns toward its plan at the '
                  'heading error / tracking_horizon [s].', (1.0e-3, 100.0)),
    # The map: nav_msgs/OccupancyGrid, cells of occupancy >= 65 % (map_server's default
    # occupied_thresh) are obstacles.
    ParameterSpec('map_topic', STRING, '/map', 'Occupancy grid (nav_msgs/OccupancyGrid, frame '
                  'map, reliable, transient local) to plan against and route through; none '
                  'published = an empty plane.', read_only=True, rule=_not_empty),
    ParameterSpec('obstacle_distance', FLOAT, 3.0, 'Map obstacles farther than this [m] are not '
                  'considered, > 0.', (0.0, 1.0e4), rule=_positive),
    ParameterSpec('unknown_is_occupied', BOOL, True, 'Unknown map cells (-1) are obstacles '
                  '(true) or free (false).'),
    ParameterSpec('route_margin', FLOAT, 0.3, 'With a map, the route keeps this much more [m] '
                  'than the radius from obstacles where there is room (a way hugging them costs '
                  'up to twice its length), in [0, 10].', (0.0, 10.0)),
    ParameterSpec('wait_for_map', BOOL, False, 'Plan only once a map has arrived (for at most '
                  'neighbor_timeout after the first own odometry), as for listed neighbours: a '
                  'run whose world has a map plans its first step on it. A map still being '
                  'built after that is held for with zero commands.'),
    # Keep right (`prvo_planner.lanes`): opposite flows form lanes instead of meeting head-on.
    # Only the preference changes, never the chance constraints; 0 is the benchmarks' ablation.
    ParameterSpec('keep_right', FLOAT, KEEP_RIGHT, 'A robot meeting a neighbour coming toward '
                  'it turns its preferred velocity this much [rad] to its right, where the way '
                  'is wide enough for two (open space, or twice the width it needs to be '
                  'certified through; among walls at most 0.3; in a corridor of two lanes '
                  'toward the middle of its lane, at most this), fading over the last metre to '
                  'its goal; longer ways (a factor 1 / cos) for smoother flow. In [0, 0.8]; '
                  '0 = never.', (0.0, 0.8)),
    # Give way (`prvo_planner.give_way`): a robot at its goal, or held short of it, steps off
    # the route a neighbour publishes on <robot>/plan where it passes; off, it stands (ablation).
    ParameterSpec('give_way', BOOL, True, 'A robot at its goal steps aside, off the route a '
                  'neighbour within 3 m publishes on <robot>/plan, where that route passes '
                  'nearer than their two radii and 0.1 m, and returns once it went by; so does '
                  'a robot held short of its goal (stalled, or within 2.5 m of it and less '
                  'than 0.3 m closer in 3 s) for a neighbour with farther to go; and a robot '
                  'on its way aims beside a neighbour standing on it. '
                  'false = none of these.'),
    # Right of way (`prvo_planner.right_of_way`): at a passage too narrow for two, found on the
    # map, robots take turns by one rule from what all publish; off, they meet in it (ablation).
    ParameterSpec('right_of_way', BOOL, True, 'With a map, robots take turns at passages too '
                  "narrow for two to pass (found on the map for the route's clearance and "
                  'margin): a robot inside, then the one that came first, then the one with '
                  'the shorter way to it (names break ties) goes first, those going the same '
                  'way follow, and a robot '
                  'without the right of way waits at the spot beside its entrance behind a '
                  "virtual wall; it takes another way round once it has waited as long as "
                  "that way adds. Decided from the neighbours' routes on <robot>/plan. "
                  'false = robots meet in the passage (the ablation).'),
    # Escalation (`prvo_planner.escalation`): a stalled robot (`prvo_planner.stalls`) turns its
    # preferred velocity to the right; off, the preferred velocity is the goal's or the route's
    # (the benchmarks' ablation). Only the preference changes, never the chance constraints.
    # Off: on the shipped wall worlds it cost more than it gained (prvo_planner.escalation).
    ParameterSpec('stall_escalation', BOOL, False, 'A stalled robot (less than 0.5 m toward its '
                  'goal in 10 s) turns its preferred velocity to the right by an angle that rises '
                  'to stall_turn_max and falls back (a sidestep), again while the stall lasts, '
                  'until it progresses; among walls only with room for its radius on its right. '
                  'false = never.'),
    ParameterSpec('stall_turn_rate', FLOAT, TURN_RATE, 'Escalation: the turn rises and falls '
                  'this fast [rad/s], in [0.01, 10].', (0.01, 10.0)),
    ParameterSpec('stall_turn_max', FLOAT, TURN_MAX, 'Escalation: the largest turn [rad], in '
                  '[0.05, 1.5]: below a right angle, so that some of the preference stays toward '
                  'the goal.', (0.05, 1.5)),
    *_PREFERRED_SOURCE_SPECS,
)

# Every planner parameter by name, in declaration order.
PARAMETERS = {spec.name: spec for spec in _SPECS}
DEFAULTS = {spec.name: spec.default for spec in _SPECS}
# How `ros2 param dump` writes an unset parameter (YAML's null): a parameters file hands it to
# the node as a string.
_DUMPED_NULLS = ('null', 'Null', 'NULL', '~')


def type_name(value):
    """Return how an error message names the type of VALUE ('a string', 'nothing', ...)."""
    if isinstance(value, bool):
        return 'a boolean'
    if isinstance(value, numbers.Integral):
        return 'an integer'
    if isinstance(value, numbers.Real):
        return 'a number'
    return {type(None): 'nothing', dict: 'a mapping', list: 'a list', tuple: 'a list',
            array.array: 'a list', str: 'a string'}.get(type(value), type(value).__name__)


def _shown(value):
    """Return VALUE as an error message shows it: arrays as lists, huge integers by size."""
    if isinstance(value, (array.array, np.ndarray, tuple)):
        value = list(value)
    if isinstance(value, list):
        return '[' + ', '.join(_shown(item) for item in value) + ']'
    if isinstance(value, numbers.Integral) and not isinstance(value, bool) and (
            abs(value) > 10 ** 30):
        return f'an integer of {value.bit_length()} bits'
    return repr(value) if isinstance(value, (str, float)) else str(value)


def nearest_name(name, names=None):
    """Return the name in NAMES (default: the planner's) closest to NAME, or None."""
    matches = difflib.get_close_matches(str(name), list(names or PARAMETERS), n=1, cutoff=0.6)
    return matches[0] if matches else None


def unknown_parameter_reason(name):
    """Return the reason an unknown parameter NAME is refused, with the nearest valid name."""
    nearest = nearest_name(name)
    suggestion = f' (did you mean {nearest!r}?)' if nearest else ''
    return f'unknown planner parameter{suggestion}'


def _is_sequence(value):
    # rclpy hands array parameters over as array.array, YAML and the command line as lists.
    return isinstance(value, (list, tuple, array.array, np.ndarray))


def _real(name, value):
    """Return VALUE as a float; NaN and numbers too large for a float are refused."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise ParameterError(name, f'expected a number, got {type_name(value)}')
    try:
        number = float(value)
    except OverflowError:
        raise ParameterError(name, f'too large a number ({_shown(value)})') from None
    if math.isnan(number):
        raise ParameterError(name, f'expected a number, got {number}')
    return number


def _typed(spec, value):
    """Return VALUE converted to SPEC's kind; raise ParameterError for a value of another type."""
    name = spec.name
    if spec.kind == BOOL:
        if not isinstance(value, (bool, np.bool_)):
            raise ParameterError(name, f'expected true or false, got {type_name(value)}')
        return bool(value)
    if spec.kind == INTEGER:
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral):
            raise ParameterError(name, f'expected an integer, got {type_name(value)}')
        return int(value)
    if spec.kind == FLOAT:
        return _real(name, value)
    if spec.kind == STRING:
        if not isinstance(value, str):
            raise ParameterError(name, f'expected a string, got {type_name(value)}')
        return value
    if not _is_sequence(value):
        raise ParameterError(name, f'expected a list, got {type_name(value)}')
    if spec.kind == FLOAT_ARRAY:
        numbers_given = [_real(f'{name}[{index}]', item) for index, item in enumerate(value)]
        if not all(math.isfinite(item) for item in numbers_given):
            raise ParameterError(name, f'expected finite numbers, got {_shown(numbers_given)}')
        return numbers_given
    if not all(isinstance(item, str) for item in value):
        raise ParameterError(name, f'expected a list of strings, got {_shown(value)}')
    return list(value)


def check_parameter(name, value):
    """Return VALUE of the planner parameter NAME, typed; raise ParameterError if unusable.

    Integers are accepted for float parameters and any sequence of numbers for an array. None
    means unset, which only parameters without a default may be.
    """
    spec = PARAMETERS.get(name)
    if spec is None:
        raise ParameterError(name, unknown_parameter_reason(name))
    if value is None:
        if spec.default is None:
            return None
        raise ParameterError(name, f'must be set (default {_shown(spec.default)})')
    typed = _typed(spec, value)
    if spec.kind == FLOAT and math.isinf(typed) and spec.bounds is not None:
        raise ParameterError(name, f'expected a finite number, got {typed}')
    if spec.bounds is not None and not spec.bounds[0] <= typed <= spec.bounds[1]:
        low, high = spec.bounds
        reason = spec.rule(typed) if spec.rule is not None else None
        raise ParameterError(name, reason or f'must be in [{_shown(low)}, {_shown(high)}], '
                             f'got {_shown(typed)}')
    if spec.choices and typed not in spec.choices:
        raise ParameterError(name, f"must be one of {', '.join(spec.choices)}, got {typed!r}")
    reason = spec.rule(typed) if spec.rule is not None else None
    if reason is not None:
        raise ParameterError(name, reason)
    return typed


def is_dumped_unset(name, value):
    """Whether VALUE of the parameter NAME, which may be unset, is a dump's null read back."""
    spec = PARAMETERS.get(name)
    return (spec is not None and spec.default is None and isinstance(value, str)
            and value in _DUMPED_NULLS)


def check_parameter_update(name, value):
    """Return VALUE of a change of NAME while the planner runs, typed; raise ParameterError.

    Unlike at start-up, None is refused: a parameter set to nothing would be undeclared, and
    every later change of it would fail.
    """
    if value is None:
        raise ParameterError(name, 'cannot be unset or deleted while the planner runs; set a '
                             'new value instead')
    return check_parameter(name, value)


def goal_array(value):
    """Return the goal (2,) of the `goal` parameter's VALUE, None when unset; ParameterError."""
    goal = check_parameter('goal', value)
    return None if goal is None else np.array(goal, dtype=float)


def neighbour_names(value):
    """Return the `neighbors` parameter's VALUE as a list of names, None to discover them."""
    names = check_parameter('neighbors', value)
    if names is None:
        return None
    for name in names:
        if name:
            try:
                validate_robot_name(name)
            except ValueError as error:
                raise ParameterError('neighbors', str(error)) from None
    return [name for name in names if name]


def checked_parameters(values):
    """Return a copy of the name -> value mapping VALUES with every value checked and typed."""
    return {name: check_parameter(name, value) for name, value in values.items()}


def planner_config_from(values, changed=None):
    """Return the core's PlannerConfig of VALUES (parameter name -> value) over the defaults.

    Raises ParameterError naming the first parameter the planner cannot use and its value. A
    rule between two parameters names the one of CHANGED, the names just set (None: those
    VALUES gives away from their defaults, as at start-up), when only one of them is.
    """
    merged = {**DEFAULTS, **checked_parameters(values)}
    low, high = merged['min_lookahead_dist'], merged['max_lookahead_dist']
    if high < low:
        if changed is None:
            changed = {name for name in ('min_lookahead_dist', 'max_lookahead_dist')
                       if merged[name] != DEFAULTS[name]}
        if 'min_lookahead_dist' in changed and 'max_lookahead_dist' not in changed:
            raise ParameterError('min_lookahead_dist', f'must be <= max_lookahead_dist '
                                 f'({_shown(high)}), got {_shown(low)}')
        raise ParameterError('max_lookahead_dist', f'must be >= min_lookahead_dist '
                             f'({_shown(low)}), got {_shown(high)}')
    k = merged['k']
    seed = merged['seed']
    try:
        return PlannerConfig(
            eta=merged['eta'], k=None if k == -1.0 else k, max_speed=merged['max_speed'],
            num_directions=merged['num_directions'], time_horizon=merged['time_horizon'],
            neighbor_distance=merged['neighbor_distance'],
            actuation_cov=merged['actuation_std'] ** 2 * np.eye(2),
            safety_margin=merged['safety_margin'], method=merged['method'],
            # A robot that does not avoid never plans: its config's model is never used.
            model=MODELS[0] if merged['model'] == NO_AVOIDANCE else merged['model'],
            risk=merged['risk'], certificate=merged['certificate'],
            seed=None if seed < 0 else seed,
            inertia=merged['inertia'], passing_bias=merged['passing_bias'],
            progress_weight=merged['progress_weight'],
            obstacle_horizon=merged['obstacle_horizon'],
            guard_time=merged['guard_time'], approach_limit=merged['approach_limit'])
    except ValueError as error:
        # The rules above cover PlannerConfig's; should they ever diverge, still one clear line.
        raise ParameterError('planner', str(error)) from error
