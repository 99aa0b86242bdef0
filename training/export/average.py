"""Weight averaging of training runs of one network (``sketchmesh average``).

Runs that end their own learning-rate cycle from a common ancestor (``predictor-v24`` and its second pass
``predictor-v24-more``: cosine decays from one start) sit in one basin of the loss; the weighted mean of
their weights is a network of the same size and cost that often generalises better than either end point
(stochastic weight averaging over cycle end points; Izmailov et al. 2018, "Averaging weights leads to wider
optima and better generalization"). The validation split decides whether it does here.

What is averaged, network by network (every run must hold the same networks):

* parameters: the weighted mean, in float64, stored in the parameter's dtype;
* batch-norm running statistics: set again from the averaged network's own batch statistics over
  ``bn_samples`` training inputs (the mean of averaged networks' statistics is not the statistics of the
  averaged network); ``bn_samples = 0`` keeps the weighted mean of the runs' statistics instead;
* ``num_batches_tracked``: the largest;
* any other buffer (the predictor's offset basis, the template): must be equal in every run, else the
  runs are not one network and nothing is written.

The result is a run folder with one checkpoint (iteration 0, no optimiser state) and the first run's
config, which ``sketchmesh eval``, ``export`` and ``train --init-mesh`` read like any other run.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import torch
from torch import nn

from engine.errors import ModelError
from engine.fileio import atomic_write_text
from training.loop.checkpoint import checkpoint_paths, require_checkpoint, save_checkpoint
from training.loop.config import TrainConfig

BN_CHUNK = 64
"""Calibration inputs per forward pass when the batch norms are set again."""


@dataclass(frozen=True)
class AverageReport:
    """What :func:`average_runs` wrote."""

    out_dir: Path
    runs: tuple[str, ...]
    weights: tuple[float, ...]
    iterations: tuple[int, ...]
    batch_norm: str

    def line(self) -> str:
        parts = ", ".join(f"{w:.3g} x {r} (iteration {i})" for r, w, i in zip(self.runs, self.weights, self.iterations))
        return f"averaged {parts} into {self.out_dir}; batch norms: {self.batch_norm}"


def _weights(count: int, weights: list[float] | None) -> list[float]:
    if weights is None:
        return [1.0 / count] * count
    if len(weights) != count:
        raise ValueError(f"--weights gives {len(weights)} weight(s) for {count} run(s)")
    if not all(math.isfinite(w) and w >= 0.0 for w in weights) or sum(weights) <= 0.0:
        raise ValueError(f"--weights must be finite, non-negative and not all zero, got {weights}")
    total = float(sum(weights))
    return [float(w) / total for w in weights]


def _batch_norms(model: nn.Module) -> list[nn.modules.batchnorm._BatchNorm]:
    return [m for m in model.modules() if isinstance(m, nn.modules.batchnorm._BatchNorm) and m.track_running_stats]


def _bn_buffer_names(model: nn.Module) -> set[str]:
    names = set()
    for prefix, m in model.named_modules():
        if isinstance(m, nn.modules.batchnorm._BatchNorm) and m.track_running_stats:
            names.update(f"{prefix}.{b}" if prefix else b for b in ("running_mean", "running_var"))
    return names


def average_state_dicts(states: list[dict[str, torch.Tensor]], weights: list[float], model: nn.Module,
                        what: str = "network") -> dict[str, torch.Tensor]:
    """The weighted mean of ``states`` (state dicts of ``model``'s architecture) by the rules of the module doc."""
    keys = list(states[0])
    for k, s in enumerate(states[1:], 1):
        if list(s) != keys:
            missing = sorted(set(keys) ^ set(s))
            raise ModelError(f"run {k + 1}'s {what} has other tensors than run 1's ({', '.join(missing[:3])}): "
                             "not the same network")
    params = {n for n, _ in model.named_parameters()}
    stats = _bn_buffer_names(model)
    out = {}
    for name in keys:
        tensors = [s[name] for s in states]
        shapes = {tuple(t.shape) for t in tensors}
        if len(shapes) > 1:
            raise ModelError(f"{what} tensor {name} has shapes {sorted(shapes)} across the runs: not the same network")
        if name in params or name in stats:
            acc = sum(w * t.double() for w, t in zip(weights, tensors))
            if not bool(torch.isfinite(acc).all()):
                raise ModelError(f"{what} tensor {name}: the average is not finite (a run holds NaN or inf)")
            out[name] = acc.to(tensors[0].dtype)
        elif name.endswith("num_batches_tracked"):
            out[name] = torch.stack([t.reshape(()) for t in tensors]).max().reshape(tensors[0].shape)
        else:
            if not all(torch.equal(tensors[0], t) for t in tensors[1:]):
                raise ModelError(f"{what} buffer {name} differs between the runs (a fixed buffer, not a weight): "
                                 "not the same network")
            out[name] = tensors[0].clone()
    return out


def recalibrate_batch_norms(model: nn.Module, inputs: torch.Tensor, chunk: int = BN_CHUNK) -> int:
    """Set every batch norm's running statistics to the mean of its batch statistics over ``inputs`` (chunks of
    ``chunk``, in order), as training would with a cumulative average; the model is left in eval mode.

    Returns the number of batch norms set (0: nothing to do, the model untouched).
    """
    bns = _batch_norms(model)
    if not bns:
        return 0
    if inputs.shape[0] < 2:
        raise ModelError("batch-norm calibration needs at least 2 inputs")
    saved = [bn.momentum for bn in bns]
    try:
        for bn in bns:
            bn.reset_running_stats()
            bn.momentum = None  # cumulative average over the forward passes
        model.train()
        with torch.no_grad():
            for part in inputs.split(chunk):
                if part.shape[0] >= 2:  # a batch of one has no variance
                    model(part)
    finally:
        for bn, m in zip(bns, saved):
            bn.momentum = m
        model.eval()
    return len(bns)


def average_runs(runs: list[str | Path], out_dir: str | Path, *, weights: list[float] | None = None,
                 bn_samples: int = 1024, data_dir: str | None = None) -> AverageReport:
    """Average the newest checkpoints of ``runs`` into the new run folder ``out_dir`` (module doc).

    Args:
        runs: two or more run folders of the same network (same architecture and fixed buffers).
        weights: one non-negative weight per run (normalised); default equal.
        bn_samples: training inputs of the first run's dataset (``data_dir`` overrides it) that set the batch
            norms of the averaged network; 0 keeps the weighted mean of the runs' statistics.

    Raises:
        ModelError: a run is missing or broken, the runs are not one network, or ``out_dir`` holds a run.
        ValueError: bad weights.
    """
    from training.loop.trainer import build_models

    if len(runs) < 2:
        raise ValueError(f"averaging needs at least two runs, got {len(runs)}")
    w = _weights(len(runs), weights)
    out = Path(out_dir)
    if checkpoint_paths(out):
        raise ModelError(f"{out} already holds a run; choose another --out")
    states = [require_checkpoint(r) for r in runs]
    configs = []
    for r, s in zip(runs, states):
        try:
            configs.append(TrainConfig.from_json(s["config"]))
        except (ValueError, TypeError) as exc:
            raise ModelError(f"run {r}: unusable config in its checkpoint: {exc}") from None
    names = list(states[0]["models"])
    for r, s in zip(runs[1:], states[1:]):
        if list(s["models"]) != names:
            raise ModelError(f"run {r} holds {sorted(s['models'])}, run {runs[0]} holds {sorted(names)}: "
                             "not the same networks")
    cfg = configs[0]
    if data_dir:
        cfg = cfg.replace(data_dir=str(data_dir))
    models = build_models(cfg)
    if sorted(models) != sorted(names):
        raise ModelError(f"run {runs[0]}'s config builds {sorted(models)} but its checkpoint holds {sorted(names)}")
    note = "no batch norms"
    for name, model in models.items():
        avg = average_state_dicts([s["models"][name] for s in states], w, model, what=name)
        try:
            model.load_state_dict(avg)
        except RuntimeError as exc:
            raise ModelError(f"the averaged {name} does not fit run {runs[0]}'s config: {exc}") from None
        if not _batch_norms(model):
            continue
        if bn_samples > 0:
            from training.export.from_onnx import calibration_inputs

            inputs, source = calibration_inputs(cfg, bn_samples)
            recalibrate_batch_norms(model, inputs)
            note = f"set from {source}"
        else:
            note = "the weighted mean of the runs' running statistics"
        model.eval()
    iterations = tuple(int(s["iteration"]) for s in states)
    extra = {"averaged_from": [str(r) for r in runs], "average_weights": w, "averaged_iterations": list(iterations),
             "batch_norm": note}
    save_checkpoint(out, 0, cfg.to_json(), f"average of {len(runs)} runs ({states[0].get('code_version', 'unknown')})",
                    models, {}, extra=extra)
    atomic_write_text(out / "AVERAGED.json", json.dumps(extra, indent=2) + "\n")
    return AverageReport(out, tuple(str(r) for r in runs), tuple(w), iterations, note)
