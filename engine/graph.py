"""Exact rewrites of a model's graph that make it faster on the CPU (``onnx`` package, the ``dev`` extra).

:func:`subpixel_model` turns every nearest-neighbour 2x upsampling followed by a one-pixel pad and a 3x3 convolution
(the ``resize`` generator's decoder: ``Resize`` -> ``Pad`` -> ``Conv``) into a 3x3 convolution on the *small* image
with four times the output channels and a ``DepthToSpace`` (a sub-pixel convolution). Output pixel ``(2i + a, 2j + b)``
of the original reads, through the nearest upsampling, only small-image rows ``i - 1, i`` (``a = 0``) or ``i, i + 1``
(``a = 1``) and the same columns, so each of the four phases ``(a, b)`` is a 3x3 convolution of the small image
whose taps are sums of the original kernel's (:func:`phase_matrix`). A reflected or replicated pad of one pixel of the
upsampled image equals a replicated pad of the small one (both repeat the border pixel), a zero pad a zero pad.

The arithmetic is the same but for the order of the kernel sums (float32 rounding): no pad, resize or reorder
passes over the large image, which on 2 cores is about a quarter of the generator's time. The new kernels are
computed in the graph from the stored ones (``MatMul`` by the phase matrix, ``Reshape``, ``Transpose``), so ONNX
Runtime folds them when it loads the model and the file keeps its weights as they were stored (int8 included).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from engine.errors import MissingExtraError, ModelError

SUBPIXEL_KERNEL_SUFFIX = "__subpixel_w9"
"""The output name's ending of the first node reading a rewritten Conv's weight (:func:`engine.bench.compact_model`
stores such a weight in int8 as the Conv's)."""

SUBPIXEL_ATOL = 1e-4
"""Largest difference of the rewritten model's outputs from the original's allowed by :func:`subpixel_model` (the
generator's outputs lie in [0, 1]; float32 summation order moves them by about 1e-6)."""


def phase_matrix() -> np.ndarray:
    """(9, 36) float32: a 3x3 kernel, flattened row-major, times this gives the four phases' 3x3 kernels on the small
    image, phase ``p = 2 a + b`` in columns ``9 p ... 9 p + 8`` (row-major). Tap ``(dy, dx)`` of the original kernel
    (offsets -1..1 on the upsampled image) lands on small-image offset ``(floor((a + dy) / 2), floor((b + dx) / 2))``."""
    s = np.zeros((9, 36), np.float32)
    for a in (0, 1):
        for b in (0, 1):
            for dy in (-1, 0, 1):
                for dx in (-1, 0, 1):
                    u, v = (a + dy) // 2 + 1, (b + dx) // 2 + 1
                    s[(dy + 1) * 3 + (dx + 1), (2 * a + b) * 9 + u * 3 + v] = 1.0
    return s


def _attrs(node) -> dict:
    from onnx import helper

    return {a.name: helper.get_attribute_value(a) for a in node.attribute}


def _text(v) -> str:
    return v.decode() if isinstance(v, bytes) else str(v)


def _dims(shape: list) -> list[int]:
    """A concrete shape for a model input: a dynamic batch 1, other dynamic dimensions 64 (an image, not a pixel)."""
    return [d if isinstance(d, int) and d > 0 else (1 if k == 0 else 64) for k, d in enumerate(shape)]


def _probe(model, names: dict[str, int]) -> dict[str, np.ndarray]:
    """Values of the tensors ``names`` (name -> onnx element type) for an all-zero input (dynamic dimensions 1): the
    pads, scales and weights of the candidates, which the exporter computes in small constant subgraphs."""
    import onnx
    import onnxruntime as ort
    from onnx import helper

    probe = onnx.ModelProto()
    probe.CopyFrom(model)
    known = {o.name for o in probe.graph.output}
    for name, elem in names.items():
        if name not in known:
            probe.graph.output.append(helper.make_tensor_value_info(name, elem, None))
    feeds = {}
    for i in probe.graph.input:
        if i.name in {t.name for t in probe.graph.initializer}:
            continue
        dims = _dims([d.dim_value if d.HasField("dim_value") else None for d in i.type.tensor_type.shape.dim])
        feeds[i.name] = np.zeros(dims, np.float32)
    sess = ort.InferenceSession(probe.SerializeToString(), providers=["CPUExecutionProvider"])
    outs = [o.name for o in sess.get_outputs()]
    return dict(zip(outs, sess.run(outs, feeds)))


def _candidates(graph) -> list[tuple]:
    """(resize, pad, conv) chains whose attributes fit; their constant inputs are checked after :func:`_probe`."""
    users: dict[str, list] = {}
    for n in graph.node:
        for i in n.input:
            users.setdefault(i, []).append(n)
    outputs = {o.name for o in graph.output}
    found = []
    for r in graph.node:
        if r.op_type != "Resize" or len(r.input) < 3 or r.input[2] == "" or (len(r.input) > 3 and r.input[3]):
            continue
        ra = _attrs(r)
        if "axes" in ra:  # opset 18: scales for chosen axes only
            continue
        if (_text(ra.get("mode", "nearest")) != "nearest"
                or _text(ra.get("coordinate_transformation_mode", "half_pixel")) != "asymmetric"
                or _text(ra.get("nearest_mode", "round_prefer_floor")) != "floor"):
            continue
        pads = users.get(r.output[0], [])
        if len(pads) != 1 or pads[0].op_type != "Pad" or r.output[0] in outputs:
            continue
        p = pads[0]
        if (_text(_attrs(p).get("mode", "constant")) not in ("constant", "reflect", "edge") or len(p.input) < 2
                or (len(p.input) > 3 and p.input[3])):  # opset 18: pads for chosen axes only
            continue
        convs = users.get(p.output[0], [])
        if len(convs) != 1 or convs[0].op_type != "Conv" or p.output[0] in outputs or convs[0].input[0] != p.output[0]:
            continue
        c = convs[0]
        ca = _attrs(c)
        if (list(ca.get("kernel_shape", [3, 3])) != [3, 3] or any(s != 1 for s in ca.get("strides", [1, 1]))
                or any(d != 1 for d in ca.get("dilations", [1, 1])) or ca.get("group", 1) != 1
                or any(ca.get("pads", [0, 0, 0, 0])) or _text(ca.get("auto_pad", "NOTSET")) != "NOTSET"):
            continue
        found.append((r, p, c))
    return found


def _subpixel(model) -> int:
    """In place: every fitting Resize -> Pad -> Conv chain rewritten (module doc). Returns how many."""
    from onnx import TensorProto, helper, numpy_helper

    graph = model.graph
    chains = _candidates(graph)
    if not chains:
        return 0
    wanted = {}
    for r, p, c in chains:
        wanted[r.input[2]] = TensorProto.FLOAT
        wanted[p.input[1]] = TensorProto.INT64
        if len(p.input) > 2 and p.input[2]:
            wanted[p.input[2]] = TensorProto.FLOAT
        wanted[c.input[1]] = TensorProto.FLOAT
    inits = {i.name: i for i in graph.initializer}
    values = {k: numpy_helper.to_array(inits[k]) for k in wanted if k in inits}
    values.update(_probe(model, {k: t for k, t in wanted.items() if k not in inits}))
    taken = {o for n in graph.node for o in n.output} | set(inits) | {i.name for i in graph.input}
    phase = "subpixel__phases"
    new_inits = [numpy_helper.from_array(phase_matrix(), phase), numpy_helper.from_array(np.ones((1, 4), np.float32),
                                                                                          "subpixel__ones")]
    if {phase, "subpixel__ones"} & taken:
        return 0
    new_nodes, drop, done = [], set(), 0
    for r, p, c in chains:
        scales, pads, w = values[r.input[2]], values[p.input[1]], values[c.input[1]]
        mode = _text(_attrs(p).get("mode", "constant"))
        fill = values.get(p.input[2]) if len(p.input) > 2 and p.input[2] else None
        if (np.asarray(scales).tolist() != [1.0, 1.0, 2.0, 2.0] or np.asarray(pads).tolist() != [0, 0, 1, 1, 0, 0, 1, 1]
                or w.ndim != 4 or w.shape[2:] != (3, 3) or (mode == "constant" and fill is not None and np.any(fill))):
            continue
        cout, cin = int(w.shape[0]), int(w.shape[1])
        k = c.name or c.output[0]
        names = {s: f"{k}__subpixel_{s}" for s in ("pads", "padded", "s1", "s2", "s3", "w9", "w36", "w4", "w4t",
                                                 "weight", "b1", "b4", "bs1", "bs2", "bias", "out4")}
        if set(names.values()) & taken:
            continue
        taken |= set(names.values())
        new_inits += [numpy_helper.from_array(np.array([0, 0, 1, 1, 0, 0, 1, 1], np.int64), names["pads"]),
                      numpy_helper.from_array(np.array([cout * cin, 9], np.int64), names["s1"]),
                      numpy_helper.from_array(np.array([cout, cin, 4, 9], np.int64), names["s2"]),
                      numpy_helper.from_array(np.array([4 * cout, cin, 3, 3], np.int64), names["s3"])]
        new_nodes += [
            helper.make_node("Pad", [r.input[0], names["pads"]], [names["padded"]],
                             mode="constant" if mode == "constant" else "edge", name=names["padded"]),
            helper.make_node("Reshape", [c.input[1], names["s1"]], [names["w9"]], name=names["w9"]),
            helper.make_node("MatMul", [names["w9"], phase], [names["w36"]], name=names["w36"]),
            helper.make_node("Reshape", [names["w36"], names["s2"]], [names["w4"]], name=names["w4"]),
            helper.make_node("Transpose", [names["w4"]], [names["w4t"]], perm=[0, 2, 1, 3], name=names["w4t"]),
            helper.make_node("Reshape", [names["w4t"], names["s3"]], [names["weight"]], name=names["weight"]),
        ]
        conv_in = [names["padded"], names["weight"]]
        if len(c.input) > 2 and c.input[2]:
            new_inits += [numpy_helper.from_array(np.array([cout, 1], np.int64), names["bs1"]),
                          numpy_helper.from_array(np.array([4 * cout], np.int64), names["bs2"])]
            new_nodes += [
                helper.make_node("Reshape", [c.input[2], names["bs1"]], [names["b1"]], name=names["b1"]),
                helper.make_node("MatMul", [names["b1"], "subpixel__ones"], [names["b4"]], name=names["b4"]),
                helper.make_node("Reshape", [names["b4"], names["bs2"]], [names["bias"]], name=names["bias"]),
            ]
            conv_in.append(names["bias"])
        new_nodes += [
            helper.make_node("Conv", conv_in, [names["out4"]], kernel_shape=[3, 3], pads=[0, 0, 0, 0],
                             name=names["out4"]),
            helper.make_node("DepthToSpace", [names["out4"]], [c.output[0]], blocksize=2, mode="CRD", name=k),
        ]
        drop |= {id(r), id(p), id(c)}
        done += 1
    if not done:
        return 0
    kept = [n for n in graph.node if id(n) not in drop]
    nodes = _live(kept + new_nodes, {o.name for o in graph.output})
    del graph.node[:]
    graph.node.extend(_topological(nodes, graph))
    used = {i for n in graph.node for i in n.input}
    inits_kept = [i for i in [*graph.initializer, *new_inits] if i.name in used]
    dropped = {i.name for i in graph.initializer} - {i.name for i in inits_kept}
    inputs_kept = [i for i in graph.input if i.name not in dropped]  # an initialiser listed as an input (old exporters)
    del graph.initializer[:]
    graph.initializer.extend(inits_kept)
    del graph.input[:]
    graph.input.extend(inputs_kept)
    return done


def fold_subpixel_kernels(model, only: set[str] | None = None) -> int:
    """In place: the kernels and biases :func:`subpixel_model` computes in the graph become float32 initialisers (what
    ONNX Runtime folds them to at load), for tools that look for a Conv's weight among the initialisers (dynamic int8
    quantisation); with ``only``, just the tensors of those names. Returns how many tensors were folded."""
    from onnx import TensorProto, numpy_helper

    graph = model.graph
    made = {o for n in graph.node for o in n.output}
    names = sorted(o for o in made if o.endswith(("__subpixel_weight", "__subpixel_bias")) and (only is None or o in only))
    if not names:
        return 0
    values = _probe(model, dict.fromkeys(names, TensorProto.FLOAT))
    keep = [n for n in graph.node if not set(n.output) & set(names)]
    inits = [*graph.initializer, *(numpy_helper.from_array(np.asarray(values[k], np.float32), k) for k in names)]
    nodes = _live(keep, {o.name for o in graph.output})
    del graph.node[:]
    graph.node.extend(nodes)
    used = {i for n in graph.node for i in n.input}
    del graph.initializer[:]
    graph.initializer.extend(i for i in inits if i.name in used)
    return len(names)


def _live(nodes: list, outputs: set[str]) -> list:
    """The nodes something needs: those feeding the graph outputs, directly or through others."""
    producer = {o: n for n in nodes for o in n.output}
    need, live, stack = set(), set(), list(outputs)
    while stack:
        t = stack.pop()
        if t in need or t not in producer:
            continue
        need.add(t)
        n = producer[t]
        if id(n) not in live:
            live.add(id(n))
            stack.extend(i for i in n.input if i)
    return [n for n in nodes if id(n) in live]


def _topological(nodes: list, graph) -> list:
    """``nodes`` in an order where every input is made before it is read (ONNX requires it)."""
    ready = {i.name for i in graph.input} | {i.name for i in graph.initializer} | {""}
    producer = {o: n for n in nodes for o in n.output}
    ready |= {i for n in nodes for i in n.input if i not in producer}  # initialisers added with the rewrite
    order, pending = [], list(nodes)
    while pending:
        rest = []
        for n in pending:
            if all(i in ready for i in n.input):
                order.append(n)
                ready.update(n.output)
            else:
                rest.append(n)
        if len(rest) == len(pending):
            raise ModelError("the rewritten graph has a cycle or an input nothing makes")
        pending = rest
    return order


def _check_input(kind: str, dims: list[int], rng: np.random.Generator) -> np.ndarray:
    """An input :func:`subpixel_model` compares the two graphs on. Not all zeros: a blank image normalises constant
    maps (instance norm), where the order of a sum decides the result, and no drawing the app runs is blank."""
    if kind == "outline":
        x = np.zeros(dims, np.float32)
        h, w = dims[-2:]
        t, b, left, right = h // 4, 3 * h // 4, w // 5, 4 * w // 5
        x[..., t:b, left:left + 2] = x[..., t:b, right - 2:right] = 1.0
        x[..., t:t + 2, left:right] = x[..., b - 2:b, left:right] = 1.0
        return x
    if kind == "sparse":
        return (rng.random(dims) > 0.95).astype(np.float32)
    return rng.random(dims).astype(np.float32)


def subpixel_bytes(data: bytes, what: str = "model", *, require: bool = True) -> bytes:
    """:func:`subpixel_model` on a serialised model: the rewritten model's bytes (``data`` itself when there is nothing
    to rewrite and not ``require``). ``what`` names the model in messages.

    Raises:
        MissingExtraError: the ``onnx`` package is not installed.
        ModelError: as :func:`subpixel_model`.
    """
    try:
        import onnx
    except ImportError as exc:
        raise MissingExtraError(f"rewriting a model's graph needs the onnx package ({exc}); "
                                "pip install 'sketchmesh[dev]'") from None
    import onnxruntime as ort

    try:
        model = onnx.load_from_string(data)
    except Exception as exc:  # onnx raises DecodeError, ...
        raise ModelError(f"{what}: cannot read the ONNX model ({' '.join(str(exc).split())[:200]})") from None
    try:
        done = _subpixel(model)
    except ModelError as exc:
        raise ModelError(f"{what}: {exc}") from None
    except Exception as exc:  # noqa: BLE001 - onnx / onnxruntime on a malformed graph
        raise ModelError(f"{what}: cannot rewrite its upsampling ({' '.join(str(exc).split())[:200]})") from None
    if done == 0:
        if not require:
            return data
        raise ModelError(f"{what}: no nearest 2x Resize -> one-pixel Pad -> 3x3 Conv to rewrite")
    new = model.SerializeToString()
    try:
        onnx.checker.check_model(model)
        fast = ort.InferenceSession(new, providers=["CPUExecutionProvider"])
        old = ort.InferenceSession(data, providers=["CPUExecutionProvider"])
    except Exception as exc:  # noqa: BLE001 - onnx / onnxruntime raise many types
        raise ModelError(f"{what}: the rewritten graph does not load: {' '.join(str(exc).split())[:300]}") from None
    rng = np.random.default_rng(0)
    for kind in ("outline", "sparse", "noise"):
        feeds = {}
        for i in old.get_inputs():
            feeds[i.name] = _check_input(kind, _dims(list(i.shape)), rng)
        try:
            pairs = list(zip(old.run(None, feeds), fast.run(None, feeds), old.get_outputs()))
        except Exception as exc:  # noqa: BLE001 - onnxruntime raises its own types
            raise ModelError(f"{what}: the rewritten graph does not run: {' '.join(str(exc).split())[:300]}") from None
        for a, b, o in pairs:
            same = a.shape == b.shape
            err = float(np.abs(np.asarray(a, np.float64) - np.asarray(b, np.float64)).max()) if same and np.size(a) else 0.0
            if not same or not err <= SUBPIXEL_ATOL:
                raise ModelError(f"{what}: the rewritten graph's {o.name!r} differs from the original's by {err:.3g} "
                                 f"on {kind} input (shapes {a.shape} / {b.shape})")
    return new


def subpixel_model(src: str | os.PathLike, dst: str | os.PathLike, *, require: bool = True) -> Path:
    """Write ``src`` with its upsampling convolutions made sub-pixel convolutions (module doc) to ``dst`` (atomically).

    The result must load in ONNX Runtime and give the original's outputs within :data:`SUBPIXEL_ATOL` on three inputs
    (a box outline, sparse random dots, uniform noise), else nothing is written. Metadata is kept. A model with
    nothing to rewrite is an error, or with ``require=False`` copied as it is.

    Raises:
        MissingExtraError: the ``onnx`` package is not installed.
        ModelError: the file cannot be read, has nothing to rewrite (``require``), or the result does not load or
            differs from the original.
    """
    from engine.fileio import atomic_write_bytes

    src, dst = Path(src), Path(dst)
    try:
        data = src.read_bytes()
    except OSError as exc:
        raise ModelError(f"{src}: cannot read the model ({exc.strerror or exc})") from None
    atomic_write_bytes(dst, subpixel_bytes(data, str(src), require=require))
    return dst
