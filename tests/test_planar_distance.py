"""Cross-checks of :mod:`previewctl.planar.distance` against Coal, plus shapes, identities and errors.

Each link is built in Coal as ``coal.Capsule(r, |b - a|)`` (axis: its local z) placed at the
segment's midpoint with a rotation taking z to ``b - a``. Separated pairs must match
``coal.distance`` (``min_distance``); overlapping ones (Coal's distance <= 0) must give <= 0.
"""

from __future__ import annotations

from collections.abc import Callable
from fractions import Fraction

import coal
import numpy as np
import numpy.typing as npt
import pytest
from helpers import rot_z
from hypothesis import given, settings
from hypothesis import strategies as st

from previewctl.errors import ConfigurationError, SceneError
from previewctl.planar import distance as pd

FloatArray = npt.NDArray[np.float64]

# Closed-form pairs in Coal (capsule vs sphere / capsule / half-space) agree to rounding.
EXACT_TOL = 1e-9
# Coal's capsule-capsule distance treats an axis shorter than ~1.5e-7 [m] as a point, so for such
# links (hypothesis finds them) it is off by up to that length; ours stays exact there.
SHORT_AXIS_TOL = 2e-7
# Coal computes capsule-box and capsule-cylinder distances with GJK, whose default stopping
# tolerance (DistanceRequest().gjk_tolerance = 1e-6) leaves errors of up to ~2.3e-6 [m] here; with
# gjk_tolerance = 1e-10 the same pairs agree to ~3e-10 (test_gjk_pairs_match_tight_coal), so the
# looser bound is Coal's, not ours.
GJK_TOL = 5e-6


# ------------------------------------------------------------------------------------ helpers


def frame_along(p0: FloatArray, p1: FloatArray) -> tuple[coal.Transform3s, float]:
    """Coal placement of a capsule whose axis is the segment p0 -> p1, and its length."""
    axis = p1 - p0
    length = float(np.linalg.norm(axis))
    z = axis / length if length > 0.0 else np.array([0.0, 0.0, 1.0])
    helper = np.array([0.0, 0.0, 1.0]) if abs(z[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    rotation = np.column_stack([x, np.cross(z, x), z])
    return coal.Transform3s(rotation, 0.5 * (p0 + p1)), length


def coal_distance(
    geom1: coal.CollisionGeometry,
    tf1: coal.Transform3s,
    geom2: coal.CollisionGeometry,
    tf2: coal.Transform3s,
    gjk_tolerance: float | None = None,
) -> float:
    """``coal.distance`` with a fresh result; the default request unless a GJK tolerance is given."""
    request = coal.DistanceRequest()
    if gjk_tolerance is not None:
        request.gjk_tolerance = gjk_tolerance
    result = coal.DistanceResult()
    coal.distance(geom1, tf1, geom2, tf2, request, result)
    return float(result.min_distance)


def coal_to_links(
    a: FloatArray,
    b: FloatArray,
    radius: FloatArray,
    obstacle: coal.CollisionGeometry,
    placement: coal.Transform3s,
    gjk_tolerance: float | None = None,
) -> FloatArray:
    """Coal's distance from every link of the batch to one obstacle, shape (B, L)."""
    out = np.empty(a.shape[:2])
    for i, j in np.ndindex(*out.shape):
        tf, length = frame_along(a[i, j], b[i, j])
        out[i, j] = coal_distance(coal.Capsule(radius[j], length), tf, obstacle, placement, gjk_tolerance)
    return out


def random_links(
    rng: np.random.Generator, n_batch: int, n_links: int, scale: float = 1.0
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Random link segments in z = 0 and radii."""
    a = np.zeros((n_batch, n_links, 3))
    b = np.zeros((n_batch, n_links, 3))
    a[..., :2] = rng.uniform(-scale, scale, (n_batch, n_links, 2))
    b[..., :2] = a[..., :2] + rng.uniform(-scale, scale, (n_batch, n_links, 2))
    return a, b, rng.uniform(0.01, 0.1, n_links)


def assert_matches_coal(ours: FloatArray, reference: FloatArray, tol: float) -> None:
    """Separated pairs match Coal to ``tol``; overlapping pairs are <= 0 (up to ``tol``)."""
    assert ours.shape == reference.shape
    separated = reference > 0.0
    np.testing.assert_allclose(ours[separated], reference[separated], rtol=0.0, atol=tol)
    assert np.all(ours[~separated] <= tol), ours[~separated].max()


def assert_mixed(reference: FloatArray) -> None:
    """Guard on the random cases: both separated and overlapping pairs occur."""
    assert np.any(reference > 0.0) and np.any(reference <= 0.0)


def segment_pair(a: FloatArray, b: FloatArray) -> tuple[FloatArray, FloatArray]:
    return a.reshape(1, 1, 3), b.reshape(1, 1, 3)


coords = st.floats(-1.0, 1.0, allow_nan=False, allow_infinity=False)
point2 = st.tuples(coords, coords).map(lambda p: np.array([p[0], p[1], 0.0]))
point3 = st.tuples(coords, coords, coords).map(np.array)


# ------------------------------------------------------------------------------------ sphere


@pytest.mark.parametrize("seed", range(4))
def test_to_sphere_matches_coal(seed: int) -> None:
    rng = np.random.default_rng(seed)
    a, b, radius = random_links(rng, 40, 3)
    references = []
    for _ in range(3):
        center = rng.uniform(-1.0, 1.0, 3) * np.array([1.0, 1.0, 0.2])
        sphere_radius = float(rng.uniform(0.0, 0.5))
        reference = coal_to_links(a, b, radius, coal.Sphere(sphere_radius), coal.Transform3s(np.eye(3), center))
        ours = pd.to_sphere(a, b, radius, center, sphere_radius)
        assert_matches_coal(ours, reference, EXACT_TOL)
        references.append(reference)
    assert_mixed(np.array(references))


def test_to_sphere_penetration_is_exact() -> None:
    a = np.array([[[0.0, 0.0, 0.0]]])
    b = np.array([[[2.0, 0.0, 0.0]]])
    # Center 0.1 [m] above the middle of the axis: penetration 0.05 + 0.2 - 0.1.
    got = pd.to_sphere(a, b, np.array([0.05]), [1.0, 0.0, 0.1], 0.2)
    np.testing.assert_allclose(got, [[-0.15]], atol=1e-15)


# ----------------------------------------------------------------------------------- capsule


@pytest.mark.parametrize("seed", range(4))
def test_to_capsule_matches_coal(seed: int) -> None:
    rng = np.random.default_rng(seed)
    a, b, radius = random_links(rng, 40, 3)
    references = []
    for _ in range(3):
        p0 = rng.uniform(-1.0, 1.0, 3) * np.array([1.0, 1.0, 0.15])
        p1 = p0 + rng.uniform(-1.0, 1.0, 3) * np.array([1.0, 1.0, 0.3])
        capsule_radius = float(rng.uniform(0.0, 0.2))
        tf, length = frame_along(p0, p1)
        reference = coal_to_links(a, b, radius, coal.Capsule(capsule_radius, length), tf)
        ours = pd.to_capsule(a, b, radius, p0, p1, capsule_radius)
        assert_matches_coal(ours, reference, EXACT_TOL)
        references.append(reference)
    assert_mixed(np.array(references))


# Special cases: parallel (overlapping and disjoint projections, same and opposite directions),
# collinear, nearly parallel, crossing, and zero-length link and/or obstacle axis.
CAPSULE_CASES = [
    # (a, b, p0, p1)
    ([0, 0, 0], [1, 0, 0], [0.5, 0.3, 0], [1.5, 0.3, 0]),
    ([0, 0, 0], [1, 0, 0], [1.5, 0.3, 0], [0.5, 0.3, 0]),
    ([0, 0, 0], [1, 0, 0], [2.0, 0.3, 0.1], [3.0, 0.3, 0.1]),
    ([0, 0, 0], [1, 0, 0], [-3.0, -0.3, 0], [-2.0, -0.3, 0]),
    ([0, 0, 0], [1, 0, 0], [1.2, 0, 0], [2.0, 0, 0]),
    ([0, 0, 0], [1, 0, 0], [-0.5, 0.3, 0.2], [2.0, 0.3, 0.2]),
    ([0, 0, 0], [1, 0, 0], [0.0, 0.3, 0], [1.0, 0.3 + 1e-9, 0]),
    ([0, 0, 0], [1, 0, 0], [0.3, 0.3, 0], [5.0, 0.3 + 1e-7, 0]),
    ([0, 0, 0], [1, 1, 0], [0, 1, 0], [1, 0, 0]),
    ([0, 0, 0], [1, 1, 0], [0, 1, 0.5], [1, 0, 0.5]),
    ([0.2, 0.1, 0], [0.2, 0.1, 0], [0, 1, 0], [1, 0, 0.3]),
    ([0, 0, 0], [1, 0, 0], [0.4, 0.5, 0.1], [0.4, 0.5, 0.1]),
    ([0, 0, 0], [1, 0, 0], [1.4, 0.5, 0.1], [1.4, 0.5, 0.1]),
    ([0.3, 0.3, 0], [0.3, 0.3, 0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]),
    ([0, 0, 0], [1, 0, 0], [0.5, 0.0, 0.4], [0.5, 0.0, 1.4]),
    ([0, 0, 0], [1, 0, 0], [1.5, 0.0, -0.4], [1.5, 0.0, -1.4]),
]


@pytest.mark.parametrize(("a", "b", "p0", "p1"), CAPSULE_CASES)
def test_to_capsule_special_cases_match_coal(a: list[float], b: list[float], p0: list[float], p1: list[float]) -> None:
    seg_a, seg_b = segment_pair(np.array(a, float), np.array(b, float))
    q0, q1 = np.array(p0, float), np.array(p1, float)
    radius = np.array([0.05])
    tf, length = frame_along(q0, q1)
    reference = coal_to_links(seg_a, seg_b, radius, coal.Capsule(0.04, length), tf)
    ours = pd.to_capsule(seg_a, seg_b, radius, q0, q1, 0.04)
    assert_matches_coal(ours, reference, EXACT_TOL)
    # The distance is symmetric in the two segments and in their orientations.
    swapped = pd.to_capsule(*segment_pair(q1, q0), radius, b, a, 0.04)
    np.testing.assert_allclose(swapped, ours, atol=1e-12)


@settings(max_examples=300, deadline=None, derandomize=True)
@given(a=point2, b=point2, p0=point3, p1=point3, capsule_radius=st.floats(0.0, 0.3))
def test_to_capsule_matches_coal_hypothesis(
    a: FloatArray, b: FloatArray, p0: FloatArray, p1: FloatArray, capsule_radius: float
) -> None:
    seg_a, seg_b = segment_pair(a, b)
    radius = np.array([0.05])
    tf, length = frame_along(p0, p1)
    reference = coal_to_links(seg_a, seg_b, radius, coal.Capsule(capsule_radius, length), tf)
    ours = pd.to_capsule(seg_a, seg_b, radius, p0, p1, capsule_radius)
    assert_matches_coal(ours, reference, SHORT_AXIS_TOL)


def exact_segment_distance(a: FloatArray, b: FloatArray, p: FloatArray, q: FloatArray) -> float:
    """Segment-segment distance in exact rational arithmetic (rounded once at the end).

    The least of the 4 end point -> segment distances and, when it lies inside both segments,
    the distance at the common perpendicular.
    """
    a_, b_, p_, q_ = ([Fraction(float(x)) for x in v] for v in (a, b, p, q))

    def sub(u: list[Fraction], v: list[Fraction]) -> list[Fraction]:
        return [ui - vi for ui, vi in zip(u, v, strict=True)]

    def dot(u: list[Fraction], v: list[Fraction]) -> Fraction:
        return sum((ui * vi for ui, vi in zip(u, v, strict=True)), Fraction(0))

    def point_segment_sq(x: list[Fraction], s0: list[Fraction], s1: list[Fraction]) -> Fraction:
        d = sub(s1, s0)
        t = min(max(dot(sub(x, s0), d) / dot(d, d), Fraction(0)), Fraction(1)) if dot(d, d) else Fraction(0)
        w = sub(x, [s0k + t * dk for s0k, dk in zip(s0, d, strict=True)])
        return dot(w, w)

    candidates = [
        point_segment_sq(a_, p_, q_),
        point_segment_sq(b_, p_, q_),
        point_segment_sq(p_, a_, b_),
        point_segment_sq(q_, a_, b_),
    ]
    d1, d2, r = sub(b_, a_), sub(q_, p_), sub(a_, p_)
    aa, ee, ab, c, f = dot(d1, d1), dot(d2, d2), dot(d1, d2), dot(d1, r), dot(d2, r)
    denom = aa * ee - ab * ab
    if denom != 0:
        s, t = (ab * f - c * ee) / denom, (aa * f - ab * c) / denom
        if 0 <= s <= 1 and 0 <= t <= 1:
            w = [rk + s * dk - t * ek for rk, dk, ek in zip(r, d1, d2, strict=True)]
            candidates.append(dot(w, w))
    return float(min(candidates)) ** 0.5


def test_to_capsule_nearly_parallel_is_exact() -> None:
    """Angles of 1e-10 .. 1e-3 rad against exact arithmetic (Coal is off by up to ~1e-7 here)."""
    rng = np.random.default_rng(5)
    for _ in range(300):
        angle, phi = 10.0 ** rng.uniform(-10.0, -3.0), rng.uniform(0.0, 2.0 * np.pi)
        u = np.array([np.cos(phi), np.sin(phi), 0.0])
        v = np.array([np.cos(phi + angle), np.sin(phi + angle), rng.choice([0.0, 1e-8, 1e-6])])
        a = np.array([*rng.uniform(-1.0, 1.0, 2), 0.0])
        b = a + u * rng.uniform(0.1, 2.0)
        p0 = a + u * rng.uniform(-2.0, 2.0) + rng.uniform(-0.2, 0.2, 3) * [1.0, 1.0, rng.choice([0.0, 1.0])]
        p1 = p0 + v * rng.uniform(-2.0, 2.0)
        got = pd.to_capsule(*segment_pair(a, b), np.zeros(1), p0, p1, 0.0)[0, 0]
        assert got == pytest.approx(exact_segment_distance(a, b, p0, p1), rel=0.0, abs=1e-12)


# --------------------------------------------------------------------------------------- box


def random_planar_box(
    rng: np.random.Generator,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    half = rng.uniform(0.05, 0.6, 3)
    center = np.array([*rng.uniform(-1.0, 1.0, 2), rng.uniform(-half[2], half[2])])
    rotation = rot_z(rng.uniform(-np.pi, np.pi))
    if rng.random() < 0.3:  # upside down: rotation[:, 2] = (0, 0, -1)
        rotation = rotation @ np.diag([1.0, -1.0, -1.0])
    return center, rotation, half


@pytest.mark.parametrize("seed", range(6))
def test_to_box_matches_coal(seed: int) -> None:
    rng = np.random.default_rng(seed)
    a, b, radius = random_links(rng, 40, 3)
    references = []
    for _ in range(3):
        center, rotation, half = random_planar_box(rng)
        reference = coal_to_links(a, b, radius, coal.Box(2.0 * half), coal.Transform3s(rotation, center))
        ours = pd.to_box(a, b, radius, center, rotation, half)
        assert_matches_coal(ours, reference, GJK_TOL)
        references.append(reference)
    assert_mixed(np.array(references))


def test_to_box_special_cases() -> None:
    """Segments along and across the box axes, through it, past a corner, and points."""
    half = np.array([0.5, 0.25, 0.3])
    ends = np.array(
        [
            [[-2.0, 0.0], [2.0, 0.0]],  # crosses the box, both ends outside
            [[-2.0, 0.6], [2.0, 0.6]],  # parallel to the long side
            [[0.8, -2.0], [0.8, 2.0]],  # parallel to the short side
            [[0.0, 0.0], [0.1, 0.1]],  # inside
            [[0.6, 0.6], [1.2, -0.1]],  # passes a corner, ends clear of the box
            [[0.5, 0.25], [1.0, 1.0]],  # starts on a corner
            [[1.0, 1.0], [1.0, 1.0]],  # a point outside
            [[0.2, -0.1], [0.2, -0.1]],  # a point inside
            [[-0.9, 0.8], [0.9, 0.8]],  # parallel to an edge, covering it
            [[0.7, 0.5], [2.0, 0.2]],  # line crosses the box, segment does not
        ]
    )
    a = np.zeros((len(ends), 1, 3))
    b = np.zeros((len(ends), 1, 3))
    for angle in (0.0, 0.3, np.pi / 2, -2.0):
        rotation = rot_z(angle)
        center = np.array([0.3, -0.2, 0.1])
        a[:, 0, :2] = center[:2] + ends[:, 0] @ rotation[:2, :2].T
        b[:, 0, :2] = center[:2] + ends[:, 1] @ rotation[:2, :2].T
        radius = np.array([0.02])
        reference = coal_to_links(a, b, radius, coal.Box(2.0 * half), coal.Transform3s(rotation, center))
        ours = pd.to_box(a, b, radius, center, rotation, half)
        assert_matches_coal(ours, reference, GJK_TOL)
        # Segments that touch the rectangle give -r (0 - r, up to the rounding of the rotation).
        np.testing.assert_allclose(ours[[0, 3, 5, 7], 0], -radius[0], rtol=0.0, atol=1e-12)


@settings(max_examples=300, deadline=None, derandomize=True)
@given(
    a=point2,
    b=point2,
    angle=st.floats(-np.pi, np.pi),
    half=st.tuples(st.floats(0.01, 0.6), st.floats(0.01, 0.6)),
    shift=st.tuples(coords, coords),
)
def test_to_box_matches_coal_hypothesis(
    a: FloatArray,
    b: FloatArray,
    angle: float,
    half: tuple[float, float],
    shift: tuple[float, float],
) -> None:
    seg_a, seg_b = segment_pair(a, b)
    radius = np.array([0.05])
    half_extents = np.array([half[0], half[1], 0.5])
    center = np.array([shift[0], shift[1], 0.2])
    rotation = rot_z(angle)
    reference = coal_to_links(seg_a, seg_b, radius, coal.Box(2.0 * half_extents), coal.Transform3s(rotation, center))
    ours = pd.to_box(seg_a, seg_b, radius, center, rotation, half_extents)
    assert_matches_coal(ours, reference, GJK_TOL)


def test_box_is_planar() -> None:
    half = np.array([0.2, 0.3, 0.4])
    flipped = rot_z(0.4) @ np.diag([1.0, -1.0, -1.0])
    assert pd.box_is_planar([0.0, 0.0, 0.0], np.eye(3), half)
    assert pd.box_is_planar([1.0, 2.0, 0.4], rot_z(1.0), half)  # plane touches the top face
    assert pd.box_is_planar([1.0, 2.0, -0.3], flipped, half)
    assert not pd.box_is_planar([0.0, 0.0, 0.41], np.eye(3), half)  # above the plane
    assert not pd.box_is_planar([0.0, 0.0, -0.5], rot_z(0.2), half)  # below the plane
    tilted = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(0.1), -np.sin(0.1)], [0.0, np.sin(0.1), np.cos(0.1)]])
    assert not pd.box_is_planar([0.0, 0.0, 0.0], tilted, half)
    with pytest.raises(SceneError, match="box"):
        pd.to_box(*random_links(np.random.default_rng(0), 2, 2), [0, 0, 0], tilted, half)
    with pytest.raises(SceneError, match="box"):
        pd.to_box(*random_links(np.random.default_rng(0), 2, 2), [0, 0, 1], np.eye(3), half)
    with pytest.raises(SceneError, match="orthonormal"):
        pd.to_box(*random_links(np.random.default_rng(0), 2, 2), [0, 0, 0], 2.0 * np.eye(3), half)


# ---------------------------------------------------------------------------------- cylinder


@pytest.mark.parametrize("seed", range(4))
def test_to_vertical_cylinder_matches_coal(seed: int) -> None:
    rng = np.random.default_rng(seed)
    a, b, radius = random_links(rng, 40, 3)
    references = []
    for _ in range(3):
        half_length = float(rng.uniform(0.05, 1.0))
        center = np.array([*rng.uniform(-1.0, 1.0, 2), rng.uniform(-half_length, half_length)])
        cyl_radius = float(rng.uniform(0.0, 0.4))
        reference = coal_to_links(
            a,
            b,
            radius,
            coal.Cylinder(cyl_radius, 2.0 * half_length),
            coal.Transform3s(np.eye(3), center),
        )
        ours = pd.to_vertical_cylinder(a, b, radius, center, cyl_radius, half_length)
        assert_matches_coal(ours, reference, GJK_TOL)
        references.append(reference)
    assert_mixed(np.array(references))


def test_gjk_pairs_match_tight_coal() -> None:
    """With Coal's GJK run to 1e-10, box and cylinder distances agree to 1e-8 [m]."""
    rng = np.random.default_rng(7)
    a, b, radius = random_links(rng, 30, 2)
    for _ in range(3):
        center, rotation, half = random_planar_box(rng)
        box = coal.Box(2.0 * half)
        reference = coal_to_links(a, b, radius, box, coal.Transform3s(rotation, center), gjk_tolerance=1e-10)
        assert_matches_coal(pd.to_box(a, b, radius, center, rotation, half), reference, 1e-8)
        cylinder = coal.Cylinder(0.3, 2.0 * half[2])
        reference = coal_to_links(a, b, radius, cylinder, coal.Transform3s(np.eye(3), center), gjk_tolerance=1e-10)
        assert_matches_coal(pd.to_vertical_cylinder(a, b, radius, center, 0.3, half[2]), reference, 1e-8)


def test_cylinder_is_planar() -> None:
    assert pd.cylinder_is_planar([0.0, 0.0, 0.0], np.eye(3), 0.5)
    assert pd.cylinder_is_planar([1.0, -1.0, 0.5], rot_z(2.0), 0.5)
    assert pd.cylinder_is_planar([1.0, -1.0, -0.2], np.diag([1.0, -1.0, -1.0]), 0.5)
    assert not pd.cylinder_is_planar([0.0, 0.0, 0.6], np.eye(3), 0.5)
    lying = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # axis along y
    assert not pd.cylinder_is_planar([0.0, 0.0, 0.0], lying, 0.5)
    with pytest.raises(SceneError, match="half_length"):
        pd.to_vertical_cylinder(*random_links(np.random.default_rng(0), 2, 2), [0, 0, 0.6], 0.1, 0.5)


# --------------------------------------------------------------------------------- halfspace


@pytest.mark.parametrize("seed", range(4))
def test_to_halfspace_matches_coal(seed: int) -> None:
    rng = np.random.default_rng(seed)
    a, b, radius = random_links(rng, 40, 3)
    references = []
    for _ in range(3):
        normal = rng.normal(size=3) * rng.uniform(0.2, 3.0)  # not unit: Coal normalises
        offset = float(rng.uniform(-1.0, 1.0))
        reference = coal_to_links(a, b, radius, coal.Halfspace(normal, offset), coal.Transform3s())
        ours = pd.to_halfspace(a, b, radius, normal, offset)
        assert_matches_coal(ours, reference, EXACT_TOL)
        references.append(reference)
    assert_mixed(np.array(references))


def test_to_halfspace_rejects_zero_normal() -> None:
    with pytest.raises(SceneError, match="normal"):
        pd.to_halfspace(*random_links(np.random.default_rng(0), 2, 2), [0.0, 0.0, 0.0], 1.0)


# ------------------------------------------------------------------ shapes, inputs, identities

CALLS: dict[str, Callable[[FloatArray, FloatArray, FloatArray], FloatArray]] = {
    "sphere": lambda a, b, r: pd.to_sphere(a, b, r, [0.3, 0.2, 0.1], 0.2),
    "capsule": lambda a, b, r: pd.to_capsule(a, b, r, [0.3, 0.2, 0.1], [-0.5, 0.4, 0.0], 0.1),
    "box": lambda a, b, r: pd.to_box(a, b, r, [0.3, 0.2, 0.1], rot_z(0.3), [0.2, 0.1, 0.5]),
    "cylinder": lambda a, b, r: pd.to_vertical_cylinder(a, b, r, [0.3, 0.2, 0.1], 0.2, 0.5),
    "halfspace": lambda a, b, r: pd.to_halfspace(a, b, r, [0.0, 1.0, 0.0], -0.5),
}


@pytest.mark.parametrize("name", sorted(CALLS))
@pytest.mark.parametrize(("n_batch", "n_links"), [(1, 1), (7, 4), (0, 3), (9000, 4)])
def test_shapes_and_inputs_untouched(name: str, n_batch: int, n_links: int) -> None:
    a, b, radius = random_links(np.random.default_rng(1), n_batch, n_links)
    copies = (a.copy(), b.copy(), radius.copy())
    got = CALLS[name](a, b, radius)
    assert got.shape == (n_batch, n_links)
    assert got.dtype == np.float64
    for before, after in zip(copies, (a, b, radius), strict=True):
        np.testing.assert_array_equal(before, after)
    # Whole batch (several blocks for the largest) = configuration by configuration.
    for i in range(0, n_batch, max(1, n_batch // 5)):
        np.testing.assert_array_equal(got[i], CALLS[name](a[i : i + 1], b[i : i + 1], radius)[0])


def test_identities_between_shapes() -> None:
    """A zero-length capsule is a sphere; a vertical cylinder centered in the plane acts as one."""
    a, b, radius = random_links(np.random.default_rng(2), 50, 3)
    center = np.array([0.2, -0.4, 0.0])
    sphere = pd.to_sphere(a, b, radius, center, 0.3)
    np.testing.assert_allclose(pd.to_capsule(a, b, radius, center, center, 0.3), sphere, atol=1e-12)
    np.testing.assert_allclose(pd.to_vertical_cylinder(a, b, radius, center, 0.3, 0.1), sphere, atol=1e-12)
    # A square box turned by 90 degrees is the same box.
    half = [0.3, 0.3, 0.1]
    np.testing.assert_allclose(
        pd.to_box(a, b, radius, center, rot_z(np.pi / 2), half),
        pd.to_box(a, b, radius, center, np.eye(3), half),
        atol=1e-12,
    )


def test_bad_link_arrays_raise() -> None:
    a, b, radius = random_links(np.random.default_rng(3), 4, 3)
    with pytest.raises(ConfigurationError, match="shape"):
        pd.to_sphere(a[..., :2], b[..., :2], radius, [0, 0, 0], 0.1)
    with pytest.raises(ConfigurationError, match="shape"):
        pd.to_sphere(a, b[:2], radius, [0, 0, 0], 0.1)
    with pytest.raises(ConfigurationError, match="radius"):
        pd.to_sphere(a, b, radius[:2], [0, 0, 0], 0.1)
    with pytest.raises(ConfigurationError, match="radii"):
        pd.to_sphere(a, b, -radius, [0, 0, 0], 0.1)
    with pytest.raises(SceneError, match="sphere radius"):
        pd.to_sphere(a, b, radius, [0, 0, 0], -0.1)
    with pytest.raises(SceneError, match="capsule p1"):
        pd.to_capsule(a, b, radius, [0, 0, 0], [0, 0], 0.1)
