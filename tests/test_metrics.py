"""3D/2D metrics against hand-computed values and a slow generalised-winding-number reference."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from engine.icosphere import icosphere
from engine.mesh import Mesh
from training.evaluation.metrics import (
    chamfer_l1,
    image_support_count,
    normal_consistency,
    sample_surface,
    silhouette_iou,
    solid_voxels,
    support_count,
    support_profile,
    surface_metrics,
    surface_voxels,
    voxel_centers,
    voxel_iou,
)


def _mesh(tm: trimesh.Trimesh) -> Mesh:
    return Mesh(tm.vertices, tm.faces)


def _box(extents, offset=(0.0, 0.0, 0.0)) -> Mesh:
    return _mesh(trimesh.creation.box(extents).apply_translation(offset))


def _square(z: float = 0.0, size: float = 0.6) -> Mesh:
    h = size / 2
    v = np.array([[-h, -h, z], [h, -h, z], [h, h, z], [-h, h, z]])
    return Mesh(v, np.array([[0, 1, 2], [0, 2, 3]]))


def slow_winding_number(mesh: Mesh, points: np.ndarray) -> np.ndarray:
    """Generalised winding number (Jacobson et al. 2013) by the Van Oosterom-Strackee solid angle, one point at a time."""
    tri = mesh.vertices.astype(np.float64)[mesh.faces]
    out = np.zeros(len(points))
    for n, p in enumerate(points):
        a, b, c = tri[:, 0] - p, tri[:, 1] - p, tri[:, 2] - p
        la, lb, lc = (np.linalg.norm(x, axis=1) for x in (a, b, c))
        det = np.einsum("ij,ij->i", a, np.cross(b, c))
        den = la * lb * lc + np.einsum("ij,ij->i", a, b) * lc + np.einsum("ij,ij->i", b, c) * la + np.einsum("ij,ij->i", c, a) * lb
        out[n] = np.sum(2.0 * np.arctan2(det, den)) / (4.0 * np.pi)
    return out


def _grid_points(resolution: int) -> np.ndarray:
    c = voxel_centers(resolution)
    return np.stack(np.meshgrid(c, c, c, indexing="ij"), axis=-1).reshape(-1, 3)


# ---------------------------------------------------------------- voxel IoU


def test_offset_cubes_hand_computed():
    a = _box((0.5, 0.5, 0.5))
    b = _box((0.5, 0.5, 0.5), (0.125, 0.0, 0.0))
    # side 0.5 covers exactly 16 cells at R = 32; a shift of 0.125 is 4 cells: IoU = 12 / 20
    assert solid_voxels(a, 32).sum() == 16**3
    assert voxel_iou(a, b, 32) == pytest.approx(0.6, abs=1e-12)
    # a shift that is not a whole number of cells: continuous IoU (0.5 - 0.1) / (0.5 + 0.1), within a cell layer
    c = _box((0.5, 0.5, 0.5), (0.1, 0.0, 0.0))
    assert abs(voxel_iou(a, c, 32) - 0.4 / 0.6) <= 2.0 / 16


def test_voxel_grid_is_indexed_xyz():
    # a 0.25 x 0.125 x 0.0625 box with its low corner at (0, 0.125, 0.25): at R = 16 the cells
    # i in [8, 12), j in [10, 12), k in [12, 13) -- one cell layer along z, distinct along each axis
    box = _box((0.25, 0.125, 0.0625), (0.125, 0.1875, 0.28125))
    got = solid_voxels(box, 16)
    expected = np.zeros((16, 16, 16), dtype=bool)
    expected[8:12, 10:12, 12:13] = True
    np.testing.assert_array_equal(got, expected)


def test_sphere_self_and_disjoint():
    s = icosphere(3)
    assert voxel_iou(s, s) == 1.0
    expected_cells = (4 / 3) * np.pi * 16**3 * 0.98  # the level-3 polyhedron is ~2 % smaller than the sphere
    assert abs(solid_voxels(s, 32, surface=False).sum() - expected_cells) / expected_cells < 0.03
    a = _box((0.3, 0.3, 0.3), (-0.3, 0.0, 0.0))
    b = _box((0.3, 0.3, 0.3), (0.3, 0.0, 0.0))
    assert voxel_iou(a, b) == 0.0
    empty = Mesh(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64))
    assert voxel_iou(empty, empty) == 1.0
    assert voxel_iou(empty, a) == 0.0


@pytest.mark.parametrize("name", ["rotated_box", "overlapping_spheres", "open_sphere", "inverted"])
def test_solid_voxels_match_slow_winding_number(name):
    R = 10
    if name == "rotated_box":
        tm = trimesh.creation.box((0.6, 0.35, 0.5))
        tm.apply_transform(trimesh.transformations.euler_matrix(0.3, 0.5, 0.2))
        mesh = _mesh(tm)
    elif name == "overlapping_spheres":  # self-intersecting: the overlap has winding number 2
        parts = [trimesh.creation.icosphere(2, 0.25).apply_translation((dx, 0.0, 0.0)) for dx in (-0.12, 0.12)]
        mesh = _mesh(trimesh.util.concatenate(parts))
    elif name == "open_sphere":  # non-watertight: a few faces removed
        s = icosphere(2, 0.45)
        mesh = Mesh(s.vertices, s.faces[6:])
    else:  # all faces wound inwards
        s = icosphere(2, 0.45)
        mesh = Mesh(s.vertices, s.faces[:, ::-1])
    w = slow_winding_number(mesh, _grid_points(R)).reshape(R, R, R)
    reference = np.abs(w) >= 0.5
    got = solid_voxels(mesh, R, surface=False)
    assert np.all(solid_voxels(mesh, R) == got | surface_voxels(mesh, R))
    mismatch = np.argwhere(got != reference)
    # allow cells whose centre is almost on the surface (|w| near 0.5), none elsewhere
    assert all(abs(abs(w[tuple(i)]) - 0.5) < 0.2 for i in mismatch), f"mismatches at {mismatch[:5].tolist()}"
    assert len(mismatch) <= 0.01 * R**3
    if name == "overlapping_spheres":
        assert got[R // 2, R // 2, R // 2]  # the overlap counts as solid (ray parity would call it empty)


def _clip_hits(tri: np.ndarray, R: int) -> np.ndarray:
    """Reference for surface_voxels: Sutherland-Hodgman clipping of each triangle to each cell, one at a time."""
    g = (tri + 0.5) * R
    out = np.zeros((R, R, R), dtype=bool)
    for t in g:
        for cell in np.ndindex(R, R, R):
            poly = list(t)
            for axis in range(3):
                for bound, sign in ((cell[axis], 1.0), (cell[axis] + 1, -1.0)):
                    nxt = []
                    for a, b in zip(poly, poly[1:] + poly[:1]):
                        da, db = sign * (a[axis] - bound), sign * (b[axis] - bound)
                        if da >= 0:
                            nxt.append(a)
                        if (da >= 0) != (db >= 0):
                            nxt.append(a + (b - a) * (da / (da - db)))
                    poly = nxt
                    if not poly:
                        break
                if not poly:
                    break
            out[cell] |= bool(poly)
    return out


def test_surface_voxels_match_triangle_clipping():
    rng = np.random.default_rng(4)
    R = 6
    for n in range(12):  # triangles of every size, some reaching out of the cube
        centre = rng.uniform(-0.5, 0.5, 3)
        tri = centre + rng.normal(size=(3, 3)) * (0.02 if n < 4 else 0.3)
        got = surface_voxels(Mesh(tri, np.array([[0, 1, 2]])), R)
        np.testing.assert_array_equal(got, _clip_hits(tri[None], R), err_msg=f"triangle {n}")


def test_thin_parts_keep_their_cells():
    # a plate 0.3 cells thick that holds no cell centre: the surface's cells alone give it its layer
    R = 32
    z0, z1 = (20.1 / R - 0.5), (20.4 / R - 0.5)
    lo, hi = 8.5 / R - 0.5, 23.5 / R - 0.5
    plate = _box((hi - lo, hi - lo, z1 - z0), ((hi + lo) / 2, (hi + lo) / 2, (z1 + z0) / 2))
    assert not solid_voxels(plate, R, surface=False).any()
    expected = np.zeros((R, R, R), dtype=bool)
    expected[8:24, 8:24, 20] = True
    np.testing.assert_array_equal(solid_voxels(plate, R), expected)
    # two disjoint rifle-thin rods: centres alone call both empty and their IoU a perfect 1
    # (0.64 cells thick, centred on cell boundaries: between the centres 15.5 and 16.5, 25.5 and 26.5)
    rod_a = _box((0.02, 0.02, 0.9))
    rod_b = _box((0.02, 0.02, 0.9), (10 / R, 10 / R, 0.0))
    assert voxel_iou(rod_a, rod_b, R, surface=False) == 1.0
    assert voxel_iou(rod_a, rod_b, R) == 0.0
    assert voxel_iou(rod_a, rod_a, R) == 1.0 and solid_voxels(rod_a, R).sum() >= 28


def test_surface_cells_of_boxes_hand_computed():
    # side 0.52 at R = 32 spans grid [7.68, 24.32]: centres give cells 8..23 (16), the surface adds a layer
    box = _box((0.52, 0.52, 0.52))
    assert solid_voxels(box, 32, surface=False).sum() == 16**3
    assert solid_voxels(box, 32).sum() == 18**3
    # faces exactly on cell boundaries touch no open cell: the 0.5 cube keeps 16^3 either way
    assert not surface_voxels(_box((0.5, 0.5, 0.5)), 32).any()
    assert solid_voxels(_box((0.5, 0.5, 0.5)), 32).sum() == 16**3


def test_surface_voxels_of_degenerate_faces_and_chunks(monkeypatch):
    import training.evaluation.metrics as metrics

    R = 8
    # a segment along x through the middle of row (y, z) = (2, 5), given as a zero-area triangle
    y, z = (2.5 / R - 0.5), (5.5 / R - 0.5)
    seg = Mesh(np.array([[-0.3, y, z], [0.1, y, z], [0.2, y, z]]), np.array([[0, 1, 2]]))
    expected = np.zeros((R, R, R), dtype=bool)
    expected[1:6, 2, 5] = True  # x from (-0.3 + 0.5) * 8 = 1.6 to 5.6: cells 1..5
    np.testing.assert_array_equal(surface_voxels(seg, R), expected)
    point = Mesh(np.full((3, 3), 0.01), np.array([[0, 1, 2]]))
    assert np.argwhere(surface_voxels(point, R)).tolist() == [[4, 4, 4]]
    outside = _box((0.2, 0.2, 0.2), (2.0, 0.0, 0.0))
    assert not surface_voxels(outside, R).any()
    # the candidate pairs are tested in chunks: any chunk size gives the same cells
    s = icosphere(3, 0.45)
    whole = surface_voxels(s, 16)
    monkeypatch.setattr(metrics, "SURFACE_CANDIDATE_CHUNK", 37)
    np.testing.assert_array_equal(surface_voxels(s, 16), whole)
    assert whole.sum() > 0 and not whole[8, 8, 8]  # a shell, hollow inside


def test_solid_voxels_rejects_bad_resolution():
    with pytest.raises(ValueError, match="resolution"):
        solid_voxels(icosphere(1), 0)
    with pytest.raises(TypeError, match="Mesh"):
        voxel_iou("a", icosphere(1))  # type: ignore[arg-type]


# ---------------------------------------------------------------- surface metrics


def test_sample_surface_is_on_the_surface_and_deterministic():
    box = _box((0.5, 0.3, 0.2))
    p, n = sample_surface(box, 2000, seed=3)
    assert p.shape == (2000, 3) and n.shape == (2000, 3)
    half = np.array([0.25, 0.15, 0.1])
    tol = 1e-6  # Mesh vertices are float32
    assert np.all(np.abs(p) <= half + tol)
    assert np.all(np.max(np.abs(p) / half, axis=1) > 1 - tol)  # every point on some face
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0)
    p2, _ = sample_surface(box, 2000, seed=3)
    np.testing.assert_array_equal(p, p2)
    # area weighting: the two 0.5 x 0.3 faces hold 0.3 / 0.62 of the area
    frac = np.mean(np.abs(np.abs(p[:, 2]) - 0.1) < tol)
    assert abs(frac - 0.15 / 0.31) < 0.04
    with pytest.raises(ValueError, match="zero surface area"):
        sample_surface(Mesh(np.zeros((3, 3)), np.array([[0, 1, 2]])), 10)


def test_chamfer_and_normal_consistency_of_parallel_and_crossed_planes():
    a, b = _square(0.0), _square(0.1)
    c = chamfer_l1(a, b, n_points=4000)
    assert 0.1 <= c <= 0.1 + 0.01  # exact 0.1 plus the in-plane sampling gap
    assert normal_consistency(a, b, n_points=4000) == pytest.approx(1.0)
    crossed = Mesh(np.asarray(a.vertices)[:, [2, 1, 0]], a.faces)  # the square rotated into the x = 0 plane
    assert normal_consistency(a, crossed, n_points=4000) == pytest.approx(0.0, abs=1e-6)


def test_surface_metrics_match_brute_force():
    a, b = icosphere(1, 0.4), _box((0.5, 0.6, 0.4))
    m = surface_metrics(a, b, n_points=300, seed=7)
    pa, na = sample_surface(a, 300, 7)
    pb, nb = sample_surface(b, 300, 8)
    d = np.linalg.norm(pa[:, None] - pb[None], axis=2)  # (300, 300)
    acc, comp = d.min(1).mean(), d.min(0).mean()
    nc = 0.5 * (np.abs((na * nb[d.argmin(1)]).sum(1)).mean() + np.abs((nb * na[d.argmin(0)]).sum(1)).mean())
    assert m["chamfer_l1"] == pytest.approx(0.5 * (acc + comp), rel=1e-12)
    assert m["normal_consistency"] == pytest.approx(nc, rel=1e-12)


# ---------------------------------------------------------------- silhouette IoU


def test_silhouette_iou_rectangles_and_edge_cases():
    a = np.zeros((10, 12), dtype=bool)
    b = np.zeros_like(a)
    a[2:6, 2:10] = True  # 32 px
    b[4:8, 6:12] = True  # 24 px, overlap 2 x 4
    assert silhouette_iou(a, b) == pytest.approx(8 / 48)
    assert silhouette_iou(a.astype(np.float32) * 0.9, b) == pytest.approx(8 / 48)  # binarised at 0.5
    assert silhouette_iou(np.zeros((4, 4), bool), np.zeros((4, 4), bool)) == 1.0
    assert silhouette_iou(a, np.zeros_like(a)) == 0.0
    with pytest.raises(ValueError, match=r"\(10, 12\) and \(12, 10\)"):
        silhouette_iou(a, a.T)


@pytest.mark.parametrize("argv", [
    ["eval", "RUN", "--data", "D"],
    ["eval", "--models", "bundled", "--data", "D"],
    ["bench", "fit", "--target", "m.obj"],
    ["bench", "overfit", "--out", "O"],
    ["bench", "variants", "--data", "D", "--out", "O", "--variant", "a"],
    ["bench", "variety"],
    ["bench", "refine", "--data", "D", "--out", "O"],
    ["bench", "tradeoff", "--data", "D", "--variant", "a=M", "--out", "O"],
])
def test_every_command_that_scores_voxels_takes_voxel_centres(argv):
    from sketchmesh.cli import build_parser

    parser = build_parser()
    assert parser.parse_args(argv).voxel_centres is False
    assert parser.parse_args([*argv, "--voxel-centres"]).voxel_centres is True


def test_surface_voxels_split_one_large_face_across_chunks(monkeypatch):
    """A chunk may end inside a face's candidates: one slanted face across the cube gives the cells that clipping
    gives, whatever the chunk size."""
    import training.evaluation.metrics as metrics

    v = np.array([[-0.49, -0.45, -0.4], [0.48, -0.3, 0.45], [-0.2, 0.47, 0.1]])
    tri = Mesh(v, np.array([[0, 1, 2]]))
    whole = surface_voxels(tri, 12)
    np.testing.assert_array_equal(whole, _clip_hits(np.asarray(tri.vertices, np.float64)[None], 12))
    monkeypatch.setattr(metrics, "SURFACE_CANDIDATE_CHUNK", 101)  # 12^3 candidates: 18 chunks, one face
    np.testing.assert_array_equal(surface_voxels(tri, 12), whole)
    assert whole.sum() > 12 * 12 // 2


# ---------------------------------------------------------------- supports (legs counted)


def _stand(feet, height=8, top=2, R=16) -> np.ndarray:
    """An (R, R, R) [x, y, z] grid: a top slab of ``top`` layers over ``height`` layers of columns at ``feet`` ((x0, x1, z0, z1) cells)."""
    v = np.zeros((R, R, R), bool)
    for x0, x1, z0, z1 in feet:
        v[x0:x1, 1:1 + height, z0:z1] = True
    v[2:14, 1 + height:1 + height + top, 2:14] = True
    return v


def test_support_count_of_hand_built_stands():
    legs = [(2, 4, 2, 4), (12, 14, 2, 4), (2, 4, 12, 14), (12, 14, 12, 14)]
    assert support_profile(_stand(legs)) == [4] * 8 + [1, 1]
    assert support_count(_stand(legs)) == 4  # a table on four legs
    assert support_count(_stand([(2, 4, 2, 14), (12, 14, 2, 14)])) == 2  # a trestle on two end panels
    assert support_count(_stand([(7, 9, 7, 9)])) == 1  # a pedestal
    assert support_count(np.ones((8, 8, 8), bool)) == 1 and support_count(np.zeros((8, 8, 8), bool)) == 0
    # a skirt with stubs: four feet one layer high under a solid block; the lowest quarter (3 of 12 layers) has 4, 1, 1
    skirt = np.zeros((16, 16, 16), bool)
    skirt[2:14, 2:13, 2:14] = True
    for x0, x1, z0, z1 in legs:
        skirt[x0:x1, 1, z0:z1] = True
    assert support_profile(skirt)[:3] == [4, 1, 1] and support_count(skirt) == 1
    assert support_count(skirt, band=1 / 12) == 4  # only the feet's layer searched
    # a leg that steps diagonally from cell to cell is one piece (8-neighbours in a layer)
    diag = np.zeros((6, 3, 6), bool)
    diag[[1, 2, 3], 1, [1, 2, 3]] = True
    assert support_profile(diag) == [1]
    # a gap layer between parts counts no pieces; the band's upper median: [3, 3, 0, 1] -> 3 (half the layers reach it)
    gaps = np.zeros((12, 12, 12), bool)
    gaps[[1, 5, 9], 0, 1] = gaps[[1, 5, 9], 1, 1] = True
    gaps[:, 3, :] = True
    assert support_profile(gaps) == [3, 3, 0, 1] and support_count(gaps, band=1.0) == 3


def test_support_count_of_voxelised_meshes():
    top = trimesh.creation.box((0.8, 0.06, 0.5)).apply_translation((0, 0.2, 0))
    legs = [trimesh.creation.box((0.06, 0.6, 0.06)).apply_translation((x, -0.13, z)) for x in (-0.35, 0.35) for z in (-0.2, 0.2)]
    table = _mesh(trimesh.util.concatenate([top, *legs]))
    assert support_count(solid_voxels(table, 32)) == 4
    assert support_count(solid_voxels(icosphere(3, 0.5), 32)) == 1


@pytest.mark.parametrize("bad, band", [(np.zeros((4, 4), bool), 0.25), (np.zeros((4, 4, 4), np.uint8), 0.25),
                                       (np.zeros((4, 4, 4), bool), 0.0), (np.zeros((4, 4, 4), bool), float("nan")),
                                       (np.zeros((4, 4, 4), bool), 1.5)])
def test_support_count_refuses_bad_input(bad, band):
    with pytest.raises(ValueError):
        support_count(bad, band)


def _image(rows) -> np.ndarray:
    """A silhouette from strings, '#' covered, top row first."""
    return np.array([[c == "#" for c in r] for r in rows], bool)


def test_image_support_count_of_hand_drawn_silhouettes():
    side = _image(["##########",
                   "##########",
                   ".#......#.",
                   ".#......#.",
                   ".#......#."])
    assert image_support_count(side) == 2  # a table from the side: its front legs hide the back ones
    four = _image(["############",
                   "#..#....#..#",
                   "#..#....#..#",
                   "#..#....#..#"])
    assert image_support_count(four) == 4  # legs at the image's border columns count too
    # a skirt with stubs one row high: the lowest quarter (3 of 12 rows) has 4, 1, 1 pieces -> 1; the stubs' row alone 4
    skirt = np.zeros((12, 12), bool)
    skirt[0:11, 1:11] = True
    skirt[11, [1, 4, 7, 10]] = True
    assert image_support_count(skirt) == 1 and image_support_count(skirt, band=1 / 12) == 4
    assert image_support_count(np.zeros((6, 6), bool)) == 0 and image_support_count(np.ones((6, 6), bool)) == 1
    # the band is of the silhouette's own rows, wherever it sits in the image
    shifted = np.zeros((30, 14), bool)
    shifted[10:15, 2:12] = side
    assert image_support_count(shifted) == 2


def test_image_support_count_is_support_count_of_the_silhouette_extruded():
    """Independent expectation: a silhouette extruded along z is a solid whose layers are its rows (image rows down, +Y
    up), counted by support_count (scipy's labelling of 8-neighbours within a layer) against the row runs here."""
    rng = np.random.default_rng(0)
    for trial in range(200):
        h, w = rng.integers(1, 14, size=2)
        mask = rng.random((h, w)) < rng.uniform(0.1, 0.9)
        vox = np.repeat(mask[::-1].T[:, :, None], 2, axis=2)  # [x, y, z]: column x, row from the bottom y
        band = float(rng.choice([0.25, 0.5, 1.0, 0.1]))
        assert image_support_count(mask, band) == support_count(vox, band), (trial, mask.astype(int), band)


@pytest.mark.parametrize("bad, band", [(np.zeros((4, 4, 4), bool), 0.25), (np.zeros((4, 4), np.uint8), 0.25),
                                       (np.zeros((4, 4), bool), 0.0), (np.zeros((4, 4), bool), float("nan")),
                                       (np.zeros((4, 4), bool), 1.5), (np.zeros((4, 4), bool), True)])
def test_image_support_count_refuses_bad_input(bad, band):
    with pytest.raises(ValueError):
        image_support_count(bad, band)
