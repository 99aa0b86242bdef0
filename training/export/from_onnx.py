"""Exported ONNX models back to training runs: continue training the bundled models on any machine.

A run folder (its checkpoints) lives on the machine that trained it; the ONNX files in a models
folder (``assets/models``: what the app ships) travel with the repository. This module turns such
a folder back into run folders, ``OUT/generator`` (mode ``normals``) and ``OUT/predictor`` (mode
``mesh``), so ``sketchmesh train ... --init-normals OUT/generator --init-mesh OUT/predictor``,
``sketchmesh eval OUT/predictor`` and ``sketchmesh export`` work on a fresh machine as on the one
that trained them.

What the export changed, and how it is undone:

* **Names.** The generator's and the fully connected layers' weights keep their torch names in the
  graph (``down.0.0.weight``, ``predictor.decoder.0.weight``); int8 files hold them quantised
  (``<name>_Transposed_quantized`` with ``_scale`` and ``_zero_point``): they are dequantised,
  ``(q - zero_point) * scale``, which is the value ONNX Runtime multiplies with.
* **Folded batch norm.** The exporter folds each of the compact predictor's ``Conv -> BatchNorm``
  pairs into one convolution with a bias ``b'``. The convolution gets the folded weight; the batch
  norm is set so that it computes ``z + b'`` in eval mode exactly *and* in train mode for batches
  like the calibration batch: with ``mu`` and ``var`` the per-channel mean and (biased) variance of
  the convolution's output ``z`` over a calibration batch of training inputs,
  ``gamma = sqrt(var + eps)``, ``beta = mu + b'``, ``running_mean = mu``, ``running_var = var``
  (train mode divides by ``sqrt(var_batch + eps)``, eval mode by ``sqrt(running_var + eps)``). (Gamma 1 and beta
  ``b'`` would be exact in eval mode only: train mode would normalise every channel to unit
  deviation and start training from another function.)
* **The offset basis** is the graph's own ``(V, M)`` matrix (the basis is not portable between
  machines: see :class:`training.model.networks.CompactMeshPredictor`).
* **The aligned branch** (``predictor_aligned``): its first layer's weight is stored whole and sliced in the graph
  (the export applies it map by map, the small maps through 1x1 convolutions whose weights are computed, so they
  are not taken for the encoder's); its last layer's weight is a folded, transposed ``MatMul`` constant found by
  the node's name.
* **The discriminator** is not exported; a generator run gets a freshly initialised one (seeded),
  and its checkpoint says so (``extra["discriminator"] = "fresh"``).

Every import ends with the export's parity check run the other way: the rebuilt torch network in
eval mode against ONNX Runtime on the same inputs, within the export's tolerances (float32 1e-4,
int8 predictor 5e-2, the error of int8 itself); a graph this module does not understand fails that
check or an earlier one with a :class:`engine.errors.ModelError` naming the problem, and nothing
is written.
"""

from __future__ import annotations

import json
import shutil
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch import nn

from engine import contract
from engine.errors import ModelError
from engine.fileio import atomic_write_text
from training.loop.config import TrainConfig

CALIBRATION_SAMPLES = 256
"""Training inputs whose batch statistics set the predictor's batch norms (see the module doc)."""
CALIBRATION_CHUNK = 64
DISCRIMINATOR_SEED = 0


@dataclass(frozen=True)
class ImportReport:
    """One imported network: the run folder written, parity against ONNX Runtime, and where it came from."""

    role: str
    run_dir: Path
    source: Path
    quantization: str
    max_abs_error: float
    tolerance: float
    parity_inputs: str
    calibration: str
    seconds: float

    def line(self) -> str:
        extra = f"  batch norm: {self.calibration}" if self.calibration else ""
        return (f"{self.role:15s} {self.source.name:22s} -> {self.run_dir}  quant {self.quantization}  "
                f"max|torch-ort| {self.max_abs_error:.2e} (tol {self.tolerance:.0e}){extra}  {self.seconds:.1f} s")


class _Graph:
    """Initialisers, constants and node links of one ONNX graph, as numpy."""

    def __init__(self, path: Path) -> None:
        import onnx
        from onnx import numpy_helper

        try:
            model = onnx.load(str(path))
        except Exception as exc:  # noqa: BLE001 - protobuf raises several types on a broken file
            raise ModelError(f"{path}: not a readable ONNX model ({type(exc).__name__}: {exc})") from None
        self.path = path
        self.meta = {p.key: p.value for p in model.metadata_props}
        self.nodes = list(model.graph.node)
        self.arrays: dict[str, np.ndarray] = {i.name: numpy_helper.to_array(i) for i in model.graph.initializer}
        for n in self.nodes:
            if n.op_type == "Constant" and n.attribute and n.attribute[0].HasField("t"):
                self.arrays[n.output[0]] = numpy_helper.to_array(n.attribute[0].t)
        for n in self.nodes:  # weights stored in float16 or int8 and made float32 on load (export --quantize fp16,
            # engine.bench.compact_model: Cast, then Mul by the per-channel scales), in graph order
            if n.op_type == "Cast" and n.input and n.input[0] in self.arrays and n.output[0] not in self.arrays:
                self.arrays[n.output[0]] = self.arrays[n.input[0]].astype(np.float32)
            elif (n.op_type == "Mul" and len(n.input) == 2 and n.output[0] not in self.arrays
                  and all(i in self.arrays and self.arrays[i].dtype == np.float32 for i in n.input)):
                self.arrays[n.output[0]] = self.arrays[n.input[0]] * self.arrays[n.input[1]]
        self.producer = {o: n for n in self.nodes for o in n.output}
        self.consumers: dict[str, list] = {}
        for n in self.nodes:
            for i in n.input:
                self.consumers.setdefault(i, []).append(n)

    def weight(self, name: str) -> np.ndarray | None:
        """The float32 value of initialiser ``name``, dequantised if only its int8 form is there (as stored:
        a ``_Transposed`` tensor is returned transposed back)."""
        if name in self.arrays:
            return self.arrays[name].astype(np.float32)
        for suffix, transposed in (("_quantized", False), ("_Transposed_quantized", True)):
            q = name + suffix
            if q in self.arrays:
                base = q[: -len("_quantized")]
                w = self._dequantize(base)
                return w.T.copy() if transposed else w
        return None

    def _dequantize(self, base: str) -> np.ndarray:
        try:
            q, scale, zero = (self.arrays[base + s] for s in ("_quantized", "_scale", "_zero_point"))
        except KeyError as exc:
            raise ModelError(f"{self.path}: quantised weight {base} lacks {exc.args[0]}") from None
        if np.asarray(scale).size != 1 or np.asarray(zero).size != 1:
            raise ModelError(f"{self.path}: {base} is quantised per channel; only per-tensor int8 is supported")
        return ((q.astype(np.float32) - np.float32(zero)) * np.float32(scale)).astype(np.float32)

    def convolutions(self) -> list[tuple[np.ndarray, np.ndarray | None]]:
        """(weight, bias) of every Conv / ConvInteger node in graph order (the int8 form's bias is the
        reshaped initialiser its output is added to)."""
        out = []
        for n in self.nodes:
            if self._computed_weight(n):
                continue  # the aligned branch's 1x1 projections: its first layer's weight, sliced (read from that)
            if n.op_type == "Conv":
                w = self.weight(n.input[1])
                b = self.weight(n.input[2]) if len(n.input) > 2 and n.input[2] else None
            elif n.op_type == "ConvInteger":
                w = self._dequantize(n.input[1][: -len("_quantized")])
                b = self._added_bias(n.output[0])
            else:
                continue
            if w is None:
                raise ModelError(f"{self.path}: convolution {n.name or n.output[0]} has no constant weight")
            out.append((w, b))
        return out

    def _computed_weight(self, node) -> bool:
        """Whether a Conv / ConvInteger node's weight is computed in the graph from a slice of another weight (the
        aligned branch projects its small maps so) rather than stored: Unsqueeze, or int8's on-the-fly quantiser."""
        if node.op_type not in ("Conv", "ConvInteger") or node.input[1] in self.arrays:
            return False
        src = self.producer.get(node.input[1])
        return src is not None and src.op_type in ("Unsqueeze", "DynamicQuantizeLinear")

    def _added_bias(self, name: str, depth: int = 4) -> np.ndarray | None:
        """Follow ``name`` through Cast/Mul to the Add that adds a (reshaped) constant bias."""
        for _ in range(depth):
            users = self.consumers.get(name, [])
            if len(users) != 1:
                return None
            node = users[0]
            if node.op_type == "Add":
                other = [i for i in node.input if i != name][0]
                src = self.producer.get(other)
                if src is not None and src.op_type == "Reshape":
                    other = src.input[0]
                value = self.weight(other)
                return None if value is None else value.reshape(-1)
            if node.op_type not in ("Cast", "Mul"):
                return None
            name = node.output[0]
        return None

    def node_weight(self, name_part: str, op_types: tuple[str, ...] = ("MatMul", "MatMulInteger")) -> str | None:
        """The name of the constant operand of the first ``op_types`` node whose name contains ``name_part`` (a
        weight that export folded under a generated name, e.g. a transposed one)."""
        for n in self.nodes:
            if n.op_type in op_types and name_part in n.name:
                for i in n.input:
                    base = i.removesuffix("_quantized")
                    if self.weight(base) is not None:
                        return base
        return None

    def matmul_constant(self, shape: tuple[int, int]) -> np.ndarray | None:
        """The first MatMul operand that is a constant of ``shape`` (the predictor's offset basis)."""
        for n in self.nodes:
            if n.op_type == "MatMul":
                for i in n.input:
                    if i in self.arrays and tuple(self.arrays[i].shape) == shape:
                        return self.arrays[i].astype(np.float32)
        return None


def _config(graph: _Graph, role: str) -> TrainConfig:
    got = graph.meta.get(contract.META_ROLE)
    if got != role:
        raise ModelError(f"{graph.path}: metadata says role {got!r}, expected {role!r}")
    text = graph.meta.get(contract.META_CONFIG)
    if not text:
        raise ModelError(f"{graph.path}: no training config in its metadata; it cannot be rebuilt as a run")
    try:
        cfg = TrainConfig.from_json(text)
    except (ValueError, TypeError) as exc:
        raise ModelError(f"{graph.path}: unusable training config in its metadata ({exc})") from None
    # the runs it was initialised from are not here; the run is a starting point of its own
    return cfg.replace(init_mesh="", init_normals="")


def _set(param: torch.Tensor, value: np.ndarray | None, what: str, path: Path) -> None:
    if value is None:
        raise ModelError(f"{path}: no weight for {what}")
    if tuple(value.shape) != tuple(param.shape):
        raise ModelError(f"{path}: {what} is {tuple(value.shape)} in the graph, {tuple(param.shape)} in the network")
    with torch.no_grad():
        param.copy_(torch.from_numpy(np.ascontiguousarray(value)))


def _linear_weight(graph: _Graph, name: str, layer: nn.Linear) -> np.ndarray | None:
    """A Linear's (out, in) weight: stored as is (Gemm transB), transposed (MatMul) or quantised transposed."""
    w = graph.weight(name)
    if w is not None and w.shape != tuple(layer.weight.shape) and w.T.shape == tuple(layer.weight.shape):
        w = w.T.copy()
    return w


def load_generator(graph: _Graph, cfg: TrainConfig) -> nn.Module:
    """The generator of ``cfg`` with the graph's weights (names as in torch)."""
    from training.model.networks import NormalGenerator

    meta_c = graph.meta.get(contract.META_BASE_CHANNELS)
    if meta_c is not None and (not meta_c.strip().isdigit() or int(meta_c) != cfg.base_channels):
        raise ModelError(f"{graph.path}: base_channels {meta_c} in the metadata, {cfg.base_channels} in its config")
    g = NormalGenerator(cfg.base_channels, arch=cfg.generator_arch)
    for name, p in g.named_parameters():
        _set(p, graph.weight(name), name, graph.path)
    return g.eval()


def generator_from_onnx(path: str | Path) -> nn.Module:
    """The generator of an exported ``generator.onnx`` as a torch module in eval mode (the weights and config
    :func:`import_models` reads; float16-stored weights come back as float32). ModelError names a file that is
    missing, broken or not an exported generator."""
    path = Path(path)
    if not path.is_file():
        raise ModelError(f"no generator file {path}")
    graph = _Graph(path)
    return load_generator(graph, _config(graph, contract.ROLE_GENERATOR))


def load_predictor(graph: _Graph, cfg: TrainConfig, calibration: torch.Tensor | None) -> nn.Module:
    """The compact predictor of ``cfg`` with the graph's weights; batch norms from ``calibration`` (module doc)."""
    from training.loop.trainer import build_models

    if cfg.predictor_arch != "compact" or cfg.predictor_blocks:
        raise ModelError(f"{graph.path}: only the compact predictor without residual blocks can be imported (this "
                         f"one: {cfg.predictor_arch}, {cfg.predictor_blocks} blocks)")
    p = build_models(cfg.replace(mode="mesh"))["predictor"]
    pairs = [(m, p.encoder[i + 1]) for i, m in enumerate(p.encoder) if isinstance(m, nn.Conv2d)]
    convs = graph.convolutions()
    if len(convs) != len(pairs):
        raise ModelError(f"{graph.path}: {len(convs)} convolutions in the graph, {len(pairs)} in the network")
    folded_bias = []
    for k, ((conv, _bn), (w, b)) in enumerate(zip(pairs, convs)):
        _set(conv.weight, w, f"encoder convolution {k}", graph.path)
        if b is None or b.shape != (conv.out_channels,):
            raise ModelError(f"{graph.path}: encoder convolution {k} has no folded batch-norm bias")
        folded_bias.append(torch.from_numpy(b.astype(np.float32)))
    for name, layer in (("encoder.13", p.encoder[13]), ("decoder.0", p.decoder[0]),
                        ("local_head", p.local_head), ("global_head", p.global_head)):
        _set(layer.weight, _linear_weight(graph, f"predictor.{name}.weight", layer), f"{name}.weight", graph.path)
        _set(layer.bias, graph.weight(f"predictor.{name}.bias"), f"{name}.bias", graph.path)
    if cfg.predictor_aligned:  # the first layer is stored whole (export slices it); the last folded, transposed
        first, last = p.aligned_mlp[0], p.aligned_mlp[2]
        _set(first.weight, graph.weight("predictor.aligned_mlp.0.weight"), "aligned_mlp.0.weight", graph.path)
        _set(first.bias, graph.weight("predictor.aligned_mlp.0.bias"), "aligned_mlp.0.bias", graph.path)
        name = graph.node_weight("aligned_mlp.2")
        _set(last.weight, None if name is None else _linear_weight(graph, name, last), "aligned_mlp.2.weight",
             graph.path)
        _set(last.bias, graph.weight("predictor.aligned_mlp.2.bias"), "aligned_mlp.2.bias", graph.path)
    basis = graph.matmul_constant(tuple(p.basis.shape))
    _set(p.basis, basis, "the offset basis", graph.path)
    _set_batch_norms(p, pairs, folded_bias, calibration)
    return p.eval()


def _set_batch_norms(p: nn.Module, pairs: list, folded_bias: list[torch.Tensor], calibration: torch.Tensor | None) -> None:
    """Batch norms that compute ``z + b'`` (eval mode exactly; train mode at the calibration batch's statistics)."""
    for (_, bn), b in zip(pairs, folded_bias):
        with torch.no_grad():  # first: identity plus bias, exact in eval mode whatever the statistics
            bn.weight.fill_(1.0)
            bn.bias.copy_(b)
            bn.running_mean.zero_()
            bn.running_var.fill_(1.0 - bn.eps)
    if calibration is None:
        return
    sums = [torch.zeros_like(b, dtype=torch.float64) for b in folded_bias]
    squares = [torch.zeros_like(s) for s in sums]
    counts = [0] * len(pairs)

    def hook(k):
        def fn(_module, _inp, out):
            z = out.detach().double()
            sums[k] += z.sum(dim=(0, 2, 3))
            squares[k] += (z * z).sum(dim=(0, 2, 3))
            counts[k] += z.numel() // z.shape[1]
        return fn

    handles = [conv.register_forward_hook(hook(k)) for k, (conv, _) in enumerate(pairs)]
    try:
        p.eval()
        with torch.no_grad():
            for chunk in calibration.split(CALIBRATION_CHUNK):
                p(chunk)
    finally:
        for h in handles:
            h.remove()
    for (_conv, bn), b, s, q, n in zip(pairs, folded_bias, sums, squares, counts):
        mu = s / n
        var = (q / n - mu * mu).clamp_min(0.0)
        with torch.no_grad():
            bn.weight.copy_((var + bn.eps).sqrt().float())
            bn.bias.copy_(mu.float() + b)
            bn.running_mean.copy_(mu.float())
            bn.running_var.copy_(var.float())


def calibration_inputs(cfg: TrainConfig, count: int = CALIBRATION_SAMPLES) -> tuple[torch.Tensor, str]:
    """(count, 3, 64, 64) predictor inputs from the train split of ``cfg.data_dir``, evenly spaced: the generated
    normal images the predictor trained on where the data folder has them, else the true ones."""
    from training.loop.trainer import make_dataset

    last = None
    for input_normals in ([cfg.input_normals] if cfg.input_normals else []) + [""]:
        try:
            ds = make_dataset(cfg.replace(mode="mesh", input_normals=input_normals, input_share=1.0, mirror=0.0, mirror_consistency=0.0,
                                          mirror_inputs="", augment_strength=0.0, extra_views=0), "train",
                              fields="mesh")
        except Exception as exc:  # noqa: BLE001 - reported below if no source works
            last = exc
            continue
        if len(ds) == 0:
            continue
        idx = np.linspace(0, len(ds) - 1, min(count, len(ds))).astype(int)
        key = "input64" if input_normals else "normals64"
        rows = []
        try:
            for i in idx:
                x = ds[int(i)][key]
                rows.append(torch.as_tensor(np.asarray(x), dtype=torch.float32).reshape(-1, *x.shape[-3:])[0])
        except Exception as exc:  # noqa: BLE001 - a broken item of the dataset: say which folder
            raise ModelError(f"cannot calibrate the predictor's batch norms: reading {cfg.data_dir} failed "
                             f"({type(exc).__name__}: {exc})") from None
        what = f"generated set {input_normals}" if input_normals else "true normal images"
        return torch.stack(rows), f"{len(rows)} train inputs of {cfg.data_dir} ({what})"
    why = f" ({type(last).__name__}: {last})" if last else ""
    raise ModelError(f"cannot calibrate the predictor's batch norms: no training inputs in {cfg.data_dir}{why}; "
                     "pass --data DIR (a dataset built with sketchmesh data)")


def _write_run(run_dir: Path, cfg: TrainConfig, models: dict[str, nn.Module], source: Path, extra: dict) -> None:
    from training.loop.checkpoint import save_checkpoint

    meta_version = extra.pop("code_version", "unknown")
    save_checkpoint(run_dir, 0, cfg.to_json(), f"imported from {source} ({meta_version})", models, {},
                    extra={"imported_from": str(source), **extra})


def import_models(models_dir: str | Path, out_dir: str | Path, *, data_dir: str | None = None,
                  roles: tuple[str, ...] = ("generator", "predictor"),
                  calibration: int = CALIBRATION_SAMPLES) -> list[ImportReport]:
    """Rebuild the networks of an exported models folder as run folders ``OUT/generator`` and ``OUT/predictor``.

    Args:
        models_dir: a folder with ``generator.onnx`` and/or ``mesh_predictor.onnx`` (``sketchmesh export``'s output).
        out_dir: where the run folders go (each must not hold a run yet).
        data_dir: dataset for the predictor's batch-norm calibration and the parity inputs (default: the data
            folder named in the model's config).
        roles: which networks to import.
        calibration: training inputs for the batch-norm statistics.

    Returns:
        One :class:`ImportReport` per run written. Raises ModelError (nothing written) when a file is missing or
        broken, its graph is not one this module can rebuild, or the rebuilt network does not reproduce it.
    """
    from training.export.to_onnx import (
        GENERATOR_INT8_TOLERANCE,
        INT8_TOLERANCE,
        PARITY_TOLERANCE,
        _max_err,
        _session,
        parity_inputs,
    )

    models_dir, out_dir = Path(models_dir), Path(out_dir)
    if not models_dir.is_dir():
        raise ModelError(f"models folder {models_dir} does not exist")
    files = {"generator": contract.GENERATOR_FILE, "predictor": contract.PREDICTOR_FILE}
    bad = [r for r in roles if r not in files]
    if bad or not roles:
        raise ValueError(f"roles must be among {sorted(files)}, got {list(roles)}")
    from training.loop.checkpoint import checkpoint_paths

    taken = [str(out_dir / r) for r in roles if checkpoint_paths(out_dir / r)]
    if taken:
        raise ModelError(f"{', '.join(taken)} already holds a run; choose another --out")
    built = []
    for role in roles:
        t0 = time.perf_counter()
        path = models_dir / files[role]
        if not path.is_file():
            raise ModelError(f"{models_dir} has no {files[role]}")
        graph = _Graph(path)
        cfg = _config(graph, contract.ROLE_GENERATOR if role == "generator" else contract.ROLE_PREDICTOR)
        if data_dir:
            cfg = cfg.replace(data_dir=str(data_dir))
        quant = graph.meta.get(contract.META_QUANTIZATION, "none")
        calib_note = ""
        extra = {"code_version": graph.meta.get(contract.META_CODE_VERSION, "unknown")}
        if role == "generator":
            from training.model.networks import PatchDiscriminator

            cfg = cfg.replace(mode="normals")
            net = load_generator(graph, cfg)
            with torch.random.fork_rng(devices=[]):  # a seeded discriminator, the caller's RNG untouched
                torch.manual_seed(DISCRIMINATOR_SEED)
                models = {"generator": net, "discriminator": PatchDiscriminator(cfg.base_channels)}
            extra["discriminator"] = "fresh"
            tol = PARITY_TOLERANCE if quant in ("none", "int8-weights") else GENERATOR_INT8_TOLERANCE  # stored: exact
        else:
            cfg = cfg.replace(mode="mesh")
            calib, calib_note = calibration_inputs(cfg, calibration)
            net = load_predictor(graph, cfg, calib)
            models = {"predictor": net}
            extra["batch_norm_calibration"] = calib_note
            tol = PARITY_TOLERANCE if quant in ("none", "fp16-weights", "int8-weights") else INT8_TOLERANCE  # stored
            # weights are the file's own, exactly
        sketches, normals64, source = parity_inputs(cfg)
        try:
            session = _session(path.read_bytes())
        except Exception as exc:  # noqa: BLE001 - ONNX Runtime's own exception types
            raise ModelError(f"{path}: ONNX Runtime cannot run it ({type(exc).__name__}: {exc})") from None
        with torch.no_grad():
            if role == "generator":
                ref = [net(sketches).numpy()]
                got = session.run([contract.GENERATOR_OUTPUT], {contract.GENERATOR_INPUT: sketches.numpy()})
            else:
                ref = [t.numpy() for t in net(normals64)]
                got = session.run([contract.PREDICTOR_OUTPUT_LOCAL, contract.PREDICTOR_OUTPUT_GLOBAL],
                                  {contract.PREDICTOR_INPUT: normals64.numpy()})
        err = _max_err(ref, got)
        if not (np.isfinite(err) and err <= tol):
            raise ModelError(f"{path}: the rebuilt {role} does not reproduce the ONNX model "
                             f"(max abs error {err:.3g} > {tol:.0e}); nothing written")
        built.append((role, cfg, models, path, extra, ImportReport(
            role, out_dir / role, path, quant, err, tol, source, calib_note, time.perf_counter() - t0)))
    written: list[Path] = []
    try:  # both runs or neither: a half-written import would block the next try ("already holds a run")
        for role, cfg, models, path, extra, _ in built:
            written.append(out_dir / role)
            _write_run(out_dir / role, cfg, models, path, dict(extra))
    except BaseException:
        for run in written:
            shutil.rmtree(run, ignore_errors=True)
        raise
    atomic_write_text(out_dir / "IMPORTED.json", json.dumps(
        {r.role: {"source": str(r.source), "quantization": r.quantization, "max_abs_error": r.max_abs_error,
                  "calibration": r.calibration} for *_, r in built}, indent=2) + "\n")
    return [r for *_, r in built]
