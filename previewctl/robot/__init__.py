"""Robots from URDF: the loaded arm (:class:`Robot`), its loading and its collision geometry."""
