"""Inputs the planner tests hand the agent in place of the messages' conversions."""

import dataclasses

import numpy as np


@dataclasses.dataclass(frozen=True)
class Odometry:
    """The fields of prvo_msgs_util.OdometryMeasurement the agent reads."""

    stamp: float
    position: np.ndarray
    velocity: np.ndarray
    covariance: np.ndarray
    yaw: float = 0.0
