"""Resolved-rate control of the hand with a null-space input (paper eq. 19) and its preview modes.

Every controller computes the joint velocity of eq. 19 with hand-position feedback,

    q̇ = J#(ṙ_d + K_p (r_d − r)) + (I − J⁺J) v,

and differs only in the null-space input ``v``:

* ``none``: ``v = 0`` (minimum-norm tracking);
* ``gradient``: ``v = K_g ∇_q S`` (local null-space ascent of the AMSIP; ``∇S`` by central finite
  differences of the :class:`~previewctl.index.evaluator.Evaluator`, one batch of ``2 nv`` configurations);
* ``single`` (eq. 20): ``v = K_v (q̃(t + t̃) − q)``;
* ``multi`` (eq. 21): ``v = K_v (Σ_i k_i q̃(t + i t̃) − q)``, ``0 < k_i < 1``, ``Σ k_i = 1``; in coherent mode the
  ``q̃_i`` are where ``reach``'s planned route puts the arm at the preview times (``imaginary_arms = "route"``);
* ``reach`` (Fig. 3): heads for the imaginary arms' best peak that a checked motion reaches, planned by
  ``horizon``'s planner (the DP, or the sampled search on spatial arms; straight routes of peaks in the
  paper-literal mode) (:mod:`previewctl.control.reach`);
* ``horizon``: the reachability DP over the preview window ``[t, t + p t̃]`` only, replanned every
  ``replan_period``: future reachability evaluated on the redundancy grid instead of by imaginary arms
  (:mod:`previewctl.control.oracle`; on spatial arms by the sampled search of :mod:`previewctl.search.roadmap`);
* ``oracle`` (non-causal, a reference): ``v`` pulls toward the best motion of the reachability DP over the
  whole future (:mod:`previewctl.control.oracle`, :mod:`previewctl.search.reachability`; on spatial arms the
  sampled search's).

``with_gradient`` (off by default; not in the paper) adds the local ascent ``K_g ∇_q S`` of
``gradient`` to the null-space input of ``single`` and ``multi``. The preview pull heads for the
imaginary arms' optima, which on a spatial arm may lie radians away. The local term keeps the
current configuration clear of an obstacle meanwhile.

The preview modes get their imaginary arms ``q̃`` from a 1-step GA (:mod:`previewctl.search.ga`), one per
preview time, which runs one generation per camera frame.

Build one with :func:`previewctl.control.factory.make_controller` and step it from your own loop,
``qdot = ctrl.step(q, t)`` (:class:`previewctl.control.controller.Controller`: the kinematics, the
camera frames and the last cycle's :class:`~previewctl.control.base.ControlInfo`). Inside, each mode is a
*control law* with ``command(t, q, state)`` (:mod:`previewctl.control.base`), built by
:func:`~previewctl.control.factory.build_law`; eq. 19 itself is in :mod:`previewctl.control.tracking`.
"""
