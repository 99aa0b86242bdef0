"""Training data: procedural shapes, mesh loaders, line drawings, augmentation, the dataset on disk.

Modules (format in docs/DATA_FORMAT.md):
    shapes   -- the 13-category procedural shape library (make_shape, split_of, CATEGORIES)
    loaders  -- ShapeNetCore v1/v2 and mesh-folder iterators (broken files skipped with warnings)
    lines    -- contours, creases and suggestive contours with hidden-line removal; stroke raster
    augment  -- hand-drawn augmentation of polylines (strength in [0, 1], deterministic by seed)
    render   -- all views of one shape: normal images, silhouettes, line drawings, framed cameras
    dataset  -- building (resumable, sharded), merging and loading (ShapeViewDataset)
    preview  -- contact sheets

Import the submodules directly; importing this package loads nothing heavy.
"""
