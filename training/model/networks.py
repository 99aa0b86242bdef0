"""The two networks of the paper and the generator's losses (paper sections 3.2, 3.3, 4.1).

* :class:`NormalGenerator` -- a pix2pix U-Net (by default with reflect padding and resize-conv
  up-sampling instead of zero padding and transposed convolutions): sketch (N, 1, 256, 256),
  1 = ink, to the encoded normal image (N, 3, 256, 256) in [0, 1] (``(n + 1) / 2``, background 0; :mod:`engine.camera`).
* :class:`PatchDiscriminator` -- the 70x70 PatchGAN conditioned on the sketch.
* :class:`MeshPredictor` -- the Neural Mesh Renderer / SoftRas encoder-decoder: normal image
  (N, 3, 64, 64) to a per-vertex local offset (N, V, 3) and a global offset (N, 3) of the
  icosphere template (:mod:`engine.icosphere`), so the mesh in the view frame is
  ``template + local + global[:, None]`` (:mod:`engine.contract`).

Pure functions for the generator objective (Eq. 7-10): :func:`adversarial_loss`,
:func:`global_l1_loss`, :func:`sobel_magnitude`, :func:`sample_edge_pixels`,
:func:`local_l1_loss`; and the batched camera helper :func:`view_frame_cameras` that renders a
view-frame prediction from the input view and the other known views.

Design choices (documented once here):

* Normalisation in the generator and discriminator is **InstanceNorm** (no affine, no running
  statistics): a batch-1 sketch at inference behaves exactly as in training, which BatchNorm does
  not guarantee; it exports to ONNX ``InstanceNormalization``. The innermost (1x1) encoder block
  has no normalisation (instance statistics of a single pixel are degenerate).
* The generator's output is ``sigmoid``: always inside [0, 1], the range of the encoded normals.
* Dropout 0.5 in the first three decoder blocks, as pix2pix (it is pix2pix's noise z); off in eval.
* The mesh predictor keeps SoftRas's BatchNorm encoder (train at batch >= 2; export in eval mode).
* The local offset is bounded: ``local_scale * tanh(.)`` (default 0.6, a bit more than the template
  radius 0.5, enough to reach any point of the normalised cube from the sphere), the global offset
  ``global_scale * tanh(.)`` (default 0.2: shapes are centred by normalisation, the global offset only
  corrects residual off-centring). The last layers start at small weights so training starts from
  (almost) the template sphere, which keeps early rendering losses stable.
* Adversarial loss: binary cross-entropy with logits (the standard cGAN objective of Eq. 7, in the
  non-saturating form for the generator).
"""

from __future__ import annotations

import math

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from engine.camera import DEFAULT_DISTANCE, FRAME_MARGIN
from engine.contract import PREDICTOR_INPUT_SIZE, SKETCH_SIZE
from engine.icosphere import TEMPLATE_RADIUS, icosphere
from engine.mesh import unique_edges

GENERATOR_LEVELS = 8
"""Down-sampling levels of the U-Net: 256 -> 1."""

LOCAL_OFFSET_SCALE = 0.6
GLOBAL_OFFSET_SCALE = 0.2
OUTPUT_INIT_STD = 1e-3
"""Std of the offset heads' initial weights: the first prediction is close to the template."""
LOCAL_BOUNDS = ("tanh", "clamp", "clamp-after")
"""How the local head's output is bounded: ``tanh`` (SoftRas) or ``clamp`` (identity within +-LOCAL_CLAMP)
on the raw output before the smoothing operator, or ``clamp-after``: the raw output is linear and
the *smoothed* offsets are clamped to +-LOCAL_CLAMP * local_scale."""
LOCAL_CLAMP = 2.0
"""With ``local_bound="clamp"``, raw local outputs are clamped to this (offsets to 2 x local_scale)."""
PREDICTOR_SMOOTHING = 16.0
"""Default ``lambda`` of the predictor's smooth offset parametrisation ``(I + lambda L)^-1``."""

SOBEL_EPS = 1e-12


def _check_image(x: torch.Tensor, channels: int, size: int | None, name: str) -> None:
    if not isinstance(x, torch.Tensor) or x.ndim != 4 or x.shape[1] != channels:
        got = tuple(x.shape) if isinstance(x, torch.Tensor) else type(x).__name__
        raise ValueError(f"{name} must be (N, {channels}, H, W), got {got}")
    if size is not None and (x.shape[2] != size or x.shape[3] != size):
        raise ValueError(f"{name} must be (N, {channels}, {size}, {size}), got {tuple(x.shape)}")


# ----------------------------------------------------------------------------------------------
# Generator: pix2pix U-Net
# ----------------------------------------------------------------------------------------------


def generator_channels(base_channels: int, levels: int = GENERATOR_LEVELS) -> list[int]:
    """Encoder output channels per level: base * (1, 2, 4, 8, 8, 8, ...)."""
    return [base_channels * min(2**i, 8) for i in range(levels)]


GENERATOR_ARCHS = ("resize", "pix2pix")
"""``resize`` (the default): reflect-padded encoder convolutions and a nearest-upsample + 3x3 conv
decoder, free of positional artefacts; ``pix2pix``: the original zero-padded encoder and
transposed-convolution decoder (the bundled models' generator)."""


class NormalGenerator(nn.Module):
    """pix2pix U-Net generator (Isola et al. 2017), 8 levels for 256x256 inputs.

    Encoder level i: Conv 4x4 stride 2 (+ InstanceNorm except at the first and innermost level),
    LeakyReLU 0.2 before every conv but the first. Decoder level i: ReLU, an x2 up-sampling layer,
    InstanceNorm (not at the outermost level), Dropout 0.5 at the three innermost decoder
    levels below the bottleneck; skip connections concatenate encoder and decoder features.

    Architectures (``arch``):

    * ``"pix2pix"``: the original layers, kept to reproduce the bundled models. Encoder convs
      zero-pad; the decoder's up-sampling layer is ConvTranspose 4x4 stride 2. Both are positional:
      zero padding makes the border pixels differ from the interior, and a stride-2 transposed
      convolution gives even and odd output pixels different kernel taps (Odena et al. 2016,
      "Deconvolution and checkerboard artifacts"). Even a blank sketch comes out with a
      checkerboard and a dotted column near the border.
    * ``"resize"`` (the default): encoder convs pad by reflection (``padding_mode="reflect"``: the
      2x2 -> 1x1 level pads 1 < 2, which reflection allows); the decoder's up-sampling layer is a
      nearest-neighbour x2 resize followed by a 3x3 stride-1 conv with reflect padding (Odena et
      al.'s resize-convolution). Every layer then maps a spatially constant input to a spatially
      constant output, so a constant sketch gives a spatially constant normal image, exactly in
      float32 (``tests/test_training_networks.py`` checks it). Nearest rather than bilinear: a
      bilinear resize of a constant map rounds differently at the border (``0.75 a + 0.25 a`` vs
      ``a``), and the decoder's InstanceNorm amplifies that rounding on near-constant maps by up to
      ``1 / sqrt(eps)`` per level (measured: a 2e-6 spread at 4x4 grows to about 1 at 256x256 on a
      blank sketch). The innermost decoder level up-samples the 1x1 code to a 2x2 map that is
      constant per channel: its conv is 1x1 (a 3x3 kernel on a constant map is a 1x1 kernel with
      the taps summed) with a bias and no InstanceNorm (which would zero a constant map and drop
      the bottleneck).

    Args:
        base_channels: channels of the first level (64 = the paper's width; 32, 16 for speed).
        levels: down-sampling levels; the input side must be divisible by ``2**levels``.
        dropout: decoder dropout probability (pix2pix: 0.5).
        arch: ``"resize"`` or ``"pix2pix"`` (:data:`GENERATOR_ARCHS`).
    """

    def __init__(self, base_channels: int = 64, levels: int = GENERATOR_LEVELS, dropout: float = 0.5,
                 arch: str = "resize") -> None:
        super().__init__()
        if base_channels < 1 or levels < 2:
            raise ValueError(f"need base_channels >= 1 and levels >= 2, got {base_channels}, {levels}")
        if arch not in GENERATOR_ARCHS:
            raise ValueError(f"generator arch must be one of {GENERATOR_ARCHS}, got {arch!r}")
        self.base_channels = int(base_channels)
        self.levels = int(levels)
        self.arch = arch
        pad_mode = "reflect" if arch == "resize" else "zeros"
        ch = generator_channels(base_channels, levels)
        self.down = nn.ModuleList()
        for i in range(levels):
            cin = 1 if i == 0 else ch[i - 1]
            layers: list[nn.Module] = [] if i == 0 else [nn.LeakyReLU(0.2)]
            layers.append(nn.Conv2d(cin, ch[i], 4, 2, 1, bias=(i == 0 or i == levels - 1), padding_mode=pad_mode))
            if 0 < i < levels - 1:
                layers.append(nn.InstanceNorm2d(ch[i]))
            self.down.append(nn.Sequential(*layers))
        self.up = nn.ModuleList()
        # up[j] produces the feature map at encoder level (levels - 2 - j), j = 0 innermost.
        for j in range(levels):
            i = levels - 1 - j  # input is at level i
            cin = ch[i] if j == 0 else 2 * ch[i]
            cout = 3 if i == 0 else ch[i - 1]
            norm = i > 0
            if arch == "pix2pix":
                layers = [nn.ReLU(), nn.ConvTranspose2d(cin, cout, 4, 2, 1, bias=(i == 0))]
            elif j == 0:  # the 1x1 code broadcast to 2x2: constant per channel, so a 1x1 conv and no norm
                norm = False
                layers = [nn.ReLU(), nn.Upsample(scale_factor=2, mode="nearest"),
                          nn.Conv2d(cin, cout, 1, bias=True)]
            else:
                layers = [nn.ReLU(), nn.Upsample(scale_factor=2, mode="nearest"),
                          nn.Conv2d(cin, cout, 3, 1, 1, bias=(i == 0), padding_mode="reflect")]
            if norm:
                layers.append(nn.InstanceNorm2d(cout))
            if i > 0 and 1 <= j <= 3 and dropout > 0:
                layers.append(nn.Dropout(dropout))
            self.up.append(nn.Sequential(*layers))

    def forward(self, sketch: torch.Tensor) -> torch.Tensor:
        """Sketch to normal image.

        Args:
            sketch: (N, 1, H, W) float in [0, 1], 1 = ink; H = W divisible by ``2**levels`` (256).

        Returns:
            (N, 3, H, W) encoded camera-space normals in [0, 1] (background ideally 0).
        """
        _check_image(sketch, 1, None, "sketch")
        if sketch.shape[2] != sketch.shape[3] or sketch.shape[2] % (2**self.levels):
            raise ValueError(f"sketch must be square with side divisible by {2 ** self.levels}, got {tuple(sketch.shape)}")
        skips = []
        x = sketch
        for block in self.down:
            x = block(x)
            skips.append(x)
        x = self.up[0](skips[-1])
        for j in range(1, self.levels):
            x = self.up[j](torch.cat([x, skips[self.levels - 1 - j]], dim=1))
        return torch.sigmoid(x)


class PatchDiscriminator(nn.Module):
    """70x70 PatchGAN conditioned on the sketch: logits per overlapping 70x70 patch.

    C(base, no norm)-C(2 base)-C(4 base), stride 2, then C(8 base) stride 1 and a 1-channel conv,
    all 4x4 with padding 1, LeakyReLU 0.2, InstanceNorm. A 256x256 input gives (N, 1, 30, 30).

    Args:
        base_channels: width of the first layer (64 in pix2pix).
    """

    def __init__(self, base_channels: int = 64, in_channels: int = 4) -> None:
        super().__init__()
        c = int(base_channels)
        self.net = nn.Sequential(
            nn.Conv2d(in_channels, c, 4, 2, 1), nn.LeakyReLU(0.2),
            nn.Conv2d(c, 2 * c, 4, 2, 1, bias=False), nn.InstanceNorm2d(2 * c), nn.LeakyReLU(0.2),
            nn.Conv2d(2 * c, 4 * c, 4, 2, 1, bias=False), nn.InstanceNorm2d(4 * c), nn.LeakyReLU(0.2),
            nn.Conv2d(4 * c, 8 * c, 4, 1, 1, bias=False), nn.InstanceNorm2d(8 * c), nn.LeakyReLU(0.2),
            nn.Conv2d(8 * c, 1, 4, 1, 1),
        )

    def forward(self, sketch: torch.Tensor, normals: torch.Tensor) -> torch.Tensor:
        """Args: sketch (N, 1, H, W), normals (N, 3, H, W). Returns logits (N, 1, H/8 - 2, W/8 - 2)."""
        _check_image(sketch, 1, None, "sketch")
        _check_image(normals, 3, sketch.shape[2], "normals")
        if normals.shape[0] != sketch.shape[0]:
            raise ValueError(f"sketch and normals batch differ: {sketch.shape[0]} vs {normals.shape[0]}")
        return self.net(torch.cat([sketch, normals], dim=1))


# ----------------------------------------------------------------------------------------------
# Mesh predictor: SoftRas / NMR encoder-decoder
# ----------------------------------------------------------------------------------------------


def smoothing_operator(faces: np.ndarray, num_vertices: int, lam: float) -> np.ndarray:
    """``(I + lam L)^-1`` (V, V) float32 for the combinatorial Laplacian ``L = D - A`` of ``faces``.

    ``I + lam L`` is a symmetric M-matrix, so its inverse is entrywise non-negative and, as
    ``L 1 = 0``, every row sums to 1: applied to offsets it is a convex averaging. ``lam = 0``
    gives the identity.
    """
    if lam == 0:
        return np.eye(num_vertices, dtype=np.float32)
    return np.linalg.inv(np.eye(num_vertices) + lam * combinatorial_laplacian(faces, num_vertices)).astype(np.float32)


def combinatorial_laplacian(faces: np.ndarray, num_vertices: int) -> np.ndarray:
    """(V, V) float64 ``L = D - A`` of the mesh's edge graph (dense: templates have at most a few thousand vertices)."""
    edges = unique_edges(np.asarray(faces))
    adj = np.zeros((num_vertices, num_vertices), dtype=np.float64)
    adj[edges[:, 0], edges[:, 1]] = 1.0
    adj[edges[:, 1], edges[:, 0]] = 1.0
    return np.diag(adj.sum(axis=1)) - adj


class _TemplateOffsets(nn.Module):
    """What both mesh predictors share: the icosphere template (non-persistent buffers, rebuilt
    from ``template_level``), the offset scales, and ``vertices = template + local + global``."""

    def _init_template(self, template_level: int, input_size: int, local_scale: float, global_scale: float,
                       smoothing: float):
        if not (math.isfinite(smoothing) and smoothing >= 0):
            raise ValueError(f"smoothing must be finite and >= 0, got {smoothing}")
        template = icosphere(template_level, TEMPLATE_RADIUS)
        self.template_level = int(template_level)
        self.num_vertices = template.num_vertices
        self.smoothing = float(smoothing)
        self.input_size = int(input_size)
        self.local_scale = float(local_scale)
        self.global_scale = float(global_scale)
        self.register_buffer("template_vertices", torch.from_numpy(np.array(template.vertices)), persistent=False)
        self.register_buffer("template_faces", torch.from_numpy(np.array(template.faces)), persistent=False)
        return template

    def vertices(self, local: torch.Tensor, glob: torch.Tensor) -> torch.Tensor:
        """(N, V, 3) view-frame vertices ``template + local + global``."""
        return self.template_vertices.to(local.dtype) + local + glob[:, None, :]


class MeshPredictor(_TemplateOffsets):
    """Normal image (N, 3, 64, 64) -> icosphere offsets (SoftRas reconstruction network).

    Encoder: three Conv 5x5 stride 2 (c, 2c, 4c; BatchNorm, ReLU) on 64x64, then FC to ``hidden``
    twice and to ``latent``. Decoder: FC ``hidden``, FC ``2 * hidden``, then two heads: per-vertex
    local offsets ``local_scale * tanh(.)`` (V * 3) and a global offset ``global_scale * tanh(.)`` (3).

    Head gain. The heads' input is multiplied by ``1 / sqrt(2 * hidden)``. Adam moves every weight
    by about ``lr`` per step, so without the gain a head's pre-activation moves by about
    ``lr * 2 * hidden * mean(h)`` per step: at lr 1e-4 and width 1024 the tanh saturates within
    ~100 steps (measured: every shape collapses to the same small diamond, where the saturated
    tanh passes no gradient back). With the gain the step is ``sqrt(2 * hidden)`` times smaller
    (the usual output multiplier for wide layers under Adam); the offsets start near zero anyway.

    Bound of the local offsets. ``local_bound="tanh"`` (SoftRas's choice, the default) saturates:
    in the trained predictor most pre-tanh outputs ended far outside the linear range, where no
    gradient passes. ``"clamp"`` keeps the head linear up to +-2 (offsets up to twice
    ``local_scale``) and only stops at the bound; ``"clamp-after"`` bounds the smoothed offsets
    instead, so the smoother cannot shrink the reachable deformations; the offsets stay finite
    either way.

    Smooth offsets. With Adam, every output weight moves by about ``lr`` per step whatever its
    gradient, so vertices that get almost no signal (interior of the silhouette) take steps as large
    as the boundary vertices and the sphere crumples within tens of steps at the paper's lr 1e-4
    (measured: dihedral term 0.045 -> 1063 in 10 steps). Following Nicolet et al. 2021 ("Large
    steps in inverse rendering"), the local head's output ``u`` is mapped to offsets
    ``(I + lambda L)^-1 u`` with ``L`` the template's combinatorial Laplacian: a fixed linear map
    (a constant V x V matrix in the exported graph) whose rows are non-negative and sum to 1, so the
    offsets stay within the head's bound and noisy per-vertex updates are averaged over a
    neighbourhood of about ``sqrt(lambda)`` rings. ``smoothing=0`` gives the plain parametrisation.

    Args:
        template_level: icosphere level of the template (3 -> 642 vertices, the paper's).
        base_channels: c (64 in SoftRas; FC 16c*8*8 -> hidden holds most parameters).
        hidden: FC width (1024 in SoftRas).
        latent: width of the code between encoder and decoder (512 in SoftRas).
        input_size: side of the input image (64).
    """

    def __init__(
        self,
        template_level: int = 3,
        base_channels: int = 64,
        hidden: int = 1024,
        latent: int = 512,
        input_size: int = PREDICTOR_INPUT_SIZE,
        local_scale: float = LOCAL_OFFSET_SCALE,
        global_scale: float = GLOBAL_OFFSET_SCALE,
        smoothing: float = PREDICTOR_SMOOTHING,
        local_bound: str = "tanh",
    ) -> None:
        super().__init__()
        if local_bound not in LOCAL_BOUNDS:
            raise ValueError(f"local_bound must be one of {LOCAL_BOUNDS}, got {local_bound!r}")
        self.local_bound = local_bound
        template = self._init_template(template_level, input_size, local_scale, global_scale, smoothing)
        self.register_buffer("offset_smoother", torch.from_numpy(
            smoothing_operator(np.asarray(template.faces), template.num_vertices, self.smoothing)), persistent=False)
        c = int(base_channels)
        self.encoder = nn.Sequential(
            nn.Conv2d(3, c, 5, 2, 2), nn.BatchNorm2d(c), nn.ReLU(),
            nn.Conv2d(c, 2 * c, 5, 2, 2), nn.BatchNorm2d(2 * c), nn.ReLU(),
            nn.Conv2d(2 * c, 4 * c, 5, 2, 2), nn.BatchNorm2d(4 * c), nn.ReLU(),
            nn.Flatten(),
            nn.Linear(4 * c * math.ceil(input_size / 8) ** 2, hidden), nn.ReLU(),
            nn.Linear(hidden, hidden), nn.ReLU(),
            nn.Linear(hidden, latent), nn.ReLU(),
        )
        self.decoder = nn.Sequential(nn.Linear(latent, hidden), nn.ReLU(), nn.Linear(hidden, 2 * hidden), nn.ReLU())
        self.head_gain = 1.0 / math.sqrt(2 * hidden)
        self.local_head = nn.Linear(2 * hidden, self.num_vertices * 3)
        self.global_head = nn.Linear(2 * hidden, 3)
        for head in (self.local_head, self.global_head):
            nn.init.normal_(head.weight, std=OUTPUT_INIT_STD)
            nn.init.zeros_(head.bias)

    def forward(self, normals: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Args: normals (N, 3, 64, 64) in [0, 1]. Returns local (N, V, 3), global (N, 3) (view frame)."""
        _check_image(normals, 3, self.input_size, "normals")
        h = self.decoder(self.encoder(normals)) * self.head_gain
        raw = self.local_head(h)
        if self.local_bound == "tanh":
            raw = torch.tanh(raw)
        elif self.local_bound == "clamp":  # linear inside +-LOCAL_CLAMP, so no gradient is lost until the bound
            raw = raw.clamp(-LOCAL_CLAMP, LOCAL_CLAMP)
        local = self.local_scale * raw.view(-1, self.num_vertices, 3)
        if self.smoothing > 0:
            local = torch.matmul(self.offset_smoother.to(local.dtype), local)
        if self.local_bound == "clamp-after":
            # the smoother shrinks most modes many times: bounding before it caps the shapes that can be
            # expressed (simple stretches reach 0.24 of the bound, the median mode 0.009)
            bound = LOCAL_CLAMP * self.local_scale
            local = local.clamp(-bound, bound)
        glob = self.global_scale * torch.tanh(self.global_head(h))
        return local, glob


PREDICTOR_ARCHS = ("softras", "compact")
"""``softras``: SoftRas's encoder-decoder (26 M parameters at its widths, a V x 3 output head);
``compact``: :class:`CompactMeshPredictor`, sized for a CPU (about 2 M parameters)."""


def laplacian_basis(faces: np.ndarray, num_vertices: int, modes: int, lam: float) -> np.ndarray:
    """(V, M) float32: the ``M`` smoothest eigenvectors of the template's combinatorial Laplacian.

    Column ``k`` is the unit eigenvector ``phi_k`` of ``L = D - A`` (eigenvalue ``mu_k``, ascending)
    times ``sqrt(V) / (1 + lam * mu_k)``. So offsets ``B c`` with ``M = V`` are exactly
    ``(I + lam L)^-1 (sqrt(V) Phi c)``, the large-steps parametrisation of :func:`smoothing_operator`
    in the eigenbasis; ``M < V`` keeps only its smoothest modes. The ``sqrt(V)`` makes a unit
    coefficient of the constant mode a unit offset of every vertex. Signs are fixed so that each
    column's largest-magnitude entry is positive (the eigensolver's sign is arbitrary).
    """
    if not 1 <= modes <= num_vertices:
        raise ValueError(f"modes must be in [1, {num_vertices}], got {modes}")
    if not (math.isfinite(lam) and lam >= 0):
        raise ValueError(f"lam must be finite and >= 0, got {lam}")
    mu, phi = np.linalg.eigh(combinatorial_laplacian(faces, num_vertices))
    mu, phi = np.clip(mu[:modes], 0.0, None), phi[:, :modes]
    idx = np.abs(phi).argmax(axis=0)
    phi = phi * np.sign(phi[idx, np.arange(modes)])[None, :]
    return (phi * (math.sqrt(num_vertices) / (1.0 + lam * mu))[None, :]).astype(np.float32)


MAX_ENCODER_BLOCKS = 4
"""Most residual blocks per encoder stage of :class:`CompactMeshPredictor`."""

ALIGNED_STAGES = 3
"""Encoder stages whose feature maps (32, 16 and 8 px) the aligned branch samples at each vertex."""


def sample_bilinear(maps: torch.Tensor, grid: torch.Tensor) -> torch.Tensor:
    """(N, V, C) ``maps`` (N, C, H, W) sampled at ``grid`` (N, V, 2): ``F.grid_sample`` with ``mode="bilinear"``,
    ``padding_mode="border"``, ``align_corners=False``, written as four row gathers.

    Why not ``grid_sample`` itself: ONNX Runtime's CPU GridSample takes about 0.9 ms to sample 642 points of a
    128-channel map (ORT's profiler), half of the whole predictor's time, where gathering the four neighbouring
    pixels' channel rows (one ``Gather`` each) costs a few microseconds; the result is the same (tested against
    ``grid_sample``). The grid's x runs right and y down over [-1, 1] (pixel edges); coordinates outside are held
    at the border pixels' centres, as the border mode holds them. The gradient reaches ``maps``, not ``grid``.
    """
    n, c, h, w = maps.shape
    x = ((grid[..., 0] + 1.0) * w - 1.0) / 2.0  # pixel coordinates, 0 at the first pixel's centre
    y = ((grid[..., 1] + 1.0) * h - 1.0) / 2.0
    x, y = x.clamp(0.0, w - 1.0).detach(), y.clamp(0.0, h - 1.0).detach()
    x0, y0 = x.floor(), y.floor()
    fx, fy = (x - x0).unsqueeze(-1), (y - y0).unsqueeze(-1)
    x0, y0 = x0.long(), y0.long()
    x1, y1 = (x0 + 1).clamp(max=w - 1), (y0 + 1).clamp(max=h - 1)  # on the last pixel fx (fy) is 0: x1 = x0 is weightless
    rows = maps.permute(0, 2, 3, 1).reshape(n * h * w, c)
    base = (torch.arange(n, device=maps.device) * (h * w)).view(n, 1)

    def tap(yy: torch.Tensor, xx: torch.Tensor) -> torch.Tensor:
        return rows[(base + yy * w + xx).reshape(-1)].view(n, -1, c)

    return ((tap(y0, x0) * (1 - fx) + tap(y0, x1) * fx) * (1 - fy)
            + (tap(y1, x0) * (1 - fx) + tap(y1, x1) * fx) * fy)


def _traced() -> bool:
    """True while torch traces the module (ONNX export, ``torch.jit.trace``): the graph written must be the one
    ONNX Runtime runs fastest, not the one torch trains fastest."""
    return torch.jit.is_tracing() or torch.onnx.is_in_onnx_export()


def sample_channels(maps: torch.Tensor, grid: torch.Tensor) -> torch.Tensor:
    """(N, C, V): :func:`sample_bilinear`'s samples, channel-major, as torch computes them fastest.

    ``F.grid_sample`` itself, whose fused CPU kernels take 2-3 times less than :func:`sample_bilinear`'s gathers and
    their ``index_put`` backward in a training step (the larger predictor's aligned branch at batch 64: its three
    samplings about 280 -> 120 ms a step), in the layout it writes. The same values and gradients (tested); as
    there, the gradient reaches ``maps``, not ``grid``. The ONNX trace uses the gathers (ONNX Runtime's GridSample
    is slow).
    """
    return F.grid_sample(maps, grid.detach()[:, :, None, :], mode="bilinear", padding_mode="border",
                         align_corners=False).squeeze(-1)  # squeeze, not [..., 0]: its backward is a view, not a fill


def basis_times(basis: torch.Tensor, coeff: torch.Tensor) -> torch.Tensor:
    """``basis @ coeff`` for a (V, M) basis and (N, M, 3) coefficients: (N, V, 3).

    ``torch.matmul`` broadcasts the basis into a batched product over N copies of it (a (N, V, M) operand, 105 MB
    at batch 64 for the 642-vertex template); in torch this is one (V, M) x (M, 3N) product instead. Traced for
    ONNX it stays ``MatMul`` with broadcasting, which ONNX Runtime runs without copying.
    """
    if _traced() or coeff.ndim != 3:
        return torch.matmul(basis, coeff)
    n, m, k = coeff.shape
    out = basis @ coeff.permute(1, 0, 2).reshape(m, n * k)  # (V, N * 3)
    return out.reshape(basis.shape[0], n, k).permute(1, 0, 2)


def framed_ndc(view_vertices: torch.Tensor, distance: float = DEFAULT_DISTANCE,
               margin: float = FRAME_MARGIN) -> torch.Tensor:
    """(N, V, 2) NDC (+u right, +v up) of view-frame vertices in the input view, framed by their own outline.

    The input view looks down -z from ``distance`` (the dataset's and the engine's view frame), and its image is
    framed like an engine sketch (:func:`engine.camera.frame_camera`): the projected bounding box centred, its
    longer side spanning ``1 - 2 margin`` of the image. Framing the mesh by its own outline makes its projection
    independent of the focal length and of where the drawing sat on the page, so a network can compute it
    without a camera. Points at or behind the camera are held at a small positive depth (finite values).
    """
    if view_vertices.ndim != 3 or view_vertices.shape[-1] != 3:
        raise ValueError(f"view_vertices must be (N, V, 3), got {tuple(view_vertices.shape)}")
    depth = (distance - view_vertices[..., 2:3]).clamp_min(1e-3)
    uv = view_vertices[..., :2] / depth
    lo, hi = uv.amin(dim=1, keepdim=True), uv.amax(dim=1, keepdim=True)
    extent = (hi - lo).amax(dim=-1, keepdim=True).clamp_min(1e-6)
    return (uv - (lo + hi) / 2.0) * (2.0 * (1.0 - 2.0 * margin) / extent)


class _ResidualBlock(nn.Module):
    """``x + alpha conv(ReLU(BN(conv(x))))`` with 3x3 convolutions and a scalar ``alpha`` that starts at 0 (ReZero,
    Bachlechner et al. 2020): a new block is the identity.

    Why a gate and not a zero-initialised last convolution: Adam moves every weight by about the
    learning rate at each step whatever its gradient, so a zero convolution with a fan-in of
    9 x 256 moved the features by O(2,304 x lr) per step, and a trained predictor deepened that way
    lost in 100 steps what it had learned (measured: its silhouette loss 0.29 -> 0.44). Adam moves
    the one gate by about lr per step instead, so the new path fades in.
    """

    def __init__(self, channels: int) -> None:
        super().__init__()
        self.body = nn.Sequential(
            nn.Conv2d(channels, channels, 3, 1, 1, bias=False), nn.BatchNorm2d(channels), nn.ReLU(),
            nn.Conv2d(channels, channels, 3, 1, 1),
        )
        self.gain = nn.Parameter(torch.zeros(()))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return x + self.gain * self.body(x)


class CompactMeshPredictor(_TemplateOffsets):
    """Normal image (N, 3, 64, 64) -> icosphere offsets, sized for a laptop CPU (``arch="compact"``).

    Same inputs, outputs and ONNX contract as :class:`MeshPredictor`; about 2 M parameters instead
    of 26 M, so a training step costs little beside the rasterizer.

    Encoder: four Conv 4x4 stride 2 (c, 2c, 4c, 8c; BatchNorm, ReLU) take 64x64 to 4x4, then one FC
    to ``latent`` (8c * 16 inputs: 4,096 at c = 32 against SoftRas's 16,384). Decoder: FC ``hidden``,
    then two heads: ``M`` x 3 coefficients of the smooth basis :func:`laplacian_basis` and the
    global offset ``global_scale * tanh(.)`` (3).

    Local offsets are ``local_scale * B c``: a linear head (nothing saturates) in a basis whose
    smooth modes take the largest steps (Nicolet et al.'s large steps, in closed form), so the
    output cannot crumple however Adam moves the head's weights; ``M`` below V drops the roughest
    modes and shrinks the head. The offsets are then clamped to ``+-LOCAL_CLAMP * local_scale``
    per coordinate (as ``local_bound="clamp-after"``), so any output stays finite and in the cube.

    Head gain: the heads' input is multiplied by ``1 / sqrt(hidden)`` (see :class:`MeshPredictor`).

    Args:
        template_level: icosphere level (3 -> 642 vertices).
        base_channels: c.
        hidden: decoder FC width.
        latent: code width.
        modes: M, basis size (0 = every vertex, V).
        smoothing: lambda of the basis's spectral damping ``1 / (1 + lambda mu)``.
        input_size: side of the input image (64; must be a multiple of 16).
        blocks: residual blocks (two 3x3 convolutions each) after each of the four strided
            convolutions, at 32, 16, 8 and 4 pixels: a deeper encoder. A block starts as the identity
            (its output is gated by a scalar that starts at 0), so :meth:`load_grown` can deepen a
            trained predictor.
        aligned: width of the aligned branch's per-vertex layer (0: no branch). The branch reads the image
            where each vertex lands (Pixel2Mesh's perceptual pooling): the mesh the heads predict is projected
            into the input view, framed by its own outline (:func:`framed_ndc`), the encoder's first three
            feature maps are sampled there (bilinear), and a two-layer perceptron shared by all vertices turns
            those features and the vertex's position into a residual offset. Its last layer starts at zero, so
            :meth:`load_grown` adds the branch to a trained predictor as the same function, and that layer
            learns from the first step (a scalar gate starting at 0 would let Adam open the branch by only
            about the learning rate per step). The global decoder reads where the drawing's parts are only
            through its code; the branch sees them at each vertex.
    """

    def __init__(
        self,
        template_level: int = 3,
        base_channels: int = 32,
        hidden: int = 512,
        latent: int = 256,
        modes: int = 0,
        smoothing: float = PREDICTOR_SMOOTHING,
        input_size: int = PREDICTOR_INPUT_SIZE,
        local_scale: float = LOCAL_OFFSET_SCALE,
        global_scale: float = GLOBAL_OFFSET_SCALE,
        blocks: int = 0,
        aligned: int = 0,
    ) -> None:
        super().__init__()
        if int(aligned) < 0:
            raise ValueError(f"aligned must be >= 0, got {aligned}")
        if not 0 <= int(blocks) <= MAX_ENCODER_BLOCKS:
            raise ValueError(f"blocks must be in [0, {MAX_ENCODER_BLOCKS}], got {blocks}")
        if input_size % 16:
            raise ValueError(f"input_size must be a multiple of 16, got {input_size}")
        template = self._init_template(template_level, input_size, local_scale, global_scale, smoothing)
        self.modes = int(modes) if modes else self.num_vertices
        if not 1 <= self.modes <= self.num_vertices:
            raise ValueError(f"modes must be in [0, {self.num_vertices}] (0 = all), got {modes}")
        self.local_bound = "clamp-after"
        # Persistent: the weights are only meaningful in the basis they were trained with, and that basis
        # is not portable. The icosphere's Laplacian has repeated eigenvalues (its symmetry), and inside a
        # repeated eigenvalue's eigenspace LAPACK returns any orthonormal basis: a different one on
        # another processor, or with another BLAS thread count on the same one (measured: the basis of a
        # GPU machine's 16-thread run differs from its 1-thread one). So the basis travels with the
        # weights, in the state dict and checkpoints; see _load_from_state_dict for older checkpoints.
        self.register_buffer("basis", torch.from_numpy(
            laplacian_basis(np.asarray(template.faces), self.num_vertices, self.modes, self.smoothing)))
        c = int(base_channels)
        layers: list[nn.Module] = []
        for cin, cout in ((3, c), (c, 2 * c), (2 * c, 4 * c), (4 * c, 8 * c)):
            layers += [nn.Conv2d(cin, cout, 4, 2, 1, bias=False), nn.BatchNorm2d(cout), nn.ReLU()]
        side = input_size // 16
        self.encoder = nn.Sequential(*layers, nn.Flatten(), nn.Linear(8 * c * side * side, latent), nn.ReLU())
        self.num_blocks = int(blocks)
        self.blocks = nn.ModuleList(
            [nn.Sequential(*[_ResidualBlock(ch) for _ in range(self.num_blocks)]) for ch in (c, 2 * c, 4 * c, 8 * c)]
        ) if self.num_blocks else None
        self.decoder = nn.Sequential(nn.Linear(latent, hidden), nn.ReLU())
        self.head_gain = 1.0 / math.sqrt(hidden)
        self.local_head = nn.Linear(hidden, self.modes * 3)
        self.global_head = nn.Linear(hidden, 3)
        for head in (self.local_head, self.global_head):
            nn.init.normal_(head.weight, std=OUTPUT_INIT_STD)
            nn.init.zeros_(head.bias)
        self.aligned = int(aligned)
        if self.aligned:
            features = sum(c * 2 ** k for k in range(ALIGNED_STAGES)) + 3
            self.aligned_mlp = nn.Sequential(nn.Linear(features, self.aligned), nn.ReLU(), nn.Linear(self.aligned, 3))
            nn.init.zeros_(self.aligned_mlp[2].weight)
            nn.init.zeros_(self.aligned_mlp[2].bias)

    def _load_from_state_dict(self, state_dict, prefix, local_metadata, strict, missing_keys, unexpected_keys,
                              error_msgs) -> None:
        # Checkpoints written before the basis was stored (the second bundled models' runs, for one) lack
        # it: they keep the basis computed here, which is the one they were trained with only on the
        # machine (and BLAS thread count) that trained them.
        if prefix + "basis" not in state_dict:
            state_dict[prefix + "basis"] = self.basis
        super()._load_from_state_dict(state_dict, prefix, local_metadata, strict, missing_keys, unexpected_keys,
                                      error_msgs)

    @torch.no_grad()
    def load_widened(self, state_dict: dict) -> tuple[int, int]:
        """Load a compact predictor with a narrower code and decoder so this one computes the same function.

        Net2Net-style growth (Chen et al. 2016) of the two fully connected layers, so a trained predictor
        can go on training with more capacity without starting again: the old weights fill the top-left
        blocks; a new code unit feeds no old hidden unit (zero columns) and a new hidden unit feeds no
        output (zero head columns), while their incoming weights keep this module's fresh initialisation.
        The zero blocks get a gradient at the first step (the units they connect are active), the new
        code units' incoming weights from the second, once those blocks moved. The heads' weights are
        rescaled by ``sqrt(hidden / old_hidden)`` to undo the change of ``head_gain``. The encoder's convolutions,
        BatchNorm statistics, basis and the heads' output sizes must match.

        Returns:
            (old latent, old hidden).

        Raises:
            ValueError: a tensor other than the widened ones differs in shape, or an old width is larger.
        """
        fc = f"encoder.{len(self.encoder) - 2}"  # the encoder's Linear (before its ReLU)
        for k in (f"{fc}.weight", "decoder.0.weight"):
            if k not in state_dict:
                raise ValueError(f"cannot widen: the weights have no {k} (not a compact predictor)")
        old_latent, old_hidden = state_dict[f"{fc}.weight"].shape[0], state_dict["decoder.0.weight"].shape[0]
        latent, hidden = self.decoder[0].in_features, self.decoder[0].out_features
        if old_latent > latent or old_hidden > hidden:
            raise ValueError(f"cannot widen latent {old_latent} -> {latent}, hidden {old_hidden} -> {hidden}: "
                             "the new widths must be at least the old")
        own = self.state_dict()
        grown = {f"{fc}.weight", f"{fc}.bias", "decoder.0.weight", "decoder.0.bias", "local_head.weight",
                 "global_head.weight"}
        bad = sorted(k for k in own if k not in grown and (k not in state_dict or state_dict[k].shape != own[k].shape))
        bad += sorted(k for k in state_dict if k not in own)
        bad += sorted(k for k in ("local_head.weight", "global_head.weight")
                      if state_dict[k].shape != (own[k].shape[0], old_hidden))
        if bad:
            raise ValueError(f"cannot widen: {', '.join(bad[:4])} differ(s) in shape or presence")
        merged = {k: (v if k in grown else state_dict[k]).clone() for k, v in own.items()}
        merged[f"{fc}.weight"][:old_latent] = state_dict[f"{fc}.weight"]
        merged[f"{fc}.bias"][:old_latent] = state_dict[f"{fc}.bias"]
        merged["decoder.0.weight"][:old_hidden, :old_latent] = state_dict["decoder.0.weight"]
        merged["decoder.0.weight"][:old_hidden, old_latent:] = 0.0
        merged["decoder.0.bias"][:old_hidden] = state_dict["decoder.0.bias"]
        gain = math.sqrt(hidden / old_hidden)  # head_gain went from 1/sqrt(old_hidden) to 1/sqrt(hidden)
        for head in ("local_head", "global_head"):
            w = merged[f"{head}.weight"]
            w[:, :old_hidden] = state_dict[f"{head}.weight"] * gain
            w[:, old_hidden:] = 0.0
        self.load_state_dict(merged)
        return int(old_latent), int(old_hidden)

    @torch.no_grad()
    def resmoothed_state(self, state_dict: dict, old_smoothing: float) -> dict:
        """The weights of a compact predictor trained with basis damping ``old_smoothing``, converted so that this
        one, damped by ``self.smoothing``, computes the same function with them (load them as usual, e.g. with
        :meth:`load_grown`, which may also widen them).

        Mode ``k`` of the stored basis is ``sqrt(V) phi_k / (1 + old mu_k)``; its eigenvalue ``mu_k`` is read
        back from the column itself (Rayleigh quotient with the template's Laplacian, exact for an eigenvector
        whatever rotation LAPACK chose inside a repeated eigenvalue's eigenspace), the column is rescaled to
        ``sqrt(V) phi_k / (1 + new mu_k)`` and the head's three coefficient rows of mode ``k`` (weights and
        bias) by the inverse ratio. The function is unchanged; what changes is how far a step of the head's
        weights moves each mode: a smaller damping lets the rougher modes (thin parts, sharp edges) move
        further per step.

        Raises:
            ValueError: ``old_smoothing`` is not finite and >= 0, the weights are not a compact predictor's
                with this one's modes, or a stored column is not an eigenvector of the template's Laplacian.
        """
        if not (math.isfinite(old_smoothing) and old_smoothing >= 0):
            raise ValueError(f"old smoothing must be finite and >= 0, got {old_smoothing}")
        basis = state_dict.get("basis")
        if basis is None or tuple(basis.shape) != tuple(self.basis.shape):
            have = None if basis is None else tuple(basis.shape)
            raise ValueError(f"cannot re-smooth: the weights' basis is {have}, this predictor's {tuple(self.basis.shape)}")
        b = basis.double()
        lap = torch.from_numpy(combinatorial_laplacian(self.template_faces.numpy(), self.num_vertices))
        norms = b.norm(dim=0)
        if not bool(torch.all(norms > 0)):
            raise ValueError("cannot re-smooth: the weights' basis has a zero column")
        phi = b / norms
        mu = (phi * (lap @ phi)).sum(dim=0).clamp_min(0.0)
        resid = (lap @ phi - phi * mu).norm(dim=0).max().item()
        if resid > 1e-3 * (1.0 + mu.max().item()):
            raise ValueError(f"cannot re-smooth: the weights' basis columns are not Laplacian eigenvectors "
                             f"(residual {resid:.2e})")
        ratio = (1.0 + old_smoothing * mu) / (1.0 + self.smoothing * mu)  # new gain / old gain, per mode
        merged = dict(state_dict)
        merged["basis"] = (b * ratio).to(basis.dtype)
        rows = (1.0 / ratio).repeat_interleave(3)  # head rows are (mode, xyz) in that order (forward's view)
        merged["local_head.weight"] = (state_dict["local_head.weight"].double() * rows[:, None]).to(basis.dtype)
        merged["local_head.bias"] = (state_dict["local_head.bias"].double() * rows).to(basis.dtype)
        return merged

    @torch.no_grad()
    def load_grown(self, state_dict: dict) -> tuple[int, int] | None:
        """Load a compact predictor with fewer encoder blocks and/or narrower FC layers as the same function.

        Missing residual blocks keep their identity initialisation (:class:`_ResidualBlock`); narrower
        fully connected layers are widened (:meth:`load_widened`). Returns the old (latent, hidden)
        when widened, else None.

        Raises:
            ValueError: the weights have blocks this predictor lacks, or do not fit otherwise.
        """
        own = self.state_dict()
        extra = sorted(k for k in state_dict if k.startswith("blocks.") and k not in own)
        if extra:
            raise ValueError(f"cannot load: the weights have encoder blocks this predictor lacks ({extra[0]})")
        extra = sorted(k for k in state_dict if k.startswith("aligned_") and k not in own)
        if extra:
            raise ValueError(f"cannot load: the weights have an aligned branch this predictor lacks ({extra[0]})")
        merged = dict(state_dict)
        merged.update({k: v for k, v in own.items()
                       if k.startswith(("blocks.", "aligned_")) and k not in state_dict})
        try:
            self.load_state_dict(merged)
            return None
        except RuntimeError:
            return self.load_widened(merged)

    def _encode_maps(self, normals: torch.Tensor) -> tuple[torch.Tensor, list[torch.Tensor]]:
        """The code (N, latent) and the four stages' feature maps (each after its residual blocks).

        In torch the image enters in channels-last memory order, in which oneDNN's convolutions run a training
        step's encoder about a fifth faster on this CPU (330 against 410 ms forward and backward at batch 64,
        ``/proc/cpuinfo`` AVX2); the values are the same, only their order in memory differs. Traced for ONNX the
        graph is unchanged.
        """
        x, maps = (normals if _traced() else normals.contiguous(memory_format=torch.channels_last)), []
        for stage in range(4):
            x = self.encoder[3 * stage:3 * stage + 3](x)
            if self.blocks is not None:
                x = self.blocks[stage](x)
            maps.append(x)
        return self.encoder[12:](x), maps

    def encode(self, normals: torch.Tensor) -> torch.Tensor:
        """The code (N, latent): the four strided stages (each followed by its residual blocks), then the FC layer."""
        return self._encode_maps(normals)[0]

    def _aligned_offsets(self, vertices: torch.Tensor, maps: list[torch.Tensor]) -> torch.Tensor:
        """(N, V, 3) the aligned branch's residual offsets for view-frame ``vertices`` (class doc).

        The perceptron's first layer reads the concatenation [map 1, map 2, map 3 sampled at the vertex; the vertex];
        it is computed as the sum of its blocks, each map's block applied where it costs least. Bilinear sampling
        is linear in the map, so a block applied to the sampled features equals the block applied to every pixel
        (a 1x1 convolution) and then sampled: a map with fewer pixels than the mesh has vertices (16 and 8 px
        against 642) is projected first, a larger one (32 px) sampled first. The same function as the layer on
        the concatenated features, at a third of its multiply-adds (12 M against 37 M per mesh for today's
        predictor); it is what export traces.
        """
        uv = framed_ndc(vertices.detach())
        grid = torch.stack([uv[..., 0], -uv[..., 1]], dim=-1)  # image rows run down: v up is -y
        if not _traced():
            return self._aligned_offsets_channels(vertices, maps, grid)
        first, last = self.aligned_mlp[0], self.aligned_mlp[2]
        hidden = F.linear(vertices.detach(), first.weight[:, -3:], first.bias)  # (N, V, W): the vertex's block
        start = 0
        for m in maps[:ALIGNED_STAGES]:
            block = first.weight[:, start:start + m.shape[1]]  # (W, C)
            start += m.shape[1]
            if m.shape[-2] * m.shape[-1] < vertices.shape[1]:  # fewer pixels than vertices: project, then sample
                m, block = F.conv2d(m, block[:, :, None, None]), None
            sampled = sample_bilinear(m, grid.to(m.dtype))  # (N, V, C or W)
            hidden = hidden + (sampled if block is None else F.linear(sampled, block))
        return self.local_scale * last(F.relu(hidden))

    def _aligned_offsets_channels(self, vertices: torch.Tensor, maps: list[torch.Tensor],
                                  grid: torch.Tensor) -> torch.Tensor:
        """:meth:`_aligned_offsets`' function as torch computes it fastest: the per-vertex features channel-major
        (N, C, V), the layout ``F.grid_sample`` writes, so nothing is transposed before the perceptron; the vertex's
        block and the maps sampled first as one 1-D convolution over their concatenation (a matrix product with 3
        inputs is the slowest kind); the projected maps' samples added in place. For the larger predictor at batch
        64 (a training step's, with its mirrored half) the branch's forward and backward take about a fifth less
        than the row-major form with ``F.grid_sample`` (173-254 against 208-327 ms, two runs on 2 threads). The
        ONNX trace keeps the row-major form, which ONNX Runtime runs fastest.
        """
        first, last = self.aligned_mlp[0], self.aligned_mlp[2]
        parts, blocks, projected = [vertices.detach().transpose(1, 2)], [first.weight[:, -3:]], []
        start = 0
        for m in maps[:ALIGNED_STAGES]:
            block = first.weight[:, start:start + m.shape[1]]  # (W, C)
            start += m.shape[1]
            small = m.shape[-2] * m.shape[-1] < vertices.shape[1]
            if small:  # fewer pixels than vertices: project, then sample
                m = F.conv2d(m, block[:, :, None, None])
            sampled = sample_channels(m, grid.to(m.dtype))  # (N, C or W, V)
            (projected if small else parts).append(sampled)
            if not small:
                blocks.append(block)
        hidden = F.conv1d(torch.cat(parts, dim=1), torch.cat(blocks, dim=1)[:, :, None], first.bias)  # (N, W, V)
        for sampled in projected:
            hidden.add_(sampled)  # the convolution's backward needs its input, not its output
        out = F.conv1d(F.relu(hidden), last.weight[:, :, None], last.bias)  # (N, 3, V)
        return self.local_scale * out.transpose(1, 2)

    def forward(self, normals: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Args: normals (N, 3, 64, 64) in [0, 1]. Returns local (N, V, 3), global (N, 3) (view frame)."""
        _check_image(normals, 3, self.input_size, "normals")
        code, maps = self._encode_maps(normals)
        h = self.decoder(code) * self.head_gain
        coeff = self.local_head(h).view(-1, self.modes, 3)
        local = self.local_scale * basis_times(self.basis.to(coeff.dtype), coeff)
        glob = self.global_scale * torch.tanh(self.global_head(h))
        if self.aligned:
            local = local + self._aligned_offsets(self.vertices(local, glob), maps)
        bound = LOCAL_CLAMP * self.local_scale
        return local.clamp(-bound, bound), glob


def build_predictor(arch: str = "softras", *, template_level: int = 3, channels: int = 64, hidden: int = 1024,
                    latent: int = 512, input_size: int = PREDICTOR_INPUT_SIZE, smoothing: float = PREDICTOR_SMOOTHING,
                    local_bound: str = "tanh", modes: int = 0, blocks: int = 0, aligned: int = 0) -> nn.Module:
    """The mesh predictor of architecture ``arch`` (:data:`PREDICTOR_ARCHS`)."""
    if arch == "softras":
        if blocks or aligned:
            raise ValueError("encoder blocks and the aligned branch are compact-predictor options (predictor_arch compact)")
        return MeshPredictor(template_level, channels, hidden, latent, input_size, smoothing=smoothing,
                             local_bound=local_bound)
    if arch == "compact":
        return CompactMeshPredictor(template_level, channels, hidden, latent, modes=modes, smoothing=smoothing,
                                    input_size=input_size, blocks=blocks, aligned=aligned)
    raise ValueError(f"predictor arch must be one of {PREDICTOR_ARCHS}, got {arch!r}")


# ----------------------------------------------------------------------------------------------
# Generator losses (Eq. 7-10)
# ----------------------------------------------------------------------------------------------


def adversarial_loss(logits: torch.Tensor, real: bool) -> torch.Tensor:
    """BCE-with-logits against an all-real (1) or all-fake (0) target; mean over patches. Scalar."""
    target = torch.ones_like(logits) if real else torch.zeros_like(logits)
    return F.binary_cross_entropy_with_logits(logits, target)


def global_l1_loss(pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Eq. 8: mean absolute difference over all pixels and channels. pred, target (N, C, H, W)."""
    if pred.shape != target.shape:
        raise ValueError(f"pred and target shapes differ: {tuple(pred.shape)} vs {tuple(target.shape)}")
    return (pred - target).abs().mean()


_SOBEL_X = torch.tensor([[-1.0, 0.0, 1.0], [-2.0, 0.0, 2.0], [-1.0, 0.0, 1.0]])


def sobel_magnitude(image: torch.Tensor) -> torch.Tensor:
    """Sobel gradient magnitude summed over channels (replicate padding at the border).

    Args:
        image: (N, C, H, W).

    Returns:
        (N, H, W) ``sqrt(sum_c gx_c^2 + gy_c^2)``. A unit step between two flat regions gives 4
        on both pixels next to the step (the kernel weights 1, 2, 1).
    """
    if image.ndim != 4:
        raise ValueError(f"image must be (N, C, H, W), got {tuple(image.shape)}")
    n, c, h, w = image.shape
    kx = _SOBEL_X.to(image)
    k = torch.stack([kx, kx.t()])[:, None]  # (2, 1, 3, 3)
    x = F.pad(image.reshape(n * c, 1, h, w), (1, 1, 1, 1), mode="replicate")
    g = F.conv2d(x, k).reshape(n, c, 2, h, w)
    return torch.sqrt((g * g).sum(dim=(1, 2)) + SOBEL_EPS) - math.sqrt(SOBEL_EPS)


def sample_edge_pixels(
    target: torch.Tensor, num_samples: int, threshold: float, generator: torch.Generator | None = None
) -> torch.Tensor:
    """Pick pixels on sharp features of the ground-truth normal image (the Eq. 9 sampling).

    Pixels whose :func:`sobel_magnitude` is at least ``threshold`` are candidates; ``num_samples``
    of them are drawn uniformly without replacement per image. An image with fewer candidates is
    filled with its next-strongest pixels (so the count is fixed and the batch stays a tensor).

    Args:
        target: (N, C, H, W) ground-truth normal image.
        num_samples: pixels per image, 1 <= num_samples <= H * W.
        threshold: Sobel magnitude above which a pixel is an edge.
        generator: torch random generator (deterministic sampling under a seed).

    Returns:
        (N, num_samples) int64 flat pixel indices ``row * W + col``.
    """
    n, _, h, w = target.shape
    if not 1 <= num_samples <= h * w:
        raise ValueError(f"num_samples must be in [1, {h * w}], got {num_samples}")
    with torch.no_grad():
        mag = sobel_magnitude(target.detach()).reshape(n, h * w)
        rand = torch.rand(mag.shape, generator=generator, device="cpu").to(mag.device)
        scale = mag.amax(dim=1, keepdim=True).clamp_min(SOBEL_EPS)
        # candidates score in [1, 2) (random order); others in [0, 1] by strength
        key = torch.where(mag >= threshold, 1.0 + 0.999 * rand, 0.999 * mag / scale)
        return key.topk(num_samples, dim=1).indices


def local_l1_loss(pred: torch.Tensor, target: torch.Tensor, indices: torch.Tensor) -> torch.Tensor:
    """Eq. 9: mean absolute difference at sampled pixels. pred/target (N, C, H, W), indices (N, S)."""
    if pred.shape != target.shape:
        raise ValueError(f"pred and target shapes differ: {tuple(pred.shape)} vs {tuple(target.shape)}")
    n, c, h, w = pred.shape
    idx = indices[:, None, :].expand(n, c, indices.shape[1])
    p = pred.reshape(n, c, h * w).gather(2, idx)
    t = target.reshape(n, c, h * w).gather(2, idx)
    return (p - t).abs().mean()


def downsample_normals(normals: torch.Tensor, size: int = PREDICTOR_INPUT_SIZE) -> torch.Tensor:
    """Area-average (N, 3, H, W) -> (N, 3, size, size); H must be a multiple of size (256 -> 64: 4x4 pooling)."""
    _check_image(normals, 3, None, "normals")
    if normals.shape[2] % size or normals.shape[3] % size:
        raise ValueError(f"normal image side must be a multiple of {size}, got {tuple(normals.shape)}")
    k = normals.shape[2] // size
    return F.avg_pool2d(normals, k) if k > 1 else normals


# ----------------------------------------------------------------------------------------------
# Cameras for view-frame predictions
# ----------------------------------------------------------------------------------------------


def view_frame_cameras(input_cameras: torch.Tensor, other_cameras: torch.Tensor | None = None) -> torch.Tensor:
    """Cameras that render a view-frame mesh from its input view and K other views, batched.

    The torch counterpart of :func:`engine.camera.relative_camera` on the (16,) packing of
    :meth:`engine.camera.Camera.to_array`: view k of item b gets rotation
    ``R_k @ R_in.T``, translation ``t_k`` and view k's intrinsics (focal, principal point).
    View 0 is the input view itself (identity rotation, the input camera's t and framed intrinsics).

    Args:
        input_cameras: (B, 16) input (framed) cameras.
        other_cameras: (B, K, 16) other known views of the same shapes, or None (K = 0).

    Returns:
        (B, 1 + K, 16) cameras, same dtype as the inputs.
    """
    if input_cameras.ndim != 2 or input_cameras.shape[1] != 16:
        raise ValueError(f"input_cameras must be (B, 16), got {tuple(input_cameras.shape)}")
    b = input_cameras.shape[0]
    if other_cameras is None:
        other_cameras = input_cameras.new_zeros((b, 0, 16))
    if other_cameras.ndim != 3 or other_cameras.shape[0] != b or other_cameras.shape[2] != 16:
        raise ValueError(f"other_cameras must be ({b}, K, 16), got {tuple(other_cameras.shape)}")
    cams = torch.cat([input_cameras[:, None], other_cameras.to(input_cameras.dtype)], dim=1)  # (B, 1+K, 16)
    r_in = input_cameras[:, :9].reshape(b, 1, 3, 3)
    r = cams[..., :9].reshape(b, -1, 3, 3)
    r_rel = r @ r_in.transpose(-1, -2)
    return torch.cat([r_rel.reshape(b, -1, 9), cams[..., 9:]], dim=-1)


__all__ = [
    "CompactMeshPredictor",
    "GENERATOR_ARCHS",
    "GENERATOR_LEVELS",
    "MeshPredictor",
    "PREDICTOR_ARCHS",
    "NormalGenerator",
    "PatchDiscriminator",
    "SKETCH_SIZE",
    "adversarial_loss",
    "build_predictor",
    "downsample_normals",
    "framed_ndc",
    "generator_channels",
    "global_l1_loss",
    "laplacian_basis",
    "local_l1_loss",
    "sample_bilinear",
    "sample_edge_pixels",
    "sobel_magnitude",
    "view_frame_cameras",
]
