"""Observed obstacles (issue 33): predictors, the tracks they make, and the world of obstacles that come and go.

* :mod:`~previewctl.sensing.predictors`: :class:`~previewctl.sensing.predictors.Predictor`, the constant-velocity
  Kalman filter, two of them mixed (cruising and manoeuvring, the default) and the stationary model;
* :mod:`~previewctl.sensing.track`: a :class:`~previewctl.sensing.track.Track`, the motion of an observed obstacle
  (its prediction, inflated by its uncertainty);
* :mod:`~previewctl.sensing.world`: the observed obstacles, added, dropped and validated;
* :mod:`~previewctl.sensing.options`: :class:`~previewctl.sensing.options.Sensing`.

A controller observes through ``Controller.observe`` (:mod:`previewctl.control.controller`); the guide is
``docs/guide/sensing.md``.
"""
