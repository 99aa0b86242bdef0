"""Refinement to the sketch's outline (engine/refine.py): rasterizer, a hand-made case, the stability sweep, CLI."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from onnx_fixtures import write_fixture_models

from engine.camera import NEAR, Camera
from engine.cli import MAX_REFINE_STEPS
from engine.icosphere import icosphere
from engine.mesh import Mesh, is_closed
from engine.pipeline import STAGES, SketchEngine
from engine.postprocess import mesh_stats
from engine.preprocess import rasterize_strokes
from engine.refine import (
    MAX_STEPS,
    OPEN_OUTLINE_WARNING,
    fill_drawing,
    fit_camera,
    generator_silhouette,
    pixel_coords,
    refine_mesh,
    refine_prediction,
    render_silhouette,
    render_silhouettes,
    silhouette_iou,
    sketch_camera,
    stroke_centre_region,
    target_outline,
)
from engine.strokes import Stroke

SIZE = 256


def _ellipse(ax: int, ay: int, size: int = SIZE) -> np.ndarray:
    m = np.zeros((size, size), np.uint8)
    cv2.ellipse(m, (size // 2, size // 2), (ax, ay), 0, 0, 360, 1, -1)
    return m > 0


def _bumpy_sphere(seed: int = 0) -> Mesh:
    m = icosphere(3, 0.5)
    rng = np.random.default_rng(seed)
    v = m.vertices * (1.0 + 0.15 * rng.standard_normal((m.num_vertices, 1)))
    return m.with_vertices(v.astype(np.float32))


def _silhouette(mesh: Mesh, camera, size: int = SIZE) -> np.ndarray:
    px, _ = pixel_coords(mesh.vertices, camera, size)
    return render_silhouette(px, mesh.faces, size)


def test_rasterizer_matches_a_per_pixel_reference():
    m = _bumpy_sphere(1)
    cam = sketch_camera(m)
    px, _ = pixel_coords(m.vertices, cam, 48)
    fast = render_silhouette(px, m.faces, 48)
    rows, cols = np.mgrid[0:48, 0:48] + 0.5
    ref = np.zeros((48, 48), bool)
    for a, b, c in px[m.faces]:  # every pixel centre against every face: obviously right, slow
        e = [(q[0] - p[0]) * (rows - p[1]) - (q[1] - p[1]) * (cols - p[0]) for p, q in ((a, b), (b, c), (c, a))]
        ref |= (e[0] >= 0) & (e[1] >= 0) & (e[2] >= 0) | (e[0] <= 0) & (e[1] <= 0) & (e[2] <= 0)
    assert np.array_equal(fast, ref), f"{np.count_nonzero(fast != ref)} pixels differ"
    assert fast.any() and not fast.all()


def _folded_sphere(seed: int) -> Mesh:
    """A closed icosphere pushed about hard enough that its surface folds over and crosses itself on screen."""
    m = icosphere(3, 0.5)
    rng = np.random.default_rng(seed)
    v = m.vertices * (1.0 + 0.6 * rng.standard_normal((m.num_vertices, 1)))
    v[:, 0] += 0.3 * np.sin(7.0 * v[:, 1])
    return m.with_vertices(v.astype(np.float32))


def test_batched_poses_are_each_pose_rendered_alone_clipped_to_its_own_image():
    """K poses in one pass give the K images of one pose at a time, also where a pose runs off the image (a face
    below one image must not reach into the next one's rows)."""
    m = _bumpy_sphere(2)
    cam = sketch_camera(m)
    px, _ = pixel_coords(m.vertices, cam, 40)
    poses = np.stack([px, px * 1.6 - 12.0, px + [0.0, 25.0], px - [30.0, 0.0], px * 0.2])
    many = render_silhouettes(poses, m.faces, 40)
    assert many.shape == (5, 40, 40)
    for k, pose in enumerate(poses):
        assert np.array_equal(many[k], render_silhouette(pose, m.faces, 40)), f"pose {k} differs"
    assert many[1, -1].any() and many[2, -1].any() and many[2, 0].sum() < many[0, 0].sum() + 1  # clipped poses


def test_a_closed_surface_needs_only_one_winding_of_its_faces():
    """For closed surfaces -- smooth, bumpy and folded over themselves -- the faces of either winding alone cover the
    silhouette every face covers, so render_silhouettes(closed=True) gives the same pixels."""
    for mesh in [icosphere(3, 0.5), _bumpy_sphere(3), _folded_sphere(4), _folded_sphere(5)]:
        assert is_closed(mesh.faces)
        px, _ = pixel_coords(mesh.vertices, sketch_camera(mesh), 64)
        poses = np.stack([px, px * 0.7 + 5.0])
        every = render_silhouettes(poses, mesh.faces, 64)
        culled = render_silhouettes(poses, mesh.faces, 64, closed=True)
        assert np.array_equal(every, culled), f"{np.count_nonzero(every != culled)} pixels differ"
        area = np.sign([(b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]) for a, b, c in px[mesh.faces]])
        for side in (-1, 1):  # each winding alone covers the silhouette: which one is used does not matter
            assert np.array_equal(render_silhouette(px, mesh.faces[area == side], 64), every[0])


def test_is_closed_needs_every_edge_twice_once_each_way():
    f = icosphere(2, 0.5).faces
    assert is_closed(f) and is_closed(f[:, ::-1])  # either orientation
    assert not is_closed(f[1:])  # a hole
    assert not is_closed(np.concatenate([f[:1, ::-1], f[1:]]))  # one face turned round
    assert not is_closed(np.concatenate([f, f[:1]]))  # a face twice
    assert not is_closed(np.zeros((0, 3), np.int64)) and not is_closed(np.array([[0, 0, 1]]))


def test_fill_drawing_fills_closed_outlines_and_handles_the_frame():
    ring = np.zeros((64, 64), np.float32)
    cv2.circle(ring, (32, 32), 20, 1.0, 2)
    filled = fill_drawing(ring)
    assert filled[32, 32] and not filled[2, 2]
    touching = np.zeros((64, 64), np.float32)
    cv2.rectangle(touching, (0, 0), (63, 40), 1.0, 2)  # the outline lies on the image border
    assert fill_drawing(touching)[20, 30]
    open_arc = np.zeros((64, 64), np.float32)
    cv2.ellipse(open_arc, (32, 32), (20, 20), 0, 0, 180, 1.0, 2)
    _, source = target_outline(open_arc, np.zeros((64, 64, 3), np.float32))
    assert source == "generator"


def test_a_drawn_outline_is_cut_back_to_its_strokes_centre_line():
    # a circle of radius 60 px drawn as the engine draws strokes (2 px wide, about the centre line): the fill takes
    # the outer half of the stroke in (about pi 61^2), the target is the region the centre line bounds (pi 60^2)
    from engine.preprocess import draw_segments

    a = np.linspace(0, 2 * np.pi, 241)
    pts = np.stack([128 + 60 * np.cos(a), 128 + 60 * np.sin(a)], 1)
    sketch = draw_segments(np.stack([pts[:-1], pts[1:]], 1))
    fill = fill_drawing(sketch)
    target, source = target_outline(sketch)
    disc = np.pi * 60**2
    assert source == "drawing" and fill.sum() > 1.025 * disc  # a full stroke-half too big
    assert abs(target.sum() - disc) < 0.01 * disc, (target.sum(), disc)
    assert np.array_equal(target, stroke_centre_region(fill)) and not (target & ~fill).any()
    # at 64 px the half stroke is a quarter pixel: nothing is cut; a fill thinner than the cut is kept whole
    small = np.zeros((64, 64), bool)
    small[20:40, 20:40] = True
    assert np.array_equal(stroke_centre_region(small), small)
    line = np.zeros((256, 256), bool)
    line[100, 50:200] = True
    assert np.array_equal(stroke_centre_region(line), line)


def test_sphere_refined_towards_an_ellipse_raises_iou_and_keeps_depth_and_topology():
    sphere = icosphere(3, 0.5)
    cam = sketch_camera(sphere)
    target = _ellipse(102, 50)
    before = silhouette_iou(_silhouette(sphere, cam), target)
    res = refine_mesh(sphere, target, 3, camera=cam)
    after = silhouette_iou(_silhouette(res.mesh, cam), target)
    assert res.warning is None and res.steps == 3
    assert before < 0.6 and after > 0.9, (before, after)
    _, d0 = pixel_coords(sphere.vertices, cam, SIZE)
    _, d1 = pixel_coords(res.mesh.vertices, cam, SIZE)
    np.testing.assert_allclose(d1, d0, atol=1e-5)  # vertices moved along the image plane only, depth kept
    stats = mesh_stats(res.mesh)
    assert stats["watertight"] and stats["winding_consistent"] and stats["self_intersections"] == 0
    assert res.crossings == 0  # counted on the returned mesh: what the fold repair then trusts
    assert refine_mesh(sphere, target, 3, camera=cam, check_intersections=False).crossings is None
    assert np.array_equal(res.mesh.faces, sphere.faces)
    assert refine_mesh(sphere, target, 0, camera=cam).mesh is sphere


def test_refinement_grows_a_thin_part_the_prediction_lacks():
    sphere = icosphere(3, 0.5)
    cam = sketch_camera(sphere)
    target = _ellipse(102, 50).astype(np.uint8)
    cv2.rectangle(target, (120, 20), (136, 128), 1, -1)  # a long neck on top of the body
    target = target > 0
    res = refine_mesh(sphere, target, 4, camera=cam)
    sil = _silhouette(res.mesh, cam)
    assert silhouette_iou(sil, target) > 0.9
    assert sil[30:60, 122:134].mean() > 0.8  # the neck is there


def _degenerate_targets() -> dict[str, tuple[np.ndarray, np.ndarray | None]]:
    normals_blob = np.zeros((SIZE, SIZE, 3), np.float32)
    normals_blob[_ellipse(80, 60)] = (0.5, 0.5, 1.0)
    thin = np.zeros((SIZE, SIZE), np.float32)
    cv2.line(thin, (26, 128), (230, 128), 1.0, 2)  # an outline a few pixels wide
    t = np.linspace(0, 2 * np.pi, 200)
    eight = np.zeros((SIZE, SIZE), np.float32)  # a self-crossing stroke
    pts = np.stack([128 + 100 * np.sin(t), 128 + 60 * np.sin(2 * t)], 1).round().astype(np.int32)
    cv2.polylines(eight, [pts], True, 1.0, 2)
    frame = np.zeros((SIZE, SIZE), np.float32)  # a drawing touching the frame
    cv2.rectangle(frame, (0, 0), (SIZE - 1, 200), 1.0, 3)
    dot = np.zeros((SIZE, SIZE), np.float32)
    dot[128, 128] = 1.0
    return {
        "thin-outline": (thin, normals_blob),
        "thin-outline-no-generator-silhouette": (thin, np.zeros((SIZE, SIZE, 3), np.float32)),
        "self-crossing": (eight, normals_blob),
        "touching-frame": (frame, normals_blob),
        "one-dot": (dot, None),
        "blank-with-empty-normals": (np.zeros((SIZE, SIZE), np.float32), np.zeros((SIZE, SIZE, 3), np.float32)),
        "all-ink": (np.ones((SIZE, SIZE), np.float32), normals_blob),
    }


def _degenerate_meshes() -> dict[str, Mesh]:
    ico = icosphere(3, 0.5)
    flat = ico.vertices * np.array([1.0, 1.0, 0.0], np.float32)  # a pancake seen face on
    line = ico.vertices * np.array([1.0, 0.0, 0.0], np.float32)  # projects to a segment
    behind = ico.vertices + np.array([0, 0, 10.0], np.float32)  # behind the camera
    return {"bumpy": _bumpy_sphere(2), "flat": ico.with_vertices(flat), "line": ico.with_vertices(line),
            "point": ico.with_vertices(np.zeros_like(ico.vertices)), "behind": ico.with_vertices(behind)}


@pytest.mark.parametrize("target_name", list(_degenerate_targets()))
def test_stability_sweep_gives_a_finite_closed_mesh_or_the_unrefined_one(target_name):
    sketch, normals = _degenerate_targets()[target_name]
    for mesh_name, mesh in _degenerate_meshes().items():
        res = refine_prediction(mesh, sketch, normals, 3)
        v = res.mesh.vertices
        assert np.all(np.isfinite(v)), (target_name, mesh_name)
        assert np.array_equal(res.mesh.faces, mesh.faces), (target_name, mesh_name)
        if res.warning is not None:
            assert res.mesh is mesh, (target_name, mesh_name)
        else:
            assert np.isfinite(res.iou_after) and res.iou_after >= res.iou_before, (target_name, mesh_name)


def test_generator_silhouette_reads_both_layouts_alike():
    rng = np.random.default_rng(0)
    nchw = (rng.random((1, 3, 40, 50)) * 0.3).astype(np.float32)  # around the 0.25 threshold in every channel
    hwc = nchw[0].transpose(1, 2, 0)
    want = nchw[0].max(axis=0) > 0.25
    assert want.any() and not want.all()
    assert np.array_equal(generator_silhouette(nchw), want) and np.array_equal(generator_silhouette(hwc), want)


def test_only_a_closed_drawn_outline_is_refined_to():
    # the engine refines to the drawing's outline; an open drawing (its target would be the generator's silhouette)
    # keeps the predicted mesh and says why
    mesh = icosphere(3, 0.5)
    normals = np.zeros((SIZE, SIZE, 3), np.float32)
    normals[_ellipse(100, 50)] = (0.5, 0.5, 1.0)  # the generator saw an ellipse
    closed = np.zeros((SIZE, SIZE), np.float32)
    cv2.ellipse(closed, (128, 128), (100, 50), 0, 0, 360, 1.0, 2)
    open_arc = np.zeros((SIZE, SIZE), np.float32)
    cv2.ellipse(open_arc, (128, 128), (100, 50), 0, 0, 200, 1.0, 2)
    assert target_outline(open_arc, normals)[1] == "generator" and target_outline(closed, normals)[1] == "drawing"
    skipped = refine_prediction(mesh, open_arc, normals, 3)
    assert skipped.mesh is mesh and skipped.steps == 0 and skipped.warning == OPEN_OUTLINE_WARNING
    refined = refine_prediction(mesh, closed, normals, 3)
    assert refined.warning is None and refined.steps == 3 and refined.iou_after > refined.iou_before
    assert not np.array_equal(refined.mesh.vertices, mesh.vertices)


def test_bad_arguments_are_refused_with_what_was_received():
    m = icosphere(2, 0.5)
    with pytest.raises(ValueError, match="steps"):
        refine_mesh(m, np.zeros((32, 32), bool), -1)
    with pytest.raises(ValueError, match="steps"):
        refine_mesh(m, np.zeros((32, 32), bool), MAX_STEPS + 1)
    with pytest.raises(ValueError, match=r"\(32, 16\)"):
        refine_mesh(m, np.zeros((32, 16), bool), 1)
    assert MAX_REFINE_STEPS == MAX_STEPS


# ---------------------------------------------------------------------------------------------- engine and CLI


@pytest.fixture(scope="module")
def models(tmp_path_factory) -> Path:
    return write_fixture_models(tmp_path_factory.mktemp("models"))


def test_engine_refines_on_request_times_it_and_caches_it(models):
    engine = SketchEngine(models, threads=1)
    t = np.linspace(0, 2 * np.pi, 80)
    strokes = [Stroke(np.stack([200 + 120 * np.cos(t), 150 + 50 * np.sin(t)], 1))]
    raw = engine.predict(strokes)
    assert set(raw.timings_ms) == set(STAGES) and raw.timings_ms["refine"] == 0.0
    refined = engine.predict(strokes, refine=2)
    assert refined.cached and refined.timings_ms["refine"] > 0.0
    assert refined.warnings or not np.array_equal(refined.mesh.vertices, raw.mesh.vertices)
    again = engine.predict(strokes, refine=2)
    assert again.timings_ms["refine"] == 0.0 and again.mesh is refined.mesh
    engine.refine_steps = 2
    assert engine.predict(strokes).mesh is refined.mesh
    with pytest.raises(ValueError, match="refinement steps"):
        engine.predict(strokes, refine=-3)


def test_engine_sweep_of_degenerate_drawings_never_crashes(models):
    engine = SketchEngine(models, threads=1, refine_steps=2)
    t = np.linspace(0, 4 * np.pi, 120)
    sketches = {
        "tiny-outline": [Stroke([[100, 100], [104, 100], [104, 103], [100, 100]])],
        "self-crossing": [Stroke(np.stack([200 + 100 * np.sin(t / 2), 150 + 60 * np.sin(t)], 1))],
        "straight-line": [Stroke([[10, 10], [300, 12]])],
    }
    for name, strokes in sketches.items():
        pred = engine.predict(rasterize_strokes(strokes))
        assert np.all(np.isfinite(pred.mesh.vertices)), name
        assert mesh_stats(pred.mesh)["watertight"], name


def test_cli_infer_refine(tmp_path, models):
    img = np.full((240, 320), 255, np.uint8)
    cv2.ellipse(img, (160, 120), (140, 60), 0, 0, 360, 0, 3)
    sketch = tmp_path / "oval.png"
    cv2.imwrite(str(sketch), img)
    report = tmp_path / "r.json"
    run = [sys.executable, "-m", "sketchmesh", "infer", str(sketch), "-o", str(tmp_path / "oval.obj"), "--models",
           str(models), "--report", str(report)]
    r = subprocess.run([*run, "--refine", "2"], capture_output=True, text=True, cwd=tmp_path, timeout=120)
    assert r.returncode == 0, r.stderr
    rec = json.loads(report.read_text())
    assert rec["refine_steps"] == 2 and rec["timings_ms"]["refine"] > 0.0 and rec["watertight"] is True
    assert isinstance(rec["warnings"], list)
    bad = subprocess.run([*run, "--refine", "-1"], capture_output=True, text=True, cwd=tmp_path, timeout=120)
    assert bad.returncode == 2 and "--refine" in bad.stderr and "Traceback" not in bad.stderr


def test_depth_of_every_vertex_stays_in_front_of_the_camera():
    m = _bumpy_sphere(3)
    cam = sketch_camera(m)
    res = refine_mesh(m, _ellipse(60, 100), 3, camera=cam)
    _, depth = pixel_coords(res.mesh.vertices, cam, SIZE)
    assert np.all(depth > NEAR)


def test_fit_camera_recovers_a_zoom_and_shift_of_the_sketch_camera():
    """A target drawn by the framed camera zoomed 12 % and moved: fit_camera finds that camera again."""
    m = _bumpy_sphere(2).with_vertices((_bumpy_sphere(2).vertices * np.array([1.0, 0.6, 0.8])).astype(np.float32))
    base = sketch_camera(m)
    s, dx, dy = 1.12, 0.05, -0.03
    true = Camera(base.R, base.t, base.focal * s, (base.principal[0] * s + dx, base.principal[1] * s + dy))
    target = _silhouette(m, true)
    fit = fit_camera(m, target)
    assert abs(fit.focal / true.focal - 1.0) < 0.03, fit.focal / true.focal
    np.testing.assert_allclose(fit.principal, true.principal, atol=0.02)
    assert np.array_equal(fit.R, base.R) and np.array_equal(fit.t, base.t)  # same centre and rotation: depth kept
    assert silhouette_iou(_silhouette(m, fit), target) > 0.97 > silhouette_iou(_silhouette(m, base), target)
    # refinement without a camera works in that one and says so
    res = refine_mesh(m, target, 2)
    assert res.camera is not None and res.camera.focal == fit.focal and res.camera.principal == fit.principal


def test_fit_camera_never_does_worse_than_the_bounding_box_and_falls_back_on_empty_input():
    """A spike sets the bounding box (the framing shrinks the body); the fit overlaps the target at least as well."""
    body = icosphere(3, 0.5)
    spiky = body.vertices.copy()
    spiky[np.argmax(spiky[:, 0])] *= 1.8  # one vertex far out to the right
    m = body.with_vertices(spiky.astype(np.float32))
    target = _ellipse(102, 102)  # the drawing: the round body alone
    base, fit = sketch_camera(m), fit_camera(m, target)
    iou_base = silhouette_iou(_silhouette(m, base), target)
    iou_fit = silhouette_iou(_silhouette(m, fit), target)
    assert iou_fit >= iou_base and iou_fit > 0.9, (iou_base, iou_fit)
    assert fit.focal > base.focal  # the body is zoomed back up to the drawing's size
    empty = np.zeros((SIZE, SIZE), bool)
    assert fit_camera(m, empty) is not None and fit_camera(m, empty).focal == base.focal
    behind = m.with_vertices((m.vertices + np.array([0, 0, 50.0])).astype(np.float32))
    cam = Camera(base.R, base.t, base.focal, base.principal)
    assert fit_camera(behind, target, cam) is cam  # cannot be projected: the starting camera, no NaN
