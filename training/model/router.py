"""A category router: which mesh predictor should read this drawing.

The paper trains one mesh predictor per category; the bundled predictor serves all 13 at once, and
a predictor trained on some categories alone (a *specialist*) does better on them and far worse on
the others (model card, "A specialist for the legged furniture"). The router sends a drawing to a
specialist only when it is sure the drawing is of that specialist's categories: it is a small
convolutional classifier over the categories that reads what the predictor reads (the generator's
normal image, area-averaged to 64 x 64), and the engine sums its probabilities over each specialist's
categories and routes when the sum passes a threshold (:mod:`engine.pipeline`).

Training data are generated sets (:mod:`training.data.generated`): the generator's own images of a
dataset's hand-drawn-augmented drawings, and of the same drawings flipped left to right, labelled
with their shapes' categories. A few pixels of random shift stand in for the framing's wobble.

The network, its config, the labelled training rows and the routing table live here; training is
:mod:`training.loop.router`, the export :mod:`training.export.router`, the command ``sketchmesh router``.
"""

from __future__ import annotations

import json
import os
from dataclasses import asdict, dataclass, field

import numpy as np

from training._torch import require_torch

torch = require_torch()
nn = torch.nn
F = torch.nn.functional

ROUTER_FORMAT = "sketchmesh-router-1"


class RouterNet(nn.Module):
    """(N, 3, 64, 64) normal images in [0, 1] -> (N, K) category logits.

    Four stride-2 3x3 convolutions (batch norm, ReLU) to 4 x 4, average-pooled to 2 x 2 (a coarse
    layout: where the legs are), one linear layer. About 50,000 parameters (0.2 MB as float32).
    """

    def __init__(self, num_classes: int, channels: tuple[int, ...] = (16, 32, 48, 64)) -> None:
        super().__init__()
        if num_classes < 2:
            raise ValueError(f"a router needs at least 2 categories, got {num_classes}")
        layers, c_in = [], 3
        for c in channels:
            layers += [nn.Conv2d(c_in, c, 3, stride=2, padding=1, bias=False), nn.BatchNorm2d(c), nn.ReLU(inplace=True)]
            c_in = c
        self.features = nn.Sequential(*layers)
        self.pool = nn.AdaptiveAvgPool2d(2)
        self.head = nn.Linear(c_in * 4, num_classes)
        self.num_classes = num_classes
        self.channels = tuple(channels)

    def forward(self, normals: torch.Tensor) -> torch.Tensor:
        if normals.ndim != 4 or normals.shape[1] != 3:
            raise ValueError(f"router input must be (N, 3, H, W), got {tuple(normals.shape)}")
        x = self.features(normals * 2.0 - 1.0)
        return self.head(torch.flatten(self.pool(x), 1))


class RouterProbabilities(nn.Module):
    """The exported graph: ``normals`` -> ``probabilities`` (softmax over the categories)."""

    def __init__(self, net: RouterNet) -> None:
        super().__init__()
        self.net = net

    def forward(self, normals: torch.Tensor) -> torch.Tensor:
        return torch.softmax(self.net(normals), dim=1)


@dataclass
class RouterConfig:
    """What a router run trains on and how (``config.json``)."""

    data: list[str]
    inputs: list[str] = field(default_factory=lambda: ["normals16", "normals16_mirror"])
    val_data: str | None = None
    epochs: int = 30
    batch: int = 128
    lr: float = 2e-3
    weight_decay: float = 1e-4
    shift: int = 3
    seed: int = 0
    channels: list[int] = field(default_factory=lambda: [16, 32, 48, 64])
    categories: list[str] = field(default_factory=list)
    format: str = ROUTER_FORMAT

    def to_json(self) -> str:
        return json.dumps(asdict(self), sort_keys=True)


def labelled_rows(root: str | os.PathLike, inputs: list[str], split: str = "train",
                  categories: list[str] | None = None) -> tuple[list, np.ndarray, list[str]]:
    """The generated inputs of a dataset's ``split`` with their category labels.

    Returns:
        (sets, rows, categories): ``sets`` is a list of (GeneratedNormals, row indices (M,), labels (M,)),
        one per input name; ``categories`` is the label order (the given one, else the manifest's, sorted).

    Raises:
        DatasetError: no such dataset or generated set, rows not generated, a category outside ``categories``.
    """
    from training.data.dataset import DatasetError, load_manifest
    from training.data.generated import open_generated
    from training.data.mesh_cache import open_mesh_cache

    manifest = load_manifest(root)
    cats = list(categories) if categories else sorted({s["category"] for s in manifest["shapes"]})
    index = {c: k for k, c in enumerate(cats)}
    cache = open_mesh_cache(root, manifest)
    rows, labels = [], []
    for s in manifest["shapes"]:
        if s["split"] != split:
            continue
        if s["category"] not in index:
            raise DatasetError(f"{root}: category {s['category']!r} is not one of the router's {cats}")
        first = cache.row(s["file"])
        rows.extend(range(first, first + int(s["num_views"])))
        labels.extend([index[s["category"]]] * int(s["num_views"]))
    if not rows:
        raise DatasetError(f"{root}: no {split} shapes to train a router on")
    rows_a, labels_a = np.asarray(rows, np.int64), np.asarray(labels, np.int64)
    sets = []
    for name in inputs:
        g = open_generated(root, name)
        if not g.done[rows_a].all():
            raise DatasetError(f"{root}: generated set {name!r} lacks rows of the {split} split (build it with "
                               f"`sketchmesh data generated {root} --name {name}`)")
        sets.append((g, rows_a, labels_a))
    return sets, rows_a, cats


def routing_table(probs: np.ndarray, labels: np.ndarray, categories: list[str], group: list[str],
                  thresholds=(0.5, 0.7, 0.8, 0.9, 0.95, 0.98, 0.99)) -> list[dict]:
    """For each threshold: how often a drawing of ``group`` is sent to its specialist (recall) and how often
    another drawing is (false routes), with the group probability the sum over its categories."""
    idx = [categories.index(c) for c in group]
    p = probs[:, idx].sum(1)
    truth = np.isin(labels, idx)
    out = []
    for t in thresholds:
        sent = p > t
        out.append({"threshold": float(t), "recall": float(sent[truth].mean()) if truth.any() else float("nan"),
                    "false_routes": float(sent[~truth].mean()) if (~truth).any() else float("nan"),
                    "group": int(truth.sum()), "others": int((~truth).sum())})
    return out
