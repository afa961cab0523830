"""Loading and validating scenario files (schema: docs/scenarios.md).

Everything is checked before any process starts: the keys, their types and ranges, and the
planner blocks by the planner's own parameter rules (`prvo_planner.parameters`), so that a file
that loads starts every planner. `check_team_memory` tells whether the machine can hold the team.
"""

from dataclasses import dataclass
import math
import pathlib
import re
import sys

from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
import numpy as np
from rclpy.exceptions import NameValidationException
from rclpy.validate_full_topic_name import validate_full_topic_name
from rclpy.validate_namespace import validate_namespace
import yaml

from prvo_msgs_util import (
    AVOIDANCE_SHARE,
    CMD_VEL,
    FOOTPRINT,
    GOAL_POSE,
    GROUND_TRUTH,
    MARKERS,
    MAX_PATH_POSES,
    ODOM,
    validate_robot_name,
)
from prvo_planner.maps import GridMap
from prvo_planner.parameters import (
    COORDINATE_LIMIT,
    KINEMATICS,
    ParameterError,
    check_parameter,
    planner_config_from,
    type_name,
    unknown_parameter_reason,
)
from prvo_sim.map_files import (
    DEFAULT_FREE_THRESH,
    DEFAULT_OCCUPIED_THRESH,
    MODES,
    cells_from_image,
    check_regular_file,
    read_image,
)
from prvo_sim.planned_path import SPACING, pose_count
from prvo_sim.static_world import StaticWorld, polygon_crossing

_SCENARIO_NAME = re.compile(r'[A-Za-z0-9_-]+')
_TOP_LEVEL_KEYS = {'name', 'description', 'seed', 'dt', 'duration', 'goal_tolerance', 'noise',
                   'planner', 'robots', 'walls', 'obstacles', 'map'}
_TOP_LEVEL_REQUIRED = {'name', 'seed', 'dt', 'duration', 'goal_tolerance', 'robots'}
_ROBOT_KEYS = {'name', 'start', 'goal', 'radius', 'max_speed', 'noise', 'planner', 'scripted',
               'kinematics', 'max_angular_speed', 'max_acceleration', 'max_angular_acceleration',
               'start_yaw', 'upstream', 'path'}
DEFAULT_MAX_ANGULAR_SPEED = 2.0
# Limits of a robot's motion [m/s^2, rad/s^2, rad/s]: as large as a speed may be, and more.
MAX_LIMIT = 1.0e3
_UNICYCLE_ONLY = ('max_angular_speed', 'max_angular_acceleration')
_ROBOT_REQUIRED = {'name', 'start', 'goal', 'radius', 'max_speed'}
_SCRIPTED_KEYS = {'waypoints', 'speed', 'loop'}
_UPSTREAM_KEYS = {'waypoints', 'speed'}
_PATH_KEYS = {'waypoints'}
_NOISE_KEYS = ('position_std', 'velocity_std', 'actuation_std')
_WALL_KEYS = {'line', 'thickness'}
_DISC_KEYS = {'position', 'radius'}
_POLYGON_KEYS = {'polygon'}
_MAP_KEYS = {'image', 'resolution', 'origin', 'negate', 'occupied_thresh', 'free_thresh', 'mode'}
_MAP_REQUIRED = {'image', 'resolution', 'origin'}
# The largest rasterised grid of a scenario's static world [cells]: 400 MB of int8 cells at most
# would be far more than a simulator or planner should hold.
MAX_GRID_CELLS = 4 * 10 ** 7
DT_RANGE = (1.0e-4, 10.0)
MAX_STEPS = 10 ** 6
MAX_NOISE_STD = 1.0e3
MAX_GOAL_TOLERANCE = 100.0
MAX_ROBOTS = 256
MAX_SEED = 2 ** 31 - 1  # the simulator's and the planner's seed parameters are 32-bit
# Planner parameters the runner sets from the robot entry or its own options: a planner block
# that sets one would be overridden, so it is refused with where the value belongs.
SET_BY_RUNNER = {
    'radius': "set by the runner from each robot's radius: set it there",
    'max_speed': "set by the runner from each robot's max_speed: set it there",
    'goal': "set by the runner from each robot's goal: set it there",
    'actuation_std': 'set by the runner from noise.actuation_std (top level or per robot): '
                     'set it there',
    'goal_tolerance': 'set by the runner from the top-level goal_tolerance: set it there',
    'model': 'set by the runner from its --method option',
    'kinematics': "set by the runner from each robot's kinematics: set it there",
    'max_angular_speed': "set by the runner from each robot's max_angular_speed: set it there",
    'max_acceleration': "set by the runner from each robot's max_acceleration: set it there",
    'max_angular_acceleration': "set by the runner from each robot's max_angular_acceleration: "
                                'set it there',
    'use_sim_time': 'set by the runner (always true: the simulator keeps the time)',
}
ENGINES = ('ros', 'inprocess')
# Resident memory of one process of a run on the ROS engine [MiB], measured by
# prvo_sim.bench.team (planners 141-149 MiB, simulator 73-81 MiB) and rounded up: an estimate,
# not a bound.
PLANNER_MEMORY_MIB = 150
SIMULATOR_MEMORY_MIB = 80
RUNNER_MEMORY_MIB = 120
# The in-process engine's one process [MiB], and per robot: above every peak measured without
# a bag (see estimate_team_memory).
INPROCESS_MEMORY_MIB = 320
INPROCESS_ROBOT_MEMORY_MIB = 0.5
# The bag of an in-process run, held in memory until the run ends [KiB per step]: per robot,
# and per planned robot and neighbour (its status and markers name every other robot).
BAG_ROBOT_STEP_KIB = 8.0
BAG_NEIGHBOUR_STEP_KIB = 0.25
# A planner's map while it is built, per cell of the world's grid [bytes]: the route's obstacle
# distances, steps and tree, the obstacles' index and the passages of right of way.
# `python -m prvo_planner.map_bench` on a 50 m office of 0.05 m cells (1 M cells): tracemalloc's
# peak over `agent.build_map` 38.5 B per cell, 16.6 kept after (without the passages 18.4 and
# 9.2; test_map_bench holds the peak under this). Rounded up. Every planner builds its own, on
# either engine.
MAP_BYTES_PER_CELL = 40
# Every topic the stack names after a robot: /<name>/<leaf>.
_ROBOT_TOPIC_LEAVES = (ODOM, GROUND_TRUTH, CMD_VEL, GOAL_POSE, MARKERS, FOOTPRINT, AVOIDANCE_SHARE)
# The longest name of the services rclpy gives the robot's planner node: /<name>/<service>.
_LONGEST_PLANNER_SERVICE = 'planner/set_parameters_atomically'
_YAML_1_2_FLOAT = re.compile(
    r'^[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?$')


def ros_name_problem(name):
    """Return why ROS refuses robot NAME as the namespace /NAME of its nodes and topics, or None.

    The name must be a robot name (`validate_robot_name`), and the namespace, the robot's
    topics and its planner's services must pass rclpy's validators.
    """
    try:
        validate_robot_name(name)
    except ValueError as error:
        return str(error)
    try:
        validate_namespace(f'/{name}')
        for leaf in _ROBOT_TOPIC_LEAVES:
            validate_full_topic_name(f'/{name}/{leaf}')
        validate_full_topic_name(f'/{name}/{_LONGEST_PLANNER_SERVICE}', is_service=True)
    except NameValidationException as error:
        # The first line names the rule broken; the others point at the character.
        return f'robot name {name!r}: {str(error).splitlines()[0].rstrip(":")}'
    return None


class ScenarioError(ValueError):
    """A scenario file that cannot be used: '<file>: <key path>: <reason>'."""

    def __init__(self, file, key, reason):
        super().__init__(f'{file}: {key}: {reason}')
        self.file = str(file)
        self.key = key
        self.reason = reason


@dataclass(frozen=True)
class NoiseSpec:
    """Standard deviations per world axis: odometry position [m], velocity and actuation [m/s]."""

    position_std: float
    velocity_std: float
    actuation_std: float


@dataclass(frozen=True, eq=False)
class ScriptedPath:
    """The path of a scripted robot: `waypoints` (K, 2), read-only, its `speed`, `loop`."""

    waypoints: np.ndarray
    speed: float
    loop: bool


@dataclass(frozen=True, eq=False)
class RobotSpec:
    """One robot of a scenario, with the file-level noise and planner blocks merged in.

    `start` and `goal` are read-only arrays (2,), so specs compare by identity. `planner` holds
    the planner parameters given for this robot, typed and checked: the file-level block with
    the robot's own block over it. `scripted` is the `ScriptedPath` of a robot that the
    simulator moves along waypoints (no planner; its `goal` is the last waypoint), else None.
    `kinematics` is 'holonomic' or 'unicycle'; the acceleration limits are inf when unlimited;
    `start_yaw` [rad] is the heading at the start (None: facing the goal). `upstream` is the
    `ScriptedPath` (never looping) that a stand-in for Nav2's controller drives the robot along,
    its planner filtering the commands (its `goal` is the last waypoint), else None.
    `followed_path` is the `ScriptedPath` (never looping, at `max_speed`) that a stand-in for
    Nav2's planner_server publishes as the robot's `nav_msgs/Path`, its planner following it
    (`preferred_source: path`; its `goal` is the last waypoint), else None.
    """

    name: str
    start: np.ndarray
    goal: np.ndarray
    radius: float
    max_speed: float
    noise: NoiseSpec
    planner: dict
    scripted: ScriptedPath = None
    kinematics: str = 'holonomic'
    max_angular_speed: float = DEFAULT_MAX_ANGULAR_SPEED
    max_acceleration: float = math.inf
    max_angular_acceleration: float = math.inf
    start_yaw: float | None = None
    upstream: ScriptedPath = None
    followed_path: ScriptedPath = None


@dataclass(frozen=True)
class Scenario:
    """A validated scenario file."""

    name: str
    description: str
    seed: int
    dt: float
    duration: float
    goal_tolerance: float
    robots: tuple
    path: pathlib.Path
    static_world: StaticWorld = StaticWorld()


class _UniqueKeyLoader(yaml.SafeLoader):
    """A SafeLoader that refuses a mapping with the same key twice instead of keeping the last."""

    def construct_mapping(self, node, deep=False):
        keys = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            if key in keys:
                mark = key_node.start_mark
                raise yaml.constructor.ConstructorError(
                    None, None, f'duplicate key {key!r}', mark)
            keys.add(key)
        return super().construct_mapping(node, deep=deep)


# PyYAML reads YAML 1.1, where `1e-2` (no dot) and `1.0e3` (unsigned exponent) are strings;
# scenario files are read with YAML 1.2's floats. Integers still resolve first.
_UniqueKeyLoader.add_implicit_resolver(
    'tag:yaml.org,2002:float', _YAML_1_2_FLOAT, list('-+0123456789.'))


class _Validator:
    """Check one parsed file; every failure raises ScenarioError with its key path."""

    def __init__(self, path):
        self.path = path

    def fail(self, key, reason):
        raise ScenarioError(self.path, key, reason)

    def mapping(self, value, key, allowed, required):
        """Return VALUE if it is a mapping with REQUIRED keys and only ALLOWED (None: any)."""
        if not isinstance(value, dict):
            self.fail(key, f'expected a mapping, got {type_name(value)}')
        prefix = f'{key}.' if key != '(top level)' else ''
        for name in value:
            if allowed is not None and name not in allowed:
                self.fail(f'{prefix}{name}',
                          f'unknown key (allowed: {", ".join(sorted(allowed))})')
        for name in sorted(required):
            if name not in value:
                self.fail(f'{prefix}{name}', 'missing required key')
        return value

    def number(self, value, key, low=None, high=None, low_open=False):
        """Return VALUE as a finite float within [LOW, HIGH] (LOW excluded if LOW_OPEN)."""
        # bool is an int in Python, but `radius: true` is a mistake, not a number.
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            self.fail(key, f'expected a number, got {type_name(value)}')
        try:
            number = float(value)
        except OverflowError:
            self.fail(key, f'too large a number (an integer of {value.bit_length()} bits)')
        if not math.isfinite(number):
            self.fail(key, f'expected a finite number, got {value}')
        below = number <= low if low_open else number < low if low is not None else False
        if below or (high is not None and number > high):
            shown = repr(value) if isinstance(value, float) else str(value)
            if high is None:
                self.fail(key, f'must be {">" if low_open else ">="} {low:g}, got {shown}')
            self.fail(key, f'must be in {"(" if low_open else "["}{low:g}, {high:g}], '
                      f'got {shown}')
        return number

    def seed(self, value, key):
        if isinstance(value, bool) or not isinstance(value, int):
            self.fail(key, f'expected an integer, got {type_name(value)}')
        if not 0 <= value <= MAX_SEED:
            self.fail(key, f'must be in [0, {MAX_SEED}], got {value}')
        return value

    def string(self, value, key):
        if not isinstance(value, str):
            self.fail(key, f'expected a string, got {type_name(value)}')
        return value

    def point(self, value, key):
        if not isinstance(value, list) or len(value) != 2:
            self.fail(key, f'expected [x, y], got {value!r}')
        point = np.array([
            self.number(coordinate, f'{key}[{index}]', -COORDINATE_LIMIT, COORDINATE_LIMIT)
            for index, coordinate in enumerate(value)])
        point.flags.writeable = False
        return point

    def noise(self, value, key):
        if value is None:
            return {}
        block = self.mapping(value, key, set(_NOISE_KEYS), set())
        return {name: self.number(std, f'{key}.{name}', 0.0, MAX_NOISE_STD)
                for name, std in block.items()}

    def planner_parameter(self, name, value, key):
        """Return VALUE of the planner parameter NAME checked by the planner's own rules."""
        try:
            return check_parameter(name, value)
        except ParameterError as error:
            self.fail(key, error.reason)

    def planner(self, value, key):
        """Return the planner block VALUE as a typed dict; refuse what a planner would."""
        if value is None:
            return {}
        block = self.mapping(value, key, None, set())
        checked = {}
        for name, parameter in block.items():
            path = f'{key}.{name}'
            if name in SET_BY_RUNNER:
                self.fail(path, SET_BY_RUNNER[name])
            if not isinstance(name, str):
                self.fail(path, unknown_parameter_reason(name))
            checked[name] = self.planner_parameter(name, parameter, path)
            if name == 'neighbors':
                for robot in checked[name] or ():
                    problem = ros_name_problem(robot)
                    if problem is not None:
                        self.fail(path, problem)
        return checked


def _parse(path):
    try:
        check_regular_file(path)
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as error:
        raise ScenarioError(path, '(file)', f'cannot read: {error}') from None
    try:
        return yaml.load(text, Loader=_UniqueKeyLoader)
    except ValueError as error:
        # Python refuses to read integers of more than 4300 digits.
        raise ScenarioError(path, '(document)', f'unreadable number: {error}') from None
    except yaml.YAMLError as error:
        mark = getattr(error, 'problem_mark', None)
        where = f'line {mark.line + 1}, column {mark.column + 1}' if mark else '(document)'
        problem = getattr(error, 'problem', None) or str(error)
        raise ScenarioError(path, where, f'YAML syntax error: {problem}') from None


def load_scenario(path, seed=None):
    """Read, validate and return the Scenario in the YAML file PATH.

    SEED, if given, replaces the file's seed. Raises ScenarioError naming the file, the key
    path (e.g. 'robots[2].radius') and the reason.
    """
    path = pathlib.Path(path)
    check = _Validator(path)
    document = check.mapping(_parse(path), '(top level)', _TOP_LEVEL_KEYS, _TOP_LEVEL_REQUIRED)
    name = check.string(document['name'], 'name')
    if _SCENARIO_NAME.fullmatch(name) is None:
        check.fail('name', f'{name!r} may only contain letters, digits, "_" and "-"')
    description = check.string(document.get('description', ''), 'description')
    file_seed = check.seed(document['seed'], 'seed')
    dt = check.number(document['dt'], 'dt', *DT_RANGE)
    duration = check.number(document['duration'], 'duration', 0.0, low_open=True)
    if duration / dt > MAX_STEPS:
        check.fail('duration', f'{duration:g} s at dt {dt:g} s is more than {MAX_STEPS} steps')
    goal_tolerance = check.number(document['goal_tolerance'], 'goal_tolerance', 0.0,
                                  MAX_GOAL_TOLERANCE, low_open=True)
    file_noise = check.noise(document.get('noise'), 'noise')
    file_planner = check.planner(document.get('planner'), 'planner')
    robot_list = document['robots']
    if not isinstance(robot_list, list) or not robot_list:
        check.fail('robots', f'expected a non-empty list, got {type_name(robot_list)}')
    if len(robot_list) > MAX_ROBOTS:
        check.fail('robots', f'{len(robot_list)} robots, more than {MAX_ROBOTS}')
    robots = tuple(_robot(check, entry, f'robots[{index}]', file_noise, file_planner)
                   for index, entry in enumerate(robot_list))
    _check_robots_distinct(check, robots)
    static_world = _static_world(check, document, robots)
    if seed is not None:
        file_seed = _Validator('seed override').seed(seed, 'seed')
    return Scenario(name=name, description=description, seed=file_seed, dt=dt,
                    duration=duration, goal_tolerance=goal_tolerance, robots=robots, path=path,
                    static_world=static_world)


def _static_world(check, document, robots):
    """Return the StaticWorld of the file's walls, obstacles and map; check the robots in it."""
    walls = [_wall(check, entry, f'walls[{index}]')
             for index, entry in enumerate(_entries(check, document, 'walls'))]
    discs, polygons = [], []
    for index, entry in enumerate(_entries(check, document, 'obstacles')):
        key = f'obstacles[{index}]'
        if isinstance(entry, dict) and 'polygon' in entry:
            polygons.append(_polygon(check, entry, key))
        else:
            discs.append(_disc(check, entry, key))
    map_grid = (_map(check, check.string(document['map'], 'map'))
                if document.get('map') is not None else None)
    points = np.array([point for robot in robots for point in (robot.start, robot.goal)])
    world = StaticWorld(walls, discs, polygons, map_grid, extent_points=points)
    if world.empty:
        return world
    _, (height, width), _ = world.grid_layout()
    if height * width > MAX_GRID_CELLS:
        check.fail('walls' if map_grid is None else 'map',
                   f'the static world spans {width} x {height} cells of '
                   f'{world.grid_layout()[2]:g} m: more than {MAX_GRID_CELLS:.3g}')
    for index, robot in enumerate(robots):
        key = f'robots[{index}]'
        for place, place_key in (('start', f'{key}.start'), ('goal', _goal_key(robot, key))):
            point = getattr(robot, place)
            clearance = float(world.clearance(point)[0])
            if clearance < robot.radius:
                where = ('inside an obstacle' if clearance <= 0.0 else
                         f'{clearance:g} m from an obstacle, closer than its radius '
                         f'{robot.radius:g} m')
                check.fail(place_key, f'{point.tolist()} is {where} (robot {robot.name!r})')
    return world


def _goal_key(robot, key):
    """Return the key path that gives ROBOT (at KEY) its goal: its goal or its last waypoint."""
    for block, name in ((robot.scripted, 'scripted'), (robot.upstream, 'upstream'),
                        (robot.followed_path, 'path')):
        if block is not None:
            return f'{key}.{name}.waypoints[{len(block.waypoints) - 1}]'
    return f'{key}.goal'


def _entries(check, document, key):
    """Return the list under KEY (absent or null: empty)."""
    value = document.get(key)
    if value is None:
        return []
    if not isinstance(value, list):
        check.fail(key, f'expected a list, got {type_name(value)}')
    return value


def _wall(check, entry, key):
    """Return (segment (2, 2), thickness) of the wall ENTRY."""
    entry = check.mapping(entry, key, _WALL_KEYS, {'line'})
    line = entry['line']
    if not isinstance(line, list) or len(line) != 2:
        check.fail(f'{key}.line', f'expected [[x1, y1], [x2, y2]], got {line!r}')
    ends = np.array([check.point(point, f'{key}.line[{index}]')
                     for index, point in enumerate(line)])
    if np.array_equal(ends[0], ends[1]):
        check.fail(f'{key}.line', f'the two ends are equal ({ends[0].tolist()}): a wall needs a '
                   'length')
    thickness = check.number(entry.get('thickness', 0.0), f'{key}.thickness', 0.0,
                             COORDINATE_LIMIT)
    return ends, thickness


def _disc(check, entry, key):
    """Return (centre (2,), radius) of the disc obstacle ENTRY."""
    entry = check.mapping(entry, key, _DISC_KEYS, _DISC_KEYS)
    centre = check.point(entry['position'], f'{key}.position')
    radius = check.number(entry['radius'], f'{key}.radius', 0.0, COORDINATE_LIMIT,
                          low_open=True)
    return centre, radius


def _polygon(check, entry, key):
    """Return the vertices (V, 2) of the polygon obstacle ENTRY: V >= 3, no edges crossing."""
    entry = check.mapping(entry, key, _POLYGON_KEYS, _POLYGON_KEYS)
    value = entry['polygon']
    if not isinstance(value, list) or len(value) < 3:
        check.fail(f'{key}.polygon', f'expected a list of at least 3 vertices [x, y], got '
                   f'{value!r}')
    vertices = np.array([check.point(point, f'{key}.polygon[{index}]')
                         for index, point in enumerate(value)])
    sides = vertices[1:] - vertices[0]
    along = sides[(sides != 0.0).any(axis=1)]
    if not len(along) or not (along[0, 0] * sides[:, 1] - along[0, 1] * sides[:, 0]).any():
        # Every edge of such a polygon folds back onto another: it has no inside to solidify.
        check.fail(f'{key}.polygon', f'its {len(vertices)} vertices lie on one line: a polygon '
                   'needs an inside')
    repeated = np.flatnonzero((vertices == np.roll(vertices, -1, axis=0)).all(axis=1))
    if len(repeated):
        index = int(repeated[0])
        check.fail(f'{key}.polygon', f'vertices {index} and {(index + 1) % len(vertices)} are '
                   'equal: an edge needs a length')
    crossing = polygon_crossing(vertices)
    if crossing is not None:
        first, second, how = crossing
        check.fail(f'{key}.polygon', f'edges {first} and {second} {how} (edge i runs from vertex '
                   'i to the next): a polygon must be simple')
    return vertices


def _map(check, name, key='map'):
    """Return the GridMap of the map_server map file NAME, relative to the scenario file."""
    path = check.path.parent / name
    if not path.is_file():
        check.fail(key, f'no map file {str(path)!r}')
    map_check = _Validator(path)
    document = map_check.mapping(_parse(path), '(top level)', _MAP_KEYS, _MAP_REQUIRED)
    image_name = map_check.string(document['image'], 'image')
    resolution = map_check.number(document['resolution'], 'resolution', 0.0, COORDINATE_LIMIT,
                                  low_open=True)
    origin = document['origin']
    if not isinstance(origin, list) or len(origin) != 3:
        map_check.fail('origin', f'expected [x, y, yaw], got {origin!r}')
    corner = map_check.point(origin[:2], 'origin')
    if map_check.number(origin[2], 'origin[2]') != 0.0:
        map_check.fail('origin[2]', f'only maps aligned with the world frame (yaw 0) are '
                       f'supported, got {origin[2]!r}')
    negate = document.get('negate', 0)
    if negate not in (0, 1) or isinstance(negate, float):
        map_check.fail('negate', f'expected 0 or 1, got {negate!r}')
    thresholds = {name: map_check.number(document.get(name, default), name, 0.0, 1.0)
                  for name, default in (('occupied_thresh', DEFAULT_OCCUPIED_THRESH),
                                        ('free_thresh', DEFAULT_FREE_THRESH))}
    if thresholds['free_thresh'] > thresholds['occupied_thresh']:
        map_check.fail('free_thresh', f"{thresholds['free_thresh']:g} is above occupied_thresh "
                       f"{thresholds['occupied_thresh']:g}")
    mode = document.get('mode', 'trinary')
    if mode not in MODES:
        map_check.fail('mode', f'must be one of {", ".join(MODES)}, got {mode!r}')
    image_path = path.parent / image_name
    try:
        levels, alpha = read_image(image_path, MAX_GRID_CELLS)
    except OSError as error:
        map_check.fail('image', f'cannot read {str(image_path)!r}: {error}')
    cells = cells_from_image(levels, alpha, mode, bool(negate), **thresholds)
    return GridMap(cells, resolution, corner)


def _robot(check, entry, key, file_noise, file_planner):
    scripted = isinstance(entry, dict) and 'scripted' in entry
    driven = isinstance(entry, dict) and 'upstream' in entry
    following = isinstance(entry, dict) and 'path' in entry
    # A scripted robot, or one driven upstream or along a path, goes to its waypoints: it has no
    # goal of its own.
    required = (_ROBOT_REQUIRED - {'goal'} if scripted or driven or following
                else _ROBOT_REQUIRED)
    entry = check.mapping(entry, key, _ROBOT_KEYS, required)
    name = check.string(entry['name'], f'{key}.name')
    problem = ros_name_problem(name)
    if problem is not None:
        check.fail(f'{key}.name', problem)
    noise = {**file_noise, **check.noise(entry.get('noise'), f'{key}.noise')}
    # A planner gets both as its parameters of the same name: the same rules apply.
    radius = check.planner_parameter('radius', entry['radius'], f'{key}.radius')
    max_speed = check.planner_parameter('max_speed', entry['max_speed'], f'{key}.max_speed')
    start = check.point(entry['start'], f'{key}.start')
    kinematics = entry.get('kinematics', 'holonomic')
    if kinematics not in KINEMATICS:
        check.fail(f'{key}.kinematics', f'must be one of {", ".join(KINEMATICS)}, '
                   f'got {kinematics!r} (robot {name!r})')
    if kinematics == 'holonomic':
        for limit in _UNICYCLE_ONLY:
            if limit in entry:
                check.fail(f'{key}.{limit}', f'only for kinematics: unicycle (robot {name!r} is '
                           'holonomic)')
    # The planner gets them as its parameters of the same names: its rules (lower bounds of the
    # turn limits) apply, and a file states a finite limit or none.
    limits = {limit: check.number(
        check.planner_parameter(limit, entry[limit], f'{key}.{limit}'), f'{key}.{limit}', 0.0,
        MAX_LIMIT, low_open=True)
        for limit in ('max_angular_speed', 'max_acceleration', 'max_angular_acceleration')
        if limit in entry}
    start_yaw = (check.number(entry['start_yaw'], f'{key}.start_yaw', -2.0 * math.pi,
                              2.0 * math.pi) if 'start_yaw' in entry else None)
    path = None
    if scripted:
        for planned_only in ('goal', 'planner'):
            if planned_only in entry:
                check.fail(f'{key}.{planned_only}',
                           f'robot {name!r} is scripted: it has no {planned_only} '
                           f'(it follows scripted.waypoints)')
        if kinematics != 'holonomic':
            check.fail(f'{key}.kinematics', f'robot {name!r} is scripted: it moves holonomic '
                       f'along its waypoints, got {kinematics!r}')
        path = _scripted_path(check, entry['scripted'], f'{key}.scripted', name, max_speed)
    upstream = None
    if driven:
        if scripted or 'goal' in entry:
            check.fail(f'{key}.upstream', f'robot {name!r} is driven along upstream.waypoints: '
                       f"it has no {'scripted block' if scripted else 'goal'}")
        upstream = _scripted_path(check, entry['upstream'], f'{key}.upstream', name, max_speed,
                                  _UPSTREAM_KEYS)
    followed = None
    if following:
        if scripted or driven or 'goal' in entry:
            other = 'scripted block' if scripted else 'upstream block' if driven else 'goal'
            check.fail(f'{key}.path', f'robot {name!r} follows path.waypoints: it has no {other}')
        followed = _scripted_path(check, entry['path'], f'{key}.path', name, max_speed,
                                  _PATH_KEYS)
        poses = pose_count(followed.waypoints)
        if poses > MAX_PATH_POSES:
            # A planner ignores a longer path.
            check.fail(f'{key}.path.waypoints', f'the path of robot {name!r} is {poses} poses '
                       f'(one every {SPACING:g} m), more than the {MAX_PATH_POSES} a planner '
                       'takes')
    waypoints = next((block.waypoints for block in (path, upstream, followed)
                      if block is not None), None)
    goal = waypoints[-1] if waypoints is not None else check.point(entry['goal'], f'{key}.goal')
    planner = {}
    if path is None:
        own = check.planner(entry.get('planner'), f'{key}.planner')
        planner = {**file_planner, **own}
        try:
            # The rules between parameters (each alone is checked above), as the planner's.
            planner_config_from(planner)
        except ParameterError as error:
            where = (f'{key}.planner.{error.name}' if error.name in own else
                     f'planner.{error.name}' if error.name in file_planner else f'{key}.planner')
            check.fail(where, f'{error.reason} (robot {name!r})')
    return RobotSpec(
        name=name, start=start, goal=goal, kinematics=kinematics, start_yaw=start_yaw,
        **limits, radius=radius, max_speed=max_speed,
        noise=NoiseSpec(**{field: noise.get(field, 0.0) for field in _NOISE_KEYS}),
        planner=planner, scripted=path, upstream=upstream, followed_path=followed)


def _scripted_path(check, value, key, name, max_speed, keys=_SCRIPTED_KEYS):
    """Return the ScriptedPath of robot NAME's block VALUE (KEYS allowed); errors name the robot.

    A `scripted` block, an `upstream` block (waypoints and speed, no loop) or a `path` block
    (waypoints).
    """
    try:
        block = check.mapping(value, key, keys, {'waypoints'})
        waypoints = block['waypoints']
        if not isinstance(waypoints, list) or not waypoints:
            check.fail(f'{key}.waypoints',
                       f'expected a non-empty list of [x, y], got {waypoints!r}')
        points = np.array([check.point(point, f'{key}.waypoints[{index}]')
                           for index, point in enumerate(waypoints)])
        points.flags.writeable = False
        speed = check.number(block.get('speed', max_speed), f'{key}.speed', 0.0, low_open=True)
        if speed > max_speed:
            check.fail(f'{key}.speed', f"{speed:g} m/s is above the robot's max_speed "
                       f'{max_speed:g} m/s')
        loop = block.get('loop', False)
        if not isinstance(loop, bool):
            check.fail(f'{key}.loop', f'expected true or false, got {type_name(loop)}')
    except ScenarioError as error:
        raise ScenarioError(error.file, error.key, f'{error.reason} (robot {name!r})') from None
    return ScriptedPath(waypoints=points, speed=speed, loop=loop)


def _check_robots_distinct(check, robots):
    for later, robot in enumerate(robots):
        for earlier, other in enumerate(robots[:later]):
            if robot.name == other.name:
                check.fail(f'robots[{later}].name',
                           f'duplicate robot name {robot.name!r} (also robots[{earlier}])')
            distance = float(np.linalg.norm(robot.start - other.start))
            if distance < robot.radius + other.radius:
                check.fail(f'robots[{later}].start',
                           f'overlaps robots[{earlier}] ({other.name!r}) at the start: centre '
                           f'distance {distance:g} m < sum of radii '
                           f'{robot.radius + other.radius:g} m')


def find_scenario(name_or_path):
    """Return the path of a scenario given as a file path or a bare name like 'circle8'.

    A bare name is a file of that name if one exists, else the installed
    share/prvo_sim/scenarios/<name>.yaml (found in the ament index, else in this Python's
    prefix, where `./run.sh setup` installs it), else the copy in the source tree. Raises
    ScenarioError if none exists.
    """
    candidate = pathlib.Path(name_or_path)
    # A directory of that name (say, an output folder) is not a scenario.
    if candidate.suffix in ('.yaml', '.yml') or len(candidate.parts) > 1 or candidate.is_file():
        return candidate
    directories = []
    try:
        directories.append(pathlib.Path(get_package_share_directory('prvo_sim')) / 'scenarios')
    except (PackageNotFoundError, OSError):
        # OSError: AMENT_PREFIX_PATH is not set.
        pass
    directories += [pathlib.Path(sys.prefix) / 'share' / 'prvo_sim' / 'scenarios',
                    pathlib.Path(__file__).resolve().parent.parent / 'scenarios']
    for directory in directories:
        path = directory / f'{name_or_path}.yaml'
        if path.is_file():
            return path
    raise ScenarioError(name_or_path, '(file)', 'no such scenario in ' + ', '.join(
        str(directory) for directory in directories))


def estimate_team_memory(scenario, engine='ros', bag=True):
    """Return the memory a run of SCENARIO on ENGINE ('ros' or 'inprocess') needs [MiB].

    An estimate, not a bound. 'ros': one planner process per robot (scripted robots have
    none), the simulator and the runner, each at the resident size measured for it
    (PLANNER_MEMORY_MIB, ...), ignoring sharing between processes and growth with the team;
    good to a few tens of percent.

    'inprocess': one process holding every robot, INPROCESS_MEMORY_MIB and
    INPROCESS_ROBOT_MEMORY_MIB per robot; with BAG, the run's bag, which it holds until the run
    ends, for the scenario's whole duration (a run that arrives sooner needs less). Peak
    resident sizes of `prvo-run --engine inprocess` on crowd circles (`bench_crowds`) measured
    them: without bag or animation 179 MiB for 16 robots (204 steps), 320 for 64 (300 steps),
    355 for 128 (300) and 374 for 256 (100); with both, 496, 640, 1032 and 1383 MiB for 64
    robots over 150, 300, 600 and 865 steps, 1070 and 1272 MiB for 128 over 174 and 220 (about
    6 KiB per robot and step and 0.22 KiB more per neighbour), 274 MiB for 8 over 112 and 2001
    MiB for 256 over 100. The constants round those up: the estimate is 8-25% above each peak,
    83% above the smallest.

    On both engines every planner builds its own map of a world with walls or a map file
    (`map_memory_mib` each, MAP_BYTES_PER_CELL of the world's grid).
    """
    robots = len(scenario.robots)
    planners = sum(robot.scripted is None for robot in scenario.robots)
    maps = planners * map_memory_mib(scenario)
    if engine == 'ros':
        return math.ceil(planners * PLANNER_MEMORY_MIB + maps + SIMULATOR_MEMORY_MIB
                         + RUNNER_MEMORY_MIB)
    if engine != 'inprocess':
        raise ValueError(f'engine must be one of {", ".join(ENGINES)}, got {engine!r}')
    return math.ceil(INPROCESS_MEMORY_MIB + robots * INPROCESS_ROBOT_MEMORY_MIB + maps + (
        _bag_memory_mib(scenario) if bag else 0.0))


def map_memory_mib(scenario):
    """Return the memory one planner's map of SCENARIO's world needs while built [MiB]."""
    if scenario.static_world.empty:
        return 0.0
    _, (height, width), _ = scenario.static_world.grid_layout()
    return height * width * MAP_BYTES_PER_CELL / 2.0 ** 20


def _run_steps(scenario):
    """Return the number of states a run of SCENARIO records at most."""
    return math.ceil(scenario.duration / scenario.dt - 1e-9) + 1


def _bag_memory_mib(scenario):
    """Return the memory the bag of an in-process run of SCENARIO holds at most [MiB]."""
    robots = len(scenario.robots)
    planners = sum(robot.scripted is None for robot in scenario.robots)
    per_step = robots * BAG_ROBOT_STEP_KIB + planners * (robots - 1) * BAG_NEIGHBOUR_STEP_KIB
    return _run_steps(scenario) * per_step / 1024.0


def available_memory_mib(meminfo='/proc/meminfo'):
    """Return MemAvailable of MEMINFO [MiB], or None where the system does not report it."""
    try:
        with open(meminfo) as lines:
            for line in lines:
                if line.startswith('MemAvailable:'):
                    return int(line.split()[1]) // 1024
    except (OSError, ValueError, IndexError):
        return None
    return None


def check_team_memory(scenario, available_mib=None, engine='ros', bag=True):
    """Raise ScenarioError if a run of SCENARIO on ENGINE needs more memory than is available.

    ENGINE and BAG (whether the run records a bag) as in `estimate_team_memory`.
    AVAILABLE_MIB defaults to the machine's MemAvailable; where that is unknown, nothing is
    checked. Call before starting anything.
    """
    needed = estimate_team_memory(scenario, engine, bag)
    available = available_memory_mib() if available_mib is None else available_mib
    if available is None or needed <= available:
        return
    map_mib = math.ceil(map_memory_mib(scenario))
    maps = f', {map_mib} MiB per planner for its map' if map_mib else ''
    if engine == 'ros':
        parts = (f'{PLANNER_MEMORY_MIB} MiB per planner{maps}, {SIMULATOR_MEMORY_MIB} MiB '
                 f'simulator, {RUNNER_MEMORY_MIB} MiB runner')
    else:
        parts = (f'in process: {INPROCESS_MEMORY_MIB} MiB, {INPROCESS_ROBOT_MEMORY_MIB:g} MiB '
                 f'per robot{maps}' + (
                     f', {math.ceil(_bag_memory_mib(scenario))} MiB for the bag of '
                     f'{_run_steps(scenario)} steps (--no-bag: none)' if bag else ''))
    raise ScenarioError(
        scenario.path, 'robots',
        f'{len(scenario.robots)} robots need an estimated {needed} MiB ({parts}), more than '
        f'the {available} MiB available')
