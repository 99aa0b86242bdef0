"""SketchEngine on the tiny fixture models, model validation, the infer CLI and bench engine."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import threading
from pathlib import Path

import cv2
import numpy as np
import onnxruntime as ort
import pytest
from onnx_fixtures import (
    make_generator,
    make_predictor,
    write_corrupt_model,
    write_fixture_models,
    write_model,
    write_wrong_shape_generator,
)

from engine import contract as C
from engine.errors import EmptySketchError, ModelError, SketchInputError, SketchmeshError
from engine.icosphere import icosphere
from engine.mesh import Mesh
from engine.models import THREADS_ENV, default_threads, load_generator, load_predictor, physical_cores
from engine.pipeline import STAGES, SketchEngine, assemble_mesh, downsample_normals
from engine.preprocess import rasterize_strokes, sketch_raster_from_image
from engine.strokes import Stroke

ROOT = Path(__file__).resolve().parents[1]
ORT_ATOL = 1e-5
"""Same models, same inputs, float32: only summation-order differences between two sessions."""


@pytest.fixture(scope="module")
def models(tmp_path_factory) -> Path:
    return write_fixture_models(tmp_path_factory.mktemp("models"))


@pytest.fixture(scope="module")
def engine(models) -> SketchEngine:
    return SketchEngine(models, threads=1)


def _strokes(shift: float = 0.0) -> list[Stroke]:
    t = np.linspace(0, 2 * np.pi, 60)
    return [Stroke(np.stack([200 + 90 * np.cos(t), 150 + (60 + shift) * np.sin(t)], 1)),
            Stroke([[130, 150], [270, 150 + shift]])]


def _reference_prediction(models: Path, raster: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Independent pipeline: raw ORT sessions, block-mean downsampling (exact 4x area average)."""
    gen = ort.InferenceSession(str(models / C.GENERATOR_FILE), providers=["CPUExecutionProvider"])
    pred = ort.InferenceSession(str(models / C.PREDICTOR_FILE), providers=["CPUExecutionProvider"])
    (normals,) = gen.run(None, {"sketch": raster[None, None].astype(np.float32)})
    small = normals.reshape(1, 3, 64, 4, 64, 4).mean(axis=(3, 5)).astype(np.float32)
    local, glob = pred.run(["local_offset", "global_offset"], {"normals": small})
    vertices = icosphere(3).vertices.astype(np.float64) + local[0] + glob[0]
    return vertices, normals[0].transpose(1, 2, 0)


def test_predict_matches_an_independent_pipeline(engine, models):
    strokes = _strokes()
    pred = engine.predict(strokes, want_normals=True)
    assert pred.mesh.vertices.shape == (642, 3) and pred.mesh.faces.shape == (1280, 3)
    np.testing.assert_array_equal(pred.mesh.faces, icosphere(3).faces)
    vertices, normals = _reference_prediction(models, rasterize_strokes(strokes))
    np.testing.assert_allclose(pred.mesh.vertices, vertices, atol=ORT_ATOL)
    assert pred.normals.shape == (256, 256, 3) and pred.normals.dtype == np.float32
    np.testing.assert_allclose(pred.normals, normals, atol=ORT_ATOL)
    np.testing.assert_array_equal(pred.sketch, rasterize_strokes(strokes))
    assert set(pred.timings_ms) == set(STAGES) and all(v >= 0 for v in pred.timings_ms.values())
    assert not pred.cached


def test_mesh_is_in_the_view_frame_near_the_template(engine):
    """Fixture offsets are ~1e-2: the view-frame mesh is the radius-0.5 sphere, centred, +Y up."""
    v = engine.predict(_strokes(5.0)).mesh.vertices.astype(np.float64)
    r = np.linalg.norm(v, axis=1)
    assert np.abs(r - 0.5).max() < 0.1
    assert np.linalg.norm(v.mean(axis=0)) < 0.05
    assert v[0, 1] > 0.4  # icosahedron vertex 0 is (-1, phi, 0): up stays up


def test_cache_hit_recomputes_nothing(models):
    eng = SketchEngine(models, threads=1)
    eng.load()
    calls = {"n": 0}

    class Counting:
        def __init__(self, session):
            self.session = session

        def run(self, *a, **k):
            calls["n"] += 1
            return self.session.run(*a, **k)

    eng._generator.session = Counting(eng._generator.session)
    eng._predictor.session = Counting(eng._predictor.session)
    first = eng.predict(_strokes(), want_normals=False)
    assert calls["n"] == 2 and first.normals is None
    second = eng.predict(_strokes(), want_normals=True)
    assert calls["n"] == 2 and second.cached
    assert second.normals is not None and second.normals.shape == (256, 256, 3)
    np.testing.assert_array_equal(second.mesh.vertices, first.mesh.vertices)
    assert {k for k, v in second.timings_ms.items() if v > 0} <= {"preprocess"}
    eng.predict(_strokes(3.0))
    assert calls["n"] == 4  # a changed sketch runs the models again
    nocache = SketchEngine(models, threads=1, cache_size=0)
    assert not nocache.predict(_strokes()).cached and not nocache.predict(_strokes()).cached


def _mirrored_back(vertices: np.ndarray, level: int = 3) -> np.ndarray:
    """A flipped drawing's mesh mirrored back (x negated) and re-indexed by nearest template vertex, by brute force."""
    t = icosphere(level).vertices.astype(np.float64)
    d = np.linalg.norm(t[:, None, :] - (t * [-1.0, 1.0, 1.0])[None, :, :], axis=-1)
    partner = d.argmin(axis=1)  # partner[i]: the template vertex whose mirror image is vertex i
    assert np.all(d[np.arange(len(t)), partner] < 1e-6)
    return (vertices * [-1.0, 1.0, 1.0])[partner]


def test_mirror_average_matches_an_independent_pipeline(models):
    strokes = _strokes(7.0)
    raster = rasterize_strokes(strokes)
    eng = SketchEngine(models, threads=1, mirror_average=True)
    pred = eng.predict(strokes, want_normals=True)
    plain, normals = _reference_prediction(models, raster)
    flipped, _ = _reference_prediction(models, np.ascontiguousarray(raster[:, ::-1]))
    expected = (plain + _mirrored_back(flipped)) / 2
    np.testing.assert_allclose(pred.mesh.vertices, expected, atol=ORT_ATOL)
    assert np.abs(expected - plain).max() > 1e-3  # the fixture is not mirror-equivariant: averaging moved the mesh
    np.testing.assert_allclose(pred.normals, normals, atol=ORT_ATOL)  # the normal image shown is the plain drawing's
    np.testing.assert_array_equal(pred.mesh.faces, icosphere(3).faces)
    # the cache keeps the two modes apart
    eng.mirror_average = False
    off = eng.predict(strokes)
    assert not off.cached
    np.testing.assert_allclose(off.mesh.vertices, plain, atol=ORT_ATOL)
    eng.mirror_average = True
    again = eng.predict(strokes)
    assert again.cached
    np.testing.assert_array_equal(again.mesh.vertices, pred.mesh.vertices)
    with pytest.raises(ValueError, match="mirror_average"):
        eng.mirror_average = "yes"
    with pytest.raises(ValueError, match="mirror_average"):
        SketchEngine(models, mirror_average=1)


def test_a_flipped_drawing_is_the_x_negated_mesh_seen_by_the_sketch_camera():
    """What mirror averaging rests on, seen by the engine's own camera and rasterizer: an asymmetric mesh negated in x
    (the view frame's mirror) and framed like a sketch looks exactly like the original's image flipped left to right."""
    from engine.refine import pixel_coords, render_silhouette, sketch_camera

    t = icosphere(2)
    v = t.vertices.astype(np.float64)
    v = v * [1.0, 0.7, 0.9] + np.where(v[:, :1] > 0.1, [[0.35, 0.1, 0.0]], 0.0)  # a bump on the right only
    plain = Mesh(v, t.faces)
    negated = Mesh(v * [-1.0, 1.0, 1.0], t.faces[:, ::-1])
    sil = [render_silhouette(pixel_coords(m.vertices, sketch_camera(m), 128)[0], m.faces, 128) > 0
           for m in (plain, negated)]
    assert sil[0].sum() > 2000 and not np.array_equal(sil[0], sil[0][:, ::-1])  # asymmetric, so the test can fail
    assert np.mean(sil[1] != sil[0][:, ::-1]) < 1e-3


def _fix_batch_at_one(src: Path, dst: Path) -> None:
    """The model ``src`` with its inputs' and outputs' batch dimension fixed at 1 (the contract allows it), as ``dst``."""
    import onnx

    m = onnx.load(str(src))
    for v in [*m.graph.input, *m.graph.output]:
        v.type.tensor_type.shape.dim[0].dim_value = 1
    onnx.save(m, str(dst))


def test_mirror_average_with_batch_fixed_at_one(tmp_path, models):
    """The two drawings of mirror averaging go through each network as one batch of two; a network whose batch dimension
    is fixed at 1 runs once per drawing instead, to the same mesh."""
    fixed = tmp_path / "fixed"
    fixed.mkdir()
    for name in (C.GENERATOR_FILE, C.PREDICTOR_FILE):
        _fix_batch_at_one(models / name, fixed / name)
    eng = SketchEngine(fixed, threads=1, mirror_average=True)
    eng.load()
    assert not eng._generator.batch_dynamic and not eng._predictor.batch_dynamic
    strokes = _strokes(3.0)
    want = SketchEngine(models, threads=1, mirror_average=True)
    want.load()
    assert want._generator.batch_dynamic and want._predictor.batch_dynamic
    got, ref = eng.predict(strokes, want_normals=True), want.predict(strokes, want_normals=True)
    np.testing.assert_allclose(got.mesh.vertices, ref.mesh.vertices, atol=ORT_ATOL)
    np.testing.assert_allclose(got.normals, ref.normals, atol=ORT_ATOL)
    with pytest.raises(ModelError, match="batch dimension must be dynamic or 1"):
        bad = tmp_path / "two"
        bad.mkdir()
        import onnx

        m = onnx.load(str(models / C.GENERATOR_FILE))
        m.graph.input[0].type.tensor_type.shape.dim[0].dim_value = 2
        onnx.save(m, str(bad / C.GENERATOR_FILE))
        load_generator(bad / C.GENERATOR_FILE)


def test_cli_infer_mirror_average(tmp_path, models, sketch_png):
    out_plain, out_mirror = tmp_path / "plain.obj", tmp_path / "mirror.obj"
    for out, extra in ((out_plain, []), (out_mirror, ["--mirror-average"])):
        report = out.with_suffix(".json")
        r = _cli("infer", sketch_png, "-o", out, "--models", models, "--threads", 1, "--report", report, *extra,
                 cwd=tmp_path)
        assert r.returncode == 0, r.stderr
        assert json.loads(report.read_text())["mirror_average"] is bool(extra)
    import trimesh

    mesh = trimesh.load(out_mirror, process=False)
    ref = SketchEngine(models, threads=1, mirror_average=True).predict(sketch_png).mesh
    np.testing.assert_allclose(mesh.vertices, ref.vertices, atol=1e-5)
    assert np.abs(mesh.vertices - trimesh.load(out_plain, process=False).vertices).max() > 1e-3


def test_path_raster_and_strokes_inputs_agree(engine, tmp_path):
    img = np.full((300, 400), 255, np.uint8)
    cv2.circle(img, (200, 150), 100, 0, 4)
    path = tmp_path / "circle.png"
    cv2.imwrite(str(path), img)
    from_path = engine.predict(path)
    from_raster = engine.predict(sketch_raster_from_image(path))
    np.testing.assert_array_equal(from_path.mesh.vertices, from_raster.mesh.vertices)
    assert from_raster.cached  # same raster -> same key
    assert engine.predict(str(path)).cached


def test_a_growing_drawing_is_rasterized_as_from_scratch(models):
    """The engine draws only the stroke under the pen once the rest is drawn (engine.preprocess.StrokeRasterizer),
    and what the networks see is still exactly the stroke list drawn from scratch."""
    eng = SketchEngine(models, threads=1)
    outline, cross = _strokes()
    committed = [outline]
    for m in (2, 20, 60):  # the stroke under the pen grows inside the outline's box
        live = Stroke(np.stack([np.linspace(150, 250, m), np.full(m, 150.0)], 1))
        pred = eng.predict([*committed, live])
        np.testing.assert_array_equal(pred.sketch, rasterize_strokes([*committed, live]))
        assert eng._rasterize.last_drawn_segments == (59 if m == 2 else 0) + m - 1
    committed.append(cross)
    pred = eng.predict(committed)  # pen-up: the committed stroke is a new object
    np.testing.assert_array_equal(pred.sketch, rasterize_strokes(committed))
    assert eng._rasterize.last_drawn_segments == 1


def test_predict_is_thread_safe(models):
    eng = SketchEngine(models, threads=1, cache_size=0)
    sketches = [_strokes(float(k)) for k in range(4)]
    serial = [eng.predict(s).mesh.vertices for s in sketches]
    results: dict[int, np.ndarray] = {}
    errors = []

    def work(k):
        try:
            for _ in range(3):
                results[k] = eng.predict(sketches[k]).mesh.vertices
        except Exception as exc:  # pragma: no cover - reported below
            errors.append(exc)

    threads = [threading.Thread(target=work, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=60)
    assert not errors
    for k in range(4):
        np.testing.assert_array_equal(results[k], serial[k])


@pytest.mark.parametrize("bad, error, match", [
    (np.zeros((256, 256), np.float32), EmptySketchError, "blank"),
    (np.full((256, 256), np.nan, np.float32), SketchInputError, "NaN"),
    (np.ones((128, 128), np.float32), SketchInputError, r"\(256, 256\)"),
    (np.full((256, 256), 2.0, np.float32), SketchInputError, r"\[0, 1\]"),
    ([], EmptySketchError, "no strokes"),
    (42, SketchInputError, "int"),
])
def test_bad_sketches_raise_clear_errors(engine, bad, error, match):
    with pytest.raises(error, match=match):
        engine.predict(bad)


def test_construction_loads_nothing_and_missing_models_are_explained(tmp_path):
    eng = SketchEngine(tmp_path / "missing")  # no error yet: loading is lazy
    assert eng.models_dir == tmp_path / "missing" and not eng.is_loaded
    with pytest.raises(ModelError, match="does not exist.*--models DIR.*sketchmesh train"):
        eng.predict(_strokes())
    (tmp_path / "empty").mkdir()
    with pytest.raises(ModelError, match="no generator.onnx or mesh_predictor.onnx in"):
        SketchEngine(tmp_path / "empty").model_info()


def test_model_info(engine, models):
    info = engine.model_info()
    assert info["template_level"] == 3 and info["models_dir"] == str(models)
    assert info["generator"]["metadata"][C.META_ROLE] == C.ROLE_GENERATOR
    assert info["predictor"]["outputs"]["local_offset"] == ["N", 642, 3]
    json.dumps(info)


def _broken(kind: str, folder: Path) -> tuple[Path, str]:
    """Write one broken model into ``folder``; return its path and the expected message fragment."""
    if kind == "corrupt":
        return write_corrupt_model(folder / "g.onnx"), "not a valid ONNX file"
    if kind == "wrong-shape":
        return write_wrong_shape_generator(folder / "g.onnx"), "dimension 2 must be 256"
    if kind == "no-metadata":
        return write_model(make_generator(drop_metadata=(C.META_CONVENTIONS,)), folder / "g.onnx"), "lacks conventions"
    if kind == "wrong-role":
        return write_model(make_predictor(), folder / "g.onnx"), "role is 'mesh_predictor'"
    if kind == "wrong-conventions":
        return write_model(make_generator(metadata={C.META_CONVENTIONS: "other-1"}), folder / "g.onnx"), "conventions"
    if kind == "wrong-channels":
        return write_model(make_generator(out_channels=1), folder / "g.onnx"), "dimension 1 must be 3"
    if kind == "level-mismatch":
        return write_model(make_predictor(3, metadata={C.META_TEMPLATE_LEVEL: "2"}), folder / "p.onnx"), "does not match"
    if kind == "bad-level":
        return write_model(make_predictor(3, metadata={C.META_TEMPLATE_LEVEL: "three"}), folder / "p.onnx"), "bad template"
    if kind == "float16-input":
        from onnx import TensorProto

        return write_model(make_generator(input_dtype=TensorProto.FLOAT16), folder / "g.onnx"), "must be float32"
    if kind == "missing":
        return folder / "absent.onnx", "no such model file"
    raise ValueError(kind)


@pytest.mark.parametrize("kind", ["corrupt", "wrong-shape", "no-metadata", "wrong-role", "wrong-conventions",
                                  "wrong-channels", "level-mismatch", "bad-level", "float16-input", "missing"])
def test_model_validation_errors_name_the_file_and_the_problem(tmp_path, kind):
    path, fragment = _broken(kind, tmp_path)
    loader = load_predictor if path.name == "p.onnx" else load_generator
    with pytest.raises(ModelError) as info:
        loader(path, threads=1)
    message = str(info.value)
    assert str(path) in message and fragment in message and "\n" not in message


def test_assemble_and_downsample_guards():
    with pytest.raises(ModelError, match="non-finite"):
        assemble_mesh(np.full((1, 642, 3), np.nan), np.zeros((1, 3)), 3, 0.5)
    with pytest.raises(ModelError, match=r"\(1, 642, 3\)"):
        assemble_mesh(np.zeros((1, 162, 3)), np.zeros((1, 3)), 3, 0.5)
    x = np.random.default_rng(0).random((1, 3, 256, 256)).astype(np.float32)
    np.testing.assert_allclose(downsample_normals(x), x.reshape(1, 3, 64, 4, 64, 4).mean(axis=(3, 5)), atol=1e-6)


def test_thread_defaults(monkeypatch):
    monkeypatch.delenv(THREADS_ENV, raising=False)
    assert 1 <= physical_cores() <= (os.cpu_count() or 1)
    assert 1 <= default_threads() <= physical_cores()


def test_threads_from_the_environment(monkeypatch, models, sketch_png, tmp_path):
    # SKETCHMESH_THREADS sets the engine's intra-op threads where no --threads is given (the app has none);
    # a bad value is a clear error naming the variable, from the engine and from the command line
    monkeypatch.setenv(THREADS_ENV, "3")
    assert default_threads() == 3 and SketchEngine(models).threads == 3
    assert SketchEngine(models, threads=2).threads == 2  # an explicit count wins
    for bad in ("0", "two", "-1", "1.5", "257"):
        monkeypatch.setenv(THREADS_ENV, bad)
        with pytest.raises(SketchmeshError, match=f"{THREADS_ENV} must be a whole number .* got '{re.escape(bad)}'"):
            SketchEngine(models)
    r = subprocess.run([sys.executable, "-m", "sketchmesh", "infer", str(sketch_png), "-o", str(tmp_path / "m.obj"),
                        "--models", str(models)], capture_output=True, text=True, cwd=tmp_path, timeout=120,
                       env={**os.environ, THREADS_ENV: "lots"})
    assert r.returncode != 0 and THREADS_ENV in r.stderr and "Traceback" not in r.stderr, r.stderr


def test_importing_the_engine_cli_is_cheap():
    code = ("import engine.cli, engine.pipeline, engine.models, sys; "
            "print(' '.join(m for m in ('torch', 'PySide6', 'onnx', 'training') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True).stdout
    assert out.strip() == ""


# ---------------------------------------------------------------------------------------------- CLI


def _cli(*args, cwd) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "sketchmesh", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, timeout=120)


@pytest.fixture(scope="module")
def sketch_png(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("sketches")
    img = np.full((240, 320), 255, np.uint8)
    cv2.ellipse(img, (160, 120), (110, 80), 0, 0, 360, 0, 3)
    cv2.line(img, (60, 120), (260, 120), 0, 3)
    cv2.imwrite(str(folder / "mug.png"), img)
    return folder / "mug.png"


def test_cli_infer_writes_mesh_normals_and_report(tmp_path, models, sketch_png):
    out, normals, report = tmp_path / "mug.glb", tmp_path / "n.png", tmp_path / "r.json"
    r = _cli("infer", sketch_png, "-o", out, "--models", models, "--normals", normals, "--report", report,
             "--smooth", 2, "--subdivide", 1, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert out.stat().st_size > 0 and cv2.imread(str(normals)).shape == (256, 256, 3)
    rec = json.loads(report.read_text())
    assert set(STAGES) <= set(rec["timings_ms"]) and "export" in rec["timings_ms"]
    assert rec["vertices"] == 2562 and rec["faces"] == 5120  # one Loop level on 642 / 1280
    assert rec["watertight"] is True and rec["self_intersections"] == 0
    import trimesh

    loaded = trimesh.load(out, force="mesh", process=False)
    assert len(loaded.vertices) == 2562


def test_cli_many_inputs_one_bad_does_not_stop_the_others(tmp_path, models, sketch_png):
    bad = tmp_path / "bad.png"
    bad.write_text("not an image")
    good2 = tmp_path / "second.png"
    good2.write_bytes(sketch_png.read_bytes())
    r = _cli("infer", sketch_png, bad, good2, "-o", tmp_path / "out", "--format", "ply", "--models", models,
             "--report", tmp_path / "reports", cwd=tmp_path)
    assert r.returncode != 0
    assert (tmp_path / "out" / "mug.ply").exists() and (tmp_path / "out" / "second.ply").exists()
    assert (tmp_path / "reports" / "second.json").exists()
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 2 and "bad.png" in lines[0] and "1 of 3" in lines[1] and "Traceback" not in r.stderr


def _write_bad_inputs(folder: Path) -> dict[str, Path]:
    import struct
    import zlib

    paths = {}
    (folder / "text.png").write_text("hello")
    paths["not-an-image"] = folder / "text.png"
    ok, buf = cv2.imencode(".png", np.full((50, 50), 255, np.uint8))
    (folder / "cut.png").write_bytes(buf.tobytes()[:40])
    paths["truncated"] = folder / "cut.png"
    cv2.imwrite(str(folder / "blank.png"), np.full((50, 50), 255, np.uint8))
    paths["blank"] = folder / "blank.png"
    cv2.imwrite(str(folder / "one.png"), np.zeros((1, 1), np.uint8))
    paths["1x1"] = folder / "one.png"
    ihdr = struct.pack(">IIBBBBB", 50000, 50000, 8, 0, 0, 0, 0)
    huge = b"\x89PNG\r\n\x1a\n" + struct.pack(">I", 13) + b"IHDR" + ihdr + struct.pack(">I", zlib.crc32(b"IHDR" + ihdr))
    (folder / "huge.png").write_bytes(huge + b"\x00\x00\x00\x00IEND\xaeB`\x82")
    paths["huge"] = folder / "huge.png"
    return paths


@pytest.mark.parametrize("case", ["not-an-image", "truncated", "blank", "1x1", "huge", "missing-models",
                                  "unknown-suffix", "bad-flag", "bad-value", "missing-file", "format-mismatch"])
def test_cli_bad_input_gives_one_line_and_nonzero_exit(tmp_path, models, sketch_png, case):
    bad = _write_bad_inputs(tmp_path)
    args = {
        "missing-models": [sketch_png, "-o", tmp_path / "x.obj", "--models", tmp_path / "nowhere"],
        "unknown-suffix": [sketch_png, "-o", tmp_path / "x.xyz", "--models", models],
        "bad-flag": [sketch_png, "-o", tmp_path / "x.obj", "--models", models, "--frobnicate"],
        "bad-value": [sketch_png, "-o", tmp_path / "x.obj", "--models", models, "--subdivide", "9"],
        "missing-file": [tmp_path / "absent.png", "-o", tmp_path / "x.obj", "--models", models],
        "format-mismatch": [sketch_png, "-o", tmp_path / "x.obj", "--format", "glb", "--models", models],
    }.get(case) or [bad[case], "-o", tmp_path / "x.obj", "--models", models]
    r = _cli("infer", *args, cwd=tmp_path)
    assert r.returncode != 0
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, r.stderr
    assert "Traceback" not in r.stderr and "error" in lines[0]
    assert not (tmp_path / "x.obj").exists()


def test_cli_formats_mirror_the_export_table():
    from engine.cli import FORMATS
    from engine.export import supported_suffixes

    assert tuple("." + f for f in FORMATS) == supported_suffixes()


# ---------------------------------------------------------------------------------------------- bench


def test_bench_engine_on_fixture_models(tmp_path, models, sketch_png, capsys):
    from engine.bench import run_engine_bench

    out = tmp_path / "bench.json"
    assert run_engine_bench(models, runs=2, warmup=0, threads=1, sketches=[str(sketch_png)],
                            variants=["fp32", "int8-predictor"], json_path=str(out)) == 0
    records = json.loads(out.read_text())
    stages = {"preprocess", "generator", "downsample", "predictor", "assemble", "export", "total"}
    assert {(r["variant"], r["stage"]) for r in records} == {(v, s) for v in ("fp32", "int8-predictor") for s in stages}
    for r in records:
        assert {"variant", "stage", "p50_ms", "p95_ms", "error"} <= set(r)
        assert 0 <= r["p50_ms"] <= r["p95_ms"]
    fp32 = next(r for r in records if r["variant"] == "fp32")
    int8 = next(r for r in records if r["variant"] == "int8-predictor")
    assert fp32["error"] == {"normals_mae": 0.0, "vertex_mean": 0.0, "vertex_max": 0.0}
    assert int8["error"]["normals_mae"] == 0.0  # the generator stayed float32
    assert 0 < int8["error"]["vertex_mean"] <= int8["error"]["vertex_max"] < 0.01
    assert int8["model_bytes"] < fp32["model_bytes"]
    table = capsys.readouterr().out
    assert "int8-predictor" in table and "p95 ms" in table


def test_bench_engine_mirror_variant(tmp_path, models, sketch_png):
    from engine.bench import run_engine_bench

    out = tmp_path / "bench.json"
    assert run_engine_bench(models, runs=1, warmup=0, threads=1, sketches=[str(sketch_png)],
                            variants=["fp32", "fp32+mirror"], json_path=str(out)) == 0
    records = {(r["variant"], r["stage"]): r for r in json.loads(out.read_text())}
    mirror = records[("fp32+mirror", "total")]
    assert mirror["error"]["normals_mae"] == 0.0  # the normal image kept is the plain drawing's
    assert mirror["error"]["vertex_mean"] > 0  # the averaged mesh moved
    assert mirror["model_bytes"] == records[("fp32", "total")]["model_bytes"]
    with pytest.raises(SketchInputError, match="mirror"):
        run_engine_bench(models, runs=1, variants=["fp16+mirror"])


def test_bench_engine_is_registered():
    from sketchmesh.cli import build_parser

    args = build_parser().parse_args(["bench", "engine", "--runs", "3", "--models", "somewhere"])
    assert args.runs == 3 and args.models == "somewhere" and callable(args.func)
