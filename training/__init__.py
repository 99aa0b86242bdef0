"""Sketchmesh training (torch): everything that makes the models the engine runs.

The folders follow the pipeline, from data to a model folder:

    data/        -- procedural shapes, mesh loaders, line drawings, augmentation, the dataset on disk
    render/      -- the differentiable rasterizer (paper Eq. 1), its loop reference and dense baseline
    model/       -- the two networks and the mesh predictor's losses (paper Eq. 2-10)
    loop/        -- the one training config, the trainer (normals / mesh / joint, DDP), checkpoints
    export/      -- a trained run -> the engine's two ONNX files, parity-checked
    evaluation/  -- metrics, ``sketchmesh eval``, the accuracy/latency trade-off study, the gallery
    bench/       -- benchmarks of the training machinery: the rasterizer, and the direct fit of
                    the template to a mesh (the ceiling the predictor is measured against)
    cli/         -- the subcommands ``sketchmesh`` registers (argparse only; torch loads lazily)

At the top level: ``_torch.py`` (the lazy torch import with a clear message when the ``train``
extra is missing) and ``reproduce_models.sh``.

May import :mod:`engine` (shared geometry, cameras, export), never :mod:`app`.
"""
