"""The bundled trainer: normal generator (cGAN), mesh predictor, and joint fine-tuning.

One :class:`Trainer` runs every mode of :class:`training.loop.config.TrainConfig`:

``normals``
    pix2pix cGAN (Eq. 7-10): D sees (sketch, real) and (sketch, G(sketch)); G minimises
    ``lambda_adv * BCE(D(s, G(s)), 1) + lambda_g * L1 + lambda_l * L1_sobel``. RMSProp for both.
``mesh``
    The predictor reads the ground-truth 64x64 normal image; its mesh (view frame) is rendered by
    :func:`training.render.rasterize` from the input view and ``extra_views`` other known views
    (:func:`training.model.networks.view_frame_cameras`) and compared with their normal images and
    silhouettes by Eq. 6 (:class:`training.model.losses.MeshLoss`). Adam.
``joint``
    G's output, area-downsampled to 64x64, feeds the predictor; the mesh loss (times
    ``joint_mesh_weight``) and G's own losses fine-tune G and the predictor together.

Both models of a step are updated "simultaneously": every loss of the step is computed and
back-propagated, then the step is taken only if every loss term and every gradient is finite.

Numerical safety
    A non-finite loss term or gradient skips the whole step (no optimizer update; BatchNorm
    running statistics restored), logs which term or parameter went non-finite to
    ``RUN/events.log``, and after ``max_bad_steps`` consecutive bad steps the last good state (an
    in-memory copy taken at every checkpoint and at the start) is restored. Gradients are clipped
    to ``grad_clip`` (global norm per model).

Determinism and resume
    The data order is a :class:`torch.utils.data.DistributedSampler` permutation per epoch,
    and every step reseeds the global torch RNG from ``(seed, rank, iteration)`` (dropout, Sobel
    sampling), so a run resumed from a checkpoint at iteration k continues exactly as the
    uninterrupted run would (on CPU; CUDA kernels may be nondeterministic).

Distributed
    Launched by ``torchrun`` (``RANK``, ``WORLD_SIZE``, ``LOCAL_RANK`` in the environment), the
    models are wrapped in DistributedDataParallel (gloo on CPU, nccl on CUDA), each rank reads its
    shard, and only rank 0 writes logs, images and checkpoints.

Run folder: ``checkpoints/``, ``config.json``, ``log.csv``, ``curves.png``, ``events.log``,
``val/iter_XXXXX.png``.
"""

from __future__ import annotations

import copy
import csv
import io
import math
import os
import time
import zlib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from engine.errors import ModelError, SketchmeshError
from engine.fileio import atomic_write_bytes, atomic_write_text
from engine.icosphere import TEMPLATE_RADIUS, icosphere, mirror_permutation
from training.data.mirror import counterpart_inputs, mirror_consistency
from training.loop.checkpoint import load_latest_checkpoint, require_checkpoint, save_checkpoint
from training.loop.config import TrainConfig, code_version
from training.model.losses import chamfer_loss, sample_mesh_points
from training.model.networks import (
    NormalGenerator,
    PatchDiscriminator,
    adversarial_loss,
    build_predictor,
    downsample_normals,
    global_l1_loss,
    local_l1_loss,
    sample_edge_pixels,
    view_frame_cameras,
)

SURFACE_POINTS = 1024
"""Points per mesh in the Chamfer term of ``supervision="3d"`` (the diagnostic ceiling)."""

MODEL_SHAPE_FIELDS = ("mode", "base_channels", "generator_arch", "predictor_arch", "predictor_channels",
                      "predictor_hidden", "predictor_latent", "predictor_modes", "predictor_blocks", "predictor_aligned",
                      "template_level",
                      "predictor_smoothing", "predictor_local_bound", "sketch_size")
"""Config fields a resumed run must share with its checkpoint (they fix the parameter shapes or
the function the parameters were trained in)."""

VAL_ITEMS = 4
"""Validation images show this many fixed items."""


class TrainingError(SketchmeshError):
    """A training run cannot start or continue (bad data folder, incompatible checkpoint)."""


# ----------------------------------------------------------------------------------------------
# Distributed setup
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class DistInfo:
    """Process placement: ``world_size`` 1 means a plain single-process run."""

    rank: int = 0
    world_size: int = 1
    local_rank: int = 0

    @property
    def distributed(self) -> bool:
        return self.world_size > 1

    @property
    def is_main(self) -> bool:
        return self.rank == 0


def dist_info_from_env() -> DistInfo:
    """Read torchrun's ``RANK``, ``WORLD_SIZE``, ``LOCAL_RANK`` (absent: single process)."""
    try:
        return DistInfo(int(os.environ.get("RANK", 0)), int(os.environ.get("WORLD_SIZE", 1)),
                        int(os.environ.get("LOCAL_RANK", 0)))
    except ValueError as exc:
        raise TrainingError(f"bad torchrun environment (RANK/WORLD_SIZE/LOCAL_RANK): {exc}") from None


def resolve_device(name: str, info: DistInfo) -> torch.device:
    """"auto" -> CUDA (this rank's local GPU) when available, else CPU."""
    if name == "cpu" or (name == "auto" and not torch.cuda.is_available()):
        return torch.device("cpu")
    if not torch.cuda.is_available():
        raise TrainingError("device 'cuda' requested but no CUDA device is available")
    return torch.device("cuda", info.local_rank % torch.cuda.device_count())


def init_distributed(info: DistInfo, device: torch.device) -> None:
    """Join the torchrun process group (gloo on CPU, nccl on CUDA) unless already joined."""
    import torch.distributed as dist

    if info.distributed and not dist.is_initialized():
        backend = "nccl" if device.type == "cuda" else "gloo"
        if device.type == "cuda":
            torch.cuda.set_device(device)
        dist.init_process_group(backend=backend, init_method="env://", rank=info.rank, world_size=info.world_size)


# ----------------------------------------------------------------------------------------------
# Models
# ----------------------------------------------------------------------------------------------


def build_models(cfg: TrainConfig) -> dict[str, nn.Module]:
    """The networks a mode trains: "generator" + "discriminator" and/or "predictor"."""
    models: dict[str, nn.Module] = {}
    if cfg.uses_generator:
        models["generator"] = NormalGenerator(cfg.base_channels, arch=cfg.generator_arch)
        models["discriminator"] = PatchDiscriminator(cfg.base_channels)
    if cfg.uses_predictor:
        models["predictor"] = build_predictor(
            cfg.predictor_arch, template_level=cfg.template_level, channels=cfg.predictor_channels,
            hidden=cfg.predictor_hidden, latent=cfg.predictor_latent, input_size=cfg.render_size,
            smoothing=cfg.predictor_smoothing, local_bound=cfg.predictor_local_bound, modes=cfg.predictor_modes,
            blocks=cfg.predictor_blocks, aligned=cfg.predictor_aligned,
        )
    return models


def build_optimizers(cfg: TrainConfig, models: dict[str, nn.Module]) -> dict[str, torch.optim.Optimizer]:
    """RMSProp (lr 5e-5) for G and D, Adam (1e-4, (0.9, 0.999)) for the predictor (paper 4.1; none when
    ``freeze_predictor``)."""
    opts: dict[str, torch.optim.Optimizer] = {}
    if "generator" in models:
        opts["generator"] = torch.optim.RMSprop(models["generator"].parameters(), lr=cfg.lr_g)
        opts["discriminator"] = torch.optim.RMSprop(models["discriminator"].parameters(), lr=cfg.lr_d)
    if "predictor" in models and not cfg.freeze_predictor:
        opts["predictor"] = torch.optim.Adam(models["predictor"].parameters(), lr=cfg.lr_mesh, betas=cfg.betas)
    return opts


def load_run(run_dir: str | Path, device: str | torch.device = "cpu") -> tuple[TrainConfig, dict[str, nn.Module], dict]:
    """Rebuild a run's networks from its newest checkpoint, in eval mode.

    Returns:
        (config, models by name, checkpoint dict). Raises ModelError for a missing or broken run.
    """
    state = require_checkpoint(run_dir)
    try:
        cfg = TrainConfig.from_json(state["config"])
    except (ValueError, TypeError) as exc:
        raise ModelError(f"checkpoint {state.get('path')} carries an unusable config: {exc}") from None
    models = build_models(cfg)
    for name, model in models.items():
        if name not in state["models"]:
            raise ModelError(f"checkpoint {state.get('path')} lacks the {name} weights")
        try:
            model.load_state_dict(state["models"][name])
        except RuntimeError as exc:
            raise ModelError(f"checkpoint {state.get('path')}: {name} weights do not fit: {exc}") from None
        model.to(device).eval()
    return cfg, models, state


# ----------------------------------------------------------------------------------------------
# Data
# ----------------------------------------------------------------------------------------------


def step_fields(cfg: TrainConfig) -> str:
    """The dataset fields a training step of ``cfg`` reads: ``"mesh"`` in mesh mode, else ``"all"``.

    Mesh mode reads normals64 / silhouette64 / cameras only, so its training set serves them from
    the dataset's mesh-array cache (decompressed once, :mod:`training.data.mesh_cache`) and never
    loads or augments a sketch.
    """
    return "mesh" if cfg.mode == "mesh" else "all"


def make_dataset(cfg: TrainConfig, split: str, fields: str = "all"):
    """The :class:`training.data.dataset.ShapeViewDataset` of a split (``fields`` as there), with a clear error if unusable."""
    root = Path(cfg.data_dir)
    if not cfg.data_dir or not root.is_dir():
        raise TrainingError(f"data folder {root} does not exist (create one with: sketchmesh data --out {root})")
    from training.data.dataset import ShapeViewDataset

    try:
        generated = split == "train" and fields == "mesh"  # validation reads the true images
        return ShapeViewDataset(
            root, split, extra_views=cfg.extra_views, augment_strength=cfg.augment_strength if split == "train" else 0.0,
            seed=cfg.seed, categories=list(cfg.categories) or None, fields=fields,
            input_normals=cfg.input_normals if generated else None, input_share=cfg.input_share,
            mirror_inputs=cfg.mirror_inputs if generated and cfg.mirror > 0 else None,
        )
    except SketchmeshError:
        raise
    except (OSError, ValueError, KeyError) as exc:
        raise TrainingError(f"cannot read the {split} split of {root}: {type(exc).__name__}: {exc}") from None


class ResumableBatchSampler(torch.utils.data.Sampler):
    """Endless batches of indices, epoch by epoch, starting at a given iteration.

    Each epoch's order is a :class:`torch.utils.data.DistributedSampler` permutation (seeded by
    ``seed`` and the epoch), cut into ``len // batch`` full batches per rank, so iteration ``i``
    always gets the same batch and a resumed run sees exactly the data an uninterrupted one would.
    """

    def __init__(self, dataset_len: int, batch: int, seed: int, start_iter: int, info: DistInfo) -> None:
        if dataset_len < 1:
            raise TrainingError("the training split is empty")
        self.sampler = torch.utils.data.DistributedSampler(
            range(dataset_len), num_replicas=info.world_size, rank=info.rank, shuffle=True, seed=seed, drop_last=False
        )
        self.batch = int(batch)
        self.per_epoch = max(1, self.sampler.num_samples // self.batch)
        self.start_iter = int(start_iter)

    def __iter__(self) -> Iterator[list[int]]:
        it = self.start_iter
        while True:
            epoch, pos = divmod(it, self.per_epoch)
            self.sampler.set_epoch(epoch)
            order = list(self.sampler)
            while len(order) < self.batch * self.per_epoch:  # tiny datasets: wrap around
                order += order
            for b in range(pos, self.per_epoch):
                yield order[b * self.batch:(b + 1) * self.batch]
                it += 1

    def __len__(self) -> int:  # endless; DataLoader only needs a number
        return 2**62


def _to_device(batch: dict, device: torch.device) -> dict:
    out = {}
    for k, v in batch.items():
        if isinstance(v, np.ndarray):
            v = torch.from_numpy(v)
        if isinstance(v, torch.Tensor):
            v = v.to(device, non_blocking=True)
            if v.is_floating_point() and k not in ("camera", "other_cameras"):
                v = v.float()
        out[k] = v
    return out


# ----------------------------------------------------------------------------------------------
# Losses of one step (pure functions of the models and the batch)
# ----------------------------------------------------------------------------------------------


def render_views(vertices: torch.Tensor, faces: torch.Tensor, cameras: torch.Tensor, cfg: TrainConfig):
    """Render view-frame meshes from all their views.

    Args:
        vertices: (B, V, 3) view-frame vertices.
        faces: (F, 3) int64.
        cameras: (B, 1 + K, 16) from :func:`training.model.networks.view_frame_cameras`.

    Returns:
        RenderOutput of batch B * (1 + K) (view-major within each item).
    """
    from training.render.soft import rasterize_for_loss

    b, nv = cameras.shape[:2]
    vv = vertices[:, None].expand(b, nv, *vertices.shape[1:]).reshape(b * nv, *vertices.shape[1:])
    return rasterize_for_loss(vv, faces, cameras.reshape(b * nv, 16), cfg.render_size, delta=cfg.delta,
                              shading=cfg.shading, edge_range=cfg.edge_range, silhouette=cfg.silhouette,
                              soft_sigma=cfg.soft_sigma, normal_edges=cfg.normal_edges)


def mesh_targets(batch: dict) -> tuple[torch.Tensor, torch.Tensor]:
    """(B * (1 + K), 3, H, W) normals and (B * (1 + K), H, W) silhouettes: input view then the others."""
    n = torch.cat([batch["normals64"][:, None], batch["other_normals64"]], dim=1)
    s = torch.cat([batch["silhouette64"][:, None], batch["other_silhouette64"]], dim=1)
    return n.reshape(-1, *n.shape[2:]), s.reshape(-1, *s.shape[2:])


def _unwrap(model: nn.Module) -> nn.Module:
    return model.module if hasattr(model, "module") else model


# ----------------------------------------------------------------------------------------------
# The trainer
# ----------------------------------------------------------------------------------------------


class Trainer:
    """Runs (or resumes) one training run described by a :class:`TrainConfig`.

    Args:
        cfg: the resolved configuration (``out_dir`` is the run folder).
        resume: continue from the run folder's newest checkpoint if there is one; if False and the
            run folder has checkpoints, refuse (TrainingError) rather than overwrite them.
        progress: show the tqdm bar (rank 0 only).
        train_set, val_set: datasets to use instead of reading ``cfg.data_dir`` (tests).
    """

    def __init__(self, cfg: TrainConfig, *, resume: bool = True, progress: bool = True,
                 train_set=None, val_set=None) -> None:
        self.cfg = cfg
        self.info = dist_info_from_env()
        self.device = resolve_device(cfg.device, self.info)
        init_distributed(self.info, self.device)
        self.run_dir = Path(cfg.out_dir)
        if not cfg.out_dir:
            raise TrainingError("no run folder given (--out RUN)")
        self.progress = progress and self.info.is_main
        self.version = code_version()

        self.train_set = train_set if train_set is not None else make_dataset(cfg, "train", step_fields(cfg))
        if len(self.train_set) == 0:
            raise TrainingError(f"the train split of {cfg.data_dir} has no samples")
        self.val_set = val_set
        if self.val_set is None and self.info.is_main and cfg.val_every:
            try:
                self.val_set = make_dataset(cfg, "val")
            except SketchmeshError:
                self.val_set = None
        if self.val_set is not None and len(self.val_set) == 0:
            self.val_set = None

        torch.manual_seed(cfg.seed)  # identical initialisation on every rank
        self.models = {k: m.to(self.device) for k, m in build_models(cfg).items()}
        if cfg.freeze_predictor:  # gradients still flow through it to the generator's image
            self.models["predictor"].requires_grad_(False)
        self.optimizers = build_optimizers(cfg, self.models)
        self.mesh_loss = None
        if cfg.uses_predictor:
            from training.model.losses import LossWeights, MeshLoss

            template = icosphere(cfg.template_level, TEMPLATE_RADIUS)
            self.mesh_loss = MeshLoss(template, LossWeights(cfg.lambda_n, cfg.lambda_s, cfg.lambda_e, cfg.lambda_m),
                                      normal_region=cfg.normal_region,
                                      support_band_weight=cfg.support_band_weight).to(self.device)
            self.faces = torch.from_numpy(np.array(template.faces)).to(self.device)
            self._mirror_perm = torch.from_numpy(np.array(mirror_permutation(cfg.template_level))).to(self.device)

        self.iteration = 0
        self.train_seconds = 0.0  # wall time in run(), over every invocation, up to the newest checkpoint (saved in it)
        self._clock: tuple[float, float] | None = None  # (train_seconds, perf_counter) when run() started
        state = load_latest_checkpoint(self.run_dir) if self.run_dir.exists() else None
        if state is not None and not resume:
            raise TrainingError(f"run folder {self.run_dir} already has checkpoints; resume it or choose a new --out")
        if state is not None:
            self._restore(state)
            self._event(f"resumed from {state['path']} at iteration {self.iteration}")
        else:
            self._init_from_runs()
        self.good_state = self._snapshot()
        self.bad_streak = 0

        self.wrapped = dict(self.models)
        if self.info.distributed:
            from torch.nn.parallel import DistributedDataParallel as DDP

            ids = [self.device.index] if self.device.type == "cuda" else None
            self.wrapped = {k: DDP(m, device_ids=ids) if k in self.optimizers else m for k, m in self.models.items()}
        self.log_columns = self._log_columns()
        self._window: dict[str, list[float]] = {}
        self._surface_cache: dict[tuple[str, str], torch.Tensor] = {}  # supervision="3d": true surface points per shape

    # ---- state ----
    def _snapshot(self) -> dict:
        return {
            "models": {k: copy.deepcopy({n: t.detach().cpu() for n, t in m.state_dict().items()}) for k, m in self.models.items()},
            "optimizers": {k: copy.deepcopy(o.state_dict()) for k, o in self.optimizers.items()},
        }

    def _load_states(self, models: dict, optimizers: dict | None) -> None:
        for k, m in self.models.items():
            m.load_state_dict(models[k])
        if optimizers:
            for k, o in self.optimizers.items():
                o.load_state_dict(optimizers[k])

    def _restore(self, state: dict) -> None:
        try:
            saved = TrainConfig.from_json(state["config"])
        except (ValueError, TypeError) as exc:
            raise TrainingError(f"checkpoint {state['path']} has an unusable config: {exc}") from None
        # a field of a network the run does not have (the generator's in mesh mode) does not bind it
        unused = () if "generator" in self.models else ("generator_arch",)
        diffs = [f"{k}: checkpoint {getattr(saved, k)!r} vs now {getattr(self.cfg, k)!r}"
                 for k in MODEL_SHAPE_FIELDS if k not in unused and getattr(saved, k) != getattr(self.cfg, k)]
        if diffs:
            raise TrainingError(f"cannot resume {self.run_dir}: the config changed ({'; '.join(diffs)})")
        missing = [k for k in self.models if k not in state["models"]]
        if missing:
            raise TrainingError(f"checkpoint {state['path']} lacks {missing}")
        try:
            self._load_states(state["models"], state["optimizers"])
        except (RuntimeError, KeyError, ValueError) as exc:
            raise TrainingError(f"checkpoint {state['path']} does not fit the models: {exc}") from None
        self.iteration = int(state["iteration"])
        # checkpoints from before this was recorded give 0: the time of those runs is unknown
        self.train_seconds = float(state.get("extra", {}).get("train_seconds", 0.0))
        # the resolved config rules: learning rates and betas given now override the checkpoint's
        lrs = {"generator": self.cfg.lr_g, "discriminator": self.cfg.lr_d, "predictor": self.cfg.lr_mesh}
        for name, opt in self.optimizers.items():
            for group in opt.param_groups:
                group["lr"] = lrs[name]
                if "betas" in group:
                    group["betas"] = self.cfg.betas

    def _train_modes(self) -> None:
        """Every network in train mode, except a frozen predictor (eval: its batch norms' running statistics) and,
        without ``generator_dropout``, the generator's dropout layers."""
        for name, m in self.models.items():
            m.train(not (name == "predictor" and self.cfg.freeze_predictor))
            if name == "generator" and not self.cfg.generator_dropout:
                for layer in m.modules():
                    if isinstance(layer, nn.Dropout):
                        layer.eval()

    def _set_learning_rates(self, it: int) -> None:
        """The predictor's schedule: step ``it`` (0-based) runs at ``min(1, (it + 1) / lr_warmup)`` of
        ``lr_mesh`` (the linear warm-up), times, with ``lr_schedule="cosine"``,
        ``f + (1 - f) (1 + cos(pi it / iters)) / 2`` with ``f = lr_final``. The generator and the
        discriminator keep the paper's constant RMSProp rates."""
        cfg = self.cfg
        scale = min(1.0, (it + 1) / cfg.lr_warmup) if cfg.lr_warmup else 1.0
        if cfg.lr_schedule == "cosine":
            t = min(1.0, it / cfg.iters)
            scale *= cfg.lr_final + (1.0 - cfg.lr_final) * 0.5 * (1.0 + math.cos(math.pi * t))
        lrs = {"generator": self.cfg.lr_g, "discriminator": self.cfg.lr_d, "predictor": self.cfg.lr_mesh * scale}
        for name, opt in self.optimizers.items():
            for group in opt.param_groups:
                group["lr"] = lrs[name]

    def _init_from_runs(self) -> None:
        """Initialise G (and D) from ``init_normals`` and the predictor from ``init_mesh``."""
        for run, names in ((self.cfg.init_normals, ("generator", "discriminator")), (self.cfg.init_mesh, ("predictor",))):
            if not run:
                continue
            state = require_checkpoint(run)
            for name in names:
                if name not in self.models:
                    continue
                if name not in state["models"]:
                    raise TrainingError(f"run {run} has no {name} weights to initialise from")
                weights = state["models"][name]
                if name == "predictor":
                    weights = self._resmooth_init(weights, state, run)
                widened = self._load_init(name, weights, run)
                if widened:
                    self._event(f"{name} widened from {run}: latent {widened[0]} -> {self.cfg.predictor_latent}, "
                                f"hidden {widened[1]} -> {self.cfg.predictor_hidden} (same function at the start)")
            self._event(f"initialised {[n for n in names if n in self.models]} from {run}")

    def _resmooth_init(self, weights: dict, state: dict, run: str) -> dict:
        """``weights`` of run ``run``'s predictor; when that run damped its basis otherwise than this config, the
        same function in this config's damping (:meth:`CompactMeshPredictor.resmoothed_state`)."""
        try:
            old = TrainConfig.from_json(state["config"]).predictor_smoothing
        except (KeyError, ValueError, TypeError):
            old = self.cfg.predictor_smoothing
        model = _unwrap(self.models["predictor"])
        if old == self.cfg.predictor_smoothing or not hasattr(model, "resmoothed_state"):
            return weights
        try:
            weights = model.resmoothed_state(weights, old)
        except ValueError as why:
            raise TrainingError(f"predictor weights of run {run} cannot be re-smoothed from {old:g} to "
                                f"{self.cfg.predictor_smoothing:g}: {why}") from None
        self._event(f"predictor re-smoothed from {run}: basis damping {old:g} -> {self.cfg.predictor_smoothing:g} "
                    "(same function at the start)")
        return weights

    def _load_init(self, name: str, weights: dict, run: str) -> tuple[int, int] | None:
        """Load ``weights`` into model ``name``; a narrower or shallower compact predictor is grown (old widths
        returned when widened)."""
        model = self.models[name]
        try:
            model.load_state_dict(weights)
            return None
        except RuntimeError as exc:
            if not hasattr(model, "load_grown"):
                raise TrainingError(f"{name} weights of run {run} do not fit this config: {exc}") from None
            try:
                return model.load_grown(weights)
            except ValueError as why:
                raise TrainingError(f"{name} weights of run {run} do not fit this config: {why}") from None

    def save(self) -> Path | None:
        """Checkpoint now (rank 0), and remember this as the last good state."""
        self.good_state = self._snapshot()
        if self._clock is not None:
            self.train_seconds = self._clock[0] + (time.perf_counter() - self._clock[1])
        if not self.info.is_main:
            return None
        return save_checkpoint(self.run_dir, self.iteration, self.cfg.to_json(), self.version, self.models,
                               self.optimizers, extra={"world_size": self.info.world_size,
                                                       "train_seconds": self.train_seconds})

    # ---- logging ----
    def _event(self, text: str) -> None:
        if not self.info.is_main:
            return
        self.run_dir.mkdir(parents=True, exist_ok=True)
        line = f"{time.strftime('%Y-%m-%dT%H:%M:%S')} iter {self.iteration}: {text}"
        with open(self.run_dir / "events.log", "a", encoding="utf-8") as fh:
            fh.write(line + "\n")
        if self.progress:
            from tqdm import tqdm

            tqdm.write(line)

    def _log_columns(self) -> list[str]:
        cols = ["iteration", "wall_s", "it_per_s", "samples_per_s", "skipped"]
        if self.cfg.uses_generator:
            cols += ["d_loss", "g_adv", "g_global", "g_local", "g_total"]
        if self.cfg.uses_predictor:
            cols += ["mesh_normal", "mesh_silhouette", "mesh_edge", "mesh_smoothness", "mesh_total"]
            if self.cfg.supervision == "3d":
                cols.insert(-1, "mesh_chamfer")
            if self.cfg.mirror_consistency > 0:
                cols.insert(-1, "mesh_mirror")
        return cols

    def _prepare_log(self) -> None:
        """Keep only well-formed rows up to the resumed iteration (a killed run may have left more)."""
        path = self.run_dir / "log.csv"
        if not self.info.is_main:
            return
        rows = []
        if path.exists():
            with open(path, newline="", encoding="utf-8") as fh:
                reader = csv.DictReader(fh)
                if reader.fieldnames == self.log_columns:
                    for row in reader:
                        try:
                            if None not in row.values() and int(row["iteration"]) <= self.iteration:
                                rows.append(row)
                        except (ValueError, TypeError):
                            continue
        buf = io.StringIO()
        w = csv.DictWriter(buf, fieldnames=self.log_columns, lineterminator="\n")
        w.writeheader()
        w.writerows(rows)
        atomic_write_text(path, buf.getvalue())

    def _append_log(self, row: dict) -> None:
        with open(self.run_dir / "log.csv", "a", newline="", encoding="utf-8") as fh:
            csv.DictWriter(fh, fieldnames=self.log_columns, lineterminator="\n").writerow(row)
            fh.flush()

    def plot_curves(self) -> None:
        """Write RUN/curves.png from log.csv (matplotlib Agg)."""
        if not self.info.is_main:
            return
        plot_log(self.run_dir / "log.csv", self.run_dir / "curves.png")

    def _reduce_window(self) -> dict[str, float]:
        """Mean of each logged term over the window's good steps, averaged over ranks when distributed."""
        cols = self.log_columns[5:]
        local = {k: float(np.mean(v)) for k, v in self._window.items()}
        if not self.info.distributed:
            return local
        import torch.distributed as dist

        vals = torch.tensor([local.get(c, 0.0) for c in cols] + [1.0 if local else 0.0], dtype=torch.float64,
                            device=self.device)
        dist.all_reduce(vals)
        count = vals[-1].item()
        if count == 0:
            return {}
        return {c: float(v) / count for c, v in zip(cols, vals[:-1].tolist()) if c in local}

    def _true_surface_points(self, batch: dict) -> torch.Tensor:
        """(B, SURFACE_POINTS, 3) points on each sample's true surface in its input view's frame
        (``supervision="3d"`` only); sampled once per shape (seeded by its id) and kept."""
        pts = []
        for cat, sid in zip(batch["category"], batch["shape_id"]):
            if (cat, sid) not in self._surface_cache:
                mesh = self.train_set.load_mesh(cat, sid)
                gen = torch.Generator().manual_seed(zlib.crc32(f"{cat}/{sid}".encode()))
                world = sample_mesh_points(torch.from_numpy(np.array(mesh.vertices, np.float32))[None],
                                           torch.from_numpy(np.array(mesh.faces, np.int64)), SURFACE_POINTS, gen)
                self._surface_cache[(cat, sid)] = world[0]
            pts.append(self._surface_cache[(cat, sid)])
        rot = batch["camera"][:, :9].reshape(-1, 3, 3).float().cpu()  # p_view = R p_world
        return (torch.stack(pts) @ rot.transpose(1, 2)).to(self.device)

    # ---- one step ----
    def _compute(self, batch: dict, it: int) -> tuple[list[torch.Tensor], dict[str, torch.Tensor], dict]:
        """Forward pass of a step: (losses to back-propagate, named detached terms, outputs)."""
        cfg = self.cfg
        backward: list[torch.Tensor] = []
        terms: dict[str, torch.Tensor] = {}
        out: dict = {}
        g_total = None
        fake = None
        if cfg.uses_generator:
            G = self.wrapped["generator"]
            sketch, real = batch["sketch"], batch["normals"]
            fake = G(sketch)
            out["fake"] = fake
            gen = torch.Generator().manual_seed(_step_seed(cfg.seed, self.info.rank, it) + 1)
            idx = sample_edge_pixels(real, cfg.sobel_samples, cfg.sobel_threshold, gen)
            g_global = global_l1_loss(fake, real)
            g_local = local_l1_loss(fake, real, idx)
            if cfg.lambda_adv > 0:  # weight 0: the discriminator is neither run nor trained (its terms log blank)
                D = self.wrapped["discriminator"]
                logits = D(torch.cat([sketch, sketch]), torch.cat([real, fake.detach()]))
                n = sketch.shape[0]
                d_loss = 0.5 * (adversarial_loss(logits[:n], True) + adversarial_loss(logits[n:], False))
                D_raw = _unwrap(D)
                D_raw.requires_grad_(False)
                try:
                    g_adv = adversarial_loss(D_raw(sketch, fake), True)
                finally:
                    D_raw.requires_grad_(True)
                g_total = cfg.lambda_adv * g_adv + cfg.lambda_g * g_global + cfg.lambda_l * g_local
                backward.append(d_loss)
                terms.update(d_loss=d_loss, g_adv=g_adv)
            else:
                g_total = cfg.lambda_g * g_global + cfg.lambda_l * g_local
            terms.update(g_global=g_global, g_local=g_local, g_total=g_total)
        if cfg.uses_predictor:
            P = self.wrapped["predictor"]
            if cfg.mode == "joint":
                inp = downsample_normals(fake, cfg.render_size)
            else:  # the generated image where the run reads one (input_normals), else the true one
                inp = batch.get("input64", batch["normals64"])
            other = batch.get("input64_counterpart") if cfg.mirror_consistency > 0 else None
            if other is None:
                local, glob = P(inp)
                verts = _unwrap(P).vertices(local, glob)
                mirror_term = None
            else:  # one forward pass over both, so batch norm sees one batch
                local, glob = P(torch.cat([inp, other.to(inp.dtype)]))
                both = _unwrap(P).vertices(local, glob)
                verts, verts_other = both[: inp.shape[0]], both[inp.shape[0]:]
                mirror_term = mirror_consistency(verts, verts_other, self._mirror_perm)
            if cfg.supervision == "3d" and bool(torch.isfinite(verts.detach()).all()):
                gen = torch.Generator().manual_seed(_step_seed(cfg.seed, self.info.rank, it) + 2)
                chamfer = chamfer_loss(sample_mesh_points(verts, self.faces, SURFACE_POINTS, gen),
                                       self._true_surface_points(batch).to(verts.dtype))
                reg_total, log = self.mesh_loss(verts)
                mesh_total = cfg.lambda_chamfer * chamfer + reg_total
                terms["mesh_chamfer"] = chamfer.detach()
                out.update(vertices=verts)
            elif bool(torch.isfinite(verts.detach()).all()):
                cams = view_frame_cameras(batch["camera"], batch["other_cameras"])
                rendered = render_views(verts, self.faces, cams.to(verts.dtype), cfg)
                tn, ts = mesh_targets(batch)
                mesh_total, log = self.mesh_loss(verts, rendered.normals, tn, rendered.silhouette, ts)
                out.update(vertices=verts, rendered=rendered)
            else:  # the rasterizer rejects NaN vertices: poison the step so the guard skips it
                mesh_total = verts.sum() * float("nan")
                log = {"predicted_vertices_nonfinite": float("nan")}
            if mirror_term is not None:
                mesh_total = mesh_total + cfg.mirror_consistency * mirror_term
                terms["mesh_mirror"] = mirror_term.detach()
            for k in ("normal", "silhouette", "edge", "smoothness"):
                terms[f"mesh_{k}"] = torch.tensor(log.get(k, float("nan") if "predicted_vertices_nonfinite" in log else 0.0))
            terms["mesh_total"] = mesh_total
            if g_total is not None:
                g_total = g_total + cfg.joint_mesh_weight * mesh_total
            else:
                g_total = mesh_total
        backward.append(g_total)
        if it in cfg.debug_nan_iters:  # debug hook: poison every loss of this step
            nan = torch.tensor(float("nan"), device=self.device)
            backward = [b * nan for b in backward]
            terms = {k: v * nan for k, v in terms.items()}
        return backward, {k: v.detach() for k, v in terms.items()}, out

    def train_step(self, batch: dict, it: int) -> tuple[bool, dict[str, float]]:
        """One guarded optimisation step. Returns (taken, logged terms)."""
        torch.manual_seed(_step_seed(self.cfg.seed, self.info.rank, it))
        if self.cfg.mirror > 0 and "camera" in batch:
            from training.data.mirror import mirror_batch

            gen = torch.Generator().manual_seed(_step_seed(self.cfg.seed, self.info.rank, it) + 3)
            flags = torch.rand(batch["camera"].shape[0], generator=gen) < self.cfg.mirror
            before = batch
            batch = mirror_batch(batch, flags.to(batch["camera"].device))
            if self.cfg.mirror_consistency > 0:
                batch = dict(batch, input64_counterpart=counterpart_inputs(before, batch, flags.to(batch["camera"].device)))
        buffers = {k: {n: b.detach().clone() for n, b in m.named_buffers()} for k, m in self.models.items()}
        for o in self.optimizers.values():
            o.zero_grad(set_to_none=True)
        backward, terms, _ = self._compute(batch, it)
        for loss in backward:
            loss.backward()
        problems = [f"loss {k} = {float(v)}" for k, v in terms.items() if not torch.isfinite(v).all()]
        norms = {}
        for name, model in self.models.items():
            grads = [p.grad for p in model.parameters() if p.grad is not None]
            if not grads:
                continue
            norm = torch.nn.utils.get_total_norm(grads)
            norms[name] = norm
            if not torch.isfinite(norm):
                bad = [n for n, p in model.named_parameters() if p.grad is not None and not torch.isfinite(p.grad).all()]
                problems.append(f"gradient of {name} non-finite in {bad[:5]}{' ...' if len(bad) > 5 else ''}")
        flag = torch.tensor([1.0 if problems else 0.0], device=self.device)
        if self.info.distributed:
            import torch.distributed as dist

            dist.all_reduce(flag, op=dist.ReduceOp.MAX)
        if flag.item() > 0:
            for k, m in self.models.items():  # undo BatchNorm statistics of the poisoned forward
                for n, b in m.named_buffers():
                    b.copy_(buffers[k][n])
            for o in self.optimizers.values():
                o.zero_grad(set_to_none=True)
            self.bad_streak += 1
            self._event(f"skipped non-finite step ({'; '.join(problems) or 'on another rank'}); "
                        f"{self.bad_streak} in a row")
            if self.bad_streak >= self.cfg.max_bad_steps:
                self._load_states(self.good_state["models"], self.good_state["optimizers"])
                self.bad_streak = 0
                self._event(f"{self.cfg.max_bad_steps} bad steps in a row: restored the last good state")
            return False, {k: float(v) for k, v in terms.items()}
        if self.cfg.grad_clip > 0:
            for name, model in self.models.items():
                if name in norms:
                    torch.nn.utils.clip_grads_with_norm_(
                        [p for p in model.parameters() if p.grad is not None], self.cfg.grad_clip, norms[name]
                    )
        self._set_learning_rates(it)
        for o in self.optimizers.values():
            o.step()
        self.bad_streak = 0
        return True, {k: float(v) for k, v in terms.items()}

    # ---- validation images ----
    @torch.no_grad()
    def validate(self) -> Path | None:
        """Write RUN/val/iter_XXXXX.png: sketch | GT normals | predicted normals | mesh (input view) | mesh (other view)."""
        if not self.info.is_main:
            return None
        data = self.val_set if self.val_set is not None else self.train_set
        n = min(VAL_ITEMS, len(data))
        full = getattr(data, "item", None)  # a mesh-mode train set serves only the step's fields: ask for all
        items = [full(i, "all") if full is not None else data[i] for i in range(n)]
        batch = _to_device(torch.utils.data.default_collate(items), self.device)
        for m in self.models.values():
            m.eval()
        try:
            image = validation_grid(self.models, batch, self.cfg, self.faces if self.cfg.uses_predictor else None)
        finally:
            self._train_modes()
        path = self.run_dir / "val" / f"iter_{self.iteration:05d}.png"
        write_png(path, image)
        return path

    # ---- the loop ----
    def run(self, max_minutes: float | None = None) -> dict[str, float]:
        """Train until ``cfg.iters``, or ``max_minutes`` (default ``cfg.max_minutes``) of this call; returns
        the last logged window's mean terms."""
        from tqdm import tqdm

        cfg = self.cfg if max_minutes is None else self.cfg.replace(max_minutes=max_minutes)
        if self.info.is_main:
            self.run_dir.mkdir(parents=True, exist_ok=True)
            self._prepare_log()
        self._train_modes()
        if self.iteration >= cfg.iters:
            self._event(f"nothing to do: the run is at iteration {self.iteration} >= --iters {cfg.iters}")
            return {}
        sampler = ResumableBatchSampler(len(self.train_set), cfg.batch, cfg.seed, self.iteration, self.info)
        loader = torch.utils.data.DataLoader(
            self.train_set, batch_sampler=sampler, num_workers=cfg.num_workers,
            generator=torch.Generator().manual_seed(cfg.seed), persistent_workers=False,
            pin_memory=self.device.type == "cuda",
        )
        bar = tqdm(total=cfg.iters, initial=self.iteration, disable=not self.progress, desc=f"train {cfg.mode}",
                   unit="it", dynamic_ncols=True)
        last = {}
        t_window, n_window, skipped = time.perf_counter(), 0, 0
        t_start = time.perf_counter()
        self._clock = (self.train_seconds, t_start)
        data_iter = iter(loader)
        try:
            deadline = t_start + 60.0 * cfg.max_minutes if cfg.max_minutes > 0 else float("inf")
            while self.iteration < cfg.iters:
                if time.perf_counter() >= deadline:
                    self._event(f"stopped at iteration {self.iteration}: --max-minutes {cfg.max_minutes:g} reached")
                    break
                batch = _to_device(next(data_iter), self.device)
                ok, terms = self.train_step(batch, self.iteration)
                self.iteration += 1
                n_window += 1
                skipped += 0 if ok else 1
                if ok:
                    for k, v in terms.items():
                        self._window.setdefault(k, []).append(v)
                if cfg.debug_sleep:
                    time.sleep(cfg.debug_sleep)
                bar.update(1)
                it = self.iteration
                if (cfg.log_every and it % cfg.log_every == 0) or it == cfg.iters:
                    dt = max(time.perf_counter() - t_window, 1e-9)
                    rate = n_window / dt
                    last = self._reduce_window()
                    row = {"iteration": it, "wall_s": f"{time.perf_counter() - t_start:.3f}",
                           "it_per_s": f"{rate:.4f}", "samples_per_s": f"{rate * cfg.batch * self.info.world_size:.3f}",
                           "skipped": skipped}
                    row.update({c: f"{last[c]:.6g}" if c in last else "" for c in self.log_columns[5:]})
                    if self.info.is_main:
                        self._append_log(row)
                    bar.set_postfix({k: f"{v:.3g}" for k, v in last.items() if k in ("d_loss", "g_total", "mesh_total")}
                                    | {"samples/s": f"{rate * cfg.batch * self.info.world_size:.2f}"})
                    self._window, t_window, n_window, skipped = {}, time.perf_counter(), 0, 0
                if cfg.ckpt_every and it % cfg.ckpt_every == 0 and it != cfg.iters:
                    self.save()
                if cfg.val_every and it % cfg.val_every == 0:
                    self.validate()
                if cfg.plot_every and it % cfg.plot_every == 0:
                    self.plot_curves()
            self.save()
            self.plot_curves()
        finally:
            self._clock = None  # train_seconds stays what the newest checkpoint holds
            bar.close()
            del data_iter
        return last


def _step_seed(seed: int, rank: int, it: int) -> int:
    return (int(seed) * 1_000_003 + int(rank) * 7_919 + int(it) * 104_729) % (2**63 - 1)


# ----------------------------------------------------------------------------------------------
# Images and plots
# ----------------------------------------------------------------------------------------------


def _tile(x: torch.Tensor, size: int) -> np.ndarray:
    """(C, H, W) in [0, 1] (C = 1 or 3) -> (size, size, 3) uint8 RGB, nearest-neighbour resized."""
    x = x.detach().float().cpu().clamp(0, 1)
    if x.shape[0] == 1:
        x = x.expand(3, -1, -1)
    x = F.interpolate(x[None], size=(size, size), mode="nearest")[0]
    return (x.permute(1, 2, 0).numpy() * 255.0 + 0.5).astype(np.uint8)


@torch.no_grad()
def validation_grid(models: dict[str, nn.Module], batch: dict, cfg: TrainConfig, faces: torch.Tensor | None,
                    tile: int = 128) -> np.ndarray:
    """Rows of: sketch (ink dark), GT normals, [predicted normals], [mesh from input view, mesh from another view].

    Returns:
        (rows * tile, cols * tile, 3) uint8 RGB.
    """
    n = batch["sketch"].shape[0]
    cols: list[list[np.ndarray]] = [[] for _ in range(n)]
    fake = models["generator"](batch["sketch"]) if "generator" in models else None
    rendered = None
    if "predictor" in models:
        inp = downsample_normals(fake, cfg.render_size) if (fake is not None and cfg.mode == "joint") else batch["normals64"]
        P = models["predictor"]
        verts = P.vertices(*P(inp))
        cams = view_frame_cameras(batch["camera"], batch["other_cameras"][:, :1])
        rendered = render_views(verts, faces, cams.to(verts.dtype), cfg)
    for i in range(n):
        cols[i].append(_tile(1.0 - batch["sketch"][i], tile))
        cols[i].append(_tile(batch["normals"][i], tile))
        if fake is not None:
            cols[i].append(_tile(fake[i], tile))
        if rendered is not None:
            nv = rendered.normals.shape[0] // n
            for v in range(nv):
                cols[i].append(_tile(rendered.normals[i * nv + v], tile))
    return np.concatenate([np.concatenate(c, axis=1) for c in cols], axis=0)


def write_png(path: str | Path, rgb: np.ndarray) -> None:
    """Write an (H, W, 3) uint8 RGB image as PNG atomically."""
    import cv2

    ok, buf = cv2.imencode(".png", np.ascontiguousarray(rgb[..., ::-1]))
    if not ok:
        raise OSError(f"PNG encoding failed for {path}")
    atomic_write_bytes(path, buf.tobytes())


def plot_log(csv_path: str | Path, png_path: str | Path) -> bool:
    """Plot every loss column of a log.csv against the iteration (PNG, atomic). False if no data.

    Columns whose values are all positive are drawn as log10(value) on a linear axis (cheap:
    matplotlib's log-axis tick labels go through mathtext, which costs seconds per figure).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(csv_path)
    if not path.exists():
        return False
    with open(path, newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    if not rows:
        return False
    cols = [c for c in rows[0] if c not in ("iteration", "wall_s", "it_per_s", "samples_per_s", "skipped")]
    its = np.array([float(r["iteration"]) for r in rows])
    ncols = 2
    nrows = (len(cols) + ncols - 1) // ncols
    fig, axes = plt.subplots(nrows, ncols, figsize=(9, 1.9 * nrows + 0.4), sharex=True, squeeze=False)
    for ax in axes.ravel()[len(cols):]:
        ax.set_visible(False)
    for ax, col in zip(axes.ravel(), cols):
        vals = np.array([float(r[col]) if r[col] not in ("", None) else np.nan for r in rows])
        finite = vals[np.isfinite(vals)]
        label = col
        if finite.size and np.all(finite > 0):
            vals, label = np.log10(vals), f"log10 {col}"
        ax.plot(its, vals, lw=1)
        ax.set_title(label, fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
    fig.subplots_adjust(left=0.08, right=0.98, top=0.93, bottom=0.08, hspace=0.45, wspace=0.2)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=80)
    plt.close(fig)
    atomic_write_bytes(png_path, buf.getvalue())
    return True


def train(cfg: TrainConfig, *, resume: bool = True, progress: bool = True) -> dict[str, float]:
    """Run (or resume) training; returns the final window's mean loss terms."""
    trainer = Trainer(cfg, resume=resume, progress=progress)
    try:
        return trainer.run()
    finally:
        if trainer.info.distributed:
            import torch.distributed as dist

            if dist.is_initialized():
                dist.barrier()
                dist.destroy_process_group()


__all__ = ["Trainer", "TrainingError", "build_models", "build_optimizers", "load_run", "train", "plot_log",
           "view_frame_cameras"]
