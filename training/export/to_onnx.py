"""Export a trained run to the two ONNX files the engine runs (:mod:`engine.contract`).

* ``generator.onnx``: input ``sketch`` (N, 1, 256, 256) -> output ``normals`` (N, 3, 256, 256).
* ``mesh_predictor.onnx``: input ``normals`` (N, 3, 64, 64) -> ``local_offset`` (N, V, 3),
  ``global_offset`` (N, 3).

Both have a dynamic batch axis N, opset :data:`OPSET`, and carry the contract's metadata
(format, role, code version, resolved config JSON, conventions id, template level and radius /
base channels and generator arch, quantization). They are produced by the TorchScript-based exporter
(``torch.onnx.export(..., dynamo=False)``): it handles the U-Net's InstanceNorm and the predictor's
BatchNorm (folded in eval mode) in one pass with no graph-break risk, and its output is what
``onnxruntime.quantization.quantize_dynamic`` expects. Every file is written atomically, and the
export reports success only after ONNX Runtime reproduces torch on real inputs within
:data:`PARITY_TOLERANCE` (:data:`INT8_TOLERANCE` for a quantised predictor).

``--quantize int8`` applies dynamic int8 quantisation to the mesh predictor only: it is made of
fully connected layers, where it halves latency and quarters the size; it does not pay for the
U-Net in speed (ConvTranspose layers stay float, QInt8 convolutions are slower on CPU;
/work/shared/MEASUREMENTS.md). ``--quantize int8-all`` also quantises the generator's Conv
weights (ONNX Runtime's dynamic quantisation leaves ConvTranspose, the decoder of the
``pix2pix`` generator arch, in float32; the ``resize`` arch's decoder is Conv and is quantised
too): it is slower and only somewhat smaller (the width-32 pix2pix generator: 54 -> 40 MB);
``sketchmesh bench tradeoff`` measures both against accuracy. ``--quantize fp16`` stores the mesh
predictor's large weights in float16, each cast to float32 by a ``Cast`` node that ONNX Runtime
folds when it loads the model: half the file, float32 arithmetic and speed, an error of order
1e-4 (dynamic int8 quarters the file but runs the larger predictor's fully connected layers
2.5x slower, 3.9 ms a pass against 1.6, and errs by 1e-2). ``--quantize int8w`` stores both networks'
large Conv / Gemm weights in int8, one scale per output channel, the predictor's other weights as
``fp16`` does, all made float32 when ONNX Runtime loads the model (:func:`engine.bench.compact_model`,
the form the bundled models ship in): about a quarter of float32's bytes at float32's speed.

The generator is rebuilt from its run's config (``generator_arch``: reflect pads and nearest
``Resize`` nodes for "resize", ``ConvTranspose`` for "pix2pix"); its arch is written to the
metadata next to ``base_channels``.
"""

from __future__ import annotations

import dataclasses
import io
import logging
import tempfile
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from engine import contract
from engine.errors import ModelError
from engine.fileio import StagedWrites
from engine.graph import subpixel_bytes
from engine.icosphere import TEMPLATE_RADIUS
from training.loop.config import TrainConfig

OPSET = 17
PARITY_TOLERANCE = 1e-4
"""Max |torch - ONNX Runtime| on float32 exports (outputs are in [0, 1] or offsets of order 0.5)."""
INT8_TOLERANCE = 5e-2
"""Max |torch - ONNX Runtime| for the int8-quantised predictor's offsets (normalised-cube units:
5 % of the shape size); the error is reported, quantisation is opt-in."""
GENERATOR_INT8_TOLERANCE = 0.5
"""Max |torch - ONNX Runtime| per pixel for an int8-quantised generator (normal images in [0, 1]):
a sanity bound only, single pixels near edges move most; the mean error and its effect on the
mesh are what ``sketchmesh bench tradeoff`` reports."""
FP16_TOLERANCE = 5e-3
"""Max |torch - ONNX Runtime| for a predictor with float16-stored weights (float16 rounds to 5e-4 relative)."""
FP16_MIN_ELEMENTS = 1024
"""Initialisers at least this large are stored in float16 by ``--quantize fp16`` (biases stay float32)."""
QUANTIZE_CHOICES = ("none", "int8", "int8-all", "fp16", "int8w")
PARITY_SAMPLES = 2


@dataclass(frozen=True)
class ExportReport:
    """What one exported file is: its path, bytes, parity error against torch and the tolerance."""

    path: Path
    role: str
    size_bytes: int
    max_abs_error: float
    tolerance: float
    quantization: str
    export_s: float
    parity_inputs: str = ""

    def line(self) -> str:
        return (f"{self.role:15s} {self.path.name:22s} {self.size_bytes / 1e6:8.2f} MB  "
                f"max|torch-ort| {self.max_abs_error:.2e} (tol {self.tolerance:.0e})  "
                f"quant {self.quantization}  {self.export_s:.1f} s")


class _PredictorExport(torch.nn.Module):
    """The predictor with the contract's output order (local_offset, global_offset)."""

    def __init__(self, predictor: torch.nn.Module) -> None:
        super().__init__()
        self.predictor = predictor

    def forward(self, normals: torch.Tensor):
        return self.predictor(normals)


def _to_onnx_bytes(module: torch.nn.Module, example: torch.Tensor, input_name: str, output_names: list[str]) -> bytes:
    module.eval()  # the exporter restores the wrapper's mode recursively afterwards: keep it eval
    buf = io.BytesIO()
    dynamic = {input_name: {0: "N"}} | {name: {0: "N"} for name in output_names}
    with warnings.catch_warnings():
        # tracer warnings about the shape checks (constant at export) and InstanceNorm's
        # "train=True" note (it has no running statistics: instance statistics are the eval behaviour)
        warnings.simplefilter("ignore")
        torch.onnx.export(
            module, (example,), buf, input_names=[input_name], output_names=output_names, dynamic_axes=dynamic,
            opset_version=OPSET, dynamo=False, do_constant_folding=True,
        )
    module.eval()
    return buf.getvalue()


def _with_metadata(model_bytes: bytes, meta: dict[str, str]) -> bytes:
    import onnx

    model = onnx.load_from_string(model_bytes)
    del model.metadata_props[:]
    for key, value in meta.items():
        entry = model.metadata_props.add()
        entry.key, entry.value = key, str(value)
    onnx.checker.check_model(model)
    return model.SerializeToString()


def _fp16_weights(model_bytes: bytes) -> bytes:
    """Every float32 initialiser of at least :data:`FP16_MIN_ELEMENTS` stored as float16 under a new name,
    with a ``Cast`` to float32 producing the old name at the head of the graph (folded at load time)."""
    import onnx
    from onnx import TensorProto, helper, numpy_helper

    model = onnx.load_from_string(model_bytes)
    graph = model.graph
    keep, half, casts = [], [], []
    for init in graph.initializer:
        a = numpy_helper.to_array(init)
        if a.dtype == np.float32 and a.size >= FP16_MIN_ELEMENTS:
            h = numpy_helper.from_array(a.astype(np.float16), init.name + "__fp16")
            half.append(h)
            casts.append(helper.make_node("Cast", [h.name], [init.name], to=TensorProto.FLOAT, name=init.name + "__cast"))
        else:
            keep.append(init)
    del graph.initializer[:]
    graph.initializer.extend(keep + half)
    nodes = list(graph.node)
    del graph.node[:]
    graph.node.extend(casts + nodes)
    onnx.checker.check_model(model)
    return model.SerializeToString()


def _int8_stored(model_bytes: bytes) -> bytes:
    """Large Conv / Gemm weights stored in int8 with per-channel scales (:func:`engine.bench._int8_weights`)."""
    import onnx

    from engine.bench import INT8W_MIN_ELEMENTS, _int8_weights

    model = onnx.load_from_string(model_bytes)
    if _int8_weights(model) == 0:
        raise ModelError(f"--quantize int8w: no Conv or Gemm weight of {INT8W_MIN_ELEMENTS} values or more to store")
    onnx.checker.check_model(model)
    return model.SerializeToString()


def _quantize_int8(model_bytes: bytes) -> bytes:
    import onnx
    from onnxruntime.quantization import QuantType, quantize_dynamic

    with tempfile.TemporaryDirectory(prefix="sketchmesh_quant_") as tmp:
        src, dst = Path(tmp) / "in.onnx", Path(tmp) / "out.onnx"
        model = onnx.load_from_string(model_bytes)
        del model.graph.value_info[:]  # stale shape info breaks quantize_dynamic's inference
        src.write_bytes(model.SerializeToString())
        root = logging.getLogger()
        level = root.level
        root.setLevel(logging.ERROR)  # quantize_dynamic logs pre-processing advice on the root logger
        try:
            quantize_dynamic(str(src), str(dst), weight_type=QuantType.QInt8)
        finally:
            root.setLevel(level)
        return dst.read_bytes()


def _session(model_bytes: bytes):
    import onnxruntime as ort

    opts = ort.SessionOptions()
    opts.intra_op_num_threads = 2
    return ort.InferenceSession(model_bytes, opts, providers=["CPUExecutionProvider"])


def parity_inputs(cfg: TrainConfig, count: int = PARITY_SAMPLES) -> tuple[torch.Tensor, torch.Tensor, str]:
    """Real inputs for the parity check: sketches (N, 1, 256, 256) and normals64 (N, 3, 64, 64).

    Taken from the run's dataset (test split, else val, else train); when the data folder is not
    available, synthetic ellipse-and-line sketches and a rendered sphere's normal image are used. A
    dataset built with small sketches (``data --size 64``, as training/gpu_predictor.sh builds it)
    gives its real normal images and synthetic sketches: the generator reads 256 x 256.

    Returns:
        (sketches, normals64, a description of the source).
    """
    for split in ("test", "val", "train"):
        try:
            from training.loop.trainer import make_dataset

            ds = make_dataset(cfg.replace(augment_strength=0.0, extra_views=0), split)
            if len(ds) == 0:
                continue
            idx = np.linspace(0, len(ds) - 1, min(count, len(ds))).astype(int)
            items = [ds[int(i)] for i in idx]
            sk = torch.stack([torch.as_tensor(np.asarray(it["sketch"]), dtype=torch.float32) for it in items])
            nm = torch.stack([torch.as_tensor(np.asarray(it["normals64"]), dtype=torch.float32) for it in items])
        except Exception:  # no data here: fall back to synthetic inputs below
            continue
        if tuple(sk.shape[-2:]) == (contract.SKETCH_SIZE, contract.SKETCH_SIZE):
            return sk, nm, f"{len(items)} {split} samples of {cfg.data_dir}"
        return (torch.from_numpy(_synthetic_sketches(len(items))), nm,
                f"synthetic sketches and {len(items)} {split} normal images of {cfg.data_dir} "
                f"(its sketches are {sk.shape[-1]} px)")
    yy, xx = np.mgrid[0:64, 0:64]
    u, v = (xx + 0.5) / 32 - 1, 1 - (yy + 0.5) / 32
    r2 = (u / 0.8) ** 2 + (v / 0.8) ** 2
    inside = r2 < 1
    nz = np.sqrt(np.clip(1 - r2, 0, 1))
    n = np.stack([u / 0.8, v / 0.8, nz]) * inside
    n = np.where(inside, (n + 1) / 2, 0.0).astype(np.float32)
    return (torch.from_numpy(_synthetic_sketches(count)), torch.from_numpy(np.repeat(n[None], count, axis=0)),
            "synthetic sketches (no data folder)")


def _synthetic_sketches(count: int) -> np.ndarray:
    """(count, 1, 256, 256) float32 ellipse-and-line drawings, each a little different."""
    import cv2

    sk = np.zeros((count, 1, contract.SKETCH_SIZE, contract.SKETCH_SIZE), np.float32)
    for i in range(count):
        img = np.zeros((contract.SKETCH_SIZE, contract.SKETCH_SIZE), np.uint8)
        cv2.ellipse(img, (128, 128), (100 - 20 * i, 60 + 10 * i), 15.0 * i, 0, 360, 255, 2)
        cv2.line(img, (40, 200), (210, 60 + 10 * i), 255, 2)
        sk[i, 0] = img / 255.0
    return sk


def _max_err(a: list[np.ndarray], b: list[np.ndarray]) -> float:
    return max(float(np.max(np.abs(x.astype(np.float64) - y.astype(np.float64)))) for x, y in zip(a, b))


def export_models(
    generator: torch.nn.Module | None,
    predictor: torch.nn.Module | None,
    out_dir: str | Path,
    *,
    config_json: str | dict[str, str],
    code_version: str | dict[str, str],
    sketches: torch.Tensor,
    normals64: torch.Tensor,
    quantize: str = "none",
) -> list[ExportReport]:
    """Export, check parity, then write atomically. Raises ModelError if parity fails (nothing written).

    Args:
        generator: :class:`training.model.networks.NormalGenerator` or None.
        predictor: :class:`training.model.networks.MeshPredictor` or None.
        out_dir: destination folder (created).
        config_json: resolved training config (metadata ``config``), or one per role
            ({"generator": ..., "predictor": ...}) when the two come from different runs.
        code_version: metadata ``code_version`` (or one per role).
        sketches: (N, 1, 256, 256) parity inputs. normals64: (N, 3, 64, 64) parity inputs.
        quantize: "none", "int8" (mesh predictor only), "int8-all" (both networks), "fp16" (the mesh
            predictor's weights stored in float16, computed in float32) or "int8w" (both networks' large weights
            stored in int8, the predictor's others in float16, computed in float32).

    Returns:
        One :class:`ExportReport` per file written.
    """
    if quantize not in QUANTIZE_CHOICES:
        raise ValueError(f"quantize must be one of {', '.join(QUANTIZE_CHOICES)}, got {quantize!r}")
    if sketches.ndim != 4 or tuple(sketches.shape[1:]) != (1, contract.SKETCH_SIZE, contract.SKETCH_SIZE):
        raise ValueError(f"sketches must be (N, 1, 256, 256), got {tuple(sketches.shape)}")
    size = contract.PREDICTOR_INPUT_SIZE
    if normals64.ndim != 4 or tuple(normals64.shape[1:]) != (3, size, size):
        raise ValueError(f"normals64 must be (N, 3, {size}, {size}), got {tuple(normals64.shape)}")
    out = Path(out_dir)
    def base_meta(role: str) -> dict[str, str]:
        return {
            contract.META_FORMAT: contract.FORMAT_VERSION,
            contract.META_CODE_VERSION: code_version[role] if isinstance(code_version, dict) else code_version,
            contract.META_CONFIG: config_json[role] if isinstance(config_json, dict) else config_json,
            contract.META_CONVENTIONS: contract.CONVENTIONS_ID,
        }

    pending: list[tuple[Path, bytes, ExportReport]] = []
    if generator is not None:
        t0 = time.perf_counter()
        g = generator.float().cpu().eval()
        data = _to_onnx_bytes(g, sketches[:1].float(), contract.GENERATOR_INPUT, [contract.GENERATOR_OUTPUT])
        gq, gtol = "none", PARITY_TOLERANCE
        if quantize == "int8-all":
            data = _quantize_int8(data)
            gq, gtol = "int8-dynamic", GENERATOR_INT8_TOLERANCE
        elif quantize == "int8w":
            data = _int8_stored(data)
            gq, gtol = "int8-weights", GENERATOR_INT8_TOLERANCE  # single edge pixels move most: a
            # sanity bound, as for int8-all
        try:  # the resize decoder as sub-pixel convolutions (engine.graph: the same arithmetic without passes over the
            # large images; checked against the graph before); a graph it cannot rewrite is exported as it is
            data = subpixel_bytes(data, "generator", require=False)
        except ModelError as exc:
            warnings.warn(f"the generator's upsampling kept as exported: {exc}", stacklevel=2)
        meta = base_meta("generator") | {contract.META_ROLE: contract.ROLE_GENERATOR,
                            contract.META_BASE_CHANNELS: str(g.base_channels),
                            contract.META_GENERATOR_ARCH: str(getattr(g, "arch", "pix2pix")),
                            contract.META_QUANTIZATION: gq}
        data = _with_metadata(data, meta)
        with torch.no_grad():
            ref = [g(sketches.float()).numpy()]
        got = _session(data).run([contract.GENERATOR_OUTPUT], {contract.GENERATOR_INPUT: sketches.float().numpy()})
        err = _max_err(ref, got)
        pending.append((out / contract.GENERATOR_FILE, data, ExportReport(
            out / contract.GENERATOR_FILE, contract.ROLE_GENERATOR, len(data), err, gtol, gq,
            time.perf_counter() - t0)))
    if predictor is not None:
        t0 = time.perf_counter()
        p = predictor.float().cpu().eval()
        names = [contract.PREDICTOR_OUTPUT_LOCAL, contract.PREDICTOR_OUTPUT_GLOBAL]
        data = _to_onnx_bytes(_PredictorExport(p), normals64[:1].float(), contract.PREDICTOR_INPUT, names)
        qname = "none"
        tol = PARITY_TOLERANCE
        if quantize in ("int8", "int8-all"):
            data = _quantize_int8(data)
            qname, tol = "int8-dynamic", INT8_TOLERANCE
        elif quantize == "fp16":
            data = _fp16_weights(data)
            qname, tol = "fp16-weights", FP16_TOLERANCE
        elif quantize == "int8w":
            data = _int8_stored(_fp16_weights(data))
            qname, tol = "int8-weights", INT8_TOLERANCE
        meta = base_meta("predictor") | {contract.META_ROLE: contract.ROLE_PREDICTOR,
                            contract.META_TEMPLATE_LEVEL: str(p.template_level),
                            contract.META_TEMPLATE_RADIUS: repr(float(TEMPLATE_RADIUS)),
                            contract.META_QUANTIZATION: qname}
        data = _with_metadata(data, meta)
        with torch.no_grad():
            ref = [t.numpy() for t in p(normals64.float())]
        got = _session(data).run(names, {contract.PREDICTOR_INPUT: normals64.float().numpy()})
        err = _max_err(ref, got)
        pending.append((out / contract.PREDICTOR_FILE, data, ExportReport(
            out / contract.PREDICTOR_FILE, contract.ROLE_PREDICTOR, len(data), err, tol, qname,
            time.perf_counter() - t0)))
    if not pending:
        raise ModelError("nothing to export: no generator and no mesh predictor given")
    failed = [r for _, _, r in pending if not (np.isfinite(r.max_abs_error) and r.max_abs_error <= r.tolerance)]
    if failed:
        raise ModelError("ONNX Runtime does not reproduce torch: " + "; ".join(
            f"{r.role} max abs error {r.max_abs_error:.3g} > {r.tolerance:.0e}" for r in failed))
    with StagedWrites() as staged:  # both models or neither: never a folder with one ONNX file
        for path, data, _ in pending:
            staged.add(path, data)
    return [r for _, _, r in pending]


def export_run(
    run_dir: str | Path,
    out_dir: str | Path,
    *,
    generator_run: str | Path | None = None,
    predictor_run: str | Path | None = None,
    quantize: str = "none",
) -> list[ExportReport]:
    """Export the generator and predictor of a run (or of the given runs) to ``out_dir``.

    The generator comes from ``generator_run`` (default ``run_dir``), the predictor from
    ``predictor_run`` (default ``run_dir``); a joint run holds both. Parity inputs come from the
    dataset of the run's config (:func:`parity_inputs`).
    """
    from training.loop.trainer import load_run

    if quantize not in QUANTIZE_CHOICES:
        raise ValueError(f"quantize must be one of {', '.join(QUANTIZE_CHOICES)}, got {quantize!r}")
    loaded = {}
    for role, run in (("generator", generator_run or run_dir), ("predictor", predictor_run or run_dir)):
        cfg, models, state = load_run(run)
        if role in models:
            loaded[role] = (cfg, models[role], state)
    if not loaded:
        raise ModelError(f"run {run_dir} has neither a generator nor a mesh predictor")
    cfg = loaded.get("predictor", loaded.get("generator"))[0]
    sketches, normals64, source = parity_inputs(cfg)
    reports = export_models(
        loaded.get("generator", (None, None, None))[1], loaded.get("predictor", (None, None, None))[1], out_dir,
        config_json={role: c.to_json() for role, (c, _, _) in loaded.items()},
        code_version={role: str(st.get("code_version", "unknown")) for role, (_, _, st) in loaded.items()},
        sketches=sketches, normals64=normals64, quantize=quantize,
    )
    return [dataclasses.replace(r, parity_inputs=source) for r in reports]
