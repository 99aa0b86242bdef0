"""Bundled data: the default ONNX models (``models/``, with their model card) and sample sketches."""

from pathlib import Path

ASSETS_DIR = Path(__file__).resolve().parent
MODELS_DIR = ASSETS_DIR / "models"
SAMPLES_DIR = ASSETS_DIR / "samples"
