"""Benchmarks of the training machinery (kept apart from the tests).

Modules:
    renderer -- ``sketchmesh bench renderer``: speed, memory and error of the differentiable
                rasterizer against the dense baseline

``sketchmesh bench fit`` lives in :mod:`training.fit` (still at the top level, see
:mod:`training`); ``bench data`` in :mod:`training.cli.data`.

Import the submodules directly; importing this package loads nothing heavy.
"""
