"""The benchmark: seeded solvable scenes, every controller x execution mode, run on Dask, reported.

* :mod:`~previewctl.bench.settings`: what every scene of a sweep shares
  (:class:`~previewctl.bench.settings.SceneSettings`).
* :mod:`~previewctl.bench.profiles`: how a robot's scenes are drawn, hand-written or derived from the arm
  (:func:`~previewctl.bench.profiles.derived_profile`).
* :mod:`~previewctl.bench.robots`: a sweep's robots, a name or a URDF file: recorded, labelled, loaded, profiled.
* :mod:`~previewctl.bench.scenes`: the scene generators (:func:`~previewctl.bench.scenes.generate`).
* :mod:`~previewctl.bench.witness`: the solvability witness a scene must pass.
* :mod:`~previewctl.bench.pink`: pink's differential IK as a baseline (``--controller pink,pink-g100``).
"""
