"""The training loop: its one configuration, the trainer and resumable checkpoints.

Modules:
    config     -- TrainConfig, the frozen dataclass every run is built from (torch-free)
    trainer    -- Trainer: the ``normals`` (cGAN), ``mesh`` and ``joint`` modes, DDP, validation
    checkpoint -- atomic, resumable checkpoints of a run folder

Import the submodules directly; importing this package loads nothing heavy.
"""
