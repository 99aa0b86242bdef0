"""Benchmarks of the training machinery (kept apart from the tests).

Modules:
    renderer -- ``sketchmesh bench renderer``: speed, memory and error of the differentiable
                rasterizer against the dense baseline
    fit      -- ``sketchmesh bench fit``: direct optimisation of the template to one mesh (or to
                procedural shapes of every category) through the renderer alone: the ceiling
                the predictor is measured against

``bench data`` lives in :mod:`training.cli.data`.

Import the submodules directly; importing this package loads nothing heavy.
"""
