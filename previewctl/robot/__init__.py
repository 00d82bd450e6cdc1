"""Robots: the loaded arm (:class:`Robot`), its joint and chain facts and its collision geometry.

Loading one from URDF is :mod:`previewctl.index.load`: a loaded arm carries the structural ranks of its
avoidance matrices, which the index computes.
"""
