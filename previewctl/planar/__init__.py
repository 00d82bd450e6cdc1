"""Pure closed forms for planar arms, vectorised: the distances from link capsules to obstacle primitives.

The planar chain's facts are :mod:`previewctl.robot.planar`, its AMSI :mod:`previewctl.index.planar` and its
redundancy map :mod:`previewctl.search.planar`; the kernels here import none of them.
"""
