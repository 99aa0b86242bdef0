"""``sketchmesh bench engine``: per-stage latency of the inference pipeline, and what int8 costs in accuracy.

For each variant -- ``fp32`` (the models as given), ``int8-predictor`` (only the mesh predictor
dynamically quantised), ``int8`` (both) and ``int8w`` (both networks' large weights stored in int8,
computed in float32: :func:`compact_model`; a quarter of float32's bytes at float32's speed) -- every
stage (preprocess, generator, downsample, predictor, assemble, export, total) is timed over ``runs``
predictions with the cache off, and the variant's error against fp32 on the same sketches is measured: normal-image mean absolute
error (in encoded [0, 1] units) and per-vertex distance mean / max (in units of the normalised
shape, whose bounding box is 1 on its longest side). Error against run time, in one table.
A variant with the suffix ``+mirror`` (e.g. ``fp32+mirror``) runs the engine with ``mirror_average``
on (:mod:`engine.pipeline`): against fp32, ``fp32+mirror``'s error columns say how far averaging
moves the mesh; an int8 ``+mirror`` variant's mix that with the quantisation's.

Quantisation needs the ``onnx`` package (a dev/train extra); without it only fp32 is measured.
"""

from __future__ import annotations

import contextlib
import functools
import io
import logging
import os
import platform
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from engine import contract as C
from engine.errors import MissingExtraError, ModelError, SketchInputError
from engine.graph import SUBPIXEL_KERNEL_SUFFIX, fold_subpixel_kernels
from engine.models import model_paths, resolve_models_dir

STAGES = ("preprocess", "generator", "downsample", "predictor", "assemble", "export", "total")
VARIANTS = C.PRECISION_VARIANTS
MIRROR_SUFFIX = C.MIRROR_SUFFIX
EXPORT_SUFFIX = ".glb"
"""Format timed by the ``export`` stage (the app's default export)."""


def _float32_weights(model, only: set[str] | None = None) -> None:
    """In place: weights stored in float16 behind a ``Cast`` to float32 (``sketchmesh export --quantize fp16``), or in
    int8 behind a ``Cast`` and a ``Mul`` by their scales (:func:`compact_model`), become float32 initialisers again, so
    that quantisation finds the weights where it looks for them; with ``only``, just the weights of those names (the
    others stay stored as they were)."""
    from onnx import TensorProto, numpy_helper

    graph = model.graph
    inputs = {i.name for i in graph.input}  # an initialiser listed as a graph input may be overridden: left alone
    inits = {i.name: i for i in graph.initializer if i.name not in inputs}
    users: dict[str, int] = {}
    for n in graph.node:
        for i in n.input:
            users[i] = users.get(i, 0) + 1
    values: dict[str, np.ndarray] = {}  # float32 values of the stored weights' node outputs
    chains: dict[str, tuple[list, set]] = {}  # each value's nodes and initialisers, dropped when it becomes one
    for n in graph.node:
        if (n.op_type == "Cast" and len(n.input) == 1 and n.input[0] in inits and users.get(n.input[0]) == 1
                and inits[n.input[0]].data_type in (TensorProto.FLOAT16, TensorProto.INT8)
                and any(a.name == "to" and a.i == TensorProto.FLOAT for a in n.attribute)):
            values[n.output[0]] = numpy_helper.to_array(inits[n.input[0]]).astype(np.float32)
            chains[n.output[0]] = ([n], {n.input[0]})
        elif (n.op_type == "Mul" and len(n.input) == 2 and n.input[0] in values and users.get(n.input[0]) == 1
              and n.input[1] in inits and users.get(n.input[1]) == 1
              and inits[n.input[1]].data_type == TensorProto.FLOAT):
            values[n.output[0]] = values.pop(n.input[0]) * numpy_helper.to_array(inits[n.input[1]])
            nodes, names = chains.pop(n.input[0])
            chains[n.output[0]] = (nodes + [n], names | {n.input[1]})
    values = {k: v for k, v in values.items() if only is None or k in only}
    drop_nodes = [n for k in values for n in chains[k][0]]
    drop_inits = set().union(*(chains[k][1] for k in values))
    for n in drop_nodes:
        graph.node.remove(n)
    kept = [i for i in graph.initializer if i.name not in drop_inits]
    del graph.initializer[:]
    graph.initializer.extend(kept + [numpy_helper.from_array(v.astype(np.float32), k) for k, v in values.items()])


def _mark_quantization(model, value: str) -> None:
    """In place: the model's metadata kept, ``quantization`` set to ``value`` (and quantize_dynamic's own
    ``onnx.infer`` note dropped)."""
    meta = {p.key: p.value for p in model.metadata_props}
    meta[C.META_QUANTIZATION] = value
    meta.pop("onnx.infer", None)
    del model.metadata_props[:]
    for k, v in meta.items():
        entry = model.metadata_props.add()
        entry.key, entry.value = k, v


def _conv_sizes(model, convs: list, x: np.ndarray) -> dict[str, tuple[int, int]]:
    """(output pixels (height x width), multiply-adds) of each Conv node of ``convs`` on the input ``x``, run with
    their inputs and outputs exposed (a copy of ``model``)."""
    import onnxruntime as ort
    from onnx import helper

    probe = type(model)()
    probe.CopyFrom(model)
    del probe.graph.value_info[:]
    names = [n.output[0] for n in convs] + [n.input[0] for n in convs]
    known = {o.name for o in probe.graph.output} | {i.name for i in probe.graph.input}
    names = list(dict.fromkeys(names))
    probe.graph.output.extend(helper.make_empty_tensor_value_info(o) for o in names if o not in known)
    try:
        session = ort.InferenceSession(probe.SerializeToString(), providers=["CPUExecutionProvider"])
        outs = session.run(names, {C.GENERATOR_INPUT: x})
    except Exception as exc:  # noqa: BLE001 - onnxruntime raises many types
        raise ModelError(f"the generator does not run on a calibration drawing: {' '.join(str(exc).split())[:300]}") from None
    shapes = dict(zip(names, (o.shape for o in outs)))
    result = {}
    for n in convs:
        attrs = {a.name: helper.get_attribute_value(a) for a in n.attribute}
        out, inp = shapes[n.output[0]], shapes[n.input[0]]
        pixels = int(np.prod(out[2:]))
        taps = int(np.prod(attrs.get("kernel_shape", [1])))
        result[n.name] = (pixels, pixels * int(out[1]) * int(inp[1]) // int(attrs.get("group", 1)) * taps)
    return result


def mark_meta(model, key: str, value: str) -> None:
    """In place: metadata ``key`` set to ``value``, the rest kept."""
    for p in model.metadata_props:
        if p.key == key:
            p.value = value
            return
    entry = model.metadata_props.add()
    entry.key, entry.value = key, value


def _routed_files(models_dir: Path) -> list[Path]:
    """A routed folder's router and the specialists it names (validated by :func:`engine.models.load_router`); none
    without a router."""
    from engine.models import load_router

    router = models_dir / C.ROUTER_FILE
    if not router.is_file():
        return []
    return [router, *(models_dir / name for name in sorted(load_router(router, threads=1).routes))]


def quantize_model(src: str | os.PathLike, dst: str | os.PathLike) -> Path:
    """Dynamic int8 quantisation of one model (weights int8, activations quantised at run time).

    ``graph.value_info`` is cleared first (dynamo-exported models otherwise fail shape
    inference, see MEASUREMENTS.md), and float16-stored weights (and a sub-pixel generator's kernels,
    :func:`engine.graph.fold_subpixel_kernels`) are made float32 initialisers;
    metadata is kept and ``quantization`` set to ``int8-dynamic``.

    Raises:
        MissingExtraError: the ``onnx`` package is not installed.
        ModelError: quantisation failed.
    """
    try:
        import onnx
        from onnxruntime.quantization import QuantType, quantize_dynamic
    except ImportError as exc:
        raise MissingExtraError(f"int8 quantisation needs the onnx package ({exc}); pip install 'sketchmesh[dev]'") from None
    src, dst = Path(src), Path(dst)
    dst.parent.mkdir(parents=True, exist_ok=True)
    root = logging.getLogger()
    level = root.level
    with tempfile.TemporaryDirectory(prefix="sketchmesh-quant-") as tmp:
        try:
            model = onnx.load(str(src))
            del model.graph.value_info[:]
            _float32_weights(model)
            fold_subpixel_kernels(model)  # a sub-pixel generator's kernels, computed in its graph, as initialisers
            cleared = Path(tmp) / "input.onnx"
            onnx.save(model, str(cleared))
            root.setLevel(logging.ERROR)  # quantize_dynamic warns on the root logger about pre-processing
            quantize_dynamic(str(cleared), str(Path(tmp) / "q.onnx"), weight_type=QuantType.QInt8)
            q = onnx.load(str(Path(tmp) / "q.onnx"))
        except Exception as exc:  # onnx / onnxruntime raise many types
            raise ModelError(f"{src}: int8 quantisation failed: {' '.join(str(exc).split())[:300]}") from None
        finally:
            root.setLevel(level)
    _mark_quantization(q, "int8-dynamic")
    from engine.fileio import atomic_write_bytes

    atomic_write_bytes(dst, q.SerializeToString())
    return dst


INT8W_MIN_ELEMENTS = 16384
"""Conv / Gemm weights at least this large are stored in int8 by :func:`compact_model` (smaller ones, biases and
other operators' constants are kept as they are)."""


def _int8_weights(model) -> int:
    """In place: every Conv weight and Gemm B of at least :data:`INT8W_MIN_ELEMENTS` values, float32 or float16 behind
    a ``Cast``, becomes int8 with one float32 scale per output channel (symmetric, the channel's largest magnitude to
    127), behind ``Cast`` to float32 and ``Mul`` by the scales producing the old name. The two nodes compute from
    initialisers alone, so ONNX Runtime folds them when it loads the model: the file holds a byte per weight, the arithmetic
    stays float32. A weight feeding anything else, or several nodes, is left alone: a basis multiplied straight into
    vertex positions (the predictor's ``MatMul``) carries its rounding into the mesh. A Conv weight that
    :func:`engine.graph.subpixel_model` reads into sub-pixel kernels counts as the Conv's. Returns how many were stored."""
    from onnx import TensorProto, helper, numpy_helper

    graph = model.graph
    inits = {i.name: i for i in graph.initializer}
    casts = {n.output[0]: n for n in graph.node if n.op_type == "Cast" and len(n.input) == 1 and n.input[0] in inits
             and inits[n.input[0]].data_type == TensorProto.FLOAT16
             and any(a.name == "to" and a.i == TensorProto.FLOAT for a in n.attribute)}
    users: dict[str, list] = {}
    for n in graph.node:
        for i in n.input:
            users.setdefault(i, []).append(n)
    inputs = {i.name for i in graph.input}  # an initialiser listed as a graph input may be overridden: left alone
    taken = set(inits) | {o for n in graph.node for o in n.output} | inputs
    new_nodes, new_inits, dropped, done = [], [], set(), 0
    for name, nodes in users.items():
        if len(nodes) != 1 or (name not in inits and name not in casts) or name in inputs:
            continue
        n = nodes[0]
        if n.op_type == "Conv" and list(n.input).index(name) == 1:
            axis = 0
        elif n.op_type == "Gemm" and list(n.input).index(name) == 1:
            axis = 0 if any(a.name == "transB" and a.i for a in n.attribute) else 1
        elif n.op_type == "Reshape" and list(n.input).index(name) == 0 and n.output[0].endswith(SUBPIXEL_KERNEL_SUFFIX):
            axis = 0  # a Conv weight engine.graph.subpixel_model reads into its phase kernels: output channels first
        else:
            continue
        if name in inits and inits[name].data_type != TensorProto.FLOAT:
            continue  # a float16 (or other) network computes in its own type: a float32 Mul would not fit it
        src = casts[name].input[0] if name in casts else name
        if (len(users.get(src, ())) != 1 and src != name) or src in inputs:
            continue
        q_name, f_name, s_name = (name + suffix for suffix in ("__int8", "__float", "__scale"))
        if {q_name, f_name, s_name} & taken:
            continue
        w = numpy_helper.to_array(inits[src]).astype(np.float32)
        if w.size < INT8W_MIN_ELEMENTS or w.ndim < 2 or not np.all(np.isfinite(w)):
            continue
        other = tuple(a for a in range(w.ndim) if a != axis)
        scale = (np.abs(w).max(axis=other, keepdims=True) / 127.0).astype(np.float32)
        scale = np.where(scale > 0, scale, np.float32(1.0)).astype(np.float32)  # all-zero (or underflowing) channels
        q = np.clip(np.rint(w / scale), -127, 127).astype(np.int8)
        new_inits += [numpy_helper.from_array(q, q_name), numpy_helper.from_array(scale, s_name)]
        new_nodes += [helper.make_node("Cast", [q_name], [f_name], to=TensorProto.FLOAT, name=name + "__cast_int8"),
                      helper.make_node("Mul", [f_name, s_name], [name], name=name + "__dequantize")]
        dropped.add(src)
        if name in casts:
            dropped.add(name)  # the old Cast node's output, now the Mul's
        done += 1
    kept_nodes = [n for n in graph.node if not (n.op_type == "Cast" and n.output[0] in dropped)]
    kept_inits = [i for i in graph.initializer if i.name not in dropped]
    del graph.node[:]
    graph.node.extend(new_nodes + kept_nodes)
    del graph.initializer[:]
    graph.initializer.extend(kept_inits + new_inits)
    return done


def compact_model(src: str | os.PathLike, dst: str | os.PathLike, *, require: bool = True) -> Path:
    """Store one model's large Conv / Gemm weights in int8 (:func:`_int8_weights`), computing in float32.

    Unlike :func:`quantize_model` the activations stay float32 and ONNX Runtime runs the same kernels as for the
    original file, so the time is the original's; each weight moves by at most half a step (its channel's largest
    magnitude / 254). ConvTranspose weights (a ``pix2pix`` generator's decoder) and MatMul constants stay as stored.
    Metadata is kept, ``quantization`` set to ``int8-weights``; the result must load in ONNX Runtime. A model with
    no such weight (a tiny network) is an error, or with ``require=False`` copied as it is.

    Raises:
        MissingExtraError: the ``onnx`` package is not installed.
        ModelError: the file cannot be read, has no such weight (``require``), or the result does not load.
    """
    try:
        import onnx
    except ImportError as exc:
        raise MissingExtraError(f"int8 weight storage needs the onnx package ({exc}); pip install 'sketchmesh[dev]'") from None
    src, dst = Path(src), Path(dst)
    try:
        model = onnx.load(str(src))
    except Exception as exc:  # onnx raises DecodeError, OSError, ...
        raise ModelError(f"{src}: cannot read the ONNX model ({' '.join(str(exc).split())[:200]})") from None
    try:
        stored = _int8_weights(model)
    except Exception as exc:  # noqa: BLE001 - numpy / onnx on a malformed tensor
        raise ModelError(f"{src}: cannot store its weights in int8 ({' '.join(str(exc).split())[:200]})") from None
    if stored == 0:
        if not require:
            from engine.fileio import atomic_write_bytes

            atomic_write_bytes(dst, src.read_bytes())
            return dst
        raise ModelError(f"{src}: no Conv or Gemm weight of {INT8W_MIN_ELEMENTS} values or more to store in int8")
    _mark_quantization(model, "int8-weights")
    data = model.SerializeToString()
    try:
        onnx.checker.check_model(model)
        import onnxruntime as ort

        ort.InferenceSession(data, providers=["CPUExecutionProvider"])
    except Exception as exc:  # noqa: BLE001 - onnx / onnxruntime raise many types
        raise ModelError(f"{src}: int8 weight storage gave a model that does not load: {' '.join(str(exc).split())[:300]}") from None
    from engine.fileio import atomic_write_bytes

    atomic_write_bytes(dst, data)
    return dst


STATIC_PERCENTILE = 99.999
"""Percentile of each convolution input's calibrated values that sets its int8 range (:func:`static_int8_generator`):
the largest few of a million pixels clip instead of stretching every step."""

STATIC_MIN_PIXELS = 256
"""A convolution is run in int8 by :func:`static_int8_generator` only if its output has at least this many pixels (16 x
16): the small-image ones near the U-Net's bottom hold most of the weights and little of the arithmetic, and stay
stored as they were (a sub-pixel kernel in int8 would take four times its source's bytes)."""


def static_int8_generator(src: str | os.PathLike, dst: str | os.PathLike, calibration: np.ndarray, *,
                          keep_float: int = 1, percentile: float = STATIC_PERCENTILE,
                          min_pixels: int = STATIC_MIN_PIXELS) -> dict:
    """The generator with its large-image convolutions run in int8 (ONNX Runtime's QLinearConv): weights int8 per
    output channel, each convolution's input quantised with a range calibrated on ``calibration``, everything else
    (instance norms, activations, sub-pixel shuffles) float32.

    Those convolutions' weights, computed in the graph as sub-pixel kernels (:func:`engine.graph.fold_subpixel_kernels`)
    or stored in int8 or float16 (:func:`compact_model`), are made float32 initialisers first. The ``keep_float`` first
    and last convolutions stay float32: the first reads the raw drawing, the last writes the colours, and both are cheap
    (4 and 60 of about 750 million multiply-adds at 256 x 256); so do those with fewer than ``min_pixels`` output
    pixels (:data:`STATIC_MIN_PIXELS`), measured on the first drawing. Metadata is kept, ``quantization`` set to
    ``int8-static`` and ``source_sha256`` to ``src``'s hash (the engine refuses an int8 file whose source is not the
    folder's generator).

    Args:
        src: a float generator (``generator.onnx``).
        dst: where to write (atomically).
        calibration: (N, 1, 256, 256) float32 drawings in [0, 1], N >= 1: training sketches, never test ones.
        keep_float: how many convolutions at each end stay float32 (0: none on that account).
        percentile: see :data:`STATIC_PERCENTILE`.
        min_pixels: see :data:`STATIC_MIN_PIXELS` (0: every convolution not kept at the ends).

    Returns:
        ``{"quantized": convolutions in int8, "macs": the convolutions' multiply-adds a drawing (a sub-pixel kernel's
        zero taps counted), "macs_int8": those of the int8 ones, "kept_float": names kept, "calibration": N,
        "mean_abs": mean |int8 - float| of the output over the calibration drawings, "max_abs": its largest}``.

    Raises:
        MissingExtraError: the ``onnx`` package is not installed.
        SketchInputError: calibration drawings of the wrong shape, non-finite or outside [0, 1].
        ModelError: the file cannot be read, has no convolution to quantise, or the result does not load or gives
            non-finite output.
    """
    try:
        import onnx
        from onnxruntime.quantization import (
            CalibrationDataReader,
            CalibrationMethod,
            QuantFormat,
            QuantType,
            quantize_static,
        )
    except ImportError as exc:
        raise MissingExtraError(f"int8 quantisation needs the onnx package ({exc}); pip install 'sketchmesh[dev]'") from None
    import onnxruntime as ort

    x = np.asarray(calibration)
    s = C.SKETCH_SIZE
    if x.ndim != 4 or x.shape[1:] != (1, s, s) or len(x) == 0:
        raise SketchInputError(f"calibration drawings must be (N >= 1, 1, {s}, {s}), got {x.shape}")
    x = x.astype(np.float32)
    if not np.all(np.isfinite(x)) or x.min() < 0.0 or x.max() > 1.0:
        raise SketchInputError("calibration drawings must be finite and lie in [0, 1]")
    if keep_float < 0 or min_pixels < 0 or not 0.0 < percentile <= 100.0:
        raise SketchInputError(f"keep_float and min_pixels must be >= 0 and percentile in (0, 100], got {keep_float}, "
                               f"{min_pixels}, {percentile}")
    src, dst = Path(src), Path(dst)
    try:
        model = onnx.load(str(src))
    except Exception as exc:  # noqa: BLE001 - protobuf raises several types on a broken file
        raise ModelError(f"{src}: cannot read the ONNX model ({' '.join(str(exc).split())[:200]})") from None
    meta = {p.key: p.value for p in model.metadata_props}
    if meta.get(C.META_ROLE) != C.ROLE_GENERATOR:
        raise ModelError(f"{src}: not a generator (role {meta.get(C.META_ROLE)!r})")
    nodes = [n for n in model.graph.node if n.op_type == "Conv"]
    convs = [n.name for n in nodes]
    if len(set(convs)) != len(convs) or not all(convs):
        raise ModelError(f"{src}: convolutions without unique names cannot be told apart")
    sizes = _conv_sizes(model, nodes, x[:1])
    kept = [c for i, c in enumerate(convs)
            if i < keep_float or i >= len(convs) - keep_float or sizes[c][0] < min_pixels]
    if len(kept) == len(convs):
        raise ModelError(f"{src}: {len(convs)} convolutions, none left to quantise with {keep_float} kept float at each "
                         f"end and {min_pixels} output pixels at least")
    weights = {i for n in nodes if n.name not in kept for i in n.input[1:]}

    class _Reader(CalibrationDataReader):
        def __init__(self) -> None:
            self._rows = iter(range(len(x)))

        def get_next(self):
            i = next(self._rows, None)
            return None if i is None else {C.GENERATOR_INPUT: x[i:i + 1]}

    root = logging.getLogger()
    level = root.level
    with tempfile.TemporaryDirectory(prefix="sketchmesh-static-") as tmp:
        try:
            del model.graph.value_info[:]
            _float32_weights(model, only=weights)
            fold_subpixel_kernels(model, only=weights)
            plain = Path(tmp) / "float.onnx"
            onnx.save(model, str(plain))
            root.setLevel(logging.ERROR)  # quantize_static warns on the root logger about pre-processing
            with contextlib.redirect_stdout(io.StringIO()):  # and its calibrator prints its progress
                quantize_static(str(plain), str(Path(tmp) / "q.onnx"), _Reader(), quant_format=QuantFormat.QDQ,
                                op_types_to_quantize=["Conv"], per_channel=True, activation_type=QuantType.QUInt8,
                                weight_type=QuantType.QInt8, calibrate_method=CalibrationMethod.Percentile,
                                nodes_to_exclude=kept, extra_options={"CalibPercentile": percentile})
            q = onnx.load(str(Path(tmp) / "q.onnx"))
        except Exception as exc:  # noqa: BLE001 - onnx / onnxruntime raise many types
            raise ModelError(f"{src}: static int8 quantisation failed: {' '.join(str(exc).split())[:300]}") from None
        finally:
            root.setLevel(level)
    from engine.models import file_sha256

    del q.metadata_props[:]  # the source's metadata, marked as what it now is
    for k, v in {**meta, C.META_QUANTIZATION: "int8-static", C.META_SOURCE_SHA256: file_sha256(src)}.items():
        mark_meta(q, k, v)
    data = q.SerializeToString()
    try:
        fast = ort.InferenceSession(data, providers=["CPUExecutionProvider"])
        ref = ort.InferenceSession(str(src), providers=["CPUExecutionProvider"])
        got = np.concatenate([fast.run(None, {C.GENERATOR_INPUT: x[i:i + 8]})[0] for i in range(0, len(x), 8)])
        want = np.concatenate([ref.run(None, {C.GENERATOR_INPUT: x[i:i + 8]})[0] for i in range(0, len(x), 8)])
    except Exception as exc:  # noqa: BLE001 - onnxruntime raises many types
        raise ModelError(f"{src}: the int8 generator does not run: {' '.join(str(exc).split())[:300]}") from None
    if not np.all(np.isfinite(got)):
        raise ModelError(f"{src}: the int8 generator gives NaN or inf on the calibration drawings")
    dequantized = {n.output[0] for n in q.graph.node if n.op_type == "DequantizeLinear"}
    done = sum(n.op_type == "Conv" and len(n.input) > 1 and n.input[1] in dequantized for n in q.graph.node)
    if done == 0:
        raise ModelError(f"{src}: static int8 quantisation left every convolution float32")
    diff = np.abs(np.clip(got, 0, 1) - np.clip(want, 0, 1))
    from engine.fileio import atomic_write_bytes

    atomic_write_bytes(dst, data)
    macs = sum(m for _, m in sizes.values())
    return {"quantized": done, "macs": macs, "macs_int8": sum(m for c, (_, m) in sizes.items() if c not in kept),
            "kept_float": kept, "calibration": len(x), "mean_abs": float(diff.mean()), "max_abs": float(diff.max())}


def folder_bytes(models_dir: Path) -> int:
    """Bytes of the models a folder holds for the engine: the generator (and its int8 form, where there is one), the
    predictor, and a router with the specialists it names."""
    fast = [models_dir / C.GENERATOR_INT8_FILE] if (models_dir / C.GENERATOR_INT8_FILE).is_file() else []
    return sum(f.stat().st_size for f in [*model_paths(models_dir), *fast, *_routed_files(models_dir)])


def split_variant(name: str) -> tuple[str, bool]:
    """``"int8+mirror"`` -> ``("int8", True)``: a variant's precision and whether mirror averaging is on."""
    if name not in C.MIRRORED_VARIANTS:
        raise SketchInputError(f"unknown variant {name!r}; choose from {', '.join(VARIANTS)}, "
                               f"each optionally with {MIRROR_SUFFIX}")
    return name.removesuffix(MIRROR_SUFFIX), name.endswith(MIRROR_SUFFIX)


def make_variant(models_dir: Path, variant: str, out_dir: Path) -> Path:
    """A folder holding the models of precision ``variant`` (``fp32`` returns ``models_dir`` itself); a folder
    already made in ``out_dir`` (marked ``.complete`` when its last file is written) is reused: a precision and its
    ``+mirror`` twin share one conversion. A routed folder's router is copied and every specialist it names is
    converted as the predictor is; other files are left out."""
    if variant == "fp32":
        return models_dir
    if variant not in VARIANTS:
        raise SketchInputError(f"unknown variant {variant!r}; choose from {', '.join(VARIANTS)}")
    gen, pred = model_paths(models_dir)
    folder = out_dir / variant
    if (folder / ".complete").is_file():
        return folder
    folder.mkdir(parents=True, exist_ok=True)
    convert = functools.partial(compact_model, require=False) if variant == "int8w" else quantize_model
    if variant in ("int8", "int8w"):
        convert(gen, folder / C.GENERATOR_FILE)
    else:
        shutil.copyfile(gen, folder / C.GENERATOR_FILE)
    convert(pred, folder / C.PREDICTOR_FILE)
    for f in _routed_files(models_dir):  # a routed folder: the router kept, its specialists made as the predictor
        if f.name == C.ROUTER_FILE:
            shutil.copyfile(f, folder / f.name)
        else:
            convert(f, folder / f.name)
    (folder / ".complete").touch()
    return folder


def synthetic_sketches(folder: Path, size: int = 512) -> list[Path]:
    """Write a few synthetic dark-on-white sketch PNGs (a mug-like outline, a box, a star) into ``folder``."""
    import cv2

    folder.mkdir(parents=True, exist_ok=True)
    c = size / 2.0
    t = np.linspace(0, 2 * np.pi, 120)
    shapes = {
        "ellipse": [np.stack([c + 0.35 * size * np.cos(t), c + 0.25 * size * np.sin(t)], 1)],
        "box": [np.array([[0.2, 0.3], [0.6, 0.3], [0.8, 0.15], [0.4, 0.15], [0.2, 0.3], [0.2, 0.8], [0.6, 0.8],
                          [0.6, 0.3], [0.8, 0.15], [0.8, 0.65], [0.6, 0.8]]) * size],
        "star": [np.stack([c + (0.4 - 0.2 * (np.arange(11) % 2)) * size * np.cos(np.arange(11) * np.pi / 5),
                           c + (0.4 - 0.2 * (np.arange(11) % 2)) * size * np.sin(np.arange(11) * np.pi / 5)], 1)],
    }
    paths = []
    for name, polys in shapes.items():
        img = np.full((size, size), 255, np.uint8)
        cv2.polylines(img, [np.round(p * 16).astype(np.int32) for p in polys], False, 0, 4, cv2.LINE_AA, 4)
        p = folder / f"{name}.png"
        cv2.imwrite(str(p), img)
        paths.append(p)
    return paths


def _default_sketches(tmp: Path) -> list[Path]:
    try:
        from assets import SAMPLES_DIR
    except ModuleNotFoundError:
        SAMPLES_DIR = Path(__file__).resolve().parents[1] / "assets" / "samples"
    found = sorted(p for p in Path(SAMPLES_DIR).glob("*") if p.suffix.lower() in (".png", ".jpg", ".jpeg", ".bmp", ".webp", ".tif", ".tiff"))
    return found or synthetic_sketches(tmp / "sketches")


def _percentiles(ms: list[float]) -> tuple[float, float, float]:
    a = np.asarray(ms, dtype=np.float64)
    return float(np.percentile(a, 50)), float(np.percentile(a, 95)), float(a.mean())


def bench_variant(folder: Path, sketches: list[Path], runs: int, warmup: int, threads: int | None, export_dir: Path,
                  progress=None, mirror: bool = False) -> tuple[dict[str, list[float]], list]:
    """Time ``runs`` predictions (+ export) of one variant with the cache off (``mirror``: mirror averaging on).

    Returns:
        (stage -> list of ms, first prediction of each sketch for the error comparison).
    """
    from engine.export import export_mesh
    from engine.pipeline import SketchEngine

    engine = SketchEngine(folder, threads=threads, cache_size=0, mirror_average=mirror)
    engine.load()
    reference = [engine.predict(s, want_normals=True) for s in sketches]
    for k in range(warmup):
        engine.predict(sketches[k % len(sketches)])
    times: dict[str, list[float]] = {s: [] for s in STAGES}
    out = export_dir / f"mesh{EXPORT_SUFFIX}"
    for k in range(runs):
        t0 = time.perf_counter()
        pred = engine.predict(sketches[k % len(sketches)])
        t1 = time.perf_counter()
        export_mesh(pred.mesh, out)
        t2 = time.perf_counter()
        for s, v in pred.timings_ms.items():
            if s in times:  # the pipeline's "refine" stage is off here (0.0)
                times[s].append(v)
        times["export"].append((t2 - t1) * 1e3)
        times["total"].append((t2 - t0) * 1e3)
        if progress is not None:
            progress.update(1)
    return times, reference


def variant_error(reference: list, candidate: list) -> dict[str, float]:
    """Error of ``candidate`` predictions against ``reference`` (same sketches, same order).

    Returns:
        normals_mae: mean |normals - normals_ref| over pixels and channels (encoded units, [0, 1]);
        vertex_mean / vertex_max: per-vertex Euclidean distance, mean over all and max over all.
    """
    mae, vmean, vmax = [], [], []
    for r, c in zip(reference, candidate):
        mae.append(float(np.abs(c.normals.astype(np.float64) - r.normals).mean()))
        d = np.linalg.norm(c.mesh.vertices.astype(np.float64) - r.mesh.vertices, axis=1)
        vmean.append(float(d.mean()))
        vmax.append(float(d.max()))
    return {"normals_mae": float(np.mean(mae)), "vertex_mean": float(np.mean(vmean)), "vertex_max": float(np.max(vmax))}


def run_engine_bench(models_dir=None, runs: int = 50, warmup: int = 3, threads: int | None = None,
                     sketches: list[str] | None = None, variants: list[str] | None = None, json_path: str | None = None) -> int:
    """Run the benchmark, print the table, optionally write JSON records. Returns the exit code (0).

    Each record: benchmark, variant, stage, p50_ms, p95_ms, mean_ms, runs, threads, error
    (normals_mae, vertex_mean, vertex_max against fp32), model_bytes, models_dir, machine.
    """
    from engine.models import default_threads

    variants = list(variants or VARIANTS)
    for v in variants:
        split_variant(v)  # every name checked before anything runs
    if "fp32" not in variants:
        variants.insert(0, "fp32")  # the reference for the error columns
    src = resolve_models_dir(models_dir)
    model_paths(src)
    threads = threads or default_threads()
    records = []
    with tempfile.TemporaryDirectory(prefix="sketchmesh-bench-") as tmp_name:
        tmp = Path(tmp_name)
        sketch_paths = [Path(s) for s in sketches] if sketches else _default_sketches(tmp)
        progress = None
        with contextlib.suppress(ImportError):
            from tqdm import tqdm

            progress = tqdm(total=runs * len(variants), unit="run", file=sys.stderr, leave=False, disable=None)
        results = {}
        notes = []
        for variant in variants:
            precision, mirror = split_variant(variant)
            try:
                folder = make_variant(src, precision, tmp / "variants")
            except MissingExtraError as exc:
                notes.append(f"{variant}: skipped ({exc})")
                continue
            times, ref = bench_variant(folder, sketch_paths, runs, warmup, threads, tmp, progress, mirror=mirror)
            size = folder_bytes(folder)
            results[variant] = (times, ref, size)
        if progress is not None:
            progress.close()
    base_ref = results["fp32"][1]
    machine = {"python": platform.python_version(), "cpu_count": os.cpu_count(), "platform": platform.platform()}
    for variant, (times, ref, size) in results.items():
        err = variant_error(base_ref, ref)
        for stage in STAGES:
            p50, p95, mean = _percentiles(times[stage])
            records.append({
                "benchmark": "engine", "variant": variant, "stage": stage, "p50_ms": round(p50, 4),
                "p95_ms": round(p95, 4), "mean_ms": round(mean, 4), "runs": runs, "threads": threads,
                "error": err, "model_bytes": size, "models_dir": str(src), "sketches": len(sketch_paths),
                "machine": machine,
            })
    print(format_table(records))
    for n in notes:
        print(f"note: {n}")
    if json_path:
        import json

        from engine.errors import ExportError
        from engine.fileio import atomic_write_text

        try:
            atomic_write_text(json_path, json.dumps(records, indent=2) + "\n")
        except OSError as exc:
            raise ExportError(f"cannot write {json_path}: {exc.strerror or exc}") from None
        print(f"wrote {len(records)} records to {json_path}")
    return 0


def format_table(records: list[dict]) -> str:
    """Plain-text table: one row per (variant, stage) with p50 / p95 and the variant's error."""
    head = f"{'variant':<22} {'stage':<11} {'p50 ms':>9} {'p95 ms':>9}  {'normals MAE':>11} {'vert mean':>10} {'vert max':>10} {'MB':>7}"
    lines = [head, "-" * len(head)]
    for r in records:
        e = r["error"]
        lines.append(
            f"{r['variant']:<22} {r['stage']:<11} {r['p50_ms']:>9.3f} {r['p95_ms']:>9.3f}  "
            f"{e['normals_mae']:>11.2e} {e['vertex_mean']:>10.2e} {e['vertex_max']:>10.2e} {r['model_bytes'] / 1e6:>7.2f}"
        )
    return "\n".join(lines)
