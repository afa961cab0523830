"""RViz markers of a planner's belief and of the static world.

A belief: neighbour ellipses, sizes, shares, the chosen velocity. The world: walls, obstacles.
"""

import math

from geometry_msgs.msg import Point
import numpy as np
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from prvo_msgs_util.conversions import seconds_to_stamp

_ELLIPSE_THICKNESS = 0.02
_ELLIPSE_COLOUR = ColorRGBA(r=1.0, g=0.5, b=0.0, a=0.4)
_ARROW_COLOUR = ColorRGBA(r=0.1, g=0.8, b=0.1, a=1.0)
_ARROW_SHAFT_DIAMETER = 0.05
_ARROW_HEAD_DIAMETER = 0.1
_ARROW_HEAD_LENGTH = 0.1
_LABEL_COLOUR = ColorRGBA(r=1.0, g=1.0, b=1.0, a=0.9)
_LABEL_HEIGHT = 0.15


def _ellipse_marker(header, namespace, marker_id, position, covariance, radius, ellipse_scale):
    """Return a flat cylinder covering the confidence ellipse of POSITION grown by RADIUS."""
    eigenvalues, eigenvectors = np.linalg.eigh(covariance)
    # Rounding can leave a PSD covariance with a tiny negative eigenvalue.
    minor_variance, major_variance = np.maximum(eigenvalues, 0.0)
    major_axis = eigenvectors[:, 1]
    yaw = math.atan2(major_axis[1], major_axis[0])
    marker = Marker(header=header, ns=namespace, id=marker_id, type=Marker.CYLINDER,
                    action=Marker.ADD, color=_ELLIPSE_COLOUR)
    marker.pose.position.x, marker.pose.position.y = (float(value) for value in position)
    marker.pose.orientation.z = math.sin(0.5 * yaw)
    marker.pose.orientation.w = math.cos(0.5 * yaw)
    marker.scale.x = 2.0 * (ellipse_scale * math.sqrt(major_variance) + radius)
    marker.scale.y = 2.0 * (ellipse_scale * math.sqrt(minor_variance) + radius)
    marker.scale.z = _ELLIPSE_THICKNESS
    return marker


def make_belief_markers(stamp_seconds, frame_id, namespace, ego_position, chosen_velocity,
                        neighbour_positions, neighbour_position_covs, neighbour_radii,
                        ellipse_scale, neighbour_shares):
    """Return a MarkerArray: DELETEALL, the chosen velocity's ARROW, an ellipse and label each.

    Each neighbour's CYLINDER (id 1 + i) spans its position ellipse of semi-axes ELLIPSE_SCALE
    sqrt(eigenvalue) (the planner's confidence ellipse:
    `prvo_planner.core.probability.confidence_ellipse_scale`) plus its radius, turned along
    the major axis; its TEXT_VIEW_FACING label (id 1 + N + i) states the radius and share of
    the avoidance (NEIGHBOUR_SHARES) it is planned with.
    """
    if not (math.isfinite(ellipse_scale) and ellipse_scale >= 0.0):
        raise ValueError(f'ellipse_scale must be finite and >= 0, got {ellipse_scale}')
    positions = np.asarray(neighbour_positions, dtype=float).reshape(-1, 2)
    covariances = np.asarray(neighbour_position_covs, dtype=float).reshape(-1, 2, 2)
    radii = np.asarray(neighbour_radii, dtype=float).reshape(-1)
    shares = np.asarray(neighbour_shares, dtype=float).reshape(-1)
    if not len(positions) == len(covariances) == len(radii) == len(shares):
        raise ValueError(
            f'{len(positions)} neighbour positions, {len(covariances)} covariances, '
            f'{len(radii)} radii and {len(shares)} shares')
    markers = MarkerArray()
    delete_all = Marker(ns=namespace, action=Marker.DELETEALL)
    delete_all.header.frame_id = frame_id
    markers.markers.append(delete_all)
    header = delete_all.header
    header.stamp = seconds_to_stamp(stamp_seconds)
    ego = np.asarray(ego_position, dtype=float)
    tip = ego + np.asarray(chosen_velocity, dtype=float)
    arrow = Marker(header=header, ns=namespace, id=0, type=Marker.ARROW, action=Marker.ADD,
                   color=_ARROW_COLOUR,
                   points=[Point(x=float(ego[0]), y=float(ego[1])),
                           Point(x=float(tip[0]), y=float(tip[1]))])
    arrow.pose.orientation.w = 1.0
    arrow.scale.x = _ARROW_SHAFT_DIAMETER
    arrow.scale.y = _ARROW_HEAD_DIAMETER
    arrow.scale.z = _ARROW_HEAD_LENGTH
    markers.markers.append(arrow)
    for index, (position, covariance, radius) in enumerate(
            zip(positions, covariances, radii, strict=True)):
        markers.markers.append(_ellipse_marker(
            header, namespace, index + 1, position, covariance, float(radius), ellipse_scale))
    for index, (position, radius, share) in enumerate(zip(positions, radii, shares, strict=True)):
        label = Marker(header=header, ns=namespace, id=len(positions) + index + 1,
                       type=Marker.TEXT_VIEW_FACING, action=Marker.ADD, color=_LABEL_COLOUR,
                       text=f'r {radius:.2f} m, share {share:.2f}')
        label.pose.position.x, label.pose.position.y = (float(value) for value in position)
        label.pose.position.z = _LABEL_HEIGHT
        label.pose.orientation.w = 1.0
        label.scale.z = _LABEL_HEIGHT
        markers.markers.append(label)
    return markers


_WALL_COLOUR = ColorRGBA(r=0.55, g=0.55, b=0.6, a=0.9)
_OBSTACLE_COLOUR = ColorRGBA(r=0.4, g=0.4, b=0.45, a=0.9)
_STATIC_HEIGHT = 0.5
# A wall of no thickness is drawn this wide, so that it shows.
_MIN_DRAWN_THICKNESS = 0.02


def make_static_world_markers(stamp_seconds, frame_id, walls, discs, polygons,
                              namespace='static_world'):
    """Return a MarkerArray of a world's walls, disc and polygon obstacles, after a DELETEALL.

    WALLS: (segment (2, 2), thickness) pairs, each a CUBE along the segment, as long as it
    plus its thickness and as wide as its thickness (at least a line's width); DISCS: (centre
    (2,), radius) pairs, each a CYLINDER; POLYGONS: vertices (V, 2), each a closed LINE_STRIP.
    Every shape stands _STATIC_HEIGHT tall on the ground; ids count from 0 in that order.
    """
    markers = MarkerArray()
    delete_all = Marker(ns=namespace, action=Marker.DELETEALL)
    delete_all.header.frame_id = frame_id
    delete_all.header.stamp = seconds_to_stamp(stamp_seconds)
    markers.markers.append(delete_all)
    header = delete_all.header
    for line, thickness in walls:
        start, end = (np.asarray(point, dtype=float) for point in line)
        along = end - start
        yaw = math.atan2(along[1], along[0])
        width = max(float(thickness), _MIN_DRAWN_THICKNESS)
        marker = Marker(header=header, ns=namespace, id=len(markers.markers) - 1,
                        type=Marker.CUBE, action=Marker.ADD, color=_WALL_COLOUR)
        centre = 0.5 * (start + end)
        marker.pose.position.x, marker.pose.position.y = float(centre[0]), float(centre[1])
        marker.pose.position.z = 0.5 * _STATIC_HEIGHT
        marker.pose.orientation.z = math.sin(0.5 * yaw)
        marker.pose.orientation.w = math.cos(0.5 * yaw)
        marker.scale.x = float(np.linalg.norm(along)) + float(thickness)
        marker.scale.y = width
        marker.scale.z = _STATIC_HEIGHT
        markers.markers.append(marker)
    for centre, radius in discs:
        marker = Marker(header=header, ns=namespace, id=len(markers.markers) - 1,
                        type=Marker.CYLINDER, action=Marker.ADD, color=_OBSTACLE_COLOUR)
        marker.pose.position.x, marker.pose.position.y = (float(value) for value in centre)
        marker.pose.position.z = 0.5 * _STATIC_HEIGHT
        marker.pose.orientation.w = 1.0
        marker.scale.x = marker.scale.y = 2.0 * float(radius)
        marker.scale.z = _STATIC_HEIGHT
        markers.markers.append(marker)
    for vertices in polygons:
        marker = Marker(header=header, ns=namespace, id=len(markers.markers) - 1,
                        type=Marker.LINE_STRIP, action=Marker.ADD, color=_OBSTACLE_COLOUR)
        marker.pose.orientation.w = 1.0
        marker.scale.x = 2.0 * _MIN_DRAWN_THICKNESS
        closed = [*vertices, vertices[0]]
        marker.points = [Point(x=float(x), y=float(y)) for x, y in closed]
        markers.markers.append(marker)
    return markers
