"""Fold repair: where a predicted surface crosses itself it is smoothed just there until it does not
(engine.postprocess.repair_self_intersections), in the engine (repair_folds), the CLI and its report."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from onnx_fixtures import fold_offsets, write_fixture_models

from engine.icosphere import icosphere
from engine.mesh import Mesh
from engine.pipeline import SketchEngine
from engine.postprocess import intersecting_pairs, repair_self_intersections, self_intersections


def _folded_sphere(level: int = 3, scale: float = 1.0) -> tuple[Mesh, np.ndarray]:
    t = icosphere(level, 1.0)
    off, cap = fold_offsets(level, 1.0)
    return Mesh((t.vertices + off) * scale, t.faces), cap


def test_a_folded_sphere_is_repaired_and_only_near_the_fold():
    mesh, cap = _folded_sphere()
    before = self_intersections(mesh)
    assert before > 20  # the cap really passes through the other side
    res = repair_self_intersections(mesh)
    assert res.before == before and res.after == 0 and self_intersections(res.mesh) == 0
    assert 1 <= res.rounds <= 8 and np.all(np.isfinite(res.mesh.vertices))
    moved = np.any(res.mesh.vertices != mesh.vertices, axis=1)
    crossing = np.unique(mesh.faces[intersecting_pairs(mesh).ravel()])
    assert res.moved == moved.sum() and moved[crossing].all()  # where it crossed moved
    # vertices far from both the cap and where it crossed (the equator band) never move
    z = mesh.vertices[:, 2]
    band = (np.abs(z) < 0.3) & ~cap
    assert band.sum() > 50 and not moved[band].any()
    np.testing.assert_array_equal(res.mesh.faces, mesh.faces)


def test_a_mesh_without_crossings_comes_back_as_the_same_object():
    m = icosphere(3)
    res = repair_self_intersections(m)
    assert res.mesh is m and (res.before, res.after, res.rounds, res.moved) == (0, 0, 0, 0)


@pytest.mark.parametrize("scale", [1e-6, 1e6])
def test_the_repair_scales_with_the_mesh(scale):
    mesh, _ = _folded_sphere()
    ref = repair_self_intersections(mesh)
    scaled = repair_self_intersections(Mesh(mesh.vertices.astype(np.float64) * scale, mesh.faces))
    assert (scaled.before, scaled.after, scaled.rounds) == (ref.before, ref.after, ref.rounds)
    np.testing.assert_allclose(scaled.mesh.vertices / scale, ref.mesh.vertices, rtol=1e-4, atol=1e-5)


def test_when_rounds_run_out_the_fewest_crossings_are_returned_and_counted():
    # two separate triangles crossing at both centroids (the origin): smoothing shrinks each towards its centroid,
    # so they never part; the result stays finite and says how many crossings are left
    v = np.array([[0, 0, 2], [-1.7, 0, -1], [1.7, 0, -1], [0, 2, 0.3], [0, -1, 1.9], [0, -1, -2.2]], np.float64)
    mesh = Mesh(v, [[0, 1, 2], [3, 4, 5]])
    assert self_intersections(mesh) == 1
    res = repair_self_intersections(mesh, rounds=3)
    assert res.before == 1 and res.after == len(intersecting_pairs(res.mesh)) == 1 and res.rounds == 3
    assert np.all(np.isfinite(res.mesh.vertices))
    counted = repair_self_intersections(mesh, rounds=0)
    assert counted.mesh is mesh and (counted.before, counted.after, counted.rounds) == (1, 1, 0)


def test_integer_vertices_are_repaired_in_floating_point():
    mesh, _ = _folded_sphere()
    m = Mesh(np.round(mesh.vertices * 1000).astype(np.int64), mesh.faces)  # a mesh in integer units
    res = repair_self_intersections(m)
    assert res.before > 20 and res.after == 0 and np.issubdtype(res.mesh.vertices.dtype, np.floating)


def test_vertices_outside_every_face_stay_put():
    mesh, _ = _folded_sphere(level=2)
    lonely = np.array([[0.0, 0.0, 0.0]])  # inside the fold's path, but in no face
    m = Mesh(np.concatenate([mesh.vertices, lonely]), mesh.faces)
    res = repair_self_intersections(m)
    assert res.after == 0
    np.testing.assert_array_equal(res.mesh.vertices[-1], lonely[0])


@pytest.mark.parametrize("kwargs, match", [
    ({"rounds": -1}, "rounds"), ({"rounds": 1.5}, "rounds"), ({"steps": 0}, "steps"), ({"weight": 0.0}, "weight"),
    ({"weight": 1.5}, "weight"), ({"weight": float("nan")}, "weight"),
])
def test_bad_arguments_are_named(kwargs, match):
    with pytest.raises(ValueError, match=match):
        repair_self_intersections(icosphere(1), **kwargs)


@pytest.fixture(scope="module")
def folded_models(tmp_path_factory) -> Path:
    """Fixture models whose predictor folds every mesh (its offsets push the template's cap through its far side)."""
    return write_fixture_models(tmp_path_factory.mktemp("folded_models"), fold=True)


@pytest.fixture(scope="module")
def sketch() -> np.ndarray:
    img = np.zeros((256, 256), np.float32)
    cv2.ellipse(img, (128, 128), (90, 60), 0, 0, 360, 1.0, 3)
    return img


def test_the_engine_repairs_its_prediction_when_asked(folded_models, sketch):
    eng = SketchEngine(folded_models, threads=1)
    assert eng.repair_folds is False
    plain = eng.predict(sketch)
    assert self_intersections(plain.mesh) > 20 and plain.timings_ms["repair"] == 0.0 and not plain.repair_folds
    eng.repair_folds = True
    fixed = eng.predict(sketch)
    assert not fixed.cached and fixed.repair_folds and fixed.timings_ms["repair"] > 0.0  # the cache keeps modes apart
    np.testing.assert_array_equal(fixed.mesh.vertices, repair_self_intersections(plain.mesh).mesh.vertices)
    assert self_intersections(fixed.mesh) == 0 and fixed.warnings == ()
    again = eng.predict(sketch)
    assert again.cached and again.timings_ms["repair"] == 0.0
    np.testing.assert_array_equal(again.mesh.vertices, fixed.mesh.vertices)
    # the refinement starts from the repaired mesh and keeps it free of crossings
    refined = eng.predict(sketch, refine=2)
    assert self_intersections(refined.mesh) == 0
    with pytest.raises(ValueError, match="repair_folds"):
        eng.repair_folds = "yes"
    with pytest.raises(ValueError, match="repair_folds"):
        SketchEngine(folded_models, repair_folds=1)


def test_the_engine_warns_when_crossings_are_left(folded_models, sketch, monkeypatch):
    import engine.postprocess as pp

    original = pp.repair_self_intersections
    monkeypatch.setattr(pp, "repair_self_intersections", lambda mesh: original(mesh, rounds=1, steps=1, weight=0.01))
    pred = SketchEngine(folded_models, threads=1, repair_folds=True).predict(sketch)
    assert len(pred.warnings) == 1 and "crosses itself" in pred.warnings[0]


def test_cli_infer_repair_folds(tmp_path, folded_models, sketch):
    png = tmp_path / "oval.png"
    cv2.imwrite(str(png), (255 * (1 - sketch)).astype(np.uint8))
    counts = {}
    for extra in ([], ["--repair-folds"]):
        out = tmp_path / f"mesh{len(extra)}.obj"
        report = out.with_suffix(".json")
        r = subprocess.run([sys.executable, "-m", "sketchmesh", "infer", str(png), "-o", str(out), "--models",
                            str(folded_models), "--threads", "1", "--report", str(report), *extra],
                           capture_output=True, text=True, cwd=tmp_path, timeout=120)
        assert r.returncode == 0, r.stderr
        rec = json.loads(report.read_text())
        assert rec["repair_folds"] is bool(extra) and "repair" in rec["timings_ms"]
        counts[bool(extra)] = rec["self_intersections"]
    assert counts[False] > 20 and counts[True] == 0


@pytest.mark.parametrize("crossings,checked", [(0, False), (None, True), (3, True)])
def test_the_repair_trusts_a_count_the_refinement_just_made(folded_models, sketch, monkeypatch, crossings, checked):
    """A refined mesh the refinement has counted free of crossings is not checked again by the fold repair (one check
    less on the app's default path); an uncounted one, or one with crossings, is repaired as before."""
    import engine.pipeline as pipeline
    import engine.postprocess as pp
    from engine.refine import RefineResult

    calls = []
    original = pp.repair_self_intersections
    monkeypatch.setattr(pp, "repair_self_intersections", lambda mesh: calls.append(mesh) or original(mesh))
    monkeypatch.setattr(pipeline, "refine_prediction",
                        lambda mesh, *a, **k: RefineResult(mesh, 1, 0.5, 0.6, crossings=crossings))
    pred = SketchEngine(folded_models, threads=1, repair_folds=True).predict(sketch, refine=1)
    assert bool(calls) is checked
    plain = SketchEngine(folded_models, threads=1).predict(sketch).mesh
    if checked:  # repaired as before: the folded prediction untangled
        assert self_intersections(pred.mesh) == 0
        np.testing.assert_array_equal(pred.mesh.vertices, original(plain).mesh.vertices)
    else:  # trusted: the mesh as refinement returned it
        np.testing.assert_array_equal(pred.mesh.vertices, plain.vertices)
        assert pred.timings_ms["repair"] < 1.0


def test_the_check_of_the_faces_that_moved_finds_what_the_full_check_finds():
    """intersecting_pairs(mesh, faces): the pairs with a listed face, exactly the full check's (and the broad phase's
    brute force's) restricted to them, on a folded sphere and random face sets."""
    from engine.postprocess import candidate_pairs_bruteforce

    mesh, _ = _folded_sphere()
    rng = np.random.default_rng(0)
    full = intersecting_pairs(mesh)
    every = candidate_pairs_bruteforce(mesh)
    assert len(full) > 20
    for k in (1, 7, 100, mesh.num_faces):
        faces = rng.choice(mesh.num_faces, k, replace=False)
        want = full[np.isin(full, faces).any(axis=1)]
        np.testing.assert_array_equal(intersecting_pairs(mesh, faces), want)
        from engine.postprocess import _candidate_pairs_of

        np.testing.assert_array_equal(_candidate_pairs_of(mesh, faces), every[np.isin(every, faces).any(axis=1)])
    assert len(intersecting_pairs(mesh, np.zeros(0, np.int64))) == 0


def test_the_repair_checking_only_what_moved_matches_checking_everything(monkeypatch):
    """Each repair round checks only pairs with a face that moved (two faces that stayed did not cross, and still do
    not): the same rounds and the same mesh as checking the whole mesh every round."""
    import engine.postprocess as pp

    mesh, _ = _folded_sphere()
    gentle = {"steps": 1, "weight": 0.1}  # small steps: several rounds, each region smaller than the last
    fast = repair_self_intersections(mesh, **gentle)
    monkeypatch.setattr(pp, "_candidate_pairs_of", lambda m, faces: (
        lambda c: c[np.isin(c, np.asarray(faces)).any(axis=1)])(pp.candidate_pairs(m)))
    slow = repair_self_intersections(mesh, **gentle)
    assert fast.rounds > 2 and (fast.before, fast.after, fast.rounds, fast.moved) == (
        slow.before, slow.after, slow.rounds, slow.moved)
    np.testing.assert_array_equal(fast.mesh.vertices, slow.mesh.vertices)
