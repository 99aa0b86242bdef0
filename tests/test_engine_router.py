"""The engine's router: a model folder with router.onnx sends a drawing to a specialist mesh predictor when the
summed probability of its categories passes the threshold, and to mesh_predictor.onnx otherwise."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import onnxruntime as ort
import pytest

from engine import contract as C
from engine.errors import ModelError
from engine.icosphere import icosphere
from engine.pipeline import SketchEngine
from engine.preprocess import rasterize_strokes
from engine.strokes import Stroke

sys.path.insert(0, str(Path(__file__).resolve().parent))
from onnx_fixtures import make_predictor, make_router, write_fixture_models, write_model  # noqa: E402

ORT_ATOL = 1e-5
SPECIALIST = "mesh_predictor_legged.onnx"


def _strokes() -> list[Stroke]:
    t = np.linspace(0, 2 * np.pi, 60)
    return [Stroke(np.stack([200 + 90 * np.cos(t), 150 + 70 * np.sin(t)], 1)), Stroke([[130, 150], [270, 170]])]


def _folder(tmp_path: Path, probabilities, **router_kwargs) -> Path:
    """Fixture pair + a specialist (another predictor: other weights, so another mesh) + a fixed-output router."""
    folder = write_fixture_models(tmp_path / "models")
    write_model(make_predictor(3, seed=7), folder / SPECIALIST)
    write_model(make_router(probabilities, **router_kwargs), folder / C.ROUTER_FILE)
    return folder


def _small(generator: Path, raster: np.ndarray) -> np.ndarray:
    """(1, 3, 64, 64) predictor input of a raster, independently of the engine (raw ORT, exact 4x block mean)."""
    gen = ort.InferenceSession(str(generator), providers=["CPUExecutionProvider"])
    (normals,) = gen.run(None, {"sketch": raster[None, None].astype(np.float32)})
    return normals.reshape(1, 3, 64, 4, 64, 4).mean(axis=(3, 5)).astype(np.float32)


def _vertices(predictor: Path, generator: Path, raster: np.ndarray) -> np.ndarray:
    """Independent pipeline: raw ORT sessions, exact 4x block-mean downsampling, template + offsets."""
    pred = ort.InferenceSession(str(predictor), providers=["CPUExecutionProvider"])
    local, glob = pred.run(["local_offset", "global_offset"], {"normals": _small(generator, raster)})
    return icosphere(3).vertices.astype(np.float64) + local[0] + glob[0]


def test_a_sure_router_sends_the_drawing_to_the_specialist(tmp_path):
    folder = _folder(tmp_path, [0.5, 0.04, 0.46])  # bench + chair = 0.96 > 0.9
    eng = SketchEngine(folder, threads=1, cache_size=0)
    raster = rasterize_strokes(_strokes())
    pred = eng.predict(raster)
    want = _vertices(folder / SPECIALIST, folder / C.GENERATOR_FILE, raster)
    other = _vertices(folder / C.PREDICTOR_FILE, folder / C.GENERATOR_FILE, raster)
    assert np.abs(want - other).max() > 1e-3  # the two predictors differ, so the test can tell them apart
    np.testing.assert_allclose(pred.mesh.vertices, want, atol=ORT_ATOL)
    assert pred.route == SPECIALIST and pred.category == "bench"
    info = eng.model_info()["router"]
    assert info["routes"] == {SPECIALIST: ["bench", "chair"]} and info["route_threshold"] == 0.9


def test_an_unsure_router_keeps_the_general_predictor_and_loads_no_specialist(tmp_path):
    folder = _folder(tmp_path, [0.45, 0.12, 0.43])  # bench + chair = 0.88 < 0.9
    eng = SketchEngine(folder, threads=1, cache_size=0)
    raster = rasterize_strokes(_strokes())
    pred = eng.predict(raster)
    np.testing.assert_allclose(pred.mesh.vertices, _vertices(folder / C.PREDICTOR_FILE, folder / C.GENERATOR_FILE, raster),
                               atol=ORT_ATOL)
    assert pred.route is None and pred.category == "bench"
    assert eng._specialists == {}  # never routed to: never loaded


SECOND = "mesh_predictor_second.onnx"
THIRD = "mesh_predictor_third.onnx"


@pytest.mark.parametrize("probabilities, route", [
    ([0.02, 0.95, 0.02, 0.01], SECOND),  # car = 0.95 passes: the second specialist
    ([0.01, 0.02, 0.02, 0.95], THIRD),  # sofa = 0.95 passes: the third
    ([0.5, 0.02, 0.46, 0.02], SPECIALIST),  # bench + chair = 0.96 passes: the first
    ([0.45, 0.1, 0.43, 0.02], None),  # no group passes 0.9: the general predictor
])
def test_three_routes_each_drawing_goes_to_its_groups_specialist_alone(tmp_path, probabilities, route):
    folder = write_fixture_models(tmp_path / "models")
    write_model(make_predictor(3, seed=7), folder / SPECIALIST)
    write_model(make_predictor(3, seed=11), folder / SECOND)
    write_model(make_predictor(3, seed=13), folder / THIRD)
    write_model(make_router(probabilities, categories=("bench", "car", "chair", "sofa"),
                            routes={SPECIALIST: ["bench", "chair"], SECOND: ["car"], THIRD: ["sofa"]}),
                folder / C.ROUTER_FILE)
    eng = SketchEngine(folder, threads=1, cache_size=0)
    raster = rasterize_strokes(_strokes())
    pred = eng.predict(raster)
    want = _vertices(folder / (route or C.PREDICTOR_FILE), folder / C.GENERATOR_FILE, raster)
    others = [_vertices(folder / f, folder / C.GENERATOR_FILE, raster)
              for f in (SPECIALIST, SECOND, THIRD, C.PREDICTOR_FILE) if f != (route or C.PREDICTOR_FILE)]
    assert all(np.abs(want - o).max() > 1e-3 for o in others)  # the four predictors can be told apart
    np.testing.assert_allclose(pred.mesh.vertices, want, atol=ORT_ATOL)
    assert pred.route == route
    assert set(eng._specialists) == ({route} if route else set())  # only the specialist routed to is loaded


def test_no_router_no_route(tmp_path):
    folder = write_fixture_models(tmp_path / "models")
    pred = SketchEngine(folder, threads=1).predict(_strokes())
    assert pred.route is None and pred.category is None
    assert SketchEngine(folder, threads=1).model_info()["router"] is None


def test_mirror_averaging_uses_the_plain_drawings_route_for_both_passes(tmp_path):
    folder = _folder(tmp_path, [0.02, 0.03, 0.95])
    eng = SketchEngine(folder, threads=1, cache_size=0, mirror_average=True)
    raster = rasterize_strokes(_strokes())
    pred = eng.predict(raster)
    plain = _vertices(folder / SPECIALIST, folder / C.GENERATOR_FILE, raster)
    flipped = _vertices(folder / SPECIALIST, folder / C.GENERATOR_FILE, np.ascontiguousarray(raster[:, ::-1]))
    t = icosphere(3).vertices.astype(np.float64)
    partner = np.linalg.norm(t[:, None] - (t * [-1.0, 1.0, 1.0])[None], axis=-1).argmin(1)
    np.testing.assert_allclose(pred.mesh.vertices, (plain + (flipped * [-1.0, 1.0, 1.0])[partner]) / 2, atol=ORT_ATOL)
    assert pred.route == SPECIALIST and pred.category == "chair"


def _lopsided() -> list[Stroke]:
    """Hatching on the left, one long line to the right: a drawing whose ink is mostly in its left half."""
    return [Stroke([[100 + 6 * i, 100], [100 + 6 * i, 220]]) for i in range(10)] + [Stroke([[100, 160], [330, 160]])]


def _mirror_router_folder(tmp_path: Path, mirror_meta: str | None, batch="N") -> tuple[Path, np.ndarray, np.ndarray]:
    """A folder whose router reads the image's left-right asymmetry d, built so that the plain drawing alone gives
    bench + chair = 0.95 (> 0.9: the specialist) and its flip 0.5: their mean, 0.725, keeps the general predictor.
    Returns the folder and the plain and flipped drawings' probabilities, computed here in numpy."""
    folder = write_fixture_models(tmp_path / "models")
    write_model(make_predictor(3, seed=7), folder / SPECIALIST)
    raster = rasterize_strokes(_lopsided())
    d = [(sm[..., :32].mean(axis=(2, 3)) - sm[..., 32:].mean(axis=(2, 3)))[0].astype(np.float64)
         for sm in (_small(folder / C.GENERATOR_FILE, raster), _small(folder / C.GENERATOR_FILE, raster[:, ::-1].copy()))]
    u = d[0] - d[1]
    assert np.linalg.norm(u) > 1e-2  # the fixture generator's image of the drawing is far from mirror-symmetric
    t_plain, t_flip = (float(u @ di / (u @ u)) for di in d)  # t_plain - t_flip = 1
    g_plain, g_flip = np.log(9.5), np.log(0.5)  # bench = chair logit: 2 e^g / (2 e^g + 1) = 0.95, 0.5
    alpha = g_plain - g_flip
    beta = g_plain - alpha * t_plain
    weights = np.zeros((3, 3))
    weights[:, 0] = weights[:, 2] = alpha * u / (u @ u)
    base = np.exp([beta, 0.0, beta]) / np.exp([beta, 0.0, beta]).sum()
    meta = {} if mirror_meta is None else {C.META_ROUTE_MIRROR: mirror_meta}
    write_model(make_router(base, weights=weights, metadata=meta, batch=batch), folder / C.ROUTER_FILE)

    def probs(di):
        z = np.log(base) + di @ weights
        return np.exp(z - z.max()) / np.exp(z - z.max()).sum()

    return folder, probs(d[0]), probs(d[1])


@pytest.mark.parametrize("batch", ["N", 1])  # 1: a router that takes one image a run reads the two in turn
def test_a_mirror_router_routes_on_the_mean_of_the_drawing_and_its_flip(tmp_path, batch):
    folder, plain, flipped = _mirror_router_folder(tmp_path, "true", batch)
    np.testing.assert_allclose([plain[0] + plain[2], flipped[0] + flipped[2]], [0.95, 0.5], atol=1e-9)
    raster = rasterize_strokes(_lopsided())
    eng = SketchEngine(folder, threads=1, cache_size=0, mirror_average=True)
    pred = eng.predict(raster)
    t = icosphere(3).vertices.astype(np.float64)
    partner = np.linalg.norm(t[:, None] - (t * [-1.0, 1.0, 1.0])[None], axis=-1).argmin(1)
    a = _vertices(folder / C.PREDICTOR_FILE, folder / C.GENERATOR_FILE, raster)
    b = _vertices(folder / C.PREDICTOR_FILE, folder / C.GENERATOR_FILE, np.ascontiguousarray(raster[:, ::-1]))
    np.testing.assert_allclose(pred.mesh.vertices, (a + (b * [-1.0, 1.0, 1.0])[partner]) / 2, atol=ORT_ATOL)
    mean = (plain + flipped) / 2  # bench + chair 0.725 < 0.9: the general predictor
    assert pred.route is None and pred.category == ("bench", "car", "chair")[int(np.argmax(mean))]
    assert eng.model_info()["router"]["route_mirror"] is True
    eng.mirror_average = False  # no flipped drawing to read: the plain drawing's 0.95 routes it
    assert eng.predict(raster).route == SPECIALIST


def test_without_route_mirror_the_plain_drawing_alone_routes_both_passes(tmp_path):
    for meta in (None, "false"):
        folder, _, _ = _mirror_router_folder(tmp_path / str(meta), meta)
        eng = SketchEngine(folder, threads=1, cache_size=0, mirror_average=True)
        assert eng.predict(_lopsided()).route == SPECIALIST
        assert eng.model_info()["router"]["route_mirror"] is False


def test_the_route_is_cached_with_the_mesh(tmp_path):
    folder = _folder(tmp_path, [0.5, 0.04, 0.46])
    eng = SketchEngine(folder, threads=1)
    first, again = eng.predict(_strokes()), eng.predict(_strokes())
    assert again.cached and again.route == first.route == SPECIALIST and again.category == "bench"


def _broken(tmp_path: Path, kind: str) -> tuple[Path, str]:
    if kind == "missing specialist":
        folder = _folder(tmp_path, [0.5, 0.04, 0.46])
        (folder / SPECIALIST).unlink()
        return folder, "not in"
    if kind == "threshold":
        return _folder(tmp_path, [0.5, 0.04, 0.46], threshold=1.5), "route_threshold"
    if kind == "unknown category":
        return _folder(tmp_path, [0.5, 0.04, 0.46], routes={SPECIALIST: ["bench", "sofa"]}), "categories of the router"
    if kind == "route to the generator":
        return _folder(tmp_path, [0.5, 0.04, 0.46], routes={C.GENERATOR_FILE: ["bench"]}), "another .onnx file"
    if kind == "categories not a list":
        return _folder(tmp_path, [0.5, 0.5], metadata={C.META_CATEGORIES: '"bench"'}), "distinct names"
    if kind == "output size":
        return _folder(tmp_path, [0.5, 0.04, 0.46], categories=("bench", "car", "chair", "lamp")), "dimension 1 must be 4"
    if kind == "no routes":
        return _folder(tmp_path, [0.5, 0.04, 0.46], drop_metadata=(C.META_ROUTES,)), "lacks 'routes'"
    if kind == "category twice":
        return _folder(tmp_path, [0.5, 0.04, 0.46], routes={SPECIALIST: ["bench", "bench"]}), "each in one route"
    if kind == "categories not names":
        return _folder(tmp_path, [0.5, 0.5], metadata={C.META_CATEGORIES: "[[1], [2]]"}), "distinct names"
    if kind == "route_mirror":
        return _folder(tmp_path, [0.5, 0.04, 0.46], metadata={C.META_ROUTE_MIRROR: 'yes'}), "true or false"
    if kind == "role":
        return _folder(tmp_path, [0.5, 0.04, 0.46], metadata={C.META_ROLE: C.ROLE_PREDICTOR}), "role"
    raise AssertionError(kind)


@pytest.mark.parametrize("kind", ["missing specialist", "threshold", "unknown category", "route to the generator",
                                  "categories not a list", "output size", "no routes", "role", "category twice",
                                  "categories not names", "route_mirror"])
def test_a_broken_router_is_refused_on_load_naming_the_file(tmp_path, kind):
    folder, match = _broken(tmp_path, kind)
    with pytest.raises(ModelError, match=match) as err:
        SketchEngine(folder, threads=1).load()
    assert "router.onnx" in str(err.value)


def test_a_specialist_of_another_sphere_and_a_nan_router_are_clear_errors(tmp_path):
    folder = _folder(tmp_path, [0.5, 0.04, 0.46])
    write_model(make_predictor(2, seed=7), folder / SPECIALIST)
    with pytest.raises(ModelError, match="same sphere"):
        SketchEngine(folder, threads=1).predict(_strokes())
    eng = SketchEngine(folder, threads=1)
    for _ in range(2):  # a specialist that failed to load is not loaded again on the next drawing
        with pytest.raises(ModelError, match="same sphere"):
            eng.predict(_strokes())
    assert list(eng._specialist_errors) == [SPECIALIST] and eng._specialists == {}
    nan = _folder(tmp_path / "nan", [np.nan, 0.5, 0.5])
    with pytest.raises(ModelError, match="finite probabilities"):
        SketchEngine(nan, threads=1).predict(_strokes())
    raw = _folder(tmp_path / "raw", [0.9, 0.9, 0.9], softmax=False)  # logits, not probabilities: sums to 2.7
    with pytest.raises(ModelError, match="sum to 1"):
        SketchEngine(raw, threads=1).predict(_strokes())


def test_a_folder_copied_without_its_router_runs_the_general_predictor(tmp_path):
    folder = _folder(tmp_path, [0.5, 0.04, 0.46])
    plain = tmp_path / "plain"
    shutil.copytree(folder, plain)
    (plain / C.ROUTER_FILE).unlink()
    raster = rasterize_strokes(_strokes())
    pred = SketchEngine(plain, threads=1).predict(raster)
    np.testing.assert_allclose(pred.mesh.vertices, _vertices(plain / C.PREDICTOR_FILE, plain / C.GENERATOR_FILE, raster),
                               atol=ORT_ATOL)


def test_infer_reports_the_route(tmp_path):
    """`sketchmesh infer --report`: the report says what the router read the drawing as and which predictor shaped it."""
    folder = _folder(tmp_path, [0.5, 0.04, 0.46])
    png = tmp_path / "sketch.png"
    cv2.imwrite(str(png), ((1.0 - rasterize_strokes(_strokes())) * 255).astype(np.uint8))
    report = tmp_path / "report.json"
    r = subprocess.run([sys.executable, "-m", "sketchmesh", "infer", str(png), "-o", str(tmp_path / "m.obj"), "--models",
                        str(folder), "--threads", "1", "--report", str(report)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    rec = json.loads(report.read_text())
    assert rec["route"] == SPECIALIST and rec["category"] == "bench"
