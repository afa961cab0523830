"""Loading and validating scenario files (schema: /work/shared/scenarios/README.md)."""

from dataclasses import dataclass
import math
import pathlib
import re

from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
import numpy as np
import yaml

from prvo_msgs_util import validate_robot_name

_SCENARIO_NAME = re.compile(r'[A-Za-z0-9_-]+')
_TOP_LEVEL_KEYS = {'name', 'description', 'seed', 'dt', 'duration', 'goal_tolerance', 'noise',
                   'planner', 'robots'}
_TOP_LEVEL_REQUIRED = {'name', 'seed', 'dt', 'duration', 'goal_tolerance', 'robots'}
_ROBOT_KEYS = {'name', 'start', 'goal', 'radius', 'max_speed', 'noise', 'planner'}
_ROBOT_REQUIRED = {'name', 'start', 'goal', 'radius', 'max_speed'}
_NOISE_KEYS = ('position_std', 'velocity_std', 'actuation_std')
_PLANNER_SCALARS = (bool, int, float, str)


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
class RobotSpec:
    """One robot of a scenario, with the file-level noise and planner blocks merged in.

    `start` and `goal` are read-only arrays (2,), so specs compare by identity.
    """

    name: str
    start: np.ndarray
    goal: np.ndarray
    radius: float
    max_speed: float
    noise: NoiseSpec
    planner: dict


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


class _Validator:
    """Check one parsed file; every failure raises ScenarioError with its key path."""

    def __init__(self, path):
        self.path = path

    def fail(self, key, reason):
        raise ScenarioError(self.path, key, reason)

    def mapping(self, value, key, allowed, required):
        """Return VALUE if it is a mapping with REQUIRED keys and only ALLOWED (None: any)."""
        if not isinstance(value, dict):
            self.fail(key, f'expected a mapping, got {_type_name(value)}')
        prefix = f'{key}.' if key != '(top level)' else ''
        for name in value:
            if allowed is not None and name not in allowed:
                self.fail(f'{prefix}{name}',
                          f'unknown key (allowed: {", ".join(sorted(allowed))})')
        for name in sorted(required):
            if name not in value:
                self.fail(f'{prefix}{name}', 'missing required key')
        return value

    def number(self, value, key, minimum=None, strictly=True):
        # bool is an int in Python, but `radius: true` is a mistake, not a number.
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            self.fail(key, f'expected a number, got {_type_name(value)}')
        if not math.isfinite(value):
            self.fail(key, f'expected a finite number, got {value}')
        if minimum is not None and (value <= minimum if strictly else value < minimum):
            self.fail(key, f'must be {">" if strictly else ">="} {minimum}, got {value}')
        return float(value)

    def seed(self, value, key):
        if isinstance(value, bool) or not isinstance(value, int):
            self.fail(key, f'expected an integer, got {_type_name(value)}')
        if value < 0:
            self.fail(key, f'must be >= 0, got {value}')
        return value

    def string(self, value, key):
        if not isinstance(value, str):
            self.fail(key, f'expected a string, got {_type_name(value)}')
        return value

    def point(self, value, key):
        if not isinstance(value, list) or len(value) != 2:
            self.fail(key, f'expected [x, y], got {value!r}')
        point = np.array([self.number(coordinate, f'{key}[{index}]')
                          for index, coordinate in enumerate(value)])
        point.flags.writeable = False
        return point

    def noise(self, value, key):
        if value is None:
            return {}
        block = self.mapping(value, key, set(_NOISE_KEYS), set())
        return {name: self.number(std, f'{key}.{name}', 0.0, strictly=False)
                for name, std in block.items()}

    def planner(self, value, key):
        if value is None:
            return {}
        block = self.mapping(value, key, None, set())
        for name, parameter in block.items():
            if not isinstance(name, str):
                self.fail(f'{key}.{name}', 'parameter names must be strings')
            items = parameter if isinstance(parameter, list) else [parameter]
            if not all(isinstance(item, _PLANNER_SCALARS) for item in items):
                self.fail(f'{key}.{name}',
                          f'expected a ROS parameter value (bool, int, float, string or a '
                          f'list of them), got {_type_name(parameter)}')
        return dict(block)


def _type_name(value):
    return {type(None): 'nothing', dict: 'a mapping', list: 'a list', bool: 'a boolean',
            str: 'a string', int: 'an integer', float: 'a number'}.get(
                type(value), type(value).__name__)


def _parse(path):
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as error:
        raise ScenarioError(path, '(file)', f'cannot read: {error}') from None
    try:
        return yaml.load(text, Loader=_UniqueKeyLoader)
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
    dt = check.number(document['dt'], 'dt', 0.0)
    duration = check.number(document['duration'], 'duration', 0.0)
    goal_tolerance = check.number(document['goal_tolerance'], 'goal_tolerance', 0.0)
    file_noise = check.noise(document.get('noise'), 'noise')
    file_planner = check.planner(document.get('planner'), 'planner')
    robot_list = document['robots']
    if not isinstance(robot_list, list) or not robot_list:
        check.fail('robots', f'expected a non-empty list, got {_type_name(robot_list)}')
    robots = tuple(_robot(check, entry, f'robots[{index}]', file_noise, file_planner)
                   for index, entry in enumerate(robot_list))
    _check_robots_distinct(check, robots)
    if seed is not None:
        file_seed = _Validator('seed override').seed(seed, 'seed')
    return Scenario(name=name, description=description, seed=file_seed, dt=dt,
                    duration=duration, goal_tolerance=goal_tolerance, robots=robots, path=path)


def _robot(check, entry, key, file_noise, file_planner):
    entry = check.mapping(entry, key, _ROBOT_KEYS, _ROBOT_REQUIRED)
    name = check.string(entry['name'], f'{key}.name')
    try:
        validate_robot_name(name)
    except ValueError as error:
        check.fail(f'{key}.name', str(error))
    noise = {**file_noise, **check.noise(entry.get('noise'), f'{key}.noise')}
    return RobotSpec(
        name=name, start=check.point(entry['start'], f'{key}.start'),
        goal=check.point(entry['goal'], f'{key}.goal'),
        radius=check.number(entry['radius'], f'{key}.radius', 0.0),
        max_speed=check.number(entry['max_speed'], f'{key}.max_speed', 0.0),
        noise=NoiseSpec(**{field: noise.get(field, 0.0) for field in _NOISE_KEYS}),
        planner={**file_planner, **check.planner(entry.get('planner'), f'{key}.planner')})


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

    A bare name resolves to the installed share/prvo_sim/scenarios/<name>.yaml, else to the
    copy in the source tree. Raises ScenarioError if neither exists.
    """
    candidate = pathlib.Path(name_or_path)
    if candidate.suffix in ('.yaml', '.yml') or len(candidate.parts) > 1 or candidate.exists():
        return candidate
    directories = []
    try:
        directories.append(pathlib.Path(get_package_share_directory('prvo_sim')) / 'scenarios')
    except PackageNotFoundError:
        pass
    directories.append(pathlib.Path(__file__).resolve().parent.parent / 'scenarios')
    for directory in directories:
        path = directory / f'{name_or_path}.yaml'
        if path.is_file():
            return path
    raise ScenarioError(name_or_path, '(file)', 'no such scenario in ' + ', '.join(
        str(directory) for directory in directories))
