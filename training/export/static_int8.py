"""``sketchmesh quantize-generator``: a models folder's generator with its convolutions in int8, calibrated on training
sketches (:func:`engine.bench.static_int8_generator`), written beside it as ``generator_int8.onnx``.

The engine runs that file in place of ``generator.onnx`` when a folder has it (:func:`engine.models.
load_runtime_generator`); ``generator.onnx`` stays the float file that training imports and continues. The calibration
drawings are a split's stored sketches (never the test split's): half as drawn, half through the hand-drawn
augmentation at full strength (broken, doubled, wobbly lines), so the ranges cover the drawings the app sees.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from engine import contract as C
from engine.errors import ModelError

CALIBRATION_DRAWINGS = 96
"""Drawings whose convolution inputs set the int8 ranges (a quarter of a minute on 2 cores)."""


def calibration_drawings(data_dir: str | Path, count: int = CALIBRATION_DRAWINGS, *, split: str = "train",
                         seed: int = 0) -> np.ndarray:
    """(count, 1, 256, 256) float32 drawings of ``split`` (not ``test``), evenly spaced over its views: the first half
    as stored, the second half augmented at strength 1.

    Raises:
        ModelError: the test split, a count below 2, or a split with fewer views than ``count``.
        DatasetError: the dataset cannot be read.
    """
    from training.data.dataset import ShapeViewDataset

    if split == "test":
        raise ModelError("calibration must not read the test split (the scores would see their own drawings)")
    if count < 2:
        raise ModelError(f"calibration needs at least 2 drawings, got {count}")
    halves = ((count + 1) // 2, count // 2)
    out = []
    for strength, n in zip((0.0, 1.0), halves):
        data = ShapeViewDataset(data_dir, split, extra_views=0, augment_strength=strength, seed=seed, fields="sketch")
        if len(data) < n:
            raise ModelError(f"{data_dir}: the {split} split has {len(data)} views, fewer than the {n} drawings asked")
        start = 0 if strength == 0.0 else len(data) // (2 * n)  # the augmented half from other views
        for i in np.linspace(start, len(data) - 1, n).round().astype(int):
            out.append(np.asarray(data[int(i)]["sketch"], np.float32).reshape(1, C.SKETCH_SIZE, C.SKETCH_SIZE))
    return np.clip(np.stack(out), 0.0, 1.0)


def quantize_generator(models_dir: str | Path, data_dir: str | Path, *, count: int = CALIBRATION_DRAWINGS,
                       split: str = "train", keep_float: int = 1, min_pixels: int | None = None) -> dict:
    """Write ``models_dir/generator_int8.onnx`` from ``models_dir/generator.onnx``; returns
    :func:`engine.bench.static_int8_generator`'s report with ``path`` and ``bytes`` added (``min_pixels`` None:
    :data:`engine.bench.STATIC_MIN_PIXELS`)."""
    from engine.bench import STATIC_MIN_PIXELS, static_int8_generator
    from engine.models import model_paths

    models_dir = Path(models_dir)
    gen, _ = model_paths(models_dir)
    x = calibration_drawings(data_dir, count, split=split)
    dst = models_dir / C.GENERATOR_INT8_FILE
    report = static_int8_generator(gen, dst, x, keep_float=keep_float,
                                   min_pixels=STATIC_MIN_PIXELS if min_pixels is None else min_pixels)
    return {**report, "path": str(dst), "bytes": dst.stat().st_size}
