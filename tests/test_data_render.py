"""Line drawings (training.data.lines), augmentation (training.data.augment) and view rendering
(training.data.render) checked against the rasterizer and hand-computed geometry."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from engine.camera import Camera, frame_camera, look_at, ndc_to_pixel, project  # noqa: E402
from engine.icosphere import icosphere  # noqa: E402
from engine.mesh import Mesh  # noqa: E402
from training.data import augment, lines  # noqa: E402
from training.render import render_normals_numpy  # noqa: E402

SIZE = 128
CONTOUR_TOL_PX = 1.5
QUANT_TOL = 0.5 / 255 + 1e-6  # uint8 storage of [0, 1] normals rounds to the nearest level


@pytest.fixture(autouse=True)
def _threads():
    torch.set_num_threads(2)


def _box_mesh(extents=(1.0, 1.0, 1.0), center=(0.0, 0.0, 0.0), subdivisions: int = 1) -> Mesh:
    import trimesh

    m = trimesh.creation.box(extents=extents)
    for _ in range(subdivisions):
        m = m.subdivide()
    return Mesh(np.asarray(m.vertices) + np.asarray(center), m.faces)


def _merge(*meshes: Mesh) -> Mesh:
    v, f, off = [], [], 0
    for m in meshes:
        v.append(m.vertices)
        f.append(m.faces + off)
        off += m.num_vertices
    return Mesh(np.concatenate(v), np.concatenate(f))


def _draw(mesh: Mesh, camera: Camera, size: int = SIZE, settings: lines.LineSettings | None = None):
    settings = settings or lines.LineSettings()
    r = render_normals_numpy(mesh, camera, size)
    d = lines.extract_lines(lines.prepare_mesh(mesh, settings), camera, size, r["depth"], r["face_index"], settings)
    return r, d


def _dense_points(polylines, step=0.5) -> np.ndarray:
    return np.concatenate([augment._resample(np.asarray(p, np.float64), step) for p in polylines])


def _segment_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ab = b - a
    t = np.clip(((points - a) @ ab) / max(float(ab @ ab), 1e-12), 0.0, 1.0)
    return np.linalg.norm(points - (a + t[:, None] * ab), axis=1)


# --------------------------------------------------------------------------- contours and hidden lines
def test_sphere_contour_lies_on_the_silhouette_boundary_and_has_no_suggestive_contours():
    from scipy import ndimage

    sphere = icosphere(3)
    cam = frame_camera(look_at(30.0, 30.0), sphere.vertices)
    r, d = _draw(sphere, cam)
    assert len(d.polylines) >= 1
    assert not np.any(d.kinds == lines.KIND_SUGGESTIVE)  # constant positive radial curvature
    sil = r["silhouette"]
    boundary = sil & ~ndimage.binary_erosion(sil)
    pts = _dense_points(d.polylines)
    dist_to_boundary = ndimage.distance_transform_edt(~boundary)
    ij = np.clip(np.floor(pts[:, ::-1]).astype(int), 0, SIZE - 1)
    assert np.mean(dist_to_boundary[ij[:, 0], ij[:, 1]] <= CONTOUR_TOL_PX) > 0.95
    # and the contour goes all the way round: almost every boundary pixel has a line point nearby
    bi = np.argwhere(boundary) + 0.5
    nearest = np.min(np.linalg.norm(bi[:, None, ::-1] - pts[None, ::4], axis=2), axis=1)
    assert np.mean(nearest <= CONTOUR_TOL_PX + 0.5) > 0.95


def _cube_edges_visibility(cam: Camera):
    """The cube's 12 edges (corner pairs) and whether each is visible, from the face normals (convex solid)."""
    corners = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
    edges, visible = [], []
    for i in range(8):
        for j in range(i + 1, 8):
            diff = corners[i] != corners[j]
            if diff.sum() != 1:
                continue
            axis = int(np.argmax(diff))
            # the two faces of this edge: the other two axes at the corner's sign
            faces_front = []
            for other in (a for a in range(3) if a != axis):
                n = np.zeros(3)
                n[other] = np.sign(corners[i][other])
                centre = n * 0.5
                faces_front.append(float(n @ (cam.position - centre)) > 0)
            edges.append((corners[i], corners[j]))
            visible.append(any(faces_front))
    return edges, np.array(visible)


@pytest.mark.parametrize("az, el", [(30.0, 30.0), (-50.0, 20.0)])
def test_cube_outline_and_inner_edges_drawn_hidden_edges_not(az, el):
    cube = _box_mesh(subdivisions=1)  # coplanar subdivision: no crease or contour inside a face
    cam = frame_camera(look_at(az, el), cube.vertices)
    _, d = _draw(cube, cam)
    pts = _dense_points(d.polylines)
    edges, visible = _cube_edges_visibility(cam)
    assert visible.sum() == 9
    for (a, b), vis in zip(edges, visible):
        pa, pb = (ndc_to_pixel(project(np.array([p]), cam)[0], SIZE)[0] for p in (a, b))
        along = augment._resample(np.stack([pa, pb]), 1.0)[2:-2]  # away from the corners
        near = np.min(np.linalg.norm(along[:, None] - pts[None], axis=2), axis=1) <= CONTOUR_TOL_PX
        if vis:
            assert near.mean() > 0.9, f"visible edge {a}->{b} drawn on only {near.mean():.0%}"
        else:
            assert near.mean() < 0.15, f"hidden edge {a}->{b} drawn on {near.mean():.0%}"
    # nothing is drawn inside the faces
    assert all(any(_segment_distance(p[None], *(ndc_to_pixel(project(np.stack(e), cam)[0], SIZE))) <= 2.0
                   for e in edges) for p in pts[::7])


def test_box_behind_a_box_is_not_drawn_unless_the_depth_test_is_disabled():
    front = _box_mesh((1.0, 1.0, 0.2), (0.0, 0.0, 0.3))
    back = _box_mesh((0.3, 0.3, 0.3), (0.0, 0.0, -0.5), subdivisions=0)
    scene = _merge(front, back)
    cam = frame_camera(look_at(0.0, 10.0), scene.vertices)
    _, d = _draw(scene, cam)
    corners = np.array([[x, y, z] for x in (-0.15, 0.15) for y in (-0.15, 0.15) for z in (-0.65, -0.35)])
    back_px = ndc_to_pixel(project(corners, cam)[0], SIZE)
    lo, hi = back_px.min(axis=0) - 1.0, back_px.max(axis=0) + 1.0  # the hidden box's outline and inside
    pts = _dense_points(d.polylines)
    inside = np.all((pts > lo) & (pts < hi), axis=1)
    assert not inside.any(), "lines of the hidden box were drawn"
    # control: with an infinite depth tolerance the back box's edges do show up there
    _, d_all = _draw(scene, cam, settings=lines.LineSettings(depth_tolerance=1e9))
    pts_all = _dense_points(d_all.polylines)
    assert np.all((pts_all > lo) & (pts_all < hi), axis=1).sum() > 20


def _wavy_sphere(level: int = 5, waves: int = 6, amplitude: float = 0.08) -> Mesh:
    s = icosphere(level)
    v = np.asarray(s.vertices, np.float64)
    lat = np.arcsin(np.clip(v[:, 1] / 0.5, -1.0, 1.0))
    r = 0.5 * (1.0 + amplitude * np.cos(waves * lat))
    return Mesh(v / 0.5 * r[:, None], s.faces)


def test_suggestive_contours_appear_on_a_wavy_surface():
    wavy = _wavy_sphere()
    cam = frame_camera(look_at(30.0, 30.0), wavy.vertices)
    _, d = _draw(wavy, cam)
    sc = [p for p, k in zip(d.polylines, d.kinds) if k == lines.KIND_SUGGESTIVE]
    lengths = [np.linalg.norm(np.diff(p, axis=0), axis=1).sum() for p in sc]
    assert lengths and max(lengths) > 25.0  # a continuous suggestive contour along a valley, not specks
    _, d_off = _draw(wavy, cam, settings=lines.LineSettings(suggestive=False))
    assert not np.any(d_off.kinds == lines.KIND_SUGGESTIVE)


def test_curvature_tensor_of_a_sphere_is_identity_over_radius():
    """T = (I - n n^T) / r: converging with exact normals; within 10% (1% on average) with mesh normals."""
    from engine.mesh import vertex_normals

    errors = []
    for level in (3, 5):
        for radius in (0.5, 3.0):
            s = icosphere(level, radius)
            v = np.asarray(s.vertices, np.float64)
            n = v / np.linalg.norm(v, axis=1, keepdims=True)
            expected = (np.eye(3)[None] - n[:, :, None] * n[:, None, :]) / radius
            exact = lines.curvature_tensors(v, s.faces, n)
            errors.append(np.max(np.abs(exact - expected)) * radius)
            T = lines.curvature_tensors(v, s.faces, vertex_normals(v, s.faces))
            rng = np.random.default_rng(level)
            t = rng.normal(size=v.shape)
            t -= np.einsum("vc,vc->v", t, n)[:, None] * n
            t /= np.linalg.norm(t, axis=1, keepdims=True)
            k = np.einsum("vi,vij,vj->v", t, T, t) * radius  # normal curvature x r, should be 1
            assert np.abs(k - 1).max() < 0.1 and abs(k.mean() - 1) < 0.01
    assert errors[0] < 0.01 and errors[2] < errors[0] / 10  # second-order convergence (h halves twice)


def test_empty_view_and_bad_buffers():
    cube = _box_mesh()
    prep = lines.prepare_mesh(cube)
    cam = frame_camera(look_at(0.0, 30.0), cube.vertices)
    empty = lines.extract_lines(prep, cam, 32, np.full((32, 32), np.inf, np.float32), np.full((32, 32), -1))
    assert empty.polylines == [] and len(empty.kinds) == 0
    with pytest.raises(ValueError, match="must be"):
        lines.extract_lines(prep, cam, 32, np.zeros((16, 16)), np.zeros((16, 16), np.int64))


def test_work_scales_with_visible_geometry_not_hidden_geometry():
    """A dense sphere hidden inside a closed box adds no line candidates and no pieces to test."""
    box = _box_mesh((1.0, 1.0, 1.0), subdivisions=1)
    hidden = icosphere(5, 0.3)  # 20480 faces, all hidden
    cam = frame_camera(look_at(20.0, 30.0), box.vertices)
    _, d_box = _draw(box, cam)
    _, d_both = _draw(_merge(box, hidden), cam)
    assert d_both.stats["visible_faces"] == d_box.stats["visible_faces"]
    assert d_both.stats["faces_tested"] == d_box.stats["faces_tested"] < 20480  # hidden cells skipped whole
    assert d_both.stats["pieces"] == d_box.stats["pieces"]
    assert len(d_both.polylines) == len(d_box.polylines)


# --------------------------------------------------------------------------- rasterising strokes
def test_stroke_raster_is_centred_on_pixel_centres_and_has_the_nominal_width():
    # a horizontal stroke through the centres of row 10 (y = 10.5)
    img = lines.rasterize_polylines([np.array([[5.0, 10.5], [27.0, 10.5]])], 32, width=2.0)
    col = img[:, 16].astype(np.float64)
    assert col.argmax() == 10
    centre = (col * (np.arange(32) + 0.5)).sum() / col.sum()
    assert centre == pytest.approx(10.5, abs=0.1)
    assert col.sum() == pytest.approx(2.0, abs=0.35)  # ink per column = stroke width in pixels
    assert img.dtype == np.float32 and img.max() <= 1.0 and img.min() >= 0.0
    assert lines.sketch_to_file_image(img)[10, 16] < 30  # dark strokes on white in files
    assert lines.rasterize_polylines([], 16).sum() == 0


# --------------------------------------------------------------------------- augmentation
def _clean_lines():
    sphere = _wavy_sphere(level=4)
    cam = frame_camera(look_at(30.0, 30.0), sphere.vertices)
    return _draw(sphere, cam)[1].polylines


def test_augmentation_is_deterministic_and_strength_zero_is_the_clean_drawing():
    clean = [np.array([[10.0, 10.0], [100.0, 20.0], [110.0, 90.0]]), np.array([[30.0, 80.0], [60.0, 120.0]])]
    zero = augment.augment_strokes(clean, 0.0, seed=5, size=SIZE)
    assert len(zero.polylines) == 2 and all(np.array_equal(a, b) for a, b in zip(zero.polylines, clean))
    assert np.all(zero.widths == lines.SKETCH_STROKE_WIDTH_PX) and np.all(zero.intensities == 1.0)
    assert np.array_equal(augment.render_sketch(clean, SIZE, 0.0, seed=3), lines.rasterize_polylines(clean, SIZE))
    a = augment.render_sketch(clean, SIZE, 0.8, seed=[1, 2])
    b = augment.render_sketch(clean, SIZE, 0.8, seed=[1, 2])
    c = augment.render_sketch(clean, SIZE, 0.8, seed=[1, 3])
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)
    assert not np.array_equal(a, augment.render_sketch(clean, SIZE, 0.0))
    with pytest.raises(ValueError, match="strength"):
        augment.augment_strokes(clean, 1.5, seed=0)


def test_augmentation_effects_grow_with_strength():
    clean = _clean_lines()
    base = lines.rasterize_polylines(clean, SIZE)
    diffs = []
    for st in (0.1, 0.5, 1.0):
        d = np.mean([np.abs(augment.render_sketch(clean, SIZE, st, seed=s) - base).mean() for s in range(3)])
        diffs.append(d)
    assert diffs[0] < diffs[1] < diffs[2]
    # at full strength the drawing is still mostly where the clean one is (small shifts only)
    strong = augment.augment_strokes(clean, 1.0, seed=0, size=SIZE)
    assert len(strong.polylines) >= len(clean) // 2
    pts = np.concatenate(strong.polylines)
    assert np.all((pts > -10) & (pts < SIZE + 10))


# --------------------------------------------------------------------------- views on disk agree with the rasterizer
def test_stored_views_agree_with_the_rasterizer_after_the_round_trip(tmp_path):
    from training.data.dataset import BuildSettings, Job, ShapeViewDataset, build_dataset
    from training.data.shapes import make_shape

    settings = BuildSettings(size=96, small_size=32, num_azimuths=2, elevations=(30.0,))
    job = Job("chair", "chair_00002", "train", "procedural", index=2)
    build_dataset(tmp_path, [job], settings, progress=False)
    ds = ShapeViewDataset(tmp_path, "all", extra_views=1, augment_strength=0.0)
    mesh = make_shape("chair", 2)
    assert np.array_equal(ds.load_mesh("chair", "chair_00002").vertices, mesh.vertices)
    for i in range(len(ds)):
        item = ds[i]
        az = 180.0 * item["view"]
        cam = frame_camera(look_at(az, 30.0), mesh.vertices)  # independent framing of the same view
        np.testing.assert_allclose(item["camera"].numpy(), cam.to_array(), atol=1e-12)
        big = render_normals_numpy(mesh, cam, 96)
        small = render_normals_numpy(mesh, cam, 32)
        err = np.abs(item["normals"].numpy().transpose(1, 2, 0) - big["normals"])
        assert err.max() <= QUANT_TOL, f"normals differ by {err.max()} at {np.unravel_index(err.argmax(), err.shape)}"
        assert np.array_equal(item["silhouette"].numpy()[0] > 0.5, big["silhouette"])
        assert np.array_equal(item["normals64"].numpy().transpose(1, 2, 0), small["normals"])  # exact at the small size
        assert np.array_equal(item["silhouette64"].numpy() > 0.5, small["silhouette"])
        # the clean sketch is the line drawing of this view's buffers
        d = lines.extract_lines(lines.prepare_mesh(mesh), cam, 96, big["depth"], big["face_index"])
        expected = np.round(lines.rasterize_polylines(d.polylines, 96) * 255) / 255
        assert np.abs(item["sketch"].numpy()[0] - expected).max() <= 1.0 / 255 + 1e-6


def test_predictor_fields_do_not_depend_on_the_sketch_size(tmp_path):
    """``data --size 64`` (training/gpu_predictor.sh) stores the same predictor targets, cameras and
    shape as the full build: they are framed and rendered independently of the sketch size."""
    import numpy.testing as npt

    from training.data.dataset import BuildSettings, Job, build_dataset

    job = Job("lamp", "lamp_00001", "train", "procedural", index=1)
    stored = {}
    for size in (96, 32):
        settings = BuildSettings(size=size, small_size=32, num_azimuths=3, elevations=(0.0, 45.0))
        build_dataset(tmp_path / str(size), [job], settings, progress=False)
        stored[size] = np.load(tmp_path / str(size) / "shapes" / "lamp" / "lamp_00001.npz")
    big, small = stored[96], stored[32]
    assert big["sketch"].shape[1:] == (96, 96) and small["sketch"].shape[1:] == (32, 32)
    for key in ("normals64", "silhouette64", "cameras", "azimuths", "elevations", "vertices", "faces"):
        npt.assert_array_equal(small[key], big[key], err_msg=key)
    assert big["silhouette64"].any() and not big["silhouette64"].all()
