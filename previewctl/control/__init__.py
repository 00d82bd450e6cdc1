"""Resolved-rate control of the hand with a null-space input (paper eq. 19) and its preview modes.

Every controller computes the joint velocity of eq. 19 with hand-position feedback,

    q̇ = J#(ṙ_d + K_p (r_d − r)) + (I − J⁺J) v,

and differs only in the null-space input ``v``, which its law computes (:mod:`previewctl.control.laws`, one class
per controller name). A controller is composed of parts, each a module here:

* :mod:`~previewctl.control.base`: what flows through a cycle (state, null-space input, reference, execution);
* :mod:`~previewctl.control.tracking`: eq. 19 as a reference for a given ``v``;
* :mod:`~previewctl.control.nullspace`: null-space inputs (the eq.-21 pull, the AMSIP gradient, limit avoidance);
* :mod:`~previewctl.control.imaginary`: imaginary arms, one search per preview time, and the policies that pick
  their targets (argmax, tracked peaks with :mod:`~previewctl.control.peaks`, route points);
* :mod:`~previewctl.control.planner`: the window planner (the reachability DP on planar arms, the sampled search on
  spatial arms) and the plans toward the imaginary arms' peaks; :mod:`~previewctl.control.sweeps`: straight sweeps;
* :mod:`~previewctl.control.execution`: the pseudo-inverse (clamping and saturation,
  :mod:`~previewctl.control.saturation`) or the constrained QP;
* :mod:`~previewctl.control.background`: the searches and the planner beside the loop, in a worker process
  (:mod:`~previewctl.control.worker`);
* :mod:`~previewctl.control.params`: the settings; :mod:`~previewctl.control.factory`: the one place that maps a
  controller name and a robot to parts.

Build one with :func:`previewctl.control.factory.make_controller` and step it from your own loop,
``qdot = ctrl.step(q, t)`` (:class:`previewctl.control.controller.Controller`); ``ctrl.describe()`` says what it
is made of and ``ctrl.last_info`` what the last cycle computed.
"""
