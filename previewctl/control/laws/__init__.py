"""Control laws: one class per controller name, each composed of parts and none holding another.

=========== ============================= ===================================================================
name        class                         null-space input ``v`` of eq. 19
=========== ============================= ===================================================================
``none``    :class:`Tracking`             0 (minimum-norm tracking; always the pseudo-inverse execution)
``qp``      :class:`QPBaseline`           0 (always the QP execution: the velocity-damper baseline, as NEO)
``gradient``:class:`Gradient`             ``K_g ∇_q S``
``single``  :class:`SinglePreview`        eq. 20 toward one imaginary arm
``multi``   :class:`MultiPreview`         eq. 21 toward several imaginary arms (argmax, tracked peaks or route)
``reach``   :class:`Reach`                a checked route through the imaginary arms' peaks (Fig. 3)
``horizon`` :class:`Horizon`              follows a plan over the preview window, replanned
``oracle``  :class:`Oracle`               follows a plan over the whole future (non-causal reference)
=========== ============================= ===================================================================
"""

from previewctl.control.laws.follow import Horizon, Oracle
from previewctl.control.laws.gradient import Gradient
from previewctl.control.laws.preview import MultiPreview, SinglePreview
from previewctl.control.laws.reach import Reach
from previewctl.control.laws.tracking import QPBaseline, Tracking

__all__ = ["Gradient", "Horizon", "MultiPreview", "Oracle", "QPBaseline", "Reach", "SinglePreview", "Tracking"]
