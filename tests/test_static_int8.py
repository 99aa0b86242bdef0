"""The generator's convolutions in int8 (engine.bench.static_int8_generator, `sketchmesh quantize-generator`): what it
writes, that the engine runs it in place of the float file and refuses a stale one, and its bad inputs."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("onnx")

from engine import contract as C  # noqa: E402
from engine.bench import folder_bytes, static_int8_generator  # noqa: E402
from engine.errors import ModelError, SketchInputError  # noqa: E402
from engine.pipeline import SketchEngine  # noqa: E402
from engine.preprocess import rasterize_strokes  # noqa: E402
from engine.strokes import Stroke  # noqa: E402

BUNDLED = Path(__file__).resolve().parents[1] / "assets" / "models"


def _drawings(seed: int, n: int) -> np.ndarray:
    """(n, 1, 256, 256) drawings of random closed outlines with a stroke across: sketch-like, not test sketches."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 2 * np.pi, 90)
    out = []
    for _ in range(n):
        cx, cy, rx, ry = rng.uniform(110, 150), rng.uniform(110, 150), rng.uniform(40, 100), rng.uniform(30, 100)
        wobble = 1 + 0.15 * np.sin(rng.integers(2, 6) * t + rng.uniform(0, 6))
        outline = np.stack([cx + rx * wobble * np.cos(t), cy + ry * wobble * np.sin(t)], 1)
        cross = [[cx - rx * 0.8, cy + rng.uniform(-20, 20)], [cx + rx * 0.8, cy + rng.uniform(-20, 20)]]
        out.append(rasterize_strokes([Stroke(outline), Stroke(cross)])[None])
    return np.stack(out).astype(np.float32)


@pytest.fixture(scope="module")
def int8_folder(tmp_path_factory):
    """The bundled pair (without its router and specialists: a drawing near the router's threshold may go to another
    predictor with either generator, a jump no precision error bounds) with generator_int8.onnx made from 16
    calibration drawings."""
    folder = tmp_path_factory.mktemp("int8") / "models"
    shutil.copytree(BUNDLED, folder, ignore=shutil.ignore_patterns(C.GENERATOR_INT8_FILE, "*.md", C.ROUTER_FILE,
                                                                   "mesh_predictor_*.onnx"))
    report = static_int8_generator(folder / C.GENERATOR_FILE, folder / C.GENERATOR_INT8_FILE, _drawings(0, 16))
    return folder, report


def test_the_convolutions_are_int8_and_the_output_stays_close(int8_folder):
    """The convolutions on images of 16 x 16 or more, but the first and the last, read int8 weights (DequantizeLinear,
    per output channel); the small-image ones keep their stored form, so the file stays near the float one's size. On
    drawings the calibration never saw, the engine runs the int8 file and its normal images stay within int8's error
    of the float generator's, and so do the meshes."""
    import onnx

    folder, report = int8_folder
    model = onnx.load(str(folder / C.GENERATOR_INT8_FILE))
    convs = [n for n in model.graph.node if n.op_type == "Conv"]
    dq = {n.output[0]: n for n in model.graph.node if n.op_type == "DequantizeLinear"}
    weights_int8 = [c for c in convs if c.input[1] in dq]
    # the encoder's 64-16 pixel levels and the decoder's 16-64 (sub-pixel): 3 + 3; the 8 x 8 and smaller and the ends not
    assert report["quantized"] == len(weights_int8) == 6
    assert sorted(report["kept_float"]) == sorted(c.name for c in convs if c not in weights_int8)
    assert convs[0] not in weights_int8 and convs[-1] not in weights_int8
    assert [c.name.split("/")[1] for c in weights_int8] == ["down.1", "down.2", "down.3", "up.4", "up.5", "up.6"]
    assert (folder / C.GENERATOR_INT8_FILE).stat().st_size < 1.5 * (folder / C.GENERATOR_FILE).stat().st_size
    # the first convolution alone: 16 kernels of 4 x 4 taps over one channel at 128 x 128 outputs
    assert report["macs"] - report["macs_int8"] > 16 * 16 * 128 * 128 and 0.5 < report["macs_int8"] / report["macs"] < 0.9
    init = {i.name: i for i in model.graph.initializer}
    w = init[dq[weights_int8[0].input[1]].input[0]]
    scale = init[dq[weights_int8[0].input[1]].input[1]]
    assert w.data_type == onnx.TensorProto.INT8 and len(scale.dims) == 1 and scale.dims[0] == w.dims[0]
    meta = {p.key: p.value for p in model.metadata_props}
    assert meta[C.META_QUANTIZATION] == "int8-static" and meta[C.META_ROLE] == C.ROLE_GENERATOR
    assert 0.0 < report["mean_abs"] < 0.01 and report["calibration"] == 16

    fast = SketchEngine(folder, threads=2, cache_size=0, mirror_average=False)
    plain_dir = folder.parent / "plain"
    shutil.copytree(folder, plain_dir, ignore=shutil.ignore_patterns(C.GENERATOR_INT8_FILE))
    plain = SketchEngine(plain_dir, threads=2, cache_size=0, mirror_average=False)
    assert fast.model_info()["generator"]["path"].endswith(C.GENERATOR_INT8_FILE)
    assert plain.model_info()["generator"]["path"].endswith(C.GENERATOR_FILE)
    diffs, moves, sizes = [], [], []
    for d in _drawings(1, 4):
        a, b = fast.predict(d[0], want_normals=True), plain.predict(d[0], want_normals=True)
        assert np.all(np.isfinite(a.normals)) and np.all(np.isfinite(a.mesh.vertices))
        diffs.append(np.abs(a.normals - b.normals).mean())
        moves.append(np.linalg.norm(a.mesh.vertices - b.mesh.vertices, axis=1).mean())
        sizes.append(np.ptp(b.mesh.vertices, axis=0).max())
    assert 0.0 < np.mean(diffs) < 0.01  # int8 moved the image a little, not nothing, not a lot
    assert np.mean(moves) < 0.02 * np.mean(sizes)
    assert folder_bytes(folder) == folder_bytes(plain_dir) + (folder / C.GENERATOR_INT8_FILE).stat().st_size


def test_a_stale_int8_file_is_an_error_naming_the_fix(int8_folder, tmp_path):
    """An int8 file beside another generator.onnx than it was made from: a ModelError saying to remake or delete it."""
    import onnx

    folder, _ = int8_folder
    stale = tmp_path / "stale"
    shutil.copytree(folder, stale)
    model = onnx.load(str(stale / C.GENERATOR_FILE))
    model.doc_string = "another export"
    onnx.save(model, str(stale / C.GENERATOR_FILE))
    engine = SketchEngine(stale, threads=1)
    with pytest.raises(ModelError, match="was not made from .*delete it"):
        engine.load()
    (stale / C.GENERATOR_INT8_FILE).unlink()  # without it the float generator runs
    assert SketchEngine(stale, threads=1).model_info()["generator"]["path"].endswith(C.GENERATOR_FILE)


def test_bad_calibration_and_models_are_clear_errors(tmp_path):
    gen, pred = BUNDLED / C.GENERATOR_FILE, BUNDLED / C.PREDICTOR_FILE
    x = _drawings(2, 2)
    for bad in (x[:, 0], x[:0], np.full_like(x, np.nan), x * 2.0):
        with pytest.raises(SketchInputError, match="calibration drawings"):
            static_int8_generator(gen, tmp_path / "g.onnx", bad)
    with pytest.raises(ModelError, match="not a generator"):
        static_int8_generator(pred, tmp_path / "g.onnx", x)
    with pytest.raises(ModelError, match="none left to quantise"):
        static_int8_generator(gen, tmp_path / "g.onnx", x, keep_float=8)
    broken = tmp_path / "broken.onnx"
    broken.write_bytes(b"not a model")
    with pytest.raises(ModelError, match="cannot read"):
        static_int8_generator(broken, tmp_path / "g.onnx", x)
    assert not (tmp_path / "g.onnx").exists()


def test_the_command_calibrates_on_a_training_split(tmp_path):
    """`sketchmesh quantize-generator` on a dataset's train split writes the file the engine then runs; the test split,
    a missing dataset or too few views are one-line errors."""
    pytest.importorskip("torch")
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from synthetic_data import write_synthetic_dataset

    data = write_synthetic_dataset(tmp_path / "data", splits=("train", "train", "val"), views=3)
    folder = tmp_path / "models"
    shutil.copytree(BUNDLED, folder, ignore=shutil.ignore_patterns(C.GENERATOR_INT8_FILE, "*.md"))
    cli = [sys.executable, "-m", "sketchmesh", "quantize-generator", str(folder)]
    r = subprocess.run([*cli, "--data", str(data), "--drawings", "6"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "6 convolutions in int8" in r.stdout and "6 calibration drawings" in r.stdout
    assert SketchEngine(folder, threads=1).model_info()["generator"]["metadata"][C.META_QUANTIZATION] == "int8-static"
    for extra, message in ((["--data", str(data), "--split", "test"], "invalid choice"),
                           (["--data", str(tmp_path / "none")], "does not exist"),
                           (["--data", str(data), "--drawings", "500"], "fewer than")):
        r = subprocess.run([*cli, *extra], capture_output=True, text=True, timeout=300)
        assert r.returncode != 0 and "Traceback" not in r.stderr and message in r.stderr, r.stderr
