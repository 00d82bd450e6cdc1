"""The benchmark: seeded solvable scenes, every controller x execution mode, run on Dask, reported.

* :mod:`~previewctl.bench.settings`: what every scene of a sweep shares
  (:class:`~previewctl.bench.settings.SceneSettings`).
* :mod:`~previewctl.bench.scenes`: the scene generators (:func:`~previewctl.bench.scenes.generate`).
* :mod:`~previewctl.bench.witness`: the solvability witness a scene must pass.
"""
