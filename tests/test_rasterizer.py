"""The differentiable rasterizer: exact forward against the loop reference, Eq. 1 gradients
against the reference, interior gradients against finite differences, hand-computed scenes,
the edge rule, back-face culling and the numpy convenience wrapper."""

from __future__ import annotations

import importlib
import math

import numpy as np
import pytest
import torch

from engine.camera import Camera, look_at, view_camera
from engine.icosphere import icosphere
from engine.mesh import Mesh, face_normals
from training.render import RenderOutput, cameras_to_tensor, rasterize, render_normals_numpy
from training.render.rasterize import project_vertices
from training.render.reference import reference_rasterize

# `training.render.rasterize` the attribute is the function; the module is reached this way
R = importlib.import_module("training.render.rasterize")

torch.set_num_threads(min(2, torch.get_num_threads()))

# ---- named tolerances -------------------------------------------------------------------
FWD_ATOL_F64 = 1e-12
"""Fast vs reference forward in float64: same formulas in the same order, so ~1 ulp."""
GRAD_RTOL_F64 = 1e-9
"""Fast vs reference Eq. 1 + interior gradients in float64, relative to the largest entry.
Looser than the forward: index_add accumulation order differs from the loop's."""
GRADCHECK_ATOL = 1e-6
"""Finite differences (eps 1e-6, float64) of the smooth interior normals."""
NORMAL_ATOL_F32 = 1e-5
"""Hand-computed normal colours rendered in float32."""


def _cat_image(out: RenderOutput) -> torch.Tensor:
    return torch.cat([out.normals, out.silhouette[:, None]], dim=1)


def _assert_close(a: torch.Tensor, b: torch.Tensor, atol: float, what: str) -> None:
    diff = (a - b).abs()
    if diff.numel() and not bool((diff <= atol).all()):
        i = int(diff.reshape(-1).argmax())
        idx = np.unravel_index(i, tuple(diff.shape))
        raise AssertionError(f"{what}: max |diff| {float(diff.max()):.3e} > {atol:.1e} at {idx}")


def _random_scene(seed: int, V: int = 7, F: int = 5, B: int = 2):
    g = torch.Generator().manual_seed(seed)
    v = torch.rand(B, V, 3, generator=g, dtype=torch.float64) - 0.5
    f = torch.randint(0, V, (F, 3), generator=g)
    rng = np.random.default_rng(seed)
    cams = [look_at(rng.uniform(0, 360), rng.uniform(-40, 40)) for _ in range(B)]
    return v, f, cameras_to_tensor(cams, dtype=torch.float64)


def _ico_scene(seed: int, level: int = 1, B: int = 1):
    m = icosphere(level)
    g = torch.Generator().manual_seed(seed)
    v = torch.tensor(np.array(m.vertices), dtype=torch.float64)[None].repeat(B, 1, 1)
    v = v * (1 + 0.15 * torch.rand(B, v.shape[1], 1, generator=g, dtype=torch.float64))
    rng = np.random.default_rng(seed)
    cams = [look_at(rng.uniform(0, 360), rng.uniform(-40, 40)) for _ in range(B)]
    return v, torch.tensor(np.array(m.faces)), cameras_to_tensor(cams, dtype=torch.float64)


# ---- fast vs reference --------------------------------------------------------------------


@pytest.mark.parametrize("shading", ["flat", "smooth"])
@pytest.mark.parametrize("cull", [False, True])
@pytest.mark.parametrize("scene", ["soup0", "soup1", "soup2", "ico", "ico1"])
def test_matches_reference_forward_and_gradients(scene, shading, cull):
    if scene == "ico":
        v, f, cams = _ico_scene(3, level=0)
        size = 12
    elif scene == "ico1":  # 80 faces at 16 px: silhouette walks across several faces
        v, f, cams = _ico_scene(4, level=1, B=1)
        size = 16
    else:
        v, f, cams = _random_scene(int(scene[-1]))
        size = 10
    g = torch.Generator().manual_seed(99)
    weights = torch.randn(v.shape[0], 4, size, size, generator=g, dtype=torch.float64)
    va, vb = v.clone().requires_grad_(), v.clone().requires_grad_()
    fast = rasterize(va, f, cams, size, shading=shading, cull_backfaces=cull, delta=0.7)
    ref = reference_rasterize(vb, f, cams, size, shading=shading, cull_backfaces=cull, delta=0.7)
    assert torch.equal(fast.face_index, ref.face_index)
    assert int((fast.face_index >= 0).sum()) > 0, "scene renders nothing; the comparison would be vacuous"
    assert torch.equal(torch.isinf(fast.depth), torch.isinf(ref.depth))
    covered = fast.face_index >= 0
    _assert_close(fast.depth[covered], ref.depth[covered], FWD_ATOL_F64, "depth")
    _assert_close(_cat_image(fast).detach(), _cat_image(ref).detach(), FWD_ATOL_F64, "image")
    (_cat_image(fast) * weights).sum().backward()
    (_cat_image(ref) * weights).sum().backward()
    scale = float(vb.grad.abs().max())
    assert scale > 0, "reference gradient is zero; the comparison would be vacuous"
    _assert_close(va.grad, vb.grad, GRAD_RTOL_F64 * scale, "vertex gradient")


@pytest.mark.parametrize("level", [1, 2, 3])
def test_silhouette_gradient_reaches_only_silhouette_edge_vertices(level):
    """Silhouette-only loss: only the endpoints of screen-space silhouette edges (edges whose two
    faces face opposite ways on screen) receive gradient, on coarse and fine spheres alike;
    interior edges next to the outline (shared by two front faces) must get none."""
    v, f, cams = _ico_scene(5, level=level, B=1)
    v.requires_grad_()
    out = rasterize(v, f, cams, 32)
    out.silhouette.sum().backward()
    moved = set((v.grad[0].abs().sum(1) > 0).nonzero().squeeze(1).tolist())
    assert moved, "no gradient at all"
    _, screen, _, _ = R.project_vertices(v.detach(), cams, 32)
    xy = screen[0].numpy()
    fa = f.numpy()
    d1, d2 = xy[fa[:, 1]] - xy[fa[:, 0]], xy[fa[:, 2]] - xy[fa[:, 0]]
    area = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
    edge_faces: dict = {}
    for fid, tri in enumerate(fa.tolist()):
        for k in range(3):
            a, b = tri[k], tri[(k + 1) % 3]
            edge_faces.setdefault((min(a, b), max(a, b)), []).append(fid)
    sil = {i for e, fs in edge_faces.items() if np.sign(area[fs[0]]) != np.sign(area[fs[1]]) for i in e}
    assert moved <= sil, f"gradient on non-silhouette vertices {sorted(moved - sil)}"
    # hidden folds (the jittered sphere has some) get none, so not every silhouette vertex moves
    assert len(moved) >= 0.3 * len(sil), f"only {len(moved)} of {len(sil)} silhouette vertices moved"


def test_face_adjacency_matches_a_dict_of_edges_and_marks_boundaries():
    m = icosphere(2)
    faces = np.array(m.faces)[1:]  # a writable copy; one face removed: its three edges become boundary edges
    nb, nbe = R.face_adjacency(torch.from_numpy(faces))
    owners: dict = {}
    for fid, tri in enumerate(faces.tolist()):
        for k in range(3):
            a, b = tri[(k + 1) % 3], tri[(k + 2) % 3]
            owners.setdefault((min(a, b), max(a, b)), []).append((fid, k))
    boundary = 0
    for fs in owners.values():
        if len(fs) == 1:
            boundary += 1
            f, k = fs[0]
            assert int(nb[f, k]) == -1 and int(nbe[f, k]) == -1
        else:
            (f, k), (g, j) = fs
            assert (int(nb[f, k]), int(nbe[f, k])) == (g, j) and (int(nb[g, j]), int(nbe[g, j])) == (f, k)
    assert boundary == 3


# ---- interior gradients vs finite differences --------------------------------------------


def _interior_mask(fi: torch.Tensor) -> torch.Tensor:
    """Pixels covered by a face whose 4 neighbours show the same face (no boundary pair touches them)."""
    m = fi >= 0
    same = torch.ones_like(m)
    same[:, 1:, :] &= fi[:, 1:, :] == fi[:, :-1, :]
    same[:, :-1, :] &= fi[:, :-1, :] == fi[:, 1:, :]
    same[:, :, 1:] &= fi[:, :, 1:] == fi[:, :, :-1]
    same[:, :, :-1] &= fi[:, :, :-1] == fi[:, :, 1:]
    same[:, 0, :] = same[:, -1, :] = same[:, :, 0] = same[:, :, -1] = False
    return m & same


@pytest.mark.parametrize("shading", ["smooth", "flat"])
def test_interior_normals_gradcheck(shading):
    v, f, cams = _ico_scene(1, level=0)
    size = 24
    fi = rasterize(v, f, cams, size).face_index
    mask = _interior_mask(fi)
    assert int(mask.sum()) >= 20

    def fn(verts):
        out = rasterize(verts, f, cams, size, shading=shading)
        assert torch.equal(out.face_index, fi), "perturbation changed coverage; pick another scene"
        return out.normals.permute(0, 2, 3, 1)[mask]

    assert torch.autograd.gradcheck(fn, (v.clone().requires_grad_(),), eps=1e-6, atol=GRADCHECK_ATOL, rtol=1e-4)


# ---- the approximate gradient points the right way ---------------------------------------


def _square(cx: float, cy: float, half: float, z: float = 0.0) -> torch.Tensor:
    return torch.tensor(
        [[[cx - half, cy - half, z], [cx + half, cy - half, z], [cx + half, cy + half, z], [cx - half, cy + half, z]]],
        dtype=torch.float64,
    )


SQUARE_FACES = torch.tensor([[0, 1, 2], [0, 2, 3]])


def _soft_iou_loss(sil: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    inter = (sil * target).sum()
    union = (sil + target - sil * target).sum()
    return 1.0 - inter / union


@pytest.mark.parametrize("dx, dy", [(0.08, 0.0), (-0.08, 0.0), (0.0, 0.08), (0.05, -0.06)])
def test_translated_square_iou_gradient_points_to_target(dx, dy):
    cam = cameras_to_tensor([view_camera(3.0)], dtype=torch.float64)
    size = 32
    target = rasterize(_square(dx, dy, 0.3), SQUARE_FACES, cam, size).silhouette.detach()
    v = _square(0.0, 0.0, 0.3).requires_grad_()
    loss = _soft_iou_loss(rasterize(v, SQUARE_FACES, cam, size).silhouette, target)
    loss.backward()
    g = v.grad[0].sum(0)  # net force on the square
    direction = torch.tensor([dx, dy, 0.0], dtype=torch.float64)
    assert float(g @ direction) < 0, f"gradient {g.tolist()} does not point towards the target {direction.tolist()}"
    # a few normalised gradient steps reduce the loss
    w = v.detach().clone()
    start = float(loss.detach())
    for _ in range(8):
        w.requires_grad_()
        step_loss = _soft_iou_loss(rasterize(w, SQUARE_FACES, cam, size).silhouette, target)
        (gw,) = torch.autograd.grad(step_loss, w)
        w = (w - 0.01 * gw / gw.abs().max().clamp(min=1e-12)).detach()
    final = float(_soft_iou_loss(rasterize(w, SQUARE_FACES, cam, size).silhouette, target))
    assert final < start * 0.7, f"loss {start:.4f} -> {final:.4f}"


def test_delta_scales_the_edge_gradient():
    cam = cameras_to_tensor([view_camera(3.0)], dtype=torch.float64)
    grads = []
    for delta in (1.0, 4.0):
        v = _square(0.01, 0.02, 0.3).requires_grad_()
        rasterize(v, SQUARE_FACES, cam, 16, delta=delta).silhouette.sum().backward()
        grads.append(v.grad)
    assert float(grads[0].abs().max()) > 0
    _assert_close(grads[1] * 4.0, grads[0], 1e-12 * float(grads[0].abs().max()), "1/delta scaling")


@pytest.mark.parametrize("scene", ["soup1", "ico1"])
@pytest.mark.parametrize("edge_range", [3, 16])
def test_far_range_gradient_matches_the_loop_reference(scene, edge_range):
    """edge_range > 1 (NMR-like far events): the vectorised backward equals the loop reference's,
    and differs from the adjacent-pixel variant (the far events are really there)."""
    v, f, cams = _ico_scene(4, level=1, B=1) if scene == "ico1" else _random_scene(1)
    size = 16 if scene == "ico1" else 10
    weights = torch.randn(v.shape[0], 4, size, size, generator=torch.Generator().manual_seed(5), dtype=torch.float64)
    grads = []
    for fn, er in ((rasterize, edge_range), (reference_rasterize, edge_range), (rasterize, 1)):
        w = v.clone().requires_grad_()
        (_cat_image(fn(w, f, cams, size, delta=0.7, edge_range=er)) * weights).sum().backward()
        grads.append(w.grad)
    scale = float(grads[1].abs().max())
    assert scale > 0
    _assert_close(grads[0], grads[1], GRAD_RTOL_F64 * scale, "far-range vertex gradient")
    assert float((grads[0] - grads[2]).abs().max()) > 1e-3 * scale, "far range changed nothing"


def test_far_range_pulls_a_square_towards_a_disjoint_target():
    """A target square 2 px of background to the right of the square, not touching it: no adjacent
    pair sees it (zero gradient with edge_range 1 and 2); with edge_range 8 the right edge is
    pulled right by the hand-computed far events of its 6 rows: the target pixels 21..26 lie
    j = 2..7 px beyond the first outside pixel (19), each has g = -1 / |T| on the silhouette
    channel and D = 1 - tau + j, with tau the edge's distance from the last inside centre."""
    cam = cameras_to_tensor([view_camera(3.0)], dtype=torch.float64)
    size = 32
    target = rasterize(_square(0.45, 0.0, 0.15), SQUARE_FACES, cam, size).silhouette.detach()
    sq = _square(0.0, 0.0, 0.15)
    screen = project_vertices(sq, cam, size)[1][0]
    assert target[0].any(0).nonzero().flatten().tolist() == list(range(21, 27))
    grads = {}
    for er in (1, 2, 8):
        v = sq.clone().requires_grad_()
        sil = rasterize(v, SQUARE_FACES, cam, size, edge_range=er).silhouette
        assert sil[0].any(0).nonzero().flatten().tolist() == list(range(13, 19))
        (-(sil * target).sum() / target.sum()).backward()
        grads[er] = v.grad[0]
    assert float(grads[1].abs().max()) == 0.0 and float(grads[2].abs().max()) == 0.0
    g8 = grads[8]
    tau = float(screen[1, 0]) - 18.5
    px_per_unit = float(screen[1, 0] - screen[0, 0]) / 0.3
    expected = 6 * sum(-1.0 / 36.0 / (1.0 - tau + j) for j in range(2, 8)) * px_per_unit
    assert float(g8[:, 1].abs().max()) == 0.0  # no vertical events reach the target
    assert float(g8[[0, 3], 0].abs().max()) == 0.0  # the left edge feels nothing
    np.testing.assert_allclose(float(g8[[1, 2], 0].sum()), expected, rtol=1e-9)


def test_edge_range_must_be_a_positive_int():
    cam = cameras_to_tensor([view_camera(3.0)], dtype=torch.float64)
    for bad in (0, -1, 1.5, True):
        with pytest.raises(ValueError, match="edge_range"):
            rasterize(_square(0.0, 0.0, 0.15), SQUARE_FACES, cam, 8, edge_range=bad)


# ---- edge rule, ties -------------------------------------------------------------------------


def _pixel_exact_camera() -> torch.Tensor:
    """Identity camera at the origin, focal 1: a vertex (x, y, -1) projects to px = (x + 1) S / 2 exactly."""
    return cameras_to_tensor([Camera(np.eye(3), np.zeros(3), 1.0)], dtype=torch.float64)


def _pix_to_world(px: float, py: float, S: int) -> list[float]:
    return [px * 2.0 / S - 1.0, 1.0 - py * 2.0 / S, -1.0]


@pytest.mark.parametrize("layout", ["diag", "antidiag", "fan", "fan_reversed"])
def test_edge_rule_covers_every_pixel_exactly_once(layout):
    """Edges through pixel centres (dyadic coordinates, exact arithmetic): per-face coverages
    partition the square's pixels -- no crack, no double coverage."""
    S = 8
    corners = [(0.5, 0.5), (7.5, 0.5), (7.5, 7.5), (0.5, 7.5)]  # outer edges on pixel centres too
    pts = [_pix_to_world(x, y, S) for x, y in corners]
    if layout == "diag":
        faces = [[0, 2, 1], [0, 3, 2]]
    elif layout == "antidiag":
        faces = [[0, 3, 1], [1, 3, 2]]
    else:
        pts.append(_pix_to_world(3.5, 4.5, S))  # centre vertex on a pixel centre
        faces = [[0, 4, 1], [1, 4, 2], [2, 4, 3], [3, 4, 0]]
        if layout == "fan_reversed":
            faces = [[a, c, b] for a, b, c in faces]  # back-facing winding
    v = torch.tensor([pts], dtype=torch.float64)
    cam = _pixel_exact_camera()
    per_face = []
    for fc in faces:
        per_face.append(rasterize(v, torch.tensor([fc]), cam, S).silhouette[0])
    total = torch.stack(per_face).sum(0)
    assert float(total.max()) == 1.0, "a pixel centre is covered twice"
    # top-left rule: the left column and top row of centres (on the left/top edges) are in,
    # the right column and bottom row (on the right/bottom edges) are out: rows/cols 0..6
    expected = torch.zeros(S, S, dtype=torch.float64)
    expected[0:7, 0:7] = 1.0
    assert torch.equal(total, expected), f"coverage\n{total}"
    full = rasterize(v, torch.tensor(faces), cam, S)
    assert torch.equal(full.silhouette[0], expected)


def test_equal_depth_smallest_face_index_wins():
    v = _square(0.0, 0.0, 0.4)
    cam = cameras_to_tensor([view_camera(3.0)], dtype=torch.float64)
    faces = torch.tensor([[0, 1, 2], [0, 2, 3], [1, 2, 0], [2, 0, 1]])  # 2 and 3 duplicate face 0
    fi = rasterize(v, faces, cam, 16).face_index
    assert set(fi[fi >= 0].unique().tolist()) == {0, 1}


# ---- hand-computed scenes ------------------------------------------------------------------


def _cube() -> Mesh:
    v = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)], dtype=np.float64)
    quads = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    faces = []
    for a, b, c, d in quads:
        faces += [[a, b, c], [a, c, d]]
    faces = np.array(faces)
    # orient outwards
    centroid = v[faces].mean(1)
    n = face_normals(v, faces)
    flip = (n * centroid).sum(1) < 0
    faces[flip] = faces[flip][:, ::-1]
    return Mesh(v, faces)


def test_cube_front_view_hand_computed():
    S = 64
    cam = look_at(0.0, 0.0)
    mesh = _cube()
    out = rasterize(
        torch.tensor(mesh.vertices)[None], torch.tensor(mesh.faces), cameras_to_tensor([cam]), S
    )
    # the front face z = +0.5 is at depth d = 2.732 - 0.5; its half side in NDC is focal * 0.5 / d
    d = 2.732 - 0.5
    half_px = cam.focal * 0.5 / d * S / 2
    lo, hi = S / 2 - half_px, S / 2 + half_px
    cols = sum(1 for k in range(S) if lo <= k + 0.5 <= hi)
    sil = out.silhouette[0]
    assert int(sil.sum()) == cols * cols
    covered = out.face_index[0] >= 0
    colours = out.normals[0].permute(1, 2, 0)[covered]
    _assert_close(colours, torch.tensor([0.5, 0.5, 1.0]).expand_as(colours), NORMAL_ATOL_F32, "front colour")
    assert abs(float(out.depth[0, S // 2, S // 2]) - d) < 1e-5
    assert bool((out.normals[0][:, ~covered] == 0).all()) and bool(torch.isinf(out.depth[0][~covered]).all())


def test_backface_culling_removes_exactly_the_back_faces():
    m = icosphere(2)
    v = torch.tensor(np.array(m.vertices), dtype=torch.float64)[None].repeat(3, 1, 1)
    f = torch.tensor(np.array(m.faces))
    cams_l = [look_at(a, e) for a, e in ((10, 20), (200, -35), (95, 60))]
    cams = cameras_to_tensor(cams_l, dtype=torch.float64)
    plain = rasterize(v, f, cams, 32)
    culled = rasterize(v, f, cams, 32, cull_backfaces=True)
    assert torch.equal(plain.face_index, culled.face_index)  # convex: culling changes nothing visible
    # reversed winding: every formerly front face is culled, only the far (formerly back) faces remain
    inside_out = rasterize(v, f.flip(1), cams, 32, cull_backfaces=True)
    for b, cam in enumerate(cams_l):
        p_cam = np.array(m.vertices, dtype=np.float64) @ cam.R.T + cam.t
        centre = p_cam[np.array(m.faces)].mean(1)
        n = face_normals(p_cam, np.array(m.faces))
        front = (n * centre).sum(1) < 0  # normal towards the camera at the origin
        seen = inside_out.face_index[b][inside_out.face_index[b] >= 0].unique().numpy()
        assert len(seen) > 0 and not front[seen].any()
        seen_plain = plain.face_index[b][plain.face_index[b] >= 0].unique().numpy()
        assert front[seen_plain].all()


# ---- outputs, chunking, numpy wrapper ------------------------------------------------------


def test_output_shapes_dtypes_and_detached_indices():
    v, f, cams = _ico_scene(2, level=1, B=2)
    v = v.float().requires_grad_()
    out = rasterize(v, f, cams.float(), 16, shading="smooth")
    assert out.normals.shape == (2, 3, 16, 16) and out.normals.dtype == torch.float32
    assert out.silhouette.shape == (2, 16, 16) and out.depth.shape == (2, 16, 16)
    assert out.face_index.shape == (2, 16, 16) and out.face_index.dtype == torch.int64
    assert out.normals.requires_grad and out.silhouette.requires_grad
    assert not out.depth.requires_grad and not out.face_index.requires_grad
    assert torch.equal(out.silhouette.detach() > 0.5, out.face_index >= 0)
    single = rasterize(v[:1], f, cams[0].float(), 16, shading="smooth")  # (16,) camera broadcasts
    assert torch.equal(single.face_index[0], out.face_index[0])


def test_chunked_rasterization_matches_unchunked():
    m = icosphere(3)
    v = torch.tensor(np.array(m.vertices), dtype=torch.float64)[None].repeat(2, 1, 1)
    f = torch.tensor(np.array(m.faces))
    cams = cameras_to_tensor([look_at(30, 20), look_at(-60, -10, distance=1.2)], dtype=torch.float64)
    _, screen, inv_w, valid = R.project_vertices(v, cams, 48)
    a = R._rasterize_fragments(screen, inv_w, valid, f, 48, False)
    b = R._rasterize_fragments(screen, inv_w, valid, f, 48, False, max_candidates=500)
    assert torch.equal(a[0], b[0]) and torch.equal(a[1], b[1])
    # big faces (the general, non-bucketed path) chunked too: a cube filling most of the image
    cube = _cube()
    cams = cameras_to_tensor([look_at(25, 20, distance=1.6)], dtype=torch.float64)
    _, screen, inv_w, valid = R.project_vertices(torch.tensor(cube.vertices, dtype=torch.float64)[None], cams, 64)
    cf = torch.tensor(cube.faces)
    a = R._rasterize_fragments(screen, inv_w, valid, cf, 64, False)
    b = R._rasterize_fragments(screen, inv_w, valid, cf, 64, False, max_candidates=300)
    assert int((a[0] >= 0).sum()) > 1500
    assert torch.equal(a[0], b[0]) and torch.equal(a[1], b[1])


def test_render_normals_numpy_matches_rasterize():
    m = icosphere(2)
    cam = look_at(40, 25)
    res = render_normals_numpy(m, cam, 24, shading="smooth")
    assert res["normals"].shape == (24, 24, 3) and res["normals"].dtype == np.float32
    assert res["silhouette"].dtype == bool and res["face_index"].dtype == np.int64
    out = rasterize(
        torch.tensor(np.array(m.vertices), dtype=torch.float64)[None], torch.tensor(np.array(m.faces)),
        cameras_to_tensor([cam], dtype=torch.float64), 24, shading="smooth",
    )
    assert np.array_equal(res["face_index"], out.face_index[0].numpy())
    np.testing.assert_allclose(res["normals"], out.normals[0].permute(1, 2, 0).numpy(), atol=1e-6)
    assert np.array_equal(res["silhouette"], res["face_index"] >= 0)
    # encoded normals of visible faces decode to unit vectors facing the camera
    n = res["normals"][res["silhouette"]] * 2 - 1
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-5)
    assert (n[:, 2] > -1e-6).mean() > 0.99
    with pytest.raises(ValueError, match="Mesh"):
        render_normals_numpy("mesh.obj", cam, 24)


def test_cameras_to_tensor_layout():
    cams = [look_at(10, 20), view_camera(2.0, (0.1, -0.2))]
    t = cameras_to_tensor(cams, dtype=torch.float64)
    assert t.shape == (2, 16)
    for row, cam in zip(t, cams):
        assert np.array_equal(row.numpy(), cam.to_array())
    with pytest.raises(ValueError, match="Camera"):
        cameras_to_tensor([])


def test_matches_engine_projection():
    """Pixel coordinates agree with engine.camera.project + ndc_to_pixel (the conventions' owner)."""
    from engine.camera import ndc_to_pixel, project

    m = icosphere(1)
    cam = look_at(33, -12)
    uv, _ = project(m.vertices, cam)
    expected = ndc_to_pixel(uv, 40)
    _, screen, _, _ = R.project_vertices(
        torch.tensor(np.array(m.vertices), dtype=torch.float64)[None], cameras_to_tensor([cam], dtype=torch.float64), 40
    )
    np.testing.assert_allclose(screen[0].numpy(), expected, atol=1e-9)
    assert math.isfinite(float(screen.sum()))


def test_dense_baseline_matches_fast_path():
    from training.render.dense import dense_rasterize

    v, f, cams = _ico_scene(4, level=2, B=2)
    for cull in (False, True):
        a = rasterize(v, f, cams, 20, cull_backfaces=cull)
        b = dense_rasterize(v, f, cams, 20, cull_backfaces=cull)
        assert torch.equal(a.face_index, b.face_index) and torch.equal(a.depth, b.depth)


def test_bench_renderer_cli_writes_records(tmp_path, capsys):
    import json

    from sketchmesh.cli import main

    out = tmp_path / "bench.json"
    rc = main(["bench", "renderer", "--resolutions", "8", "--batches", "2", "--repeats", "1", "--in-process",
               "--dense-max-mb", "100", "--json", str(out)])
    assert rc == 0
    records = json.loads(out.read_text())
    assert len(records) == 1
    r = records[0]
    for key in ("resolution", "batch", "forward_ms", "forward_backward_ms", "peak_mb", "silhouette_iou_error",
                "normal_error", "dense_forward_backward_ms"):
        assert key in r
    assert r["resolution"] == 8 and r["batch"] == 2
    assert r["forward_ms"] > 0 and 0 <= r["silhouette_iou_error"] <= 1 and r["dense_forward_backward_ms"] > 0
    assert "fwd+bwd" in capsys.readouterr().out
    with pytest.raises(SystemExit) as exc:
        main(["bench", "renderer", "--resolutions", "-4"])
    assert exc.value.code == 2
    capsys.readouterr()
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    rc = main(["bench", "renderer", "--resolutions", "8", "--batches", "1", "--repeats", "1", "--in-process",
               "--dense-max-mb", "0", "--json", str(blocker / "bench.json")])
    assert rc != 0
    err = capsys.readouterr().err.strip().splitlines()  # the progress bar, then one error line
    assert err[-1].startswith("sketchmesh: error: cannot write the benchmark records")


def _facing_square(z: float = 0.0):
    """Two triangles in the plane z = ``z`` facing a look_at(0, 0) camera (on +z), counter-clockwise from it."""
    v = torch.tensor([[-0.3, -0.25, z], [0.3, -0.25, z], [0.3, 0.25, z], [-0.3, 0.25, z]], dtype=torch.float64)
    return v, torch.tensor([[0, 1, 2], [0, 2, 3]])


def test_normal_edges_off_leaves_the_outline_to_the_silhouette():
    """normal_edges=False: the normal image's gradient only orients the surface. Sliding a vertex of a square that
    faces the camera within its plane changes where the outline is, not any face's normal: with the edge gradient
    the normal image pulls it, without it the gradient is exactly 0; the silhouette's gradient is the same either
    way; and tilting a vertex out of the plane moves the covered pixels' normals as finite differences say."""
    S = 32
    cam = cameras_to_tensor([look_at(0.0, 0.0)], dtype=torch.float64)
    v0, f = _facing_square()
    w = torch.linspace(0.2, 1.0, 3 * S * S, dtype=torch.float64).view(1, 3, S, S)  # any fixed weights

    def grads(normal_edges: bool):
        v = v0.clone()[None].requires_grad_(True)
        out = rasterize(v, f, cam, S, normal_edges=normal_edges)
        gn, = torch.autograd.grad((out.normals * w).sum(), v, retain_graph=True)
        gs, = torch.autograd.grad((out.silhouette * w[:, 0]).sum(), v)
        return gn[0], gs[0], out

    gn_on, gs_on, out_on = grads(True)
    gn_off, gs_off, out_off = grads(False)
    torch.testing.assert_close(out_off.normals, out_on.normals, rtol=0, atol=0)  # the same image
    assert gn_on[:, :2].abs().sum() > 0  # Eq. 1 moves the outline for the normal term
    assert float(gn_off[:, :2].abs().max()) < 1e-9 * float(gn_on[:, :2].abs().max())  # in-plane: rounding only
    torch.testing.assert_close(gs_off, gs_on, rtol=0, atol=0)
    # out of the plane: vertex 2's z tilts both faces' normals; pixels that stay covered follow finite differences
    covered = out_off.silhouette[0] > 0.5
    mask = torch.zeros_like(w)
    mask[:, :, covered] = 1.0
    interior = torch.nn.functional.max_pool2d(1.0 - covered.double()[None, None], 3, 1, 1)[0, 0] == 0  # not by an edge
    mask[:, :, ~interior] = 0.0
    v = v0.clone()[None].requires_grad_(True)
    g, = torch.autograd.grad((rasterize(v, f, cam, S, normal_edges=False).normals * w * mask).sum(), v)
    eps = 1e-6
    vals = []
    for sgn in (1.0, -1.0):
        vp = v0.clone()
        vp[2, 2] += sgn * eps
        vals.append(float((rasterize(vp[None], f, cam, S).normals * w * mask).sum()))
    fd = (vals[0] - vals[1]) / (2 * eps)
    assert abs(fd) > 1e-3 and float(g[0, 2, 2]) == pytest.approx(fd, rel=1e-4)
