"""Vectorised signed distances between the links of a planar arm and obstacle primitives.

Each link is a capsule: the segment from ``a`` to ``b`` (3-D points in the plane z = 0) swept by a
ball of radius ``r`` [m]. Every function takes a batch of links, ``a`` and ``b`` of shape
``(B, L, 3)`` and ``radius`` of shape ``(L,)``, and returns the ``(B, L)`` signed distances [m]
between each link and one obstacle: positive is clearance, ``<= 0`` touching or overlapping.
No Python loop runs over configurations: each function is a fixed sequence of numpy operations
over blocks of ~16k links (the kernels of :mod:`previewctl.planar.kernels`); their throughput:
docs/decisions.md#planar-distance-kernels-blocks-and-throughput.

* Sphere and capsule obstacles are exact in 3-D (the obstacle may leave the plane):
  ``d(S1, S2) - r1 - r2`` for the axes ``S1, S2``, minus the penetration depth on overlap.
* Boxes and cylinders must be vertical prisms whose z-range contains the plane z = 0
  (:func:`box_is_planar`, :func:`cylinder_is_planar`). Their section by the plane is a rectangle
  or a disc, and the 3-D distance equals the 2-D one. On overlap a box gives ``-r`` (the segment
  touches or crosses the rectangle) or the negative value ``d - r``; a cylinder gives ``d - R - r``.
* A half-space ``{x : n.x <= offset}`` gives ``min(n.a, n.b) - offset - r`` (n normalised).

All of them agree with Coal's ``coal.distance`` on separated pairs (``tests/test_planar_distance.py``).

Each obstacle has a builder (``sphere_kernel`` ...) that validates it once and returns the kernel to
apply to many batches, and a one-shot function (``to_sphere`` ...) that also checks the links.
:func:`planar_kernel` picks the builder for a scene obstacle at a time, or says the closed form does
not apply.
"""

from __future__ import annotations

from functools import partial

import numpy as np
import numpy.typing as npt

from previewctl.errors import ConfigurationError, SceneError
from previewctl.planar.kernels import (
    FloatArray,
    Kernel,
    apply,
    halfspace_distance,
    point_distance,
    rectangle_distance,
    segment_distance,
)
from previewctl.scene.shapes import Box, Capsule, Cylinder, Halfspace, Obstacle, Sphere
from previewctl.validation import rotation_matrix

# --------------------------------------------------------------------------------------- checks


def _links(a: npt.ArrayLike, b: npt.ArrayLike, radius: npt.ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Link end points and radii as float64 arrays of shapes ``(B, L, 3)`` and ``(L,)``."""
    a_arr = np.asarray(a, dtype=np.float64)
    b_arr = np.asarray(b, dtype=np.float64)
    r_arr = np.asarray(radius, dtype=np.float64)
    if a_arr.ndim < 2 or a_arr.shape[-1] != 3 or b_arr.shape != a_arr.shape:
        raise ConfigurationError(
            f"link end points a and b must both have shape (B, L, 3); got {a_arr.shape} and {b_arr.shape}"
        )
    if r_arr.shape != a_arr.shape[-2:-1]:
        raise ConfigurationError(f"link radius must have shape (L,) = ({a_arr.shape[-2]},); got {r_arr.shape}")
    if not (np.all(np.isfinite(r_arr)) and np.all(r_arr >= 0.0)):
        raise ConfigurationError(f"link radii must be finite and >= 0; got {r_arr}")
    return a_arr, b_arr, r_arr


def _vector3(value: npt.ArrayLike, name: str) -> FloatArray:
    vec = np.asarray(value, dtype=np.float64)
    if vec.shape != (3,) or not np.all(np.isfinite(vec)):
        raise SceneError(f"{name} must be 3 finite numbers; got {value!r}")
    return vec


def _length(value: float, name: str) -> float:
    length = float(value)
    if not length >= 0.0 or not np.isfinite(length):
        raise SceneError(f"{name} must be finite and >= 0 [m]; got {value!r}")
    return length


def _rotation(value: npt.ArrayLike) -> FloatArray:
    return rotation_matrix(value, "rotation", SceneError)


def _z_axis_vertical(rotation: FloatArray, atol: float) -> bool:
    """Whether the third column of ``rotation`` (the local z axis in the world) is +-z."""
    col = rotation[:, 2]
    return bool(abs(col[0]) <= atol and abs(col[1]) <= atol and abs(abs(col[2]) - 1.0) <= atol)


def box_is_planar(
    center: npt.ArrayLike,
    rotation: npt.ArrayLike,
    half_extents: npt.ArrayLike,
    atol: float = 1e-9,
) -> bool:
    """Whether :func:`to_box` applies to a box: a vertical prism whose z-range holds z = 0.

    That is ``rotation[:, 2] = (0, 0, +-1)`` (the box is only turned about z, or flipped) and
    ``|center_z| <= half_extents_z``; then the box meets the plane in an oriented rectangle.

    Args:
        center: Box center in the world [m], shape ``(3,)``.
        rotation: Box orientation in the world (columns: box axes), shape ``(3, 3)``.
        half_extents: Half side lengths along the box axes [m], shape ``(3,)``.
        atol: Absolute tolerance on the rotation entries [-] and on the z-range [m].

    Returns:
        True when the box is planar in that sense.
    """
    c = _vector3(center, "box center")
    h = _vector3(half_extents, "box half_extents")
    return _z_axis_vertical(_rotation(rotation), atol) and abs(c[2]) <= h[2] + atol


def cylinder_is_planar(
    center: npt.ArrayLike,
    rotation: npt.ArrayLike,
    half_length: float,
    atol: float = 1e-9,
) -> bool:
    """Whether :func:`to_vertical_cylinder` applies: a vertical cylinder whose z-range holds z = 0.

    That is ``rotation[:, 2] = (0, 0, +-1)`` (Coal's cylinder axis is its local z) and
    ``|center_z| <= half_length``; then the cylinder meets the plane in a disc.

    Args:
        center: Cylinder center in the world [m], shape ``(3,)``.
        rotation: Cylinder orientation in the world, shape ``(3, 3)``.
        half_length: Half of the cylinder's length along its axis [m].
        atol: Absolute tolerance on the rotation entries [-] and on the z-range [m].

    Returns:
        True when the cylinder is planar in that sense.
    """
    c = _vector3(center, "cylinder center")
    half = _length(half_length, "cylinder half_length")
    return _z_axis_vertical(_rotation(rotation), atol) and abs(c[2]) <= half + atol


# -------------------------------------------------------------------------------- distances


def sphere_kernel(
    center: npt.ArrayLike,
    sphere_radius: float,
) -> Kernel:
    """The validated distance kernel of :func:`to_sphere` (build once, apply with :func:`apply`)."""
    return partial(
        point_distance,
        center=tuple(_vector3(center, "sphere center").tolist()),
        clearance=_length(sphere_radius, "sphere radius"),
    )


def to_sphere(
    a: FloatArray,
    b: FloatArray,
    radius: FloatArray,
    center: npt.ArrayLike,
    sphere_radius: float,
) -> FloatArray:
    """Signed distances between link capsules and a sphere (3-D; the center may leave the plane).

    ``d = min_t |a + t (b - a) - c| - r - R``, ``t in [0, 1]``.

    Args:
        a: Link start points [m], shape ``(B, L, 3)``.
        b: Link end points [m], shape ``(B, L, 3)``.
        radius: Link radii ``r`` [m], shape ``(L,)``.
        center: Sphere center ``c`` [m], shape ``(3,)``.
        sphere_radius: Sphere radius ``R`` [m].

    Returns:
        Signed distances [m], shape ``(B, L)``; negative values are penetration depths.

    Raises:
        ConfigurationError: ``a``, ``b`` or ``radius`` has a wrong shape, or a radius is < 0.
        SceneError: The center is not 3 finite numbers or the sphere radius is < 0.
    """
    a, b, radius = _links(a, b, radius)
    return apply(sphere_kernel(center, sphere_radius), a, b, radius)


def capsule_kernel(
    p0: npt.ArrayLike,
    p1: npt.ArrayLike,
    capsule_radius: float,
) -> Kernel:
    """The validated distance kernel of :func:`to_capsule` (build once, apply with :func:`apply`)."""
    q0 = _vector3(p0, "capsule p0")
    return partial(
        segment_distance,
        p=tuple(q0.tolist()),
        d2=tuple((_vector3(p1, "capsule p1") - q0).tolist()),
        clearance=_length(capsule_radius, "capsule radius"),
    )


def to_capsule(
    a: FloatArray,
    b: FloatArray,
    radius: FloatArray,
    p0: npt.ArrayLike,
    p1: npt.ArrayLike,
    capsule_radius: float,
) -> FloatArray:
    """Signed distances between link capsules and a capsule obstacle (3-D).

    ``d = min_{s, t in [0, 1]} |a + s (b - a) - p0 - t (p1 - p0)| - r - R``, by the clamped
    closed form of the segment-segment distance; parallel and zero-length segments included.

    Args:
        a: Link start points [m], shape ``(B, L, 3)``.
        b: Link end points [m], shape ``(B, L, 3)``.
        radius: Link radii ``r`` [m], shape ``(L,)``.
        p0: First end of the obstacle's axis [m], shape ``(3,)``.
        p1: Second end of the obstacle's axis [m], shape ``(3,)``.
        capsule_radius: Obstacle radius ``R`` [m].

    Returns:
        Signed distances [m], shape ``(B, L)``; negative values are penetration depths.

    Raises:
        ConfigurationError: ``a``, ``b`` or ``radius`` has a wrong shape, or a radius is < 0.
        SceneError: An axis end is not 3 finite numbers or the capsule radius is < 0.
    """
    a, b, radius = _links(a, b, radius)
    return apply(capsule_kernel(p0, p1, capsule_radius), a, b, radius)


def box_kernel(
    center: npt.ArrayLike,
    rotation: npt.ArrayLike,
    half_extents: npt.ArrayLike,
) -> Kernel:
    """The validated distance kernel of :func:`to_box` (build once, apply with :func:`apply`)."""
    c = _vector3(center, "box center")
    rot = _rotation(rotation)
    h = _vector3(half_extents, "box half_extents")
    if np.any(h < 0.0) or not box_is_planar(c, rot, h):
        raise SceneError(
            "to_box needs half_extents >= 0, a box turned only about z (rotation[:, 2] = "
            f"(0, 0, +-1)) and |center_z| <= half_extents_z; got center {c.tolist()}, "
            f"rotation {rot.tolist()}, half_extents {h.tolist()}"
        )
    return partial(
        rectangle_distance,
        center=(float(c[0]), float(c[1])),
        axes=(float(rot[0, 0]), float(rot[1, 0]), float(rot[0, 1]), float(rot[1, 1])),
        half=(float(h[0]), float(h[1])),
    )


def to_box(
    a: FloatArray,
    b: FloatArray,
    radius: FloatArray,
    center: npt.ArrayLike,
    rotation: npt.ArrayLike,
    half_extents: npt.ArrayLike,
) -> FloatArray:
    """Signed distances between link capsules and a box turned about z that meets the plane.

    In the box frame the plane cuts the box in the rectangle ``[-hx, hx] x [-hy, hy]``. A segment
    touches it iff none of x, y and the segment's normal separates them; then the result is
    ``-r``. Otherwise the 2-D distance ``d`` is the least of the end point -> rectangle and
    corner -> segment distances, and the result is ``d - r`` (the 3-D distance: the box is a
    vertical prism over the rectangle).

    Args:
        a: Link start points [m], shape ``(B, L, 3)``, z = 0.
        b: Link end points [m], shape ``(B, L, 3)``, z = 0.
        radius: Link radii ``r`` [m], shape ``(L,)``.
        center: Box center [m], shape ``(3,)``.
        rotation: Box orientation (columns: the box axes in the world), shape ``(3, 3)``, with
            ``rotation[:, 2] = (0, 0, +-1)``.
        half_extents: Half side lengths ``(hx, hy, hz)`` [m], shape ``(3,)``.

    Returns:
        Signed distances [m], shape ``(B, L)``; ``<= 0`` when a link touches the box.

    Raises:
        ConfigurationError: ``a``, ``b`` or ``radius`` has a wrong shape, or a radius is < 0.
        SceneError: The box is not planar (see :func:`box_is_planar`) or a half extent is < 0.
    """
    a, b, radius = _links(a, b, radius)
    return apply(box_kernel(center, rotation, half_extents), a, b, radius)


def vertical_cylinder_kernel(
    center: npt.ArrayLike,
    cyl_radius: float,
    half_length: float,
) -> Kernel:
    """The validated distance kernel of :func:`to_vertical_cylinder` (build once, apply with :func:`apply`)."""
    c = _vector3(center, "cylinder center")
    clearance = _length(cyl_radius, "cylinder radius")
    if not cylinder_is_planar(c, np.eye(3), half_length):
        raise SceneError(
            "to_vertical_cylinder needs |center_z| <= half_length so that the cylinder meets the "
            f"plane z = 0; got center {c.tolist()}, half_length {half_length!r}"
        )
    return partial(point_distance, center=(float(c[0]), float(c[1])), clearance=clearance)


def to_vertical_cylinder(
    a: FloatArray,
    b: FloatArray,
    radius: FloatArray,
    center: npt.ArrayLike,
    cyl_radius: float,
    half_length: float,
) -> FloatArray:
    """Signed distances between link capsules and a vertical cylinder that meets the plane.

    The cylinder's axis is the world z axis through ``center`` and ``|center_z| <= half_length``;
    then ``d = min_t |(a + t (b - a) - c)_xy| - r - R`` (a 2-D point-segment distance, which is
    also the 3-D one).

    Args:
        a: Link start points [m], shape ``(B, L, 3)``, z = 0.
        b: Link end points [m], shape ``(B, L, 3)``, z = 0.
        radius: Link radii ``r`` [m], shape ``(L,)``.
        center: Cylinder center ``c`` [m], shape ``(3,)``.
        cyl_radius: Cylinder radius ``R`` [m].
        half_length: Half of the cylinder's height [m].

    Returns:
        Signed distances [m], shape ``(B, L)``; ``<= 0`` when a link touches the cylinder.

    Raises:
        ConfigurationError: ``a``, ``b`` or ``radius`` has a wrong shape, or a radius is < 0.
        SceneError: The cylinder does not meet the plane z = 0, or a size is < 0.
    """
    a, b, radius = _links(a, b, radius)
    return apply(vertical_cylinder_kernel(center, cyl_radius, half_length), a, b, radius)


def halfspace_kernel(
    normal: npt.ArrayLike,
    offset: float,
) -> Kernel:
    """The validated distance kernel of :func:`to_halfspace` (build once, apply with :func:`apply`)."""
    n = _vector3(normal, "half-space normal")
    norm = float(np.linalg.norm(n))
    if norm == 0.0 or not np.isfinite(float(offset)):
        raise SceneError(f"a half-space needs a nonzero normal and a finite offset; got {normal!r}, {offset!r}")
    return partial(halfspace_distance, normal=tuple((n / norm).tolist()), offset=float(offset) / norm)


def to_halfspace(
    a: FloatArray,
    b: FloatArray,
    radius: FloatArray,
    normal: npt.ArrayLike,
    offset: float,
) -> FloatArray:
    """Signed distances between link capsules and the half-space ``{x : n.x <= offset}``.

    Coal's ``Halfspace(n, d)`` convention: ``n`` and ``offset`` are both divided by ``|n|``. The
    signed distance is linear along the segment, so ``d = min(n.a, n.b) - offset - r``.

    Args:
        a: Link start points [m], shape ``(B, L, 3)``.
        b: Link end points [m], shape ``(B, L, 3)``.
        radius: Link radii ``r`` [m], shape ``(L,)``.
        normal: Outward normal ``n`` of the half-space, shape ``(3,)``, nonzero.
        offset: Offset ``d`` [m] (times ``|n|``).

    Returns:
        Signed distances [m], shape ``(B, L)``; negative values are penetration depths.

    Raises:
        ConfigurationError: ``a``, ``b`` or ``radius`` has a wrong shape, or a radius is < 0.
        SceneError: The normal is zero or not finite, or the offset is not finite.
    """
    a, b, radius = _links(a, b, radius)
    return apply(halfspace_kernel(normal, offset), a, b, radius)


# ------------------------------------------------------------------------------ obstacles


def planar_kernel(obstacle: Obstacle, t: float) -> Kernel | None:
    """The validated planar distance kernel of ``obstacle`` at time ``t`` [s], or ``None`` when the
    closed form does not apply (meshes, planes, boxes/cylinders not straddling the arm's plane)."""
    shape, pose = obstacle.shape, obstacle.placement(t)
    p, R = pose.translation, pose.rotation
    if isinstance(shape, Sphere):
        return sphere_kernel(p, shape.radius)
    if isinstance(shape, Capsule):
        axis = R[:, 2] * shape.length / 2
        return capsule_kernel(p - axis, p + axis, shape.radius)
    if isinstance(shape, Box):
        half = np.array(shape.size) / 2
        return box_kernel(p, R, half) if box_is_planar(p, R, half) else None
    if isinstance(shape, Cylinder):
        if not cylinder_is_planar(p, R, shape.length / 2):
            return None
        return vertical_cylinder_kernel(p, shape.radius, shape.length / 2)
    if isinstance(shape, Halfspace):
        normal = R @ np.array(shape.normal)
        return halfspace_kernel(normal, shape.offset + float(normal @ p))
    return None
