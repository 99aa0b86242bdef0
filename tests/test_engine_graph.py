"""engine.graph: the decoder's upsampling convolutions made sub-pixel convolutions, against direct computation."""

from __future__ import annotations

import numpy as np
import onnx
import onnxruntime as ort
import pytest
from onnx import TensorProto, helper, numpy_helper

from engine.bench import compact_model
from engine.errors import ModelError
from engine.graph import SUBPIXEL_ATOL, phase_matrix, subpixel_model


def _upsample_pad_conv(x: np.ndarray, w: np.ndarray, b: np.ndarray | None, mode: str) -> np.ndarray:
    """The original chain by hand, in float64: nearest 2x upsampling, a one-pixel pad, a 3x3 convolution (loops)."""
    up = x.repeat(2, axis=2).repeat(2, axis=3)
    pad = {"reflect": "reflect", "edge": "edge", "constant": "constant"}[mode]
    p = np.pad(up, ((0, 0), (0, 0), (1, 1), (1, 1)), mode=pad)
    n, _, h, wd = up.shape
    y = np.zeros((n, w.shape[0], h, wd))
    for dy in range(3):
        for dx in range(3):
            y += np.einsum("nchw,oc->nohw", p[:, :, dy:dy + h, dx:dx + wd], w[:, :, dy, dx])
    return y + (0 if b is None else b[None, :, None, None])


def test_phase_matrix_gives_the_upsampled_convolution():
    """Each phase's 3x3 kernel on the replicate-padded small image, interleaved, is the original chain exactly (float64),
    for reflected and replicated pads; a zero pad needs a zero pad of the small image."""
    rng = np.random.default_rng(0)
    x = rng.standard_normal((2, 3, 5, 7))
    w = rng.standard_normal((4, 3, 3, 3))
    s = phase_matrix().astype(np.float64)
    assert s.shape == (9, 36) and set(np.unique(s)) == {0.0, 1.0}
    assert np.all(s.sum(axis=1) == 4)  # every original tap lands in each of the four phases once
    k = (w.reshape(12, 9) @ s).reshape(4, 3, 4, 9).transpose(0, 2, 1, 3).reshape(16, 3, 3, 3)
    for mode, small_pad in (("reflect", "edge"), ("edge", "edge"), ("constant", "constant")):
        xp = np.pad(x, ((0, 0), (0, 0), (1, 1), (1, 1)), mode=small_pad)
        y4 = np.zeros((2, 16, 5, 7))
        for dy in range(3):
            for dx in range(3):
                y4 += np.einsum("nchw,oc->nohw", xp[:, :, dy:dy + 5, dx:dx + 7], k[:, :, dy, dx])
        y = y4.reshape(2, 4, 2, 2, 5, 7).transpose(0, 1, 4, 2, 5, 3).reshape(2, 4, 10, 14)  # DepthToSpace, CRD
        np.testing.assert_allclose(y, _upsample_pad_conv(x, w, None, mode), atol=1e-12)


def _chain_model(path, *, mode="reflect", bias=True, scale=2.0, pads=1, stride=1, dilation=1, cin=3, cout=5,
                 opset=17, pad_axes=None, init_inputs=False) -> np.ndarray:
    """A model: input x (N, cin, 6, 8) -> Relu -> Resize (nearest, asymmetric, floor) -> Pad (pads from a Constant node,
    as torch exports them) -> Conv 3x3 -> Sigmoid. Returns the weight."""
    rng = np.random.default_rng(1)
    w = rng.standard_normal((cout, cin, 3, 3)).astype(np.float32)
    b = rng.standard_normal(cout).astype(np.float32)
    nodes = [
        helper.make_node("Relu", ["x"], ["r"]),
        helper.make_node("Constant", [], ["scales"], value=numpy_helper.from_array(
            np.array([1, 1, scale, scale], np.float32))),
        helper.make_node("Resize", ["r", "", "scales"], ["u"], mode="nearest",
                         coordinate_transformation_mode="asymmetric", nearest_mode="floor"),
        helper.make_node("Constant", [], ["pads"], value=numpy_helper.from_array(
            np.array([0, 0, pads, pads, 0, 0, pads, pads], np.int64))),
        helper.make_node("Pad", ["u", "pads", "", "axes"] if pad_axes is not None else ["u", "pads"], ["p"], mode=mode),
        helper.make_node("Conv", ["p", "w", "b"] if bias else ["p", "w"], ["c"], kernel_shape=[3, 3],
                         strides=[stride, stride], dilations=[dilation, dilation]),
        helper.make_node("Sigmoid", ["c"], ["y"]),
    ]
    if pad_axes is not None:
        nodes.insert(3, helper.make_node("Constant", [], ["axes"], value=numpy_helper.from_array(
            np.array(pad_axes, np.int64))))
    inits = [numpy_helper.from_array(w, "w")] + ([numpy_helper.from_array(b, "b")] if bias else [])
    inputs = [helper.make_tensor_value_info("x", TensorProto.FLOAT, ["N", cin, 6, 8])]
    if init_inputs:  # as old exporters wrote them: the scales an initialiser listed among the inputs too
        nodes[1] = helper.make_node("Identity", ["scales_init"], ["scales"])
        inits.append(numpy_helper.from_array(np.array([1, 1, scale, scale], np.float32), "scales_init"))
        inputs.append(helper.make_tensor_value_info("scales_init", TensorProto.FLOAT, [4]))
    g = helper.make_graph(nodes, "chain", inputs,
                          [helper.make_tensor_value_info("y", TensorProto.FLOAT, ["N", cout, "H", "W"])], inits)
    m = helper.make_model(g, opset_imports=[helper.make_opsetid("", opset)])
    m.metadata_props.add(key="sketchmesh_role", value="generator")
    onnx.save(m, str(path))
    return w


def _run(path, x):
    return ort.InferenceSession(str(path), providers=["CPUExecutionProvider"]).run(None, {"x": x})[0]


@pytest.mark.parametrize("mode,bias", [("reflect", True), ("edge", False), ("constant", True)])
def test_subpixel_model_keeps_the_outputs(tmp_path, mode, bias):
    src, dst = tmp_path / "a.onnx", tmp_path / "b.onnx"
    _chain_model(src, mode=mode, bias=bias)
    subpixel_model(src, dst)
    m = onnx.load(str(dst))
    ops = [n.op_type for n in m.graph.node]
    assert "Resize" not in ops and ops.count("DepthToSpace") == 1 and ops.count("Conv") == 1
    assert {p.key: p.value for p in m.metadata_props} == {"sketchmesh_role": "generator"}
    x = np.random.default_rng(2).standard_normal((3, 3, 6, 8)).astype(np.float32)
    got, want = _run(dst, x), _run(src, x)
    assert got.shape == want.shape == (3, 5, 12, 16)
    np.testing.assert_allclose(got, want, atol=1e-6)


@pytest.mark.parametrize("change", [{"scale": 3.0}, {"pads": 2}, {"stride": 2}, {"dilation": 2},
                                    {"opset": 18, "pad_axes": [2, 3, 0, 1]}])
def test_a_chain_that_does_not_fit_is_left_alone(tmp_path, change):
    src = tmp_path / "a.onnx"
    _chain_model(src, **change)
    with pytest.raises(ModelError, match="no nearest 2x Resize"):
        subpixel_model(src, tmp_path / "b.onnx")
    assert not (tmp_path / "b.onnx").exists()
    subpixel_model(src, tmp_path / "b.onnx", require=False)  # copied as it is
    assert (tmp_path / "b.onnx").read_bytes() == src.read_bytes()


def test_a_wrong_rewrite_is_caught_and_nothing_written(tmp_path, monkeypatch):
    import engine.graph as graph

    src = tmp_path / "a.onnx"
    _chain_model(src)
    monkeypatch.setattr(graph, "phase_matrix", lambda: np.roll(phase_matrix(), 1, axis=1))
    with pytest.raises(ModelError, match="differs from the original's"):
        subpixel_model(src, tmp_path / "b.onnx")
    assert not (tmp_path / "b.onnx").exists()


def test_bad_files_give_a_clear_error(tmp_path):
    bad = tmp_path / "bad.onnx"
    bad.write_bytes(b"not a model")
    with pytest.raises(ModelError, match="cannot read the ONNX model"):
        subpixel_model(bad, tmp_path / "out.onnx")
    with pytest.raises(ModelError, match="cannot read the model"):
        subpixel_model(tmp_path / "missing.onnx", tmp_path / "out.onnx")


def test_int8_storage_before_or_after_the_rewrite(tmp_path):
    """The rewrite reads int8-stored weights (compact_model first) without making them float32 in the file, and
    compact_model stores a rewritten Conv's weight in int8 as the Conv's: either order gives the same outputs."""
    src = tmp_path / "a.onnx"
    w = _chain_model(src, cin=64, cout=64)  # 36,864 weights: stored in int8
    compact_model(src, tmp_path / "q.onnx")
    subpixel_model(tmp_path / "q.onnx", tmp_path / "qs.onnx")
    subpixel_model(src, tmp_path / "s.onnx")
    compact_model(tmp_path / "s.onnx", tmp_path / "sq.onnx")
    for name in ("qs.onnx", "sq.onnx"):
        inits = {i.name: numpy_helper.to_array(i) for i in onnx.load(str(tmp_path / name)).graph.initializer}
        assert inits["w__int8"].dtype == np.int8 and inits["w__int8"].shape == w.shape and "w" not in inits
        assert (tmp_path / name).stat().st_size < w.nbytes / 2
    x = np.random.default_rng(3).standard_normal((1, 64, 6, 8)).astype(np.float32)
    ref = _run(tmp_path / "q.onnx", x)
    for name in ("qs.onnx", "sq.onnx"):
        np.testing.assert_allclose(_run(tmp_path / name, x), ref, atol=SUBPIXEL_ATOL)


def test_dynamic_int8_quantises_the_subpixel_kernels(tmp_path):
    """quantize_model folds the kernels the rewrite computes in its graph into initialisers (fold_subpixel_kernels):
    the rewritten convolution is quantised like any other, and its outputs stay near the float model's."""
    from engine.bench import quantize_model

    src = tmp_path / "a.onnx"
    _chain_model(src, cin=16, cout=16)
    subpixel_model(src, tmp_path / "s.onnx")
    quantize_model(tmp_path / "s.onnx", tmp_path / "q.onnx")
    ops = [n.op_type for n in onnx.load(str(tmp_path / "q.onnx")).graph.node]
    assert "ConvInteger" in ops and "Conv" not in ops and "DepthToSpace" in ops and "MatMul" not in ops
    x = np.random.default_rng(4).standard_normal((2, 16, 6, 8)).astype(np.float32)
    quantize_model(src, tmp_path / "q0.onnx")  # the original chain quantised: the error int8 costs it
    err = np.abs(_run(tmp_path / "q.onnx", x) - _run(src, x)).max()
    err0 = np.abs(_run(tmp_path / "q0.onnx", x) - _run(src, x)).max()
    assert 0 < err < 2 * err0 + 1e-3  # int8 weights and activations: as near the float model as the original's


def test_an_initialiser_listed_as_an_input_is_dropped_with_it(tmp_path):
    """Old exporters list initialisers among the graph inputs: one the rewrite no longer reads leaves the inputs too,
    or it would become a required input."""
    src, dst = tmp_path / "a.onnx", tmp_path / "b.onnx"
    _chain_model(src, init_inputs=True)
    subpixel_model(src, dst)
    assert [i.name for i in onnx.load(str(dst)).graph.input] == ["x"]
    x = np.random.default_rng(5).standard_normal((1, 3, 6, 8)).astype(np.float32)
    np.testing.assert_allclose(_run(dst, x), _run(src, x), atol=1e-6)
