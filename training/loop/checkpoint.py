"""Atomic, resumable checkpoints of a training run.

Layout of a run folder::

    RUN/checkpoints/ckpt_00001000.pt   # newest two kept (last and previous)
    RUN/checkpoints/ckpt_00000500.pt
    RUN/config.json                    # resolved TrainConfig + code version of the newest checkpoint

A checkpoint is a plain dict of tensors and primitive types so it loads with
``torch.load(weights_only=True)``: ``{"format", "iteration", "config" (JSON string),
"code_version", "models" {name: state_dict}, "optimizers" {name: state_dict},
"rng" {"torch", "numpy", "python", ["cuda"]}, "extra" {...}}``. The trainer's ``extra`` holds
``world_size`` and ``train_seconds``, the wall time the run has trained up to this checkpoint over
all its invocations (absent in checkpoints written before it was recorded).

Each file is written to a temporary sibling, fsynced and renamed (:mod:`engine.fileio`), so an
interrupted write leaves the previous checkpoints intact; a load that finds the newest file
corrupt falls back to the previous one. The temporary file of a write killed midway
(``.ckpt_XXXXXXXX.pt.*.tmp``, as big as a checkpoint) is deleted by the next write, and by
``sketchmesh train`` when it resumes (:func:`remove_stale_checkpoint_files`).
"""

from __future__ import annotations

import json
import random
import re
import warnings
from pathlib import Path

import numpy as np
import torch

from engine.errors import ModelError
from engine.fileio import atomic_open, atomic_write_text, remove_stale_temporaries

CHECKPOINT_FORMAT = 1
CHECKPOINT_DIR = "checkpoints"
KEEP_CHECKPOINTS = 2
_NAME = re.compile(r"^ckpt_(\d{8,})\.pt$")


def checkpoint_paths(run_dir: str | Path) -> list[Path]:
    """Checkpoint files of a run, newest (highest iteration) first."""
    folder = Path(run_dir) / CHECKPOINT_DIR
    if not folder.is_dir():
        return []
    found = [(int(m.group(1)), p) for p in folder.iterdir() if (m := _NAME.match(p.name))]
    return [p for _, p in sorted(found, reverse=True)]


def rng_state() -> dict:
    """The global RNG states of torch, numpy and Python as tensors (weights_only-loadable)."""
    np_state = np.random.get_state()
    state = {
        "torch": torch.get_rng_state(),
        "numpy_keys": torch.from_numpy(np.asarray(np_state[1], dtype=np.int64)),
        "numpy_meta": torch.tensor([np_state[2], np_state[3]], dtype=torch.int64),
        "numpy_gauss": torch.tensor(float(np_state[4]), dtype=torch.float64),
        "python": torch.tensor(random.getstate()[1], dtype=torch.int64),
    }
    if torch.cuda.is_available():
        state["cuda"] = torch.stack(torch.cuda.get_rng_state_all())
    return state


def set_rng_state(state: dict) -> None:
    """Inverse of :func:`rng_state`."""
    torch.set_rng_state(state["torch"].cpu().to(torch.uint8))
    meta = state["numpy_meta"].tolist()
    np.random.set_state(
        ("MT19937", state["numpy_keys"].numpy().astype(np.uint32), int(meta[0]), int(meta[1]), float(state["numpy_gauss"]))
    )
    random.setstate((3, tuple(int(x) for x in state["python"].tolist()), None))
    if "cuda" in state and torch.cuda.is_available() and len(state["cuda"]) == torch.cuda.device_count():
        torch.cuda.set_rng_state_all(list(state["cuda"].cpu()))


def save_checkpoint(
    run_dir: str | Path,
    iteration: int,
    config_json: str,
    code_version: str,
    models: dict[str, torch.nn.Module],
    optimizers: dict[str, torch.optim.Optimizer],
    extra: dict | None = None,
    keep: int = KEEP_CHECKPOINTS,
) -> Path:
    """Write ``RUN/checkpoints/ckpt_<iteration>.pt`` atomically, then drop all but the newest ``keep``.

    Also writes ``RUN/config.json`` (config + code version + iteration) atomically.

    Returns:
        The path written.
    """
    if keep < 1:
        raise ValueError(f"keep must be >= 1, got {keep}")
    state = {
        "format": CHECKPOINT_FORMAT,
        "iteration": int(iteration),
        "config": str(config_json),
        "code_version": str(code_version),
        "models": {k: {n: t.detach().cpu() for n, t in m.state_dict().items()} for k, m in models.items()},
        "optimizers": {k: o.state_dict() for k, o in optimizers.items()},
        "rng": rng_state(),
        "extra": dict(extra or {}),
    }
    path = Path(run_dir) / CHECKPOINT_DIR / f"ckpt_{int(iteration):08d}.pt"
    remove_stale_checkpoint_files(run_dir)
    with atomic_open(path, "wb") as fh:
        torch.save(state, fh)
    atomic_write_text(
        Path(run_dir) / "config.json",
        json.dumps(
            {"config": json.loads(config_json), "code_version": code_version, "iteration": int(iteration)},
            indent=2,
            sort_keys=True,
        ),
    )
    for old in checkpoint_paths(run_dir)[keep:]:
        old.unlink(missing_ok=True)
    return path


def remove_stale_checkpoint_files(run_dir: str | Path) -> list[Path]:
    """Delete what writes killed midway left in a run folder (checkpoint, config and log temporaries).

    Only the process that writes the run may call this (rank 0 of the training run). Returns the
    files removed.
    """
    run = Path(run_dir)
    return remove_stale_temporaries(run / CHECKPOINT_DIR, "ckpt_*.pt") + remove_stale_temporaries(run)


def load_checkpoint_file(path: str | Path, map_location: str | torch.device = "cpu") -> dict:
    """Load one checkpoint file with ``weights_only=True``; raise ModelError naming the file if unusable."""
    try:
        state = torch.load(Path(path), map_location=map_location, weights_only=True)
    except Exception as exc:  # corrupt, truncated, or not a checkpoint
        raise ModelError(f"checkpoint {path} cannot be read: {type(exc).__name__}: {exc}") from None
    if not isinstance(state, dict) or state.get("format") != CHECKPOINT_FORMAT or "models" not in state:
        raise ModelError(f"checkpoint {path} is not a Sketchmesh checkpoint (format {CHECKPOINT_FORMAT})")
    return state


def load_latest_checkpoint(run_dir: str | Path, map_location: str | torch.device = "cpu") -> dict | None:
    """The newest readable checkpoint of a run, or None if the run has none.

    A newest file that cannot be read (for example a disk filled mid-write by another tool) is
    reported with a warning and the previous one is used. Raises ModelError if checkpoints exist
    but none is readable.
    """
    paths = checkpoint_paths(run_dir)
    errors = []
    for path in paths:
        try:
            state = load_checkpoint_file(path, map_location)
        except ModelError as exc:
            errors.append(str(exc))
            warnings.warn(f"skipping unreadable checkpoint: {exc}", stacklevel=2)
            continue
        state["path"] = str(path)
        return state
    if errors:
        raise ModelError(f"no readable checkpoint in {run_dir}: " + "; ".join(errors))
    return None


def check_run_folder(run: str | Path, what: str = "RUN") -> Path:
    """A run folder given as input exists and is a folder; ModelError naming ``what`` otherwise."""
    p = Path(run)
    if not p.exists():
        raise ModelError(f"{what} {p}: run folder does not exist")
    if not p.is_dir():
        raise ModelError(f"{what} {p}: is a file, expected a run folder")
    return p


def require_checkpoint(run_dir: str | Path, map_location: str | torch.device = "cpu") -> dict:
    """Like :func:`load_latest_checkpoint` but a run with no checkpoint raises ModelError."""
    run = check_run_folder(run_dir, "run")
    state = load_latest_checkpoint(run, map_location)
    if state is None:
        raise ModelError(f"run folder {run} has no checkpoint (expected {run / CHECKPOINT_DIR}/ckpt_*.pt)")
    return state


def save_slim_copy(run_dir: str | Path, dest: str | Path) -> int | None:
    """Write ``run_dir``'s newest checkpoint to file ``dest`` without optimiser and RNG state (what a lent GPU
    machine sends back: a third of the size; ``sketchmesh export`` / ``eval`` and ``--init-mesh`` need only the
    models). Atomic. Returns its iteration, or None when the run has no checkpoint yet."""
    state = load_latest_checkpoint(run_dir)
    if state is None:
        return None
    state.pop("path", None)
    state.pop("rng", None)
    state["optimizers"] = {}
    with atomic_open(dest, "wb") as fh:
        torch.save(state, fh)
    return int(state["iteration"])
