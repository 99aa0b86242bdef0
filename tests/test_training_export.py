"""ONNX export: contract names and metadata, torch vs ONNX Runtime parity, int8, and the engine running it."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")
onnx = pytest.importorskip("onnx")
ort = pytest.importorskip("onnxruntime")

from engine import contract as C  # noqa: E402
from engine.errors import ModelError  # noqa: E402
from engine.icosphere import icosphere  # noqa: E402
from training.export.to_onnx import PARITY_TOLERANCE, export_models, export_run  # noqa: E402
from training.loop.config import TrainConfig  # noqa: E402
from training.loop.trainer import load_run  # noqa: E402
from training.model.networks import downsample_normals  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from synthetic_data import train_tiny_joint_run, write_synthetic_dataset  # noqa: E402

torch.set_num_threads(2)


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("export")
    data = write_synthetic_dataset(root / "data", splits=("train", "test"), views=2)
    train_tiny_joint_run(data, root / "run", iters=1)
    return root / "run"


@pytest.fixture(scope="module")
def exported(run_dir, tmp_path_factory) -> Path:
    from sketchmesh.cli import main

    out = tmp_path_factory.mktemp("models")
    assert main(["export", str(run_dir), "-o", str(out)]) == 0
    return out


def _meta(path: Path) -> dict[str, str]:
    return {p.key: p.value for p in onnx.load(str(path)).metadata_props}


def test_export_writes_contract_names_and_metadata(exported, run_dir):
    gen, pred = exported / C.GENERATOR_FILE, exported / C.PREDICTOR_FILE
    g, p = _meta(gen), _meta(pred)
    for meta, role in ((g, C.ROLE_GENERATOR), (p, C.ROLE_PREDICTOR)):
        assert set(C.REQUIRED_METADATA) <= set(meta)
        assert meta[C.META_ROLE] == role and meta[C.META_FORMAT] == C.FORMAT_VERSION
        assert meta[C.META_CONVENTIONS] == C.CONVENTIONS_ID
        assert TrainConfig.from_json(meta[C.META_CONFIG]).mode == "joint"
        assert meta[C.META_CODE_VERSION].startswith("0.")
    assert g[C.META_BASE_CHANNELS] == "8" and g[C.META_QUANTIZATION] == "none"
    assert g[C.META_GENERATOR_ARCH] == "resize"  # rebuilt from the run's config (the default arch)
    assert p[C.META_TEMPLATE_LEVEL] == "2" and float(p[C.META_TEMPLATE_RADIUS]) == 0.5
    assert onnx.load(str(gen)).opset_import[0].version >= 17
    sess = ort.InferenceSession(str(pred), providers=["CPUExecutionProvider"])
    assert [i.name for i in sess.get_inputs()] == [C.PREDICTOR_INPUT]
    assert [o.name for o in sess.get_outputs()] == [C.PREDICTOR_OUTPUT_LOCAL, C.PREDICTOR_OUTPUT_GLOBAL]
    assert sess.get_inputs()[0].shape[1:] == [3, 64, 64] and not isinstance(sess.get_inputs()[0].shape[0], int)


def test_onnx_runtime_reproduces_torch_at_any_batch(exported, run_dir):
    """Independent of the exporter's own check: fresh inputs, batch 3 (the export traced batch 1)."""
    _, models, _ = load_run(run_dir)
    gen = ort.InferenceSession(str(exported / C.GENERATOR_FILE), providers=["CPUExecutionProvider"])
    pred = ort.InferenceSession(str(exported / C.PREDICTOR_FILE), providers=["CPUExecutionProvider"])
    rng = np.random.default_rng(1)
    sketch = (rng.random((3, 1, 256, 256)) > 0.97).astype(np.float32)
    normals64 = rng.random((3, 3, 64, 64)).astype(np.float32)
    with torch.no_grad():
        g_ref = models["generator"](torch.from_numpy(sketch)).numpy()
        l_ref, gl_ref = (t.numpy() for t in models["predictor"](torch.from_numpy(normals64)))
    (g_out,) = gen.run(None, {C.GENERATOR_INPUT: sketch})
    l_out, gl_out = pred.run(None, {C.PREDICTOR_INPUT: normals64})
    for ref, out in ((g_ref, g_out), (l_ref, l_out), (gl_ref, gl_out)):
        assert ref.shape == out.shape
        assert np.abs(ref - out).max() < PARITY_TOLERANCE, np.abs(ref - out).max()


def test_engine_runs_the_exported_models_like_torch(exported, run_dir):
    """Integration with engine/models.py + engine/pipeline.py: same mesh as the torch pipeline."""
    pipeline = pytest.importorskip("engine.pipeline")
    _, models, _ = load_run(run_dir)
    raster = np.zeros((256, 256), np.float32)
    raster[60:200, 60:62] = raster[60:62, 60:200] = raster[198:200, 60:200] = raster[60:200, 198:200] = 1.0
    prediction = pipeline.SketchEngine(models_dir=exported).predict(raster)
    mesh = prediction.mesh
    assert mesh.num_vertices == 162 and np.isfinite(mesh.vertices).all()
    with torch.no_grad():
        n = models["generator"](torch.from_numpy(raster)[None, None])
        local, glob = models["predictor"](downsample_normals(n))
    expected = np.array(icosphere(2).vertices) + local[0].numpy() + glob[0].numpy()
    assert np.abs(mesh.vertices - expected).max() < 1e-3
    assert np.array_equal(mesh.faces, icosphere(2).faces)


def test_int8_export_quantizes_the_predictor_only(run_dir, tmp_path, exported):
    reports = export_run(run_dir, tmp_path, quantize="int8")
    by_role = {r.role: r for r in reports}
    assert by_role[C.ROLE_PREDICTOR].quantization == "int8-dynamic"
    assert by_role[C.ROLE_GENERATOR].quantization == "none"
    assert _meta(tmp_path / C.PREDICTOR_FILE)[C.META_QUANTIZATION] == "int8-dynamic"
    assert (tmp_path / C.PREDICTOR_FILE).stat().st_size < 0.5 * (exported / C.PREDICTOR_FILE).stat().st_size
    assert all(r.max_abs_error <= r.tolerance for r in reports)


def test_fp16_export_stores_the_predictor_weights_in_half_and_computes_in_float32(run_dir, tmp_path, exported):
    import onnx
    from onnx import TensorProto

    from engine.pipeline import SketchEngine
    from training.export.to_onnx import FP16_TOLERANCE

    reports = export_run(run_dir, tmp_path, quantize="fp16")
    by_role = {r.role: r for r in reports}
    assert by_role[C.ROLE_PREDICTOR].quantization == "fp16-weights" and by_role[C.ROLE_GENERATOR].quantization == "none"
    assert _meta(tmp_path / C.PREDICTOR_FILE)[C.META_QUANTIZATION] == "fp16-weights"
    size, full = (tmp_path / C.PREDICTOR_FILE).stat().st_size, (exported / C.PREDICTOR_FILE).stat().st_size
    assert 0.45 * full < size < 0.6 * full
    assert 0 < by_role[C.ROLE_PREDICTOR].max_abs_error <= FP16_TOLERANCE
    graph = onnx.load(str(tmp_path / C.PREDICTOR_FILE)).graph
    assert any(i.data_type == TensorProto.FLOAT16 for i in graph.initializer)
    assert all(n.op_type != "Cast" or n.attribute[0].i == TensorProto.FLOAT for n in graph.node)
    raster = np.zeros((256, 256), np.float32)
    raster[60:200, 120:124] = 1.0
    half = SketchEngine(tmp_path, threads=1).predict(raster).mesh.vertices
    ref = SketchEngine(exported, threads=1).predict(raster).mesh.vertices
    assert 0 < np.abs(half - ref).max() <= FP16_TOLERANCE
    # the benches quantise it like a float32 file (the float16 weights made float32 initialisers first)
    from engine.bench import quantize_model
    from training.export.to_onnx import INT8_TOLERANCE

    q = tmp_path / "q"
    q.mkdir()
    quantize_model(tmp_path / C.PREDICTOR_FILE, q / C.PREDICTOR_FILE)
    (q / C.GENERATOR_FILE).write_bytes((tmp_path / C.GENERATOR_FILE).read_bytes())
    assert _meta(q / C.PREDICTOR_FILE)[C.META_QUANTIZATION] == "int8-dynamic"
    assert any(n.op_type == "DynamicQuantizeLinear" for n in onnx.load(str(q / C.PREDICTOR_FILE)).graph.node)
    assert np.abs(SketchEngine(q, threads=1).predict(raster).mesh.vertices - ref).max() <= INT8_TOLERANCE


def test_int8_weight_storage_rounds_each_channel_to_its_own_scale_and_computes_in_float32(run_dir, tmp_path, exported):
    """engine.bench.compact_model on a float32 generator and a float16-stored predictor: every stored weight is its
    channel's largest magnitude / 127 times an integer within half a step of the original, the originals are gone,
    and ONNX Runtime computes with exactly the stored weights (the same predictor written with q * scale as float32
    initialisers gives the same mesh)."""
    from onnx import TensorProto, numpy_helper

    from engine.bench import INT8W_MIN_ELEMENTS, compact_model
    from engine.pipeline import SketchEngine
    from training.export.to_onnx import INT8_TOLERANCE

    src = exported / C.GENERATOR_FILE
    dst = compact_model(src, tmp_path / "g" / C.GENERATOR_FILE)
    assert _meta(dst)[C.META_QUANTIZATION] == "int8-weights"
    orig = {i.name: numpy_helper.to_array(i) for i in onnx.load(str(src)).graph.initializer}
    graph = onnx.load(str(dst)).graph
    arrays = {i.name: numpy_helper.to_array(i) for i in graph.initializer}
    stored = [n[: -len("__int8")] for n, a in arrays.items() if a.dtype == np.int8]
    big = [n for n, a in orig.items() if a.ndim == 4 and a.size >= INT8W_MIN_ELEMENTS]
    assert stored and sorted(stored) == sorted(big)  # every large Conv weight, nothing else
    assert all(n not in arrays for n in stored) and dst.stat().st_size < 0.5 * src.stat().st_size
    for name in stored:
        q, scale, w = arrays[name + "__int8"], arrays[name + "__scale"], orig[name]
        assert scale.shape == (w.shape[0],) + (1,) * (w.ndim - 1)
        np.testing.assert_allclose(scale.ravel(), np.abs(w).reshape(len(w), -1).max(1) / 127, rtol=1e-6)
        assert np.all(np.abs(q.astype(np.float32) * scale - w) <= scale / 2 * (1 + 1e-5))
        assert np.all(np.abs(q).reshape(len(q), -1).max(1) == 127)
    # a float16-stored predictor: the Cast nodes of its stored weights gone, Mul by the scales in their place
    export_run(run_dir, tmp_path / "half", quantize="fp16")
    pred = compact_model(tmp_path / "half" / C.PREDICTOR_FILE, tmp_path / "p" / C.PREDICTOR_FILE)
    pgraph = onnx.load(str(pred)).graph
    muls = {n.output[0] for n in pgraph.node if n.op_type == "Mul" and n.input[1].endswith("__scale")}
    assert muls and not any(n.op_type == "Cast" and n.output[0] in muls for n in pgraph.node)
    assert any(i.data_type == TensorProto.FLOAT16 for i in pgraph.initializer)  # the small ones stay float16
    raster = np.zeros((256, 256), np.float32)
    raster[60:200, 120:124] = 1.0
    (tmp_path / "p" / C.GENERATOR_FILE).write_bytes(src.read_bytes())
    got = SketchEngine(tmp_path / "p", threads=1).predict(raster).mesh.vertices
    ref = SketchEngine(exported, threads=1).predict(raster).mesh.vertices
    assert 0 < np.abs(got - ref).max() <= INT8_TOLERANCE
    dq = onnx.load(str(tmp_path / "half" / C.PREDICTOR_FILE))
    by_name = {i.name: i for i in dq.graph.initializer}
    pa = {i.name: numpy_helper.to_array(i) for i in pgraph.initializer}
    for n in list(dq.graph.node):  # the stored weights written as float32 initialisers: the same function
        if n.op_type == "Cast" and n.input[0] in by_name and n.output[0] in muls:
            dq.graph.node.remove(n)
            dq.graph.initializer.remove(by_name[n.input[0]])
            w = pa[n.output[0] + "__int8"].astype(np.float32) * pa[n.output[0] + "__scale"]
            dq.graph.initializer.append(numpy_helper.from_array(w.astype(np.float32), n.output[0]))
    (tmp_path / "f").mkdir()
    onnx.save(dq, str(tmp_path / "f" / C.PREDICTOR_FILE))
    (tmp_path / "f" / C.GENERATOR_FILE).write_bytes(src.read_bytes())
    np.testing.assert_allclose(SketchEngine(tmp_path / "f", threads=1).predict(raster).mesh.vertices, got, atol=1e-5)
    # the benches' dynamic int8 finds the int8-stored weights as it finds float ones: every Gemm quantised
    from engine.bench import quantize_model

    (tmp_path / "q").mkdir()
    quantize_model(pred, tmp_path / "q" / C.PREDICTOR_FILE)
    (tmp_path / "q" / C.GENERATOR_FILE).write_bytes(src.read_bytes())
    qnodes = onnx.load(str(tmp_path / "q" / C.PREDICTOR_FILE)).graph.node
    assert not any(n.op_type == "Gemm" for n in qnodes) and not any(n.name.endswith("__dequantize") for n in qnodes)
    assert np.abs(SketchEngine(tmp_path / "q", threads=1).predict(raster).mesh.vertices - ref).max() <= INT8_TOLERANCE
    # bad input is a ModelError naming the file, not a traceback
    (tmp_path / "bad.onnx").write_bytes(b"not a model")
    with pytest.raises(ModelError, match="cannot read"):
        compact_model(tmp_path / "bad.onnx", tmp_path / "bad_out.onnx")


def test_int8w_export_stores_both_networks_large_weights_in_int8(run_dir, tmp_path, exported):
    """`export --quantize int8w`: the bundled models' form straight from a run, both files marked, smaller, within the
    export's tolerances of torch, and run by the engine."""
    from engine.pipeline import SketchEngine
    from sketchmesh.cli import main

    assert main(["export", str(run_dir), "-o", str(tmp_path), "--quantize", "int8w"]) == 0
    for f in (C.GENERATOR_FILE, C.PREDICTOR_FILE):
        assert _meta(tmp_path / f)[C.META_QUANTIZATION] == "int8-weights"
        assert any(i.data_type == onnx.TensorProto.INT8 for i in onnx.load(str(tmp_path / f)).graph.initializer)
    assert (tmp_path / C.GENERATOR_FILE).stat().st_size < 0.5 * (exported / C.GENERATOR_FILE).stat().st_size
    assert (tmp_path / C.PREDICTOR_FILE).stat().st_size < 0.5 * (exported / C.PREDICTOR_FILE).stat().st_size
    raster = np.zeros((256, 256), np.float32)
    raster[60:200, 120:124] = 1.0
    mesh = SketchEngine(tmp_path, threads=1).predict(raster).mesh
    ref = SketchEngine(exported, threads=1).predict(raster).mesh
    assert mesh.num_vertices == ref.num_vertices and np.isfinite(mesh.vertices).all()


def test_int8_weight_storage_by_operator_layout_and_what_it_leaves_alone(tmp_path):
    """A hand-built graph: a Gemm with B as (K, N) (transB=0: one scale per column), one with B as (N, K) (transB=1: per
    row), a weight shared by two nodes, a weight that is also a graph input, a small one and a MatMul constant. Only the
    first two are stored, each rounded within half its own channel's step; the output is numpy's with those weights."""
    import onnxruntime as ort
    from onnx import TensorProto, helper, numpy_helper

    from engine.bench import INT8W_MIN_ELEMENTS, compact_model

    rng = np.random.default_rng(0)
    k = n = 128
    assert k * n >= INT8W_MIN_ELEMENTS
    col_scaled = rng.normal(size=(k, n)).astype(np.float32) * np.logspace(-3, 1, n, dtype=np.float32)  # columns differ
    row_scaled = rng.normal(size=(n, k)).astype(np.float32) * np.logspace(-3, 1, n, dtype=np.float32)[:, None]
    shared, as_input, small, basis = (rng.normal(size=s).astype(np.float32) for s in ((k, n), (k, n), (n, 64), (k, n)))
    assert small.size < INT8W_MIN_ELEMENTS
    inits = [numpy_helper.from_array(a, name) for a, name in ((col_scaled, "A"), (row_scaled, "B"), (shared, "S"),
                                                              (as_input, "I"), (small, "T"), (basis, "M"))]
    nodes = [helper.make_node("Gemm", ["x", "A"], ["a"]),
             helper.make_node("Gemm", ["a", "B"], ["b"], transB=1),
             helper.make_node("Gemm", ["b", "S"], ["c"]),
             helper.make_node("Gemm", ["c", "S"], ["d"]),
             helper.make_node("Gemm", ["d", "I"], ["e"]),
             helper.make_node("MatMul", ["e", "M"], ["f"]),
             helper.make_node("Gemm", ["f", "T"], ["y"])]
    graph = helper.make_graph(nodes, "g", [helper.make_tensor_value_info("x", TensorProto.FLOAT, [2, k]),
                                           helper.make_tensor_value_info("I", TensorProto.FLOAT, [k, n])],
                              [helper.make_tensor_value_info("y", TensorProto.FLOAT, [2, 64])], initializer=inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    src = tmp_path / "m.onnx"
    onnx.save(model, str(src))
    dst = compact_model(src, tmp_path / "c.onnx")
    arrays = {i.name: numpy_helper.to_array(i) for i in onnx.load(str(dst)).graph.initializer}
    assert sorted(n for n, a in arrays.items() if a.dtype == np.int8) == ["A__int8", "B__int8"]
    assert arrays["A__scale"].shape == (1, n) and arrays["B__scale"].shape == (n, 1)
    for name, w in (("A", col_scaled), ("B", row_scaled)):
        step = arrays[name + "__scale"]
        assert np.all(np.abs(arrays[name + "__int8"] * step - w) <= step / 2 * (1 + 1e-5))
    x = rng.normal(size=(2, k)).astype(np.float32)
    a_q, b_q = (arrays[m + "__int8"].astype(np.float32) * arrays[m + "__scale"] for m in "AB")
    want = ((x @ a_q) @ b_q.T @ shared @ shared @ as_input) @ basis @ small
    got = ort.InferenceSession(str(dst), providers=["CPUExecutionProvider"]).run(None, {"x": x, "I": as_input})[0]
    np.testing.assert_allclose(got, want, rtol=1e-4, atol=1e-4 * np.abs(want).max())
    onnx.save(helper.make_model(helper.make_graph(nodes[-2:-1], "g", [
        helper.make_tensor_value_info("e", TensorProto.FLOAT, [2, k])], [
        helper.make_tensor_value_info("f", TensorProto.FLOAT, [2, n])], initializer=inits[-1:]),
        opset_imports=[helper.make_opsetid("", 17)]), str(tmp_path / "mm.onnx"))
    with pytest.raises(ModelError, match="no Conv or Gemm weight"):  # nothing to store: said, not a silent copy
        compact_model(tmp_path / "mm.onnx", tmp_path / "mm_c.onnx")


def test_precision_variants_keep_a_routed_folders_router_and_convert_its_specialist(tmp_path, exported):
    """make_variant on a routed folder: the router copied byte for byte, the specialist it names converted as the
    predictor, a stray .onnx left out; the folder is made once and reused; the engine routes with it."""
    import shutil

    from engine.bench import make_variant
    from engine.pipeline import SketchEngine

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from onnx_fixtures import make_router, write_model

    folder = tmp_path / "routed"
    shutil.copytree(exported, folder)
    shutil.copyfile(exported / C.PREDICTOR_FILE, folder / "mesh_predictor_legged.onnx")
    (folder / "old_notes.onnx").write_bytes(b"not a model")  # neither a contract file nor routed to
    write_model(make_router([0.05, 0.05, 0.9]), folder / C.ROUTER_FILE)
    raster = np.zeros((256, 256), np.float32)
    raster[60:200, 120:124] = 1.0
    for variant, quant in (("int8w", "int8-weights"), ("int8-predictor", "int8-dynamic")):
        v = make_variant(folder, variant, tmp_path / "variants")
        assert sorted(p.name for p in v.glob("*.onnx")) == sorted(
            [C.GENERATOR_FILE, C.PREDICTOR_FILE, C.ROUTER_FILE, "mesh_predictor_legged.onnx"])
        assert (v / C.ROUTER_FILE).read_bytes() == (folder / C.ROUTER_FILE).read_bytes()
        assert _meta(v / "mesh_predictor_legged.onnx")[C.META_QUANTIZATION] == quant
        stamp = (v / "mesh_predictor_legged.onnx").stat().st_mtime_ns
        (folder / "mesh_predictor_legged.onnx").rename(folder / "moved.onnx")  # a rebuild would now fail
        assert make_variant(folder, variant, tmp_path / "variants") == v
        assert (v / "mesh_predictor_legged.onnx").stat().st_mtime_ns == stamp
        (folder / "moved.onnx").rename(folder / "mesh_predictor_legged.onnx")
        pred = SketchEngine(v, threads=1).predict(raster)
        assert pred.route == "mesh_predictor_legged.onnx" and np.all(np.isfinite(pred.mesh.vertices))


def test_int8_all_export_quantizes_both_networks(run_dir, tmp_path, exported):
    from engine.pipeline import SketchEngine

    reports = export_run(run_dir, tmp_path, quantize="int8-all")
    assert {r.role: r.quantization for r in reports} == {C.ROLE_GENERATOR: "int8-dynamic", C.ROLE_PREDICTOR: "int8-dynamic"}
    assert _meta(tmp_path / C.GENERATOR_FILE)[C.META_QUANTIZATION] == "int8-dynamic"
    # the Conv weights become int8 (with the default resize arch, the decoder's too; a pix2pix decoder's
    # ConvTranspose weights would stay float32)
    assert (tmp_path / C.GENERATOR_FILE).stat().st_size < 0.8 * (exported / C.GENERATOR_FILE).stat().st_size
    assert all(r.max_abs_error <= r.tolerance for r in reports)
    sketch = np.zeros((256, 256), np.float32)
    sketch[60:200, 128] = 1.0
    pred = SketchEngine(tmp_path, threads=1).predict(sketch)  # the engine runs the quantised pair
    assert np.isfinite(pred.mesh.vertices).all()


@pytest.mark.parametrize("arch", ["resize", "pix2pix"])
def test_generator_export_matches_torch_for_both_archs(arch, tmp_path):
    """Reflect pads and nearest Resize (resize arch, its decoder exported as sub-pixel convolutions) or ConvTranspose
    (pix2pix) run in ONNX Runtime like torch on drawings, a single dot included; the arch is in the metadata; the resize
    network keeps a blank sketch blank."""
    from training.export.to_onnx import parity_inputs
    from training.model.networks import NormalGenerator

    torch.manual_seed(0)
    g = NormalGenerator(4, arch=arch)
    sketches, normals64, _ = parity_inputs(TrainConfig(data_dir=str(tmp_path / "no_data")))
    (report,) = export_models(g, None, tmp_path, config_json=TrainConfig(generator_arch=arch).to_json(),
                              code_version="t", sketches=sketches, normals64=normals64)
    assert report.max_abs_error <= PARITY_TOLERANCE
    path = tmp_path / C.GENERATOR_FILE
    meta = _meta(path)
    assert meta[C.META_GENERATOR_ARCH] == arch and meta[C.META_BASE_CHANNELS] == "4"
    nodes = onnx.load(str(path)).graph.node
    ops = {n.op_type for n in nodes}
    pad_modes = [a.s for n in nodes if n.op_type == "Pad" for a in n.attribute if a.name == "mode"]
    if arch == "resize":
        assert "ConvTranspose" not in ops and "Resize" in ops  # the 1x1 convolution after the innermost upsampling
        # 8 encoder convs reflect-padded; the 7 decoder 3x3 convs made sub-pixel convolutions (engine.graph): each
        # pads its small input by replication and ends in a DepthToSpace
        assert sorted(pad_modes) == [b"edge"] * 7 + [b"reflect"] * 8
        assert sum(n.op_type == "DepthToSpace" for n in nodes) == 7
    else:
        assert "ConvTranspose" in ops and "Resize" not in ops and not pad_modes
    sess = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    rng = np.random.default_rng(2)
    x = np.concatenate([(rng.random((2, 1, 256, 256)) > 0.97).astype(np.float32),
                        np.zeros((1, 1, 256, 256), np.float32), np.full((1, 1, 256, 256), 0.3, np.float32)])
    dot = np.zeros((1, 1, 256, 256), np.float32)
    dot[..., 5, 250] = 1.0  # one pixel in a corner: the least a drawing can be
    x = np.concatenate([x, dot])
    (out,) = sess.run(None, {C.GENERATOR_INPUT: x})
    with torch.no_grad():
        ref = g.eval()(torch.from_numpy(x)).numpy()
    # the blank and constant images normalise constant maps, where the order of a sum decides the result (engine.graph's
    # rewrite sums the kernel taps in another order; the engine refuses blank sketches); a lone dot leaves the deep maps
    # of this untrained network nearly constant, which amplifies the rounding (the bundled generator: 2e-6)
    assert np.abs(out[:2] - ref[:2]).max() < PARITY_TOLERANCE
    assert np.abs(out[4] - ref[4]).max() < 10 * PARITY_TOLERANCE
    if arch == "pix2pix":  # not rewritten: the same on every input, blank and constant ones included
        assert np.abs(out - ref).max() < PARITY_TOLERANCE
    spread = (ref[2:4].max(axis=(2, 3)) - ref[2:4].min(axis=(2, 3))).max()  # the network itself: no border pattern
    assert spread < 1e-5 if arch == "resize" else spread > 1e-3


def test_failed_parity_writes_nothing(run_dir, tmp_path, monkeypatch):
    import training.export.to_onnx as ex

    class Broken:
        def __init__(self, real):
            self.real = real

        def run(self, names, feeds):
            return [o + 1e-2 for o in self.real.run(names, feeds)]

    real_session = ex._session
    monkeypatch.setattr(ex, "_session", lambda data: Broken(real_session(data)))
    _, models, _ = load_run(run_dir)
    with pytest.raises(ModelError, match="does not reproduce torch"):
        export_models(models["generator"], models["predictor"], tmp_path / "out", config_json="{}", code_version="t",
                      sketches=torch.zeros(1, 1, 256, 256), normals64=torch.zeros(1, 3, 64, 64))
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


def test_export_bad_input_is_a_clear_error(run_dir, tmp_path):
    with pytest.raises(ModelError, match="no checkpoint"):
        export_run(tmp_path, tmp_path / "o")
    with pytest.raises(ValueError, match="quantize"):
        export_run(run_dir, tmp_path / "o", quantize="fp8")
    _, models, _ = load_run(run_dir)
    with pytest.raises(ValueError, match="sketches"):
        export_models(models["generator"], None, tmp_path / "o", config_json="{}", code_version="t",
                      sketches=torch.zeros(1, 1, 128, 128), normals64=torch.zeros(1, 3, 64, 64))


# ---------------------------------------------------------------------- bench tradeoff


def test_resample_level_nests_and_subdivides():
    from training.evaluation.tradeoff import TradeoffError, resample_level

    fine = icosphere(3)
    coarse = resample_level(fine, 3, 2)
    ref = icosphere(2)
    np.testing.assert_array_equal(coarse.vertices, ref.vertices)  # level 2's vertices are level 3's first 162
    np.testing.assert_array_equal(coarse.faces, ref.faces)
    up = resample_level(ref, 2, 3)
    assert (up.num_vertices, up.num_faces) == (642, 1280)
    assert resample_level(fine, 3, 3) is fine
    with pytest.raises(TradeoffError, match="not level 2"):
        resample_level(fine, 2, 1)


def test_bench_tradeoff_reports_every_combination(run_dir, exported, tmp_path, capsys):
    import json

    from sketchmesh.cli import main

    out = tmp_path / "tradeoff"
    rc = main(["bench", "tradeoff", "--data", str(run_dir.parent / "data"), "--variant", f"tiny={exported}",
               "--precisions", "fp32", "int8-predictor", "fp32+mirror", "--levels", "1", "2", "3", "--bundled", "tiny",
               "--threads", "1", "--quiet", "--out", str(out)])
    assert rc == 0
    records = json.loads((out / "tradeoff.json").read_text())
    assert [(r["precision"], r["level"], r["vertices"]) for r in records] == [
        (p, lv, n) for p in ("fp32", "int8-predictor", "fp32+mirror") for lv, n in ((1, 42), (2, 162), (3, 642))]
    plain, mirror = (next(r for r in records if r["precision"] == p and r["level"] == 2) for p in ("fp32", "fp32+mirror"))
    assert mirror["chamfer_l1"] != plain["chamfer_l1"]  # averaging with the flipped drawing's mesh moved it
    assert mirror["model_mb"] == plain["model_mb"]
    for r in records:
        assert 0.0 <= r["voxel_iou"] <= 1.0 and np.isfinite(r["chamfer_l1"]) and r["latency_ms_p50"] > 0
    assert (out / "tradeoff.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    table = (out / "tradeoff.md").read_text()
    assert table.count("(bundled)") == 1 and "| tiny (bundled) | fp32 | 2 (162) |" in table


def test_bench_tradeoff_bad_variant_is_a_clear_error(run_dir, tmp_path, capsys):
    from sketchmesh.cli import main

    rc = main(["bench", "tradeoff", "--data", str(run_dir.parent / "data"), "--variant", "nofolder",
               "--out", str(tmp_path)])
    assert rc != 0
    assert "LABEL=DIR" in capsys.readouterr().err


def test_gallery_writes_one_row_per_category(run_dir, exported, tmp_path, capsys):
    from PIL import Image

    from sketchmesh.cli import main

    out = tmp_path / "gallery.png"
    rc = main(["gallery", "--data", str(run_dir.parent / "data"), "--models", str(exported), "-o", str(out),
               "--azimuth", "0", "--turn", "15", "--size", "48", "--threads", "1"])
    assert rc == 0, capsys.readouterr().err
    w, h = Image.open(out).size
    assert w == 1000 and h == 200 * 2  # 5 columns x 2 test categories of 2 inches at 100 dpi
    mirrored = tmp_path / "gallery_mirror.png"
    rc = main(["gallery", "--data", str(run_dir.parent / "data"), "--models", str(exported), "-o", str(mirrored),
               "--azimuth", "0", "--turn", "15", "--size", "48", "--threads", "1", "--mirror-average"])
    assert rc == 0 and Image.open(mirrored).size == (w, h)
    diff = np.abs(np.asarray(Image.open(mirrored), np.float64) - np.asarray(Image.open(out), np.float64))
    assert 0 < diff.mean() < 0.1 * 255  # the sketches and normal images agree; the meshes moved
    rc = main(["gallery", "--data", str(run_dir.parent / "data"), "--models", str(exported), "-o", str(out),
               "--categories", "nosuch"])
    assert rc != 0 and "no test shapes" in capsys.readouterr().err


def test_gallery_repair_folds_shows_the_repaired_meshes(run_dir, tmp_path, capsys):
    from onnx_fixtures import write_fixture_models
    from PIL import Image

    from sketchmesh.cli import main

    folding = write_fixture_models(tmp_path / "folding", fold=True)  # every mesh crosses itself
    images = []
    for extra in ([], ["--repair-folds"]):
        out = tmp_path / f"gallery{len(extra)}.png"
        rc = main(["gallery", "--data", str(run_dir.parent / "data"), "--models", str(folding), "-o", str(out),
                   "--azimuth", "0", "--turn", "15", "--size", "48", "--threads", "1", *extra])
        assert rc == 0, capsys.readouterr().err
        images.append(np.asarray(Image.open(out), np.float64))
    assert images[0].shape == images[1].shape
    assert 0 < np.abs(images[1] - images[0]).mean() < 0.1 * 255  # same sketches and normals; the meshes moved


def test_gallery_picks_the_nearest_elevation_then_azimuths():
    from training.evaluation.gallery import pick_views

    # 4 azimuths x 3 elevations, elevation-major like the data command renders them
    az = [0, 90, 180, 270] * 3
    el = [0] * 4 + [15] * 4 + [30] * 4
    assert pick_views(az, el, azimuth=45.0, elevation=30.0, turn=90.0) == (8, 9)  # tie 0/90: the lower index
    assert pick_views(az, el, azimuth=100.0, elevation=2.0, turn=90.0) == (1, 2)
    assert pick_views(az, el, azimuth=350.0, elevation=20.0, turn=200.0) == (4, 6)  # 350 ~ 0 (wraps); 0 + 200 ~ 180
    assert pick_views(az, el, azimuth=270.0, elevation=-40.0, turn=100.0) == (3, 0)  # 270 + 100 = 370 ~ 0
    assert pick_views([10.0], [30.0], 0.0, 30.0, 90.0) == (0, 0)  # one view: the second is the first


def test_shade_is_lambert_with_a_white_background():
    from engine.camera import encode_normals
    from training.evaluation.gallery import LIGHT, shade

    n = np.stack([LIGHT, -LIGHT, np.array([0.0, 0.0, 1.0])])[None]  # (1, 3, 3)
    img = shade(encode_normals(n), np.array([[1, 1, 1]]))
    np.testing.assert_allclose(img[0], [1.0, 0.25, 0.25 + 0.75 * LIGHT[2]], atol=1e-6)
    assert shade(encode_normals(n), np.array([[0, 0, 0]])).tolist() == [[1.0, 1.0, 1.0]]


def test_retrieval_index_from_the_array_cache_equals_the_shape_files(run_dir, monkeypatch):
    """eval's retrieval index reads the mesh-array cache in chunks: the same rows as item by item from the shape files."""
    import torch

    import training.evaluation.evaluate as E
    from training.data.dataset import ShapeViewDataset

    data = run_dir.parent / "data"
    files = E._RetrievalMethod(ShapeViewDataset(data, "train", extra_views=0, augment_strength=0.0, mesh_cache="none"),
                               None, False)
    monkeypatch.setattr(E, "RETRIEVAL_CHUNK", 3)  # several chunks and a remainder
    cached = E._RetrievalMethod(ShapeViewDataset(data, "train", extra_views=0, fields="mesh"), None, False)
    assert len(files.keys) > 3 and len(files.keys) % 3 != 0
    assert torch.equal(files.images, cached.images)
    assert np.array_equal(files.cameras, cached.cameras) and files.keys == cached.keys


def test_eval_markdown_table_shows_iou_and_chamfer_per_category():
    from training.evaluation.evaluate import METRICS, markdown_table

    def method(iou, cd):
        per = {"car": {"voxel_iou": iou, "chamfer_l1": cd}, "lamp": {"voxel_iou": iou / 2, "chamfer_l1": 2 * cd}}
        return {"per_category": per, "mean": {m: 0.5 for m in METRICS}, "ms_per_sample": 3.0}

    result = {"method_order": ["full", "retrieval"], "methods": {"full": method(0.25, 0.1), "retrieval": method(0.5, 0.05)},
              "voxel_resolution": 32, "split": "test", "samples": 4, "gt_normals": False}
    table = markdown_table(result)
    assert "| car | 0.250 / 0.100 | 0.500 / 0.050 |" in table
    assert "| lamp | 0.125 / 0.200 | 0.250 / 0.100 |" in table
    assert "| full | 0.5000 | 0.5000 | 0.5000 | 0.5000 | 3.0 |" in table
    assert table.splitlines()[0] == "Voxel IoU (32^3) / Chamfer-L1 on the test split, 4 samples"
    side = markdown_table({**result, "elevation": 0.0, "augment_strength": 1.0})
    assert side.splitlines()[0].endswith("4 samples, views at 0 degrees elevation, sketches augmented at strength 1")
    assert markdown_table({**result, "gt_normals": True}).splitlines()[0].endswith("4 samples, ground-truth normals")


def test_category_mean_se_is_the_stratified_standard_error():
    """Hand-computed on two categories, then against the spread of the estimate over many draws."""
    from training.evaluation.evaluate import category_mean_se

    # a: mean 0.3, sample variance 0.02 over 2; b: mean 0.7, sample variance 0.04 over 3
    mean, se = category_mean_se([0.2, 0.5, 0.4, 0.7, 0.9], ["a", "b", "a", "b", "b"])
    assert mean == pytest.approx(0.5) and se == pytest.approx(np.sqrt(0.02 / 2 + 0.04 / 3) / 2)
    # a non-finite value is left out; a category with one value has no variance: NaN, not a made-up figure
    assert category_mean_se([0.2, np.nan, 0.4], ["a", "a", "a"]) == (pytest.approx(0.3), pytest.approx(0.1))
    m1, s1 = category_mean_se([0.2, 0.4, 0.9], ["a", "a", "b"])
    assert m1 == pytest.approx(0.6) and np.isnan(s1)
    assert all(np.isnan(category_mean_se([np.nan], ["a"])))
    with pytest.raises(ValueError, match="1-D arrays of one length"):
        category_mean_se([0.1, 0.2], ["a"])
    # clusters (a shape's views): one value per cluster is the formula above; a cluster that repeats one value
    # m times adds no information, so the SE is that of the distinct values
    values, cats = [0.2, 0.5, 0.4, 0.7, 0.9], ["a", "b", "a", "b", "b"]
    assert category_mean_se(values, cats, clusters=list("vwxyz")) == (pytest.approx(mean), pytest.approx(se))
    repeated = np.repeat(values, 3)
    got = category_mean_se(repeated, np.repeat(cats, 3), clusters=np.repeat(list("vwxyz"), 3))
    assert got == (pytest.approx(mean), pytest.approx(se))
    assert category_mean_se(repeated, np.repeat(cats, 3))[1] < se / 1.5  # taken as independent: too confident
    # one cluster per category: no spread between draws to measure
    assert np.isnan(category_mean_se([0.1, 0.3], ["a", "a"], clusters=["s", "s"])[1])
    # the SE predicts how far the category mean moves between independent draws of the same size
    rng = np.random.default_rng(0)
    cats = np.repeat(["a", "b", "c"], [5, 12, 30])
    scale = np.select([cats == "a", cats == "b"], [0.3, 0.1], 0.05)
    draws = [category_mean_se(rng.normal(0.5, scale), cats) for _ in range(4000)]
    spread = np.std([d[0] for d in draws])
    assert spread == pytest.approx(np.sqrt(0.09 / 5 + 0.01 / 12 + 0.0025 / 30) / 3, rel=0.05)
    assert np.mean([d[1] for d in draws]) == pytest.approx(spread, rel=0.1)


def test_eval_paired_difference_and_its_table_line():
    """Two methods on the same sketches: the difference of their category means and its paired SE, which is 0 for
    a constant shift whatever the samples' own spread; a different sample order is a bug, not a number."""
    from training.evaluation.evaluate import METRICS, _paired_difference, markdown_table

    first = [{"category": c, "shape_id": f"{c}{i}", "view": 0, "voxel_iou": v}
             for i, (c, v) in enumerate([("a", 0.1), ("a", 0.9), ("b", 0.3), ("b", 0.7)])]
    shifted = [dict(r, voxel_iou=r["voxel_iou"] + 0.05) for r in first]
    d = _paired_difference(shifted, first)
    assert d["voxel_iou"] == pytest.approx(0.05) and d["voxel_iou_se"] == pytest.approx(0.0, abs=1e-12)
    with pytest.raises(AssertionError, match="same sketches"):
        _paired_difference(shifted[::-1], first)

    per = {"a": {"voxel_iou": 0.5, "chamfer_l1": 0.1}}
    mean = {m: 0.5 for m in METRICS} | {"voxel_iou_se": 0.0123}
    result = {"method_order": ["full", "other"], "voxel_resolution": 32, "split": "val", "samples": 4,
              "gt_normals": False,
              "methods": {"full": {"per_category": per, "mean": mean, "ms_per_sample": 3.0},
                          "other": {"per_category": per, "mean": mean | {"voxel_iou_se": float("nan")},
                                    "ms_per_sample": 3.0, "vs_first": {"method": "full"} | d}}}
    table = markdown_table(result)
    assert "| full | 0.5000 +- 0.0123 | 0.5000 | 0.5000 | 0.5000 | 3.0 |" in table
    assert "| other | 0.5000 | 0.5000 |" in table  # no SE shown where there is none
    assert "Voxel IoU minus full's on the same sketches (paired): other +0.0500 +- 0.0000." in table
    # read back from JSON, where a NaN standard error is None: the difference alone
    result["methods"]["other"]["vs_first"]["voxel_iou_se"] = None
    assert "(paired): other +0.0500." in markdown_table(result)


def test_parity_inputs_of_a_small_sketch_dataset_keep_its_normal_images(tmp_path):
    """A run trained on ``data --size 64`` (training/gpu_predictor.sh) exports: the predictor's parity check
    reads the data's real normal images, the generator's reads drawn 256 x 256 sketches (the data's are 64)."""
    from training.data.dataset import BuildSettings, Job, build_dataset
    from training.export.to_onnx import parity_inputs
    from training.loop.trainer import make_dataset

    settings = BuildSettings(size=64, small_size=64, num_azimuths=3, elevations=(30.0,))
    build_dataset(tmp_path / "d", [Job("lamp", "lamp_00001", "test", "procedural", index=1)], settings, progress=False)
    cfg = TrainConfig(data_dir=str(tmp_path / "d"))
    ds = make_dataset(cfg.replace(augment_strength=0.0, extra_views=0), "test")
    assert np.asarray(ds[0]["sketch"]).shape[-1] == 64
    sketches, normals64, source = parity_inputs(cfg)
    assert tuple(sketches.shape) == (2, 1, 256, 256) and "synthetic sketches and 2 test normal images" in source
    expected = np.stack([np.asarray(ds[i]["normals64"], np.float32) for i in (0, len(ds) - 1)])
    np.testing.assert_array_equal(normals64.numpy(), expected)
    _, fallback, _ = parity_inputs(TrainConfig(data_dir=str(tmp_path / "no_data")))
    assert not np.array_equal(normals64.numpy(), fallback.numpy())
    assert sketches.amax() == 1.0 and sketches.amin() == 0.0


def test_ceiling_sheet_sets_the_fits_beside_the_models_mesh_and_the_shape(run_dir, exported, tmp_path):
    """A "fit" that is the true shape written to OBJ renders as the true shape does; the models' mesh does not."""
    from PIL import Image

    from engine.export import export_mesh
    from training.data.dataset import ShapeViewDataset
    from training.evaluation.gallery import GalleryError, ceiling_images, ceiling_sheet

    data = run_dir.parent / "data"
    test = ShapeViewDataset(data, "test", extra_views=0, augment_strength=0.0)
    recs = test._shapes[:2]
    fits = tmp_path / "fits"
    fits.mkdir()
    for rec in recs:
        export_mesh(test.load_mesh(rec["category"], rec["shape_id"]), fits / f"{rec['shape_id']}.obj")
    ids = [rec["shape_id"] for rec in recs]
    rows = ceiling_images(exported, data, {"fit": fits}, ids, azimuth=0, turn=15, size=48, threads=1)
    assert [r["shape_id"] for r in rows] == ids
    for r in rows:
        im = r["images"]
        assert list(im) == ["drawing", "models' mesh", "fit", "true shape"]
        assert all(im[k].shape == (48, 48) for k in ("models' mesh", "fit", "true shape"))
        assert np.abs(im["fit"] - im["true shape"]).mean() < 2e-3  # float32 OBJ round trip, same camera and frame
        assert im["true shape"].min() < 1.0  # the shape is in the picture
        assert np.abs(im["models' mesh"] - im["true shape"]).mean() > 0.01
    out = ceiling_sheet(exported, data, {"fit": fits}, ids, tmp_path / "sheet.png", azimuth=0, turn=15, size=48,
                        threads=1)
    assert Image.open(out).size == (720, 360)  # 4 columns x 2 rows of 1.8 inches at 100 dpi
    with pytest.raises(GalleryError, match="no fitted mesh"):
        ceiling_images(exported, data, {"fit": tmp_path}, ids, size=48, threads=1)
    with pytest.raises(GalleryError, match="true shape"):
        ceiling_images(exported, data, {"true shape": fits}, ids, size=48, threads=1)
    with pytest.raises(GalleryError, match="nosuch_00000"):
        ceiling_images(exported, data, {"fit": fits}, ["nosuch_00000"], size=48, threads=1)
