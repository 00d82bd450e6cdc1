"""The numpy kernels of the planar distances: link capsules against one primitive, on unchecked blocks.

A kernel maps one block of links, ``a`` and ``b`` of shape ``(n, L, 3)`` [m] and radii ``(L,)`` [m], to
``(n, L)`` signed distances [m]; :func:`apply` runs it over blocks of about ``_BLOCK_LINKS`` links. Every
operation inside is a numpy operation over the whole block: the blocks only keep the ~30 temporaries of a
kernel in the CPU cache (measured: docs/decisions.md#planar-distance-kernels-blocks-and-throughput).

The functions here take their obstacle as already-validated keyword arguments; the validated builders
(``sphere_kernel`` ...) and one-shot functions (``to_sphere`` ...) are in :mod:`previewctl.planar.distance`,
which also documents the formulas.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

_TINY = float(np.finfo(np.float64).tiny)
# Below this value of sin^2 of the angle between two segments they count as parallel (see
# `segment_distance`): the closed form for the interior point is then ill-conditioned.
_PARALLEL_SIN2 = 1e-14

Kernel = Callable[[FloatArray, FloatArray, FloatArray], FloatArray]
_BLOCK_LINKS = 16384


def apply(kernel: Kernel, a: FloatArray, b: FloatArray, radius: FloatArray) -> FloatArray:
    """Distances ``(..., L)`` [m] of a prepared kernel (``*_kernel``) for links with ``(..., L, 3)`` end
    points (unchecked), evaluated block by block."""
    out = np.empty(a.shape[:-1])
    if out.size == 0:
        return out
    n_links = a.shape[-2]
    a_rows, b_rows = a.reshape(-1, n_links, 3), b.reshape(-1, n_links, 3)
    out_rows = out.reshape(-1, n_links)
    step = max(1, _BLOCK_LINKS // n_links)
    for start in range(0, len(a_rows), step):
        block = slice(start, start + step)
        out_rows[block] = kernel(a_rows[block], b_rows[block], radius)
    return out


def _dot(u: Sequence[FloatArray | float], v: Sequence[FloatArray | float]) -> FloatArray:
    """``sum_k u[k] * v[k]``, one entry per axis; at least one of each pair is an array."""
    out = np.multiply(u[0], v[0])
    for uk, vk in zip(u[1:], v[1:], strict=True):
        out += uk * vk
    return out


def _point_segment_sq(
    p: Sequence[FloatArray | float],
    a: Sequence[FloatArray],
    d: Sequence[FloatArray],
    dd: FloatArray,
) -> FloatArray:
    """Squared distances from points ``p`` to the segments ``a + t d``, ``t in [0, 1]``.

    Coordinates come one entry per axis (2 or 3 of them); ``dd = max(|d|^2, tiny)``, so that a
    zero-length segment (where the numerator is exactly 0) gives ``t = 0``.
    """
    rel = [pk - ak for pk, ak in zip(p, a, strict=True)]
    t = _dot(rel, d) / dd
    np.clip(t, 0.0, 1.0, out=t)
    diff = [rk - t * dk for rk, dk in zip(rel, d, strict=True)]
    return _dot(diff, diff)


def _coords(points: FloatArray, n: int) -> list[FloatArray]:
    """The first ``n`` coordinates of ``(..., 3)`` points, one ``(...)`` view per axis."""
    return [points[..., k] for k in range(n)]


def point_distance(
    a: FloatArray, b: FloatArray, radius: FloatArray, center: tuple[float, ...], clearance: float
) -> FloatArray:
    """Point-segment distance minus radii, in 3-D (sphere) or in x, y (``center`` of size 2) [m]."""
    pa = _coords(a, len(center))
    d = [bk - ak for ak, bk in zip(pa, _coords(b, len(center)), strict=True)]
    dd = np.maximum(_dot(d, d), _TINY)
    return np.sqrt(_point_segment_sq(center, pa, d, dd)) - radius - clearance


def segment_distance(
    a: FloatArray,
    b: FloatArray,
    radius: FloatArray,
    p: tuple[float, ...],
    d2: tuple[float, ...],
    clearance: float,
) -> FloatArray:
    """Segment-segment distance by the clamped closed form, written without branches.

    For the link ``a + s d1`` and the obstacle axis ``p + t d2`` (Ericson, Real-Time Collision
    Detection, 5.1.9): ``s`` minimises ``|a + s d1 - p - t d2|^2`` over both variables and is
    clamped to [0, 1]; then ``t`` is optimal for that ``s`` and clamped; then ``s`` is optimal for
    that ``t`` and clamped. Each step minimises a convex quadratic exactly in one variable, so the
    result is never worse than Ericson's, which is the exact minimum. For parallel segments
    (``sin^2`` of their angle below `_PARALLEL_SIN2`) the first ``s`` is ill-conditioned but any
    ``s in [0, 1]`` then leads to the exact minimum, and nearly parallel ones are off by at most
    ``sqrt(_PARALLEL_SIN2)`` times the segment length. Zero-length segments give exactly-zero
    numerators, and floored denominators turn them into ``s = 0`` or ``t = 0``.
    """
    pa = _coords(a, 3)
    d1 = [bk - ak for ak, bk in zip(pa, _coords(b, 3), strict=True)]
    r = [ak - pk for ak, pk in zip(pa, p, strict=True)]
    aa = _dot(d1, d1)
    ee = sum(ek * ek for ek in d2)
    ab = _dot(d1, d2)
    c = _dot(d1, r)
    f = _dot(d2, r)
    denom = aa * ee - ab * ab
    floor = aa * (_PARALLEL_SIN2 * ee) + _TINY
    s = (ab * f - c * ee) / np.maximum(denom, floor)
    np.clip(s, 0.0, 1.0, out=s)
    if ee > 0.0:
        t = (ab * s + f) * (1.0 / ee)
        np.clip(t, 0.0, 1.0, out=t)
    else:
        t = np.zeros_like(s)
    s = (ab * t - c) / np.maximum(aa, _TINY)
    np.clip(s, 0.0, 1.0, out=s)
    w = [rk + s * dk - t * ek for rk, dk, ek in zip(r, d1, d2, strict=True)]
    return np.sqrt(_dot(w, w)) - radius - clearance


def rectangle_distance(
    a: FloatArray,
    b: FloatArray,
    radius: FloatArray,
    center: tuple[float, float],
    axes: tuple[float, float, float, float],
    half: tuple[float, float],
) -> FloatArray:
    """Segment - rectangle distance in the box frame [m] (see :func:`previewctl.planar.distance.to_box`)."""
    (cx, cy), (ux, uy, vx, vy), (hx, hy) = center, axes, half
    ax, ay = a[..., 0] - cx, a[..., 1] - cy
    bx, by = b[..., 0] - cx, b[..., 1] - cy
    pax, pay = ax * ux + ay * uy, ax * vx + ay * vy  # end points in the box frame
    pbx, pby = bx * ux + by * uy, bx * vx + by * vy
    dx, dy = pbx - pax, pby - pay
    adx, ady = np.abs(dx), np.abs(dy)
    # w / |d| is the signed offset of the segment's line from the box center.
    w = dx * pay - dy * pax
    # Separating axes x, y (tests doubled on both sides) and the line's normal.
    touching = np.abs(pax + pbx) <= 2.0 * hx + adx
    touching &= np.abs(pay + pby) <= 2.0 * hy + ady
    touching &= np.abs(w) <= hx * ady + hy * adx
    # Separated: end point -> rectangle, and the corner nearest the segment's line -> segment.
    # The segment's nearest point is interior only if its line misses the rectangle, and then it
    # faces the corner that lies farthest toward the line (any choice is an upper bound).
    dist_sq = np.minimum(
        np.maximum(np.abs(pax) - hx, 0.0) ** 2 + np.maximum(np.abs(pay) - hy, 0.0) ** 2,
        np.maximum(np.abs(pbx) - hx, 0.0) ** 2 + np.maximum(np.abs(pby) - hy, 0.0) ** 2,
    )
    side = np.sign(w)
    corner = (-hx * side * np.sign(dy), hy * side * np.sign(dx))
    dd = np.maximum(dx * dx + dy * dy, _TINY)
    np.minimum(dist_sq, _point_segment_sq(corner, (pax, pay), (dx, dy), dd), out=dist_sq)
    dist = np.sqrt(dist_sq)
    dist[touching] = 0.0
    return dist - radius


def halfspace_distance(
    a: FloatArray, b: FloatArray, radius: FloatArray, normal: tuple[float, ...], offset: float
) -> FloatArray:
    """Height of the lower end point over the plane ``normal . x = offset`` minus the radii [m]."""
    height = np.minimum(_dot(_coords(a, 3), normal), _dot(_coords(b, 3), normal))
    return height - offset - radius
