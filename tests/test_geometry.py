"""Shared geometry: the mesh type, the icosphere template and the camera conventions."""

import numpy as np
import pytest
import trimesh

from engine.camera import (
    Camera,
    decode_normals,
    encode_normals,
    frame_camera,
    look_at,
    ndc_to_pixel,
    normalize_vertices,
    paper_views,
    pixel_centers_ndc,
    project,
    relative_camera,
    view_camera,
)
from engine.icosphere import (
    LEG_AZIMUTHS_DEG,
    LEG_DROP,
    LEG_POLAR_DEG,
    icosphere,
    level_for_vertex_count,
    mirror_average,
    mirror_permutation,
    template_mesh,
)
from engine.mesh import Mesh, adjacent_face_pairs, face_normals, unique_edges, vertex_normals

# ---- mesh value type -------------------------------------------------------------------

def test_mesh_converts_and_freezes():
    m = Mesh(np.zeros((3, 3), np.float64), np.array([[0, 1, 2]], np.int32))
    assert m.vertices.dtype == np.float32 and m.faces.dtype == np.int64
    with pytest.raises(ValueError):
        m.vertices[0, 0] = 1.0


@pytest.mark.parametrize("v, f, msg", [
    (np.zeros((3, 2)), [[0, 1, 2]], r"\(V, 3\)"),
    (np.zeros((3, 3)), [[0, 1]], r"\(F, 3\)"),
    (np.full((3, 3), np.nan), [[0, 1, 2]], "NaN"),
    (np.zeros((3, 3)), [[0, 1, 3]], r"\[0, 3\)"),
    (np.zeros((3, 3)), [[-1, 1, 2]], r"\[0, 3\)"),
    (np.zeros((3, 3)), [[0.5, 1, 2]], "integer"),
])
def test_mesh_rejects_bad_input(v, f, msg):
    with pytest.raises(ValueError, match=msg):
        Mesh(v, np.asarray(f))


def test_face_and_vertex_normals_hand_computed():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [5, 5, 5]], float)
    f = np.array([[0, 1, 2], [0, 0, 1]])  # second face is degenerate
    fn = face_normals(v, f)
    np.testing.assert_allclose(fn, [[0, 0, 1], [0, 0, 0]])
    vn = vertex_normals(v, f)
    np.testing.assert_allclose(vn[:3], [[0, 0, 1]] * 3)
    np.testing.assert_allclose(vn[3], [0, 0, 0])  # unused vertex: zero, not NaN


def test_edges_and_adjacency_on_tetrahedron():
    f = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
    assert unique_edges(f).tolist() == [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]]
    pairs, edges = adjacent_face_pairs(f)
    assert len(pairs) == 6
    for (f0, f1), (a, b) in zip(pairs, edges):
        assert {a, b} <= set(f[f0]) and {a, b} <= set(f[f1]) and f0 != f1


# ---- icosphere --------------------------------------------------------------------------

@pytest.mark.parametrize("level, nv, nf", [(2, 162, 320), (3, 642, 1280), (4, 2562, 5120)])
def test_icosphere_counts_and_watertight_outward(level, nv, nf):
    m = icosphere(level)
    assert (m.num_vertices, m.num_faces) == (nv, nf)
    np.testing.assert_allclose(np.linalg.norm(m.vertices, axis=1), 0.5, rtol=1e-6)
    t = trimesh.Trimesh(m.vertices, m.faces, process=False)
    assert t.is_watertight and t.is_winding_consistent and t.volume > 0  # positive volume = outward
    centres = m.vertices[m.faces].mean(axis=1)
    assert np.all(np.sum(face_normals(m.vertices, m.faces) * centres, axis=1) > 0)
    assert level_for_vertex_count(nv) == level


def test_icosphere_is_deterministic_and_prefix_stable():
    a, b = icosphere(3), icosphere(3)
    np.testing.assert_array_equal(a.vertices, b.vertices)
    np.testing.assert_array_equal(a.faces, b.faces)
    # each level keeps the previous level's vertices first, in order
    np.testing.assert_allclose(icosphere(3).vertices[:162], icosphere(2).vertices)


@pytest.mark.parametrize("bad", [-1, 7, 2.5])
def test_icosphere_rejects_bad_level(bad):
    with pytest.raises(ValueError):
        icosphere(bad)


@pytest.mark.parametrize("level", [0, 1, 2, 3, 4])
def test_mirror_permutation_is_the_templates_reflection(level):
    """perm[i] sits at vertex i's mirror image; it is an involution fixing exactly the vertices on x = 0, and the
    reflection maps the triangulation onto itself (faces map to faces)."""
    m = icosphere(level)
    v = m.vertices.astype(np.float64)
    perm = mirror_permutation(level)
    np.testing.assert_allclose(v[perm], v * [-1.0, 1.0, 1.0], atol=1e-7)
    np.testing.assert_array_equal(perm[perm], np.arange(len(v)))
    np.testing.assert_array_equal(np.flatnonzero(perm == np.arange(len(v))), np.flatnonzero(np.abs(v[:, 0]) < 1e-7))
    assert {tuple(sorted(f)) for f in perm[m.faces].tolist()} == {tuple(sorted(f)) for f in m.faces.tolist()}
    with pytest.raises(ValueError):
        perm[0] = 1  # shared and cached: read-only
    for bad in (-1, 7, 2.5):
        with pytest.raises(ValueError, match="level"):
            mirror_permutation(bad)


@pytest.mark.parametrize("level", [2, 3, 4])
def test_legged_template_is_the_sphere_with_four_legs(level):
    sphere, legs = icosphere(level), template_mesh(level, shape="legs")
    assert template_mesh(level) is not None and np.array_equal(template_mesh(level).vertices, sphere.vertices)
    np.testing.assert_array_equal(legs.faces, sphere.faces)  # same topology and vertex order
    v, s = np.asarray(legs.vertices, np.float64), np.asarray(sphere.vertices, np.float64)
    moved = np.abs(v - s).max(1) > 0
    assert np.all(s[moved, 1] < 0)  # only the lower half moves, and only down
    assert np.all(v[moved, 1] < s[moved, 1])
    # each leg's tip: the vertex nearest its centre, pulled down by about LEG_DROP radii (hand-computed bound: the
    # nearest vertex is within one edge of the centre, where the weight is close to 1)
    r = 0.5
    for az in np.radians(LEG_AZIMUTHS_DEG):
        p = np.radians(LEG_POLAR_DEG)
        centre = r * np.array([np.sin(p) * np.cos(az), np.cos(p), np.sin(p) * np.sin(az)])
        tip = int(np.argmin(np.linalg.norm(s - centre, axis=1)))
        assert centre[1] - LEG_DROP * r - 1e-6 <= v[tip, 1] < centre[1] - 0.6 * LEG_DROP * r
    # mirror-symmetric in x, so the sphere's mirror pairing holds for it
    np.testing.assert_allclose(v[mirror_permutation(level)] * [-1, 1, 1], v, atol=1e-6)
    # closed and outward
    tm = trimesh.Trimesh(v, np.asarray(legs.faces), process=False)
    assert tm.is_watertight and tm.volume > 0
    # no fold: the lower half is a height field over the xz plane on the sphere and stays one (a leg is pulled
    # straight down and narrowed radially), so seen from below every lower face keeps its orientation
    lower = np.all(s[np.asarray(sphere.faces), 1] < 0, axis=1)

    def xz_area(x):
        t = x[np.asarray(sphere.faces)[lower]]
        a, b = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
        return a[:, 0] * b[:, 2] - a[:, 2] * b[:, 0]

    assert np.all(np.sign(xz_area(v)) == np.sign(xz_area(s))) and np.all(xz_area(s) != 0)
    assert tm.area_faces.min() > 0
    with pytest.raises(ValueError, match="template shape"):
        template_mesh(level, shape="torus")


def test_mirror_average_by_hand():
    t = icosphere(2).vertices.astype(np.float64)
    # a flipped prediction shifted by (0.1, 0.2, 0) is, mirrored back, the template shifted by (-0.1, 0.2, 0)
    out = mirror_average(t, t + [0.1, 0.2, 0.0])
    np.testing.assert_allclose(out, t + [-0.05, 0.1, 0.0], atol=1e-7)
    # a prediction of the mirror image that agrees with the plain one leaves it unchanged, batched too
    rng = np.random.default_rng(0)
    plain = t + rng.normal(0.0, 0.05, size=(2, *t.shape))
    agreeing = (plain * [-1.0, 1.0, 1.0])[:, mirror_permutation(2)]
    np.testing.assert_allclose(mirror_average(plain, agreeing), plain, atol=1e-12)
    for a, b in ((t, t[:-1]), (t[:, :2], t[:, :2]), (t[:100], t[:100])):
        with pytest.raises(ValueError):
            mirror_average(a, b)


# ---- cameras ----------------------------------------------------------------------------

def test_look_at_azimuth_zero_sees_front_from_plus_z():
    cam = look_at(0.0, 0.0, distance=3.0)
    np.testing.assert_allclose(cam.position, [0, 0, 3], atol=1e-12)
    uv, depth = project(np.array([[0, 0, 0], [0.5, 0, 0], [0, 0.5, 0]]), cam)
    np.testing.assert_allclose(depth, [3, 3, 3])
    f = cam.focal
    np.testing.assert_allclose(uv, [[0, 0], [f * 0.5 / 3, 0], [0, f * 0.5 / 3]], atol=1e-12)


def test_positive_azimuth_moves_camera_towards_plus_x_and_elevation_up():
    cam = look_at(90.0, 30.0, distance=2.0)
    p = cam.position
    assert p[0] > 1.0 and abs(p[2]) < 1e-9 and p[1] == pytest.approx(1.0)
    # the world origin projects to the image centre, world up stays up on screen
    uv, _ = project(np.array([[0, 0, 0], [0, 0.1, 0]]), cam)
    np.testing.assert_allclose(uv[0], [0, 0], atol=1e-12)
    assert uv[1, 1] > 0


def test_paper_views():
    views = paper_views()
    assert len(views) == 24
    assert [az for az, _, _ in views] == [15.0 * k for k in range(24)]
    assert all(el == 30.0 for _, el, _ in views)


def test_pixel_convention_top_left_origin():
    u, v = pixel_centers_ndc(4)
    assert (u[0, 0], v[0, 0]) == (-0.75, 0.75)  # top-left pixel centre
    px = ndc_to_pixel(np.array([[u[2, 3], v[2, 3]]]), 4)
    np.testing.assert_allclose(px, [[3.5, 2.5]])  # (col + 0.5, row + 0.5)


def test_projection_behind_camera_is_nan_not_inf():
    cam = look_at(0, 0, 2.0)
    uv, depth = project(np.array([[0, 0, 2.0], [0, 0, 5.0]]), cam)
    assert np.all(np.isnan(uv)) and np.all(depth <= 0)


def test_frame_camera_centres_and_scales_bbox():
    rng = np.random.default_rng(0)
    pts = rng.uniform(-0.5, 0.5, (200, 3)) * [1.0, 0.3, 0.6] + [0.2, 0.1, 0.0]
    cam = frame_camera(look_at(30, 30), pts, margin=0.1)
    uv, _ = project(pts, cam)
    lo, hi = uv.min(0), uv.max(0)
    np.testing.assert_allclose((lo + hi) / 2, 0, atol=1e-9)
    assert max(hi - lo) == pytest.approx(1.6)


def test_camera_array_round_trip_and_relative_camera():
    a = frame_camera(look_at(45, 30), icosphere(2).vertices)
    b = Camera.from_array(a.to_array())
    np.testing.assert_array_equal(a.R, b.R)
    assert (a.focal, a.principal) == (b.focal, b.principal)
    # a world point seen by view j equals its view-frame image seen through relative_camera
    cam_in, cam_j = look_at(45, 30), look_at(120, 30)
    p = np.array([[0.1, -0.2, 0.3]])
    uv_world, _ = project(p, cam_j)
    uv_view, _ = project(p @ cam_in.R.T, relative_camera(cam_in, cam_j))
    np.testing.assert_allclose(uv_world, uv_view, atol=1e-12)
    # the input view itself becomes view_camera
    uv_in, _ = project(p, cam_in)
    uv_vc, _ = project(p @ cam_in.R.T, view_camera(cam_in.focal))
    np.testing.assert_allclose(uv_in, uv_vc, atol=1e-12)


def test_normalize_vertices():
    v = np.array([[0, 0, 0], [4, 1, 2], [2, 3, 1]], float)
    n = normalize_vertices(v)
    np.testing.assert_allclose(n.min(0) + n.max(0), 0, atol=1e-12)
    assert (n.max(0) - n.min(0)).max() == pytest.approx(1.0)
    with pytest.raises(ValueError):
        normalize_vertices(np.ones((4, 3)))


def test_normal_encoding_round_trip():
    n = np.array([[0, 0, 1], [-1, 0, 0]], float)
    rgb = encode_normals(n)
    np.testing.assert_allclose(rgb, [[0.5, 0.5, 1.0], [0, 0.5, 0.5]])
    np.testing.assert_allclose(decode_normals(rgb), n)


@pytest.mark.parametrize("kwargs", [dict(distance=0), dict(distance=np.inf), dict(elevation_deg=90)])
def test_look_at_rejects_degenerate(kwargs):
    args = dict(azimuth_deg=0.0, elevation_deg=30.0) | kwargs
    with pytest.raises(ValueError):
        look_at(**args)
