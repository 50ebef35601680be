"""Plane geometry of an operating area, written once: points, segments, polygons and circles.

Every point is (north_m, east_m) in the local NED frame [m]. A polygon is its vertices in order
(either winding), closed implicitly (the last vertex joins the first). Boundaries count as inside
(closed sets): a keep-in polygon allows its own boundary and a keep-out area forbids its own.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence

Point = tuple[float, float]

_EPS_M = 1e-9
"""Tolerance of the orientation tests [m^2 scale]: far below any distance that matters on the water,
above the rounding of coordinates up to 100 km."""


def _cross(o: Point, a: Point, b: Point) -> float:
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


def _edges(polygon: Sequence[Point]) -> list[tuple[Point, Point]]:
    n = len(polygon)
    return [(polygon[i], polygon[(i + 1) % n]) for i in range(n)]


def distance_point_segment_m(p: Point, a: Point, b: Point) -> float:
    """Distance of point ``p`` from the segment a-b [m] (from ``a`` if the segment is a point)."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    length2 = dx * dx + dy * dy
    t = 0.0 if length2 == 0.0 else max(0.0, min(1.0, ((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / length2))
    return math.hypot(p[0] - (a[0] + t * dx), p[1] - (a[1] + t * dy))


def polygon_area_m2(polygon: Sequence[Point]) -> float:
    """Signed area (shoelace) [m^2]: positive when the vertices turn from north to east."""
    return 0.5 * sum(a[0] * b[1] - b[0] * a[1] for a, b in _edges(polygon))


def on_boundary(p: Point, polygon: Sequence[Point], tol_m: float = 1e-6) -> bool:
    """True if ``p`` lies on an edge of the polygon (within ``tol_m``)."""
    x, y = p
    for a, b in _edges(polygon):
        if (
            x < min(a[0], b[0]) - tol_m
            or x > max(a[0], b[0]) + tol_m
            or y < min(a[1], b[1]) - tol_m
            or y > max(a[1], b[1]) + tol_m
        ):
            continue  # outside the edge's box: not on it (cheap, and most edges)
        if distance_point_segment_m(p, a, b) <= tol_m:
            return True
    return False


def point_in_polygon(p: Point, polygon: Sequence[Point]) -> bool:
    """True if ``p`` is inside the polygon or on its boundary (even-odd rule)."""
    inside = False
    x, y = p
    for (x1, y1), (x2, y2) in _edges(polygon):
        if (y1 > y) != (y2 > y):
            x_cross = x1 + (y - y1) * (x2 - x1) / (y2 - y1)
            if x < x_cross:
                inside = not inside
    return inside or on_boundary(p, polygon)


def distance_to_polygon_boundary_m(p: Point, polygon: Sequence[Point]) -> float:
    """Distance of ``p`` from the nearest edge of the polygon [m], inside or out."""
    return min(distance_point_segment_m(p, a, b) for a, b in _edges(polygon))


def segments_intersect(a: Point, b: Point, c: Point, d: Point) -> bool:
    """True if the closed segments a-b and c-d share at least one point."""
    d1, d2 = _cross(c, d, a), _cross(c, d, b)
    d3, d4 = _cross(a, b, c), _cross(a, b, d)
    if ((d1 > _EPS_M and d2 < -_EPS_M) or (d1 < -_EPS_M and d2 > _EPS_M)) and (
        (d3 > _EPS_M and d4 < -_EPS_M) or (d3 < -_EPS_M and d4 > _EPS_M)
    ):
        return True
    return (
        distance_point_segment_m(a, c, d) <= 1e-6
        or distance_point_segment_m(b, c, d) <= 1e-6
        or distance_point_segment_m(c, a, b) <= 1e-6
        or distance_point_segment_m(d, a, b) <= 1e-6
    )


def self_intersection(polygon: Sequence[Point]) -> tuple[int, int] | None:
    """The first pair of edges (i, j) that cross or touch other than at the vertex two neighbouring
    edges share, or None for a simple polygon. Edge i joins vertex i to vertex i+1."""
    edges = _edges(polygon)
    n = len(edges)
    for i in range(n):
        for j in range(i + 1, n):
            neighbours = j == i + 1 or (i == 0 and j == n - 1)
            a, b = edges[i]
            c, d = edges[j]
            if not neighbours:
                if segments_intersect(a, b, c, d):
                    return i, j
            else:  # neighbours share a vertex: they overlap only if they fold back on each other
                shared, oi, oj = (b, a, d) if j == i + 1 else (a, b, c)
                back = (oi[0] - shared[0]) * (oj[0] - shared[0]) + (oi[1] - shared[1]) * (oj[1] - shared[1])
                if abs(_cross(shared, oi, oj)) <= _EPS_M and back > 0:
                    return i, j
    return None


def _crossing_params(a: Point, b: Point, polygon: Sequence[Point]) -> tuple[list[float], bool]:
    """Parameters t in [0, 1] along a-b where it meets the polygon's boundary (sorted, with 0 and
    1), and whether it meets the boundary at all (if not, the whole segment is on the side of
    ``a``)."""
    ts = {0.0, 1.0}
    met = False
    rx, ry = b[0] - a[0], b[1] - a[1]
    r2 = rx * rx + ry * ry
    lo_x, hi_x = min(a[0], b[0]) - 1e-6, max(a[0], b[0]) + 1e-6
    lo_y, hi_y = min(a[1], b[1]) - 1e-6, max(a[1], b[1]) + 1e-6
    for c, d in _edges(polygon):
        if (
            max(c[0], d[0]) < lo_x
            or min(c[0], d[0]) > hi_x
            or max(c[1], d[1]) < lo_y
            or min(c[1], d[1]) > hi_y
        ):
            continue  # the boxes do not overlap: no contact (the common case, and cheap)
        sx, sy = d[0] - c[0], d[1] - c[1]
        denom = rx * sy - ry * sx
        qx, qy = c[0] - a[0], c[1] - a[1]
        if abs(denom) > 1e-12:
            t = (qx * sy - qy * sx) / denom
            u = (qx * ry - qy * rx) / denom
            if -1e-12 <= t <= 1 + 1e-12 and -1e-12 <= u <= 1 + 1e-12:
                ts.add(min(1.0, max(0.0, t)))
                met = True
        elif segments_intersect(a, b, c, d):  # parallel and touching: where it passes the edge's ends
            met = True
            if r2 > 0.0:
                for e in (c, d):
                    t = ((e[0] - a[0]) * rx + (e[1] - a[1]) * ry) / r2
                    if 0.0 <= t <= 1.0:
                        ts.add(t)
    return sorted(ts), met


def _at(a: Point, b: Point, t: float) -> Point:
    return a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])


def segment_leaves_polygon(a: Point, b: Point, polygon: Sequence[Point]) -> float | None:
    """Where the segment a-b is first outside the polygon, as a parameter t in [0, 1] along it
    (0 if ``a`` is outside), or None if it stays inside (the boundary counts as inside)."""
    ts, met = _crossing_params(a, b, polygon)
    if not point_in_polygon(a, polygon):
        return 0.0
    if not met:
        return None
    for t0, t1 in itertools.pairwise(ts):
        if not point_in_polygon(_at(a, b, 0.5 * (t0 + t1)), polygon):
            return t0
        if not point_in_polygon(_at(a, b, t1), polygon):
            return t1
    return None


def segment_enters_polygon(a: Point, b: Point, polygon: Sequence[Point]) -> float | None:
    """Where the segment a-b first touches the polygon (boundary included), as a parameter t in
    [0, 1] along it, or None if it stays clear."""
    ts, met = _crossing_params(a, b, polygon)
    if not met:
        return 0.0 if point_in_polygon(a, polygon) else None
    for k, t in enumerate(ts):
        if point_in_polygon(_at(a, b, t), polygon):
            return t
        if k + 1 < len(ts) and point_in_polygon(_at(a, b, 0.5 * (t + ts[k + 1])), polygon):
            return t
    return None


def segment_enters_circle(a: Point, b: Point, center: Point, radius_m: float) -> float | None:
    """Where the segment a-b first comes within ``radius_m`` of ``center`` (the closed disc), as a
    parameter t in [0, 1] along it, or None if it stays clear."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    fx, fy = a[0] - center[0], a[1] - center[1]
    c = fx * fx + fy * fy - radius_m * radius_m
    if c <= 0.0:
        return 0.0
    qa = dx * dx + dy * dy
    if qa == 0.0:
        return None
    qb = 2.0 * (fx * dx + fy * dy)
    disc = qb * qb - 4.0 * qa * c
    if disc < 0.0:
        return None
    t = (-qb - math.sqrt(disc)) / (2.0 * qa)
    return t if 0.0 <= t <= 1.0 else None
