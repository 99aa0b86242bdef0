"""The command line of the training layer: the subcommands ``sketchmesh`` registers from here.

Modules (each cheap to import: argparse only; torch loads inside the command functions):
    data  -- ``sketchmesh data`` (build, merge, preview) and ``bench data``
    train -- ``sketchmesh train | eval | export`` (also ``python -m training.cli.train``)
    bench -- ``bench renderer | fit | tradeoff`` and ``sketchmesh gallery``

Each defines ``register(commands, bench)`` (the contract is in :mod:`sketchmesh.cli`).
"""
