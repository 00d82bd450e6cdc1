"""The validation layer: field types that state each bound once, and messages that name the bad value.

Every user value is checked by pydantic against a type from :mod:`~previewctl.validation.fields`,
whether it comes from a file (the TOML schemas :mod:`previewctl.sim.schema` and
:mod:`previewctl.scene.schema`) or from the API (a frozen dataclass such as
:class:`~previewctl.control.params.ControllerParams` calls :func:`check_fields` in its
``__post_init__``). A file section that mirrors a value object is made from its fields by
:func:`table`, so a bound lives in one place: the field's annotation.

* :mod:`~previewctl.validation.fields`: :data:`Finite`, :data:`Positive`, :data:`NonNegative`,
  :data:`Negative`, :data:`Integer`, :data:`Count`, :data:`Flag`, :data:`Text`, :data:`Probability`;
  ``Annotated[Finite, interval(0, 1, "(]")]`` for another two-sided bound,
  ``Annotated[tuple[Finite, ...], Size(3)]`` for a vector; :func:`invalid` for a rule of one's own.
* :mod:`~previewctl.validation.tables`: :class:`Section` (``extra="forbid"``), :func:`table`,
  :class:`Checked` (a value object that checks itself), :func:`check_fields`, :func:`build`, :func:`validate`.
* :mod:`~previewctl.validation.messages`: :func:`explain` turns a :class:`pydantic.ValidationError`
  into one line with the dotted key (``controller.gain``, ``obstacles[1].motion.velocity``), the bad
  value, what was expected, the valid choices and, for a near miss, a "did you mean". No
  ``ValidationError`` leaves the package: :func:`validate` and :func:`check_fields` raise the
  caller's :class:`~previewctl.errors.PreviewctlError` with that line.
* :mod:`~previewctl.validation.arrays`: checks for the value objects that hold NumPy arrays (motions,
  hand paths, targets), which pydantic does not describe.
* :mod:`~previewctl.validation.toml`: :func:`~previewctl.validation.toml.read_toml`, the one reader of the
  scenario and scene files (a missing, unreadable or malformed file named in the message).
"""

from previewctl.validation.arrays import (
    ROTATION_TOLERANCE,
    check_finite,
    real_array,
    real_scalar,
    rotation_matrix,
    show,
)
from previewctl.validation.fields import (
    Count,
    Finite,
    Flag,
    Integer,
    Negative,
    NonNegative,
    Positive,
    Probability,
    Size,
    Text,
    interval,
    invalid,
)
from previewctl.validation.messages import explain
from previewctl.validation.tables import Checked, Section, build, check_fields, fields_of, table, validate

__all__ = [
    "ROTATION_TOLERANCE", "Checked", "Count", "Finite", "Flag", "Integer", "Negative", "NonNegative", "Positive",
    "Probability", "Section", "Size", "Text", "build", "check_fields", "check_finite", "explain", "fields_of",
    "interval", "invalid", "real_array", "real_scalar", "rotation_matrix", "show", "table", "validate",
]
