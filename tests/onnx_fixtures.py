"""Tiny, contract-conforming ONNX models for tests (built with the onnx helper API, no torch).

They let the engine, the CLI, the app and the benchmarks run end to end without trained
models:

* generator ``sketch`` (N, 1, 256, 256) -> ``normals`` (N, 3, 256, 256): a 5x5 convolution
  (3 output channels) followed by a sigmoid, so the output depends on the input and lies in
  (0, 1);
* mesh predictor ``normals`` (N, 3, 64, 64) -> ``local_offset`` (N, V, 3) and
  ``global_offset`` (N, 3): 8x8 average pooling to (N, 3, 8, 8), flatten to (N, 192) and two
  small Gemms (weights ~ N(0, 0.002)), so the mesh stays within a few hundredths of the template
  sphere but moves when the sketch changes.

Both carry all of :data:`engine.contract.REQUIRED_METADATA` plus the role-specific keys.
Opset 17, IR version 8 (loadable by every onnxruntime >= 1.14).

Public helpers: :func:`write_fixture_models`, :func:`make_generator`, :func:`make_predictor`, :func:`make_router`,
:func:`write_corrupt_model`, :func:`write_wrong_shape_generator`, :func:`write_model`.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

from engine import contract as C
from engine.icosphere import TEMPLATE_RADIUS

OPSET = 17
IR_VERSION = 8
PREDICTOR_WEIGHT_STD = 0.002
"""Std of the predictor's Gemm weights: offsets stay ~1e-2, the mesh near the sphere."""


def _metadata(role: str, **extra: str) -> dict[str, str]:
    meta = {
        C.META_FORMAT: C.FORMAT_VERSION,
        C.META_ROLE: role,
        C.META_CODE_VERSION: "test-fixture",
        C.META_CONFIG: json.dumps({"fixture": True}),
        C.META_CONVENTIONS: C.CONVENTIONS_ID,
        C.META_QUANTIZATION: "none",
    }
    meta.update(extra)
    return meta


def _finish(graph: onnx.GraphProto, metadata: dict[str, str]) -> onnx.ModelProto:
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", OPSET)], producer_name="sketchmesh-tests")
    model.ir_version = IR_VERSION
    helper.set_model_props(model, metadata)
    onnx.checker.check_model(model)
    return model


def make_generator(
    seed: int = 0,
    *,
    size: int = C.SKETCH_SIZE,
    out_channels: int = 3,
    metadata: dict[str, str] | None = None,
    drop_metadata: tuple[str, ...] = (),
    input_dtype: int = TensorProto.FLOAT,
) -> onnx.ModelProto:
    """A conv + sigmoid generator: (N, 1, size, size) -> (N, out_channels, size, size) in (0, 1).

    Args:
        seed: RNG seed of the weights.
        size: spatial size of input and output (256 for a conforming model).
        out_channels: output channels (3 for a conforming model).
        input_dtype: element type of the input (FLOAT for a conforming model; others are cast).
        metadata: entries that replace or extend the default metadata.
        drop_metadata: keys removed from the metadata (for validation tests).
    """
    rng = np.random.default_rng(seed)
    w = (rng.standard_normal((out_channels, 1, 5, 5)) * 0.5).astype(np.float32)
    b = (rng.standard_normal(out_channels) * 0.1).astype(np.float32)
    x = C.GENERATOR_INPUT
    nodes = []
    if input_dtype != TensorProto.FLOAT:
        nodes.append(helper.make_node("Cast", [x], ["x_float"], to=TensorProto.FLOAT))
        x = "x_float"
    nodes += [
        helper.make_node("Conv", [x, "W", "B"], ["z"], pads=[2, 2, 2, 2], kernel_shape=[5, 5]),
        helper.make_node("Sigmoid", ["z"], [C.GENERATOR_OUTPUT]),
    ]
    graph = helper.make_graph(
        nodes,
        "fixture_generator",
        [helper.make_tensor_value_info(C.GENERATOR_INPUT, input_dtype, ["N", 1, size, size])],
        [helper.make_tensor_value_info(C.GENERATOR_OUTPUT, TensorProto.FLOAT, ["N", out_channels, size, size])],
        initializer=[numpy_helper.from_array(w, "W"), numpy_helper.from_array(b, "B")],
    )
    meta = _metadata(C.ROLE_GENERATOR, **{C.META_BASE_CHANNELS: "3"})
    meta.update(metadata or {})
    for k in drop_metadata:
        meta.pop(k, None)
    return _finish(graph, meta)


def make_predictor(
    level: int = 3,
    seed: int = 0,
    *,
    metadata: dict[str, str] | None = None,
    drop_metadata: tuple[str, ...] = (),
    local_bias: np.ndarray | None = None,
) -> onnx.ModelProto:
    """A pooling + Gemm mesh predictor: (N, 3, 64, 64) -> (N, V, 3), (N, 3), V = 10 * 4**level + 2.

    Args:
        level: icosphere level of the template (3 -> 642 vertices).
        seed: RNG seed of the weights.
        metadata: entries that replace or extend the default metadata (e.g. a wrong template_level).
        drop_metadata: keys removed from the metadata.
        local_bias: (V, 3) offsets added to every prediction (e.g. to fold the mesh); zeros when None.
    """
    V = 10 * 4**level + 2
    rng = np.random.default_rng(seed + 1000)
    feat = 3 * 8 * 8
    w_local = (rng.standard_normal((feat, V * 3)) * PREDICTOR_WEIGHT_STD).astype(np.float32)
    b_local = np.zeros(V * 3, np.float32) if local_bias is None else np.asarray(local_bias, np.float32).reshape(V * 3)
    w_global = (rng.standard_normal((feat, 3)) * PREDICTOR_WEIGHT_STD).astype(np.float32)
    b_global = np.zeros(3, np.float32)
    nodes = [
        helper.make_node("AveragePool", [C.PREDICTOR_INPUT], ["pooled"], kernel_shape=[8, 8], strides=[8, 8]),
        helper.make_node("Flatten", ["pooled"], ["flat"], axis=1),
        helper.make_node("Gemm", ["flat", "Wl", "Bl"], ["local_flat"]),
        helper.make_node("Reshape", ["local_flat", "local_shape"], [C.PREDICTOR_OUTPUT_LOCAL]),
        helper.make_node("Gemm", ["flat", "Wg", "Bg"], [C.PREDICTOR_OUTPUT_GLOBAL]),
    ]
    inits = [
        numpy_helper.from_array(w_local, "Wl"),
        numpy_helper.from_array(b_local, "Bl"),
        numpy_helper.from_array(w_global, "Wg"),
        numpy_helper.from_array(b_global, "Bg"),
        numpy_helper.from_array(np.array([-1, V, 3], np.int64), "local_shape"),
    ]
    s = C.PREDICTOR_INPUT_SIZE
    graph = helper.make_graph(
        nodes,
        "fixture_mesh_predictor",
        [helper.make_tensor_value_info(C.PREDICTOR_INPUT, TensorProto.FLOAT, ["N", 3, s, s])],
        [
            helper.make_tensor_value_info(C.PREDICTOR_OUTPUT_LOCAL, TensorProto.FLOAT, ["N", V, 3]),
            helper.make_tensor_value_info(C.PREDICTOR_OUTPUT_GLOBAL, TensorProto.FLOAT, ["N", 3]),
        ],
        initializer=inits,
    )
    meta = _metadata(
        C.ROLE_PREDICTOR, **{C.META_TEMPLATE_LEVEL: str(level), C.META_TEMPLATE_RADIUS: repr(TEMPLATE_RADIUS)}
    )
    meta.update(metadata or {})
    for k in drop_metadata:
        meta.pop(k, None)
    return _finish(graph, meta)


def make_router(
    probabilities,
    categories=("bench", "car", "chair"),
    routes: dict | None = None,
    threshold: float = 0.9,
    *,
    metadata: dict[str, str] | None = None,
    drop_metadata: tuple[str, ...] = (),
    softmax: bool = True,
    weights=None,
    batch: int | str = "N",
) -> onnx.ModelProto:
    """A router whose ``probabilities`` are fixed: softmax of log(``probabilities``) whatever the image
    (the input is pooled and multiplied by zero, so the graph still reads it), or, with ``weights``, read from the
    image's left-right asymmetry.

    Args:
        probabilities: (K,) the output for every drawing (NaN entries make a broken router).
        categories, routes, threshold: the metadata (routes default: mesh_predictor_legged.onnx serves
            bench and chair).
        softmax: False outputs ``probabilities`` as given, unnormalised (a router exported without its softmax).
        weights: (3, K): the logits are ``log(probabilities) + d @ weights``, d (N, 3) each channel's mean over the
            image's left half minus its mean over the right half.
        batch: the batch dimension ("N" dynamic; 1 a router that takes one image a run, as the contract allows).
    """
    p = np.asarray(probabilities, np.float64)
    k = len(p)
    logits = np.log(np.where(p > 0, p, 1e-30)).astype(np.float32) if softmax else p.astype(np.float32)
    logits[np.isnan(p)] = np.nan
    s = C.PREDICTOR_INPUT_SIZE
    halves = np.where(np.arange(s) < s // 2, 2.0, -2.0).astype(np.float32) * np.ones((1, 1, s, 1), np.float32)
    w = np.zeros((3, k), np.float32) if weights is None else np.asarray(weights, np.float32).reshape(3, k)
    nodes = [
        helper.make_node("Mul", [C.ROUTER_INPUT, "halves"], ["signed"]),
        helper.make_node("GlobalAveragePool", ["signed"], ["pooled"]),
        helper.make_node("Flatten", ["pooled"], ["flat"], axis=1),
        helper.make_node("Gemm", ["flat", "W", "B"], ["logits"]),
        helper.make_node("Softmax", ["logits"], [C.ROUTER_OUTPUT], axis=1) if softmax
        else helper.make_node("Identity", ["logits"], [C.ROUTER_OUTPUT]),
    ]
    graph = helper.make_graph(
        nodes,
        "fixture_router",
        [helper.make_tensor_value_info(C.ROUTER_INPUT, TensorProto.FLOAT, [batch, 3, s, s])],
        [helper.make_tensor_value_info(C.ROUTER_OUTPUT, TensorProto.FLOAT, [batch, k])],
        initializer=[numpy_helper.from_array(w, "W"), numpy_helper.from_array(logits, "B"),
                     numpy_helper.from_array(halves, "halves")],
    )
    meta = _metadata(C.ROLE_ROUTER, **{
        C.META_CATEGORIES: json.dumps(list(categories)),
        C.META_ROUTES: json.dumps(routes if routes is not None else {"mesh_predictor_legged.onnx": ["bench", "chair"]}),
        C.META_ROUTE_THRESHOLD: repr(threshold),
    })
    meta.update(metadata or {})
    for key in drop_metadata:
        meta.pop(key, None)
    return _finish(graph, meta)


def write_model(model: onnx.ModelProto, path: str | Path) -> Path:
    """Serialise a model to ``path`` (parents created). Returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(model.SerializeToString())
    return path


def fold_offsets(level: int, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """(V, 3) offsets that fold a template sphere (its +z cap pushed down through its -z side, a little off the
    template's symmetry so no vertex lands on another), and the cap's (V,) mask."""
    from engine.icosphere import icosphere

    t = icosphere(level, radius).vertices.astype(np.float64)
    cap = t[:, 2] > 0.7 * radius
    off = np.zeros_like(t)
    off[cap] = [0.05 * radius, 0.0, -1.5 * radius]
    return off, cap


def write_fixture_models(folder: str | Path, level: int = 3, seed: int = 0, *, fold: bool = False) -> Path:
    """Write ``generator.onnx`` and ``mesh_predictor.onnx`` into ``folder``; returns the folder. ``fold``: the
    predictor folds every mesh (:func:`fold_offsets`), so its surface crosses itself."""
    folder = Path(folder)
    write_model(make_generator(seed), folder / C.GENERATOR_FILE)
    bias = fold_offsets(level, TEMPLATE_RADIUS)[0] if fold else None
    write_model(make_predictor(level, seed, local_bias=bias), folder / C.PREDICTOR_FILE)
    return folder


def write_corrupt_model(path: str | Path) -> Path:
    """Write bytes that are not an ONNX model (a truncated protobuf) to ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    good = make_generator().SerializeToString()
    path.write_bytes(b"\x08\x07\x12\x04junk" + good[: len(good) // 3][::-1])
    return path


def write_wrong_shape_generator(path: str | Path) -> Path:
    """Write a generator whose tensors are 128x128 instead of 256x256 (metadata otherwise valid)."""
    return write_model(make_generator(size=128), path)
