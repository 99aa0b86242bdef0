"""The ``sketchmesh`` command: a thin dispatcher over ``app``, ``engine`` and ``training``."""
