"""Checks of NumPy array arguments (configurations, positions, rotations, times); each raises the caller's error."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from previewctl.errors import PreviewctlError


def show(value: object, limit: int = 200) -> str:
    """A short, single-line representation of ``value`` for error messages."""
    if isinstance(value, np.ndarray):
        text = np.array2string(value, threshold=20, precision=6, separator=", ")
    else:
        text = repr(value)
    text = " ".join(text.split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def real_array(value: object, name: str, error: type[PreviewctlError]) -> NDArray[np.float64]:
    """``value`` as a fresh float64 array; ``error`` naming ``name`` if it is not real numbers."""
    if isinstance(value, (str, bytes)):
        raise error(f"{name} must be an array of real numbers, got {show(value)}")
    try:
        raw = np.asarray(value)
    except (TypeError, ValueError) as exc:  # ragged nested lists
        raise error(f"{name} must be an array of real numbers, got {show(value)}") from exc
    if raw.dtype.kind not in "biuf":
        raise error(f"{name} must be an array of real numbers, got {show(value)} (dtype {raw.dtype})")
    return np.array(raw, dtype=np.float64)


def real_scalar(value: object, name: str, error: type[PreviewctlError]) -> float:
    """``value`` as a finite float; ``error`` otherwise (booleans rejected)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise error(f"{name} must be a real number, got {show(value)}")
    number = float(value)
    if not np.isfinite(number):
        raise error(f"{name} must be finite, got {number!r}")
    return number


ROTATION_TOLERANCE = 1e-6
"""Tolerance on ``R^T R = I`` and ``det R = 1`` for a user-given rotation matrix."""


def rotation_matrix(value: object, name: str, error: type[PreviewctlError]) -> NDArray[np.float64]:
    """``value`` as a fresh ``(3, 3)`` rotation matrix (orthonormal, det +1, to ``ROTATION_TOLERANCE``);
    ``error`` naming ``name`` and what is wrong otherwise."""
    matrix = real_array(value, name, error)
    if matrix.shape != (3, 3):
        raise error(f"{name} must have shape (3, 3), got shape {matrix.shape}: {show(matrix)}")
    check_finite(matrix, name, error)
    gram_error = float(np.abs(matrix.T @ matrix - np.eye(3)).max())
    det = float(np.linalg.det(matrix))
    if gram_error > ROTATION_TOLERANCE or abs(det - 1.0) > ROTATION_TOLERANCE:
        raise error(
            f"{name} must be a rotation matrix (orthonormal to {ROTATION_TOLERANCE}, det +1), got "
            f"{show(matrix)} with max|R^T R - I| = {gram_error:.3g} and det = {det:.6g}"
        )
    return matrix


def check_finite(array: NDArray[np.float64], name: str, error: type[PreviewctlError]) -> None:
    """Raise ``error`` naming the first non-finite entry of ``array``."""
    finite = np.isfinite(array)
    if not finite.all():
        index = tuple(int(i) for i in np.argwhere(~finite)[0])  # () for a 0-d array
        entry = f"entry {list(index)} " if index else ""
        raise error(f"{name} must be finite; {entry}is {float(array[index])!r} (in {name} = {show(array)})")
