"""Exact convex decomposition of simple polygons (holes allowed).

The collision checks and the planners' obstacle constraints work on convex polygons; a
layout's obstacles may be any simple polygon, and the outside of a drivable-area boundary
is a box with a hole. Each is cut exactly into convex parts: shapely's constrained
Delaunay triangulation (its triangles cover the polygon exactly and meet along
diagonals), then Hertel and Mehlhorn's merge: a diagonal is dropped whenever the two parts
it separates form a convex polygon. The result has at most four times the fewest convex
parts possible, and the parts' union is the polygon (their areas add up to its area).
"""

from __future__ import annotations

import numpy as np

_EPS = 1e-9


def _ccw(pts: list[tuple[float, float]]) -> list[tuple[float, float]]:
    a = sum(x0 * y1 - x1 * y0 for (x0, y0), (x1, y1) in zip(pts, pts[1:] + pts[:1]))
    return pts if a > 0 else pts[::-1]


def _convex(pts: list[tuple[float, float]]) -> bool:
    n = len(pts)
    for i in range(n):
        (ax, ay), (bx, by), (cx, cy) = pts[i - 1], pts[i], pts[(i + 1) % n]
        if (bx - ax) * (cy - by) - (by - ay) * (cx - bx) < -_EPS:
            return False
    return True


def _drop_collinear(pts: list[tuple[float, float]]) -> list[tuple[float, float]]:
    out = []
    n = len(pts)
    for i in range(n):
        (ax, ay), (bx, by), (cx, cy) = pts[i - 1], pts[i], pts[(i + 1) % n]
        if abs((bx - ax) * (cy - by) - (by - ay) * (cx - bx)) > _EPS:
            out.append(pts[i])
    return out


def _merge(p: list, q: list, a, b) -> list:
    """P (CCW, holds edge a->b) and Q (CCW, holds b->a) joined along that edge."""
    i = p.index(b)
    p_part = p[i:] + p[:i]  # starts at b, ends at a
    j = q.index(a)
    q_part = q[j:] + q[:j]  # starts at a, ends at b
    return p_part + q_part[1:-1]


def convex_parts(polygon) -> list[np.ndarray]:
    """Convex parts (each (n, 2), CCW) whose union is ``polygon``.

    ``polygon``: an (n, 2) vertex array, or a shapely ``Polygon`` (holes allowed). A convex
    input comes back as itself.
    """
    import shapely
    from shapely.geometry import Polygon

    from .geometry import as_ccw, is_convex

    poly = polygon if isinstance(polygon, Polygon) else Polygon(np.asarray(polygon, float))
    if not poly.is_valid or poly.area <= 0:
        raise ValueError(f"not a simple polygon of positive area ({shapely.is_valid_reason(poly)})")
    if not isinstance(polygon, Polygon) and is_convex(np.asarray(polygon, float)):
        return [as_ccw(np.asarray(polygon, float))]
    tris = shapely.constrained_delaunay_triangles(poly)
    parts: dict[int, list] = {}
    for k, t in enumerate(tris.geoms):
        parts[k] = _ccw(list(t.exterior.coords)[:-1])
    # Each diagonal (an edge two parts share) is tried once, longest first.
    owner: dict[tuple, int] = {}
    diagonals = []
    for k, pts in parts.items():
        for a, b in zip(pts, pts[1:] + pts[:1]):
            if (b, a) in owner:
                diagonals.append((-np.hypot(b[0] - a[0], b[1] - a[1]), a, b))
            owner[(a, b)] = k
    diagonals.sort(key=lambda d: d[0])
    for _, a, b in diagonals:
        kp, kq = owner.get((a, b)), owner.get((b, a))
        if kp is None or kq is None or kp == kq:
            continue
        merged = _merge(parts[kp], parts[kq], a, b)
        if not _convex(merged):
            continue
        del parts[kq]
        parts[kp] = merged
        for e in zip(merged, merged[1:] + merged[:1]):
            owner[e] = kp
        owner.pop((a, b), None)
        owner.pop((b, a), None)
    return [np.array(_drop_collinear(p)) for p in parts.values()]
