"""The one training configuration: a frozen dataclass, parsed once by the CLI, saved with every checkpoint.

Kept torch-free so the CLI can build and validate it before importing torch.
"""

from __future__ import annotations

import dataclasses
import json
import math
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

import engine

MODES = ("normals", "mesh", "joint")
DEVICES = ("auto", "cpu", "cuda")
GENERATOR_ARCHS = ("resize", "pix2pix")
"""``generator_arch`` values (the same as :data:`training.model.networks.GENERATOR_ARCHS`; kept here
so the config stays torch-free)."""
LEGACY_DEFAULTS = {"generator_arch": "pix2pix", "lr_schedule": "constant", "lr_final": 0.05, "edge_range": 1,
                   "silhouette": "eq1", "soft_sigma": 1e-4, "normal_edges": True}
"""Values for keys a saved config lacks because it predates them: what those runs were trained with
(the field's default for new runs may differ). Used by :meth:`TrainConfig.from_dict`."""
DEFAULT_BATCH = {"normals": 4, "mesh": 32, "joint": 4}
"""What ``batch = 0`` resolves to per mode."""


@dataclass(frozen=True)
class TrainConfig:
    """Every training setting. Defaults follow the paper (section 4.1) unless noted.

    The mesh predictor's defaults depart from the paper where measurements on a 2-core CPU chose
    otherwise (``sketchmesh bench overfit`` and ``sketchmesh bench variants``; the model card gives
    the figures): the compact predictor (offsets in a smooth Laplacian basis, a linear head), Adam
    2e-3 with a 100-step warm-up, batch 32, three extra known views per sample, and the normal term
    inside the target silhouette.

    Attributes:
        mode: "normals" (the cGAN sketch -> normal image), "mesh" (the predictor on ground-truth
            normals), or "joint" (generated normals feed the predictor; both fine-tuned end to end).
        data_dir: dataset root (``sketchmesh data --out``).
        out_dir: run folder (checkpoints, log.csv, curves, validation images).
        iters: total optimisation steps of the run (a resumed run continues to this count).
        max_minutes: also stop (with a checkpoint) after this much wall time of one invocation
            (0: no limit); what equal-time comparisons and ``bench overfit`` use.
        batch: per-process batch size; 0 (the default) resolves to the mode's own: 32 in mesh mode
            (the paper: 64), 4 in normals and joint mode.
        lr_g, lr_d: RMSProp learning rates of the generator and the discriminator (paper: 5e-5).
        lr_mesh, betas: Adam settings of the mesh predictor (paper: 1e-4, (0.9, 0.999); default 2e-3,
            which the compact predictor's linear head in a smooth basis takes without crumpling).
        lr_warmup: the predictor's learning rate rises linearly from 0 over this many first
            iterations (0: off); the generator's RMSProp rates stay constant.
        lr_schedule: the predictor's rate after the warm-up: "cosine" (the default: half a cosine
            from ``lr_mesh`` at step 0 down to ``lr_final * lr_mesh`` at step ``iters``; a run cut
            short by ``max_minutes`` should set ``iters`` to what fits in the time) or "constant".
        lr_final: the cosine schedule's final fraction of ``lr_mesh``.
        lambda_n, lambda_s, lambda_e, lambda_m: Eq. 6 weights (paper: 0.002, 0.9, 0.9, 0.01);
            ``lambda_n = 0`` trains the silhouette-only baseline.
        lambda_g, lambda_l: Eq. 10 weights of the global and local (Sobel-sampled) L1 terms.
        lambda_adv: weight of the adversarial term of the generator (1 in Eq. 10); 0 leaves the
            discriminator out of every step (neither run nor trained; ``d_loss`` and ``g_adv`` log blank).
        joint_mesh_weight: weight of the mesh loss on the generator in joint mode.
        freeze_predictor: joint mode only: hold the predictor fixed (eval mode, so its batch norms
            keep their running statistics and a small batch cannot disturb them; no optimiser) and
            fine-tune the generator alone to draw the normal images the predictor reads best.
        generator_dropout: the generator's dropout (pix2pix's noise) is on while it trains (True, the
            default); False trains it as it runs at inference, dropout off, e.g. for a fine-tune through
            the predictor, whose loss should judge the image the app will see.
        sobel_samples: pixels sampled per image for Eq. 9.
        sobel_threshold: Sobel magnitude above which a ground-truth pixel is an edge (a unit step gives 4).
        base_channels: generator / discriminator width (64 = paper; 32 or 16 for speed).
        generator_arch: "resize" (the default: reflect padding and nearest x2 up-sampling + 3x3
            conv in the decoder, no positional artefacts) or "pix2pix" (zero padding and transposed
            convolutions: the bundled models' generator, which draws a checkerboard and a dotted
            border column even on a blank sketch); see :class:`training.model.networks.NormalGenerator`.
            A saved config without this key (a run from before the option) loads as "pix2pix".
        predictor_arch: "compact" (the default: a CPU-sized encoder with its offsets in a smooth
            Laplacian basis; see :class:`training.model.networks.CompactMeshPredictor`) or "softras"
            (SoftRas's encoder-decoder, the paper's).
        predictor_channels, predictor_hidden, predictor_latent: mesh predictor widths (SoftRas: 64, 1024, 512;
            default 32, 512, 256).
        predictor_modes: size M of the compact predictor's offset basis (0: one mode per vertex).
        predictor_blocks: residual blocks after each strided convolution of the compact predictor's
            encoder (0: none). ``--init-mesh`` from a run with fewer deepens it as the same function.
        predictor_aligned: width of the compact predictor's aligned branch, which samples the encoder's
            feature maps where each vertex lands in the input view (0: none; see
            :class:`training.model.networks.CompactMeshPredictor`). ``--init-mesh`` from a run without it
            adds it as the same function.
        template_level: icosphere level (3 -> 642 vertices, the paper's).
        predictor_local_bound: "tanh" or "clamp" bound of the softras predictor's local offsets (see
            :class:`training.model.networks.MeshPredictor`; the compact predictor's head is linear).
        normal_region: "target" (the default: inside the ground-truth silhouette only; see
            :class:`training.model.losses.MeshLoss`) or "image" (Eq. 2 over the whole image, the paper's).
        support_band_weight: the silhouette term's pixels in the lowest quarter of each target
            silhouette's rows, where a standing shape's legs and the gaps between them are, weigh
            ``1 + support_band_weight`` (:func:`training.model.losses.support_band_weights`); 0 (the
            default): the paper's Eq. 3.
        predictor_smoothing: lambda of the predictor's smooth offsets ``(I + lambda L)^-1`` (0: off;
            see :class:`training.model.networks.MeshPredictor`).
        extra_views: K other known views rendered per sample for the mesh loss (default 3).
        supervision: "2d" (the method: the rendered normal images and silhouettes of Eq. 6) or "3d",
            a diagnostic ceiling only, never the paper's method: the same predictor trained on the
            Chamfer-L1 distance to points on the true surface (plus the edge and dihedral terms), which
            says whether a limit lies in the network or in the 2D signal. Mesh mode only.
        lambda_chamfer: weight of the Chamfer term with ``supervision="3d"``.
        input_normals: mesh mode: the predictor's input is, instead of the ground-truth normal image,
            the generator's normal image of the view's hand-drawn sketch, from the set of that name
            built by ``sketchmesh data generated`` (:mod:`training.data.generated`); what the app
            feeds it. The targets stay the true normal images and silhouettes. Several sets joined
            by commas (e.g. other augmentation seeds): every (view, set) pair is a training item.
            "" (default): off.
        input_share: with ``input_normals``, the share of training samples that read the generated
            image (the others read the true one), fixed per sample; in (0, 1], default 1.
        mirror: mesh mode: the share of training items mirrored at each step (drawn anew per step),
            the scene reflected in the input camera's vertical plane with every image and camera
            (:mod:`training.data.mirror`); in [0, 1], default 0 (off).
        mirror_inputs: with ``mirror`` and ``input_normals``: the mirrored generated sets
            (``sketchmesh data generated --mirror``), one per ``input_normals`` set, joined by
            commas; a mirrored item then reads the generator's image of its flipped drawing
            instead of its generated image flipped (which only approximates it); with ``input_share``
            below 1, an item that reads the true image reads it mirrored exactly (its silhouette as
            coverage). "" (default): off.
        mirror_consistency: with ``mirror``: weight of a term asking the predictor to answer an
            item's input and its mirror counterpart (the generator's image of the flipped drawing
            with ``mirror_inputs``, else the input mirrored) with the same mesh: the mean squared
            distance between the prediction and the counterpart's prediction mirrored back, vertex i
            against its reflection's vertex (:func:`engine.icosphere.mirror_average`); the app's
            mirror averaging learned into one pass. 2D only (no true shape is read). 0 (default): off.
        sketch_size: generator resolution (256). render_size: mesh-loss rendering resolution (64).
        delta: gradient strength of the rasterizer's approximate gradient (Eq. 1).
        edge_range: reach of that gradient along rows and columns in pixels: 1 (the default) uses
            adjacent pixel pairs; larger values add NMR-like farther events (see
            :mod:`training.render.rasterize`, "Far range").
        silhouette: "eq1" (the method: the rasterizer's silhouette with the Eq. 1 gradient) or
            "soft", SoftRas's soft silhouette (:mod:`training.render.soft`), an outside reference
            for the comparison, not the paper's method.
        soft_sigma: SoftRas's sharpness (NDC units squared) with ``silhouette="soft"``.
        normal_edges: the normal term's gradient includes the Eq. 1 edge gradient (True, the paper's);
            False (the default) lets it orient the surface only and leaves the outline to the silhouette
            term (:func:`training.render.rasterize`): the edge gradient pulls thin parts' outlines in
            against the silhouette term (the 13-shape overfit check: silhouette gap 0.080 and voxel IoU
            0.681 with it, 0.044 and 0.743 without; silhouette-only 0.050 and 0.682).
        shading: "flat" or "smooth" normals in the rendered normal image.
        grad_clip: max global gradient norm per model (0 disables clipping).
        max_bad_steps: consecutive non-finite steps after which the last good state is restored.
        seed: seed of the data order, sampling and initialisation.
        device: "auto" (CUDA when available, else CPU), "cpu" or "cuda".
        log_every, val_every, ckpt_every, plot_every: periods in iterations (0 disables).
        num_workers: DataLoader worker processes.
        augment_strength: sketch augmentation strength of the dataset.
        categories: restrict to these categories (empty = all).
        init_normals, init_mesh: runs whose last checkpoint initialises the generator / predictor.
            A compact predictor with a smaller ``predictor_latent`` / ``predictor_hidden`` than this
            config's is widened to it, computing the same function at the start
            (:meth:`training.model.networks.CompactMeshPredictor.load_widened`).
        debug_nan_iters: iterations at which a NaN is injected into every loss (tests of the guard).
        debug_sleep: seconds to sleep per iteration (tests that kill a run mid-way).
    """

    mode: str = "normals"
    data_dir: str = ""
    out_dir: str = ""
    iters: int = 20000
    max_minutes: float = 0.0
    batch: int = 0
    lr_g: float = 5e-5
    lr_d: float = 5e-5
    lr_mesh: float = 2e-3
    betas: tuple[float, float] = (0.9, 0.999)
    lr_warmup: int = 100
    lr_schedule: str = "cosine"
    lr_final: float = 0.05
    lambda_n: float = 0.002
    lambda_s: float = 0.9
    lambda_e: float = 0.9
    lambda_m: float = 0.01
    lambda_g: float = 100.0
    lambda_l: float = 100.0
    lambda_adv: float = 1.0
    joint_mesh_weight: float = 1.0
    freeze_predictor: bool = False
    generator_dropout: bool = True
    sobel_samples: int = 512
    sobel_threshold: float = 0.5
    base_channels: int = 64
    generator_arch: str = "resize"
    predictor_arch: str = "compact"
    predictor_channels: int = 32
    predictor_hidden: int = 512
    predictor_latent: int = 256
    predictor_modes: int = 0
    predictor_blocks: int = 0
    predictor_aligned: int = 0
    template_level: int = 3
    predictor_smoothing: float = 16.0
    predictor_local_bound: str = "tanh"
    normal_region: str = "target"
    support_band_weight: float = 0.0
    extra_views: int = 3
    supervision: str = "2d"
    lambda_chamfer: float = 10.0
    input_normals: str = ""
    input_share: float = 1.0
    mirror: float = 0.0
    mirror_inputs: str = ""
    mirror_consistency: float = 0.0
    sketch_size: int = 256
    render_size: int = 64
    delta: float = 1.0
    edge_range: int = 1
    silhouette: str = "eq1"
    soft_sigma: float = 1e-4
    normal_edges: bool = False
    shading: str = "flat"
    grad_clip: float = 10.0
    max_bad_steps: int = 5
    seed: int = 0
    device: str = "auto"
    log_every: int = 10
    val_every: int = 500
    ckpt_every: int = 500
    plot_every: int = 100
    num_workers: int = 0
    augment_strength: float = 0.5
    categories: tuple[str, ...] = field(default_factory=tuple)
    init_normals: str = ""
    init_mesh: str = ""
    debug_nan_iters: tuple[int, ...] = field(default_factory=tuple)
    debug_sleep: float = 0.0

    def __post_init__(self) -> None:
        problems = []
        if self.mode not in MODES:
            problems.append(f"mode must be one of {MODES}, got {self.mode!r}")
        if self.device not in DEVICES:
            problems.append(f"device must be one of {DEVICES}, got {self.device!r}")
        if self.predictor_local_bound not in ("tanh", "clamp", "clamp-after"):
            problems.append(f"predictor_local_bound must be 'tanh', 'clamp' or 'clamp-after', got {self.predictor_local_bound!r}")
        if self.generator_arch not in GENERATOR_ARCHS:
            problems.append(f"generator_arch must be 'resize' or 'pix2pix', got {self.generator_arch!r}")
        if self.predictor_arch not in ("softras", "compact"):
            problems.append(f"predictor_arch must be 'softras' or 'compact', got {self.predictor_arch!r}")
        if self.normal_region not in ("image", "target"):
            problems.append(f"normal_region must be 'image' or 'target', got {self.normal_region!r}")
        if not (math.isfinite(float(self.support_band_weight)) and float(self.support_band_weight) >= 0):
            problems.append(f"support_band_weight must be finite and >= 0, got {self.support_band_weight}")
        if self.supervision not in ("2d", "3d"):
            problems.append(f"supervision must be '2d' or '3d', got {self.supervision!r}")
        elif self.supervision == "3d" and self.mode != "mesh":
            problems.append(f"supervision '3d' (the diagnostic ceiling) is for mesh mode only, not {self.mode!r}")
        if self.input_normals and self.mode != "mesh":
            problems.append(f"input_normals (generated predictor inputs) is for mesh mode only, not {self.mode!r}")
        if not 0 <= float(self.mirror) <= 1:
            problems.append(f"mirror must be in [0, 1], got {self.mirror}")
        elif self.mirror and self.mode != "mesh":
            problems.append(f"mirror (mirrored training items) is for mesh mode only, not {self.mode!r}")
        elif self.mirror and self.supervision == "3d":
            problems.append("mirror does not apply to supervision '3d' (its targets are the unmirrored meshes)")
        if not (math.isfinite(float(self.mirror_consistency)) and float(self.mirror_consistency) >= 0):
            problems.append(f"mirror_consistency must be finite and >= 0, got {self.mirror_consistency}")
        elif self.mirror_consistency and not (self.mirror and self.mode == "mesh" and self.supervision == "2d"):
            problems.append("mirror_consistency needs mesh mode, mirror > 0 and supervision '2d'")
        if self.mirror_inputs and not (self.mirror and self.input_normals):
            problems.append("mirror_inputs (exact inputs of mirrored items) needs mirror > 0 and input_normals")
        if not 0 < float(self.input_share) <= 1:
            problems.append(f"input_share must be in (0, 1], got {self.input_share}")
        if self.silhouette not in ("eq1", "soft"):
            problems.append(f"silhouette must be 'eq1' or 'soft', got {self.silhouette!r}")
        if self.lr_schedule not in ("constant", "cosine"):
            problems.append(f"lr_schedule must be 'constant' or 'cosine', got {self.lr_schedule!r}")
        if not 0 <= float(self.lr_final) <= 1:
            problems.append(f"lr_final must be in [0, 1], got {self.lr_final}")
        if self.shading not in ("flat", "smooth"):
            problems.append(f"shading must be 'flat' or 'smooth', got {self.shading!r}")
        for name in ("iters", "edge_range", "base_channels", "predictor_channels", "predictor_hidden",
                     "predictor_latent", "sobel_samples", "max_bad_steps", "sketch_size", "render_size"):
            if int(getattr(self, name)) < 1:
                problems.append(f"{name} must be >= 1, got {getattr(self, name)}")
        for name in ("extra_views", "log_every", "val_every", "ckpt_every", "plot_every", "num_workers",
                     "template_level", "seed", "batch", "predictor_modes", "lr_warmup"):
            if int(getattr(self, name)) < 0:
                problems.append(f"{name} must be >= 0, got {getattr(self, name)}")
        if not 0 <= int(self.predictor_blocks) <= 4:
            problems.append(f"predictor_blocks must be in [0, 4], got {self.predictor_blocks}")
        elif self.predictor_blocks and self.predictor_arch != "compact":
            problems.append("predictor_blocks needs predictor_arch compact")
        if int(self.predictor_aligned) < 0:
            problems.append(f"predictor_aligned must be >= 0, got {self.predictor_aligned}")
        elif self.predictor_aligned and self.predictor_arch != "compact":
            problems.append("predictor_aligned needs predictor_arch compact")
        if not 0 <= self.template_level <= 5:
            problems.append(f"template_level must be in [0, 5], got {self.template_level}")
        for name in ("lr_g", "lr_d", "lr_mesh", "delta", "soft_sigma"):
            v = float(getattr(self, name))
            if not (v > 0 and v < float("inf")):
                problems.append(f"{name} must be finite and > 0, got {v}")
        for name in ("lambda_n", "lambda_s", "lambda_e", "lambda_m", "lambda_g", "lambda_l", "lambda_adv",
                     "joint_mesh_weight", "lambda_chamfer", "predictor_smoothing", "grad_clip", "augment_strength", "sobel_threshold", "debug_sleep",
                     "max_minutes"):
            v = float(getattr(self, name))
            if not (v >= 0 and v < float("inf")):
                problems.append(f"{name} must be finite and >= 0, got {v}")
        if len(self.betas) != 2 or not all(0 <= b < 1 for b in self.betas):
            problems.append(f"betas must be two numbers in [0, 1), got {self.betas}")
        if self.sketch_size % (2**8):
            problems.append(f"sketch_size must be a multiple of 256 (8 U-Net levels), got {self.sketch_size}")
        if self.sobel_samples > self.sketch_size**2:
            problems.append(f"sobel_samples must be <= sketch_size^2, got {self.sobel_samples}")
        if self.freeze_predictor and self.mode != "joint":
            problems.append(f"freeze_predictor needs mode joint (it fine-tunes the generator through a fixed "
                            f"predictor), got mode {self.mode!r}")
        if problems:
            raise ValueError("invalid training config: " + "; ".join(problems))
        if int(self.batch) == 0:
            object.__setattr__(self, "batch", DEFAULT_BATCH[self.mode])
        object.__setattr__(self, "betas", tuple(float(b) for b in self.betas))
        object.__setattr__(self, "categories", tuple(str(c) for c in self.categories))
        object.__setattr__(self, "debug_nan_iters", tuple(int(i) for i in self.debug_nan_iters))

    # ---- serialisation ----
    def to_dict(self) -> dict:
        d = dataclasses.asdict(self)
        d["betas"] = list(self.betas)
        d["categories"] = list(self.categories)
        d["debug_nan_iters"] = list(self.debug_nan_iters)
        return d

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2, sort_keys=True)

    @staticmethod
    def from_dict(d: dict) -> TrainConfig:
        """A config from a saved dict (``to_dict``). Unknown keys are an error; a missing key takes the
        dataclass default, except the :data:`LEGACY_DEFAULTS` (e.g. ``generator_arch`` "pix2pix")."""
        known = {f.name for f in dataclasses.fields(TrainConfig)}
        unknown = sorted(set(d) - known)
        if unknown:
            raise ValueError(f"unknown training config keys: {unknown}")
        # a saved config from before a field existed: that run used the legacy value, not today's default
        d = {**LEGACY_DEFAULTS, **d}
        for key in ("betas", "categories", "debug_nan_iters"):
            if key in d:
                d[key] = tuple(d[key])
        return TrainConfig(**d)

    @staticmethod
    def from_json(text: str) -> TrainConfig:
        return TrainConfig.from_dict(json.loads(text))

    def replace(self, **changes) -> TrainConfig:
        return dataclasses.replace(self, **changes)

    @property
    def uses_generator(self) -> bool:
        return self.mode in ("normals", "joint")

    @property
    def uses_predictor(self) -> bool:
        return self.mode in ("mesh", "joint")


def code_version() -> str:
    """``engine.__version__`` plus ``git describe --always --dirty`` of the source tree when available."""
    version = engine.__version__
    root = Path(__file__).resolve().parents[2]
    try:
        out = subprocess.run(
            ["git", "describe", "--always", "--dirty"], cwd=root, capture_output=True, text=True, timeout=5
        )
        if out.returncode == 0 and out.stdout.strip():
            version += "+" + out.stdout.strip()
    except (OSError, subprocess.SubprocessError):
        pass
    return version
