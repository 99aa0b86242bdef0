"""Losses (paper Eq. 2-6) against naive loops, hand-computed values and finite differences."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
import torch

from engine.icosphere import icosphere
from engine.mesh import Mesh, unique_edges
from training.model.losses import (
    LossWeights,
    MeshLoss,
    dihedral_cosines,
    dihedral_indices,
    dihedral_smoothness_loss,
    edge_loss,
    normal_loss,
    silhouette_iou_loss,
    support_band_weights,
    total_loss,
)

TOL64 = dict(rtol=1e-10, atol=1e-12)
TOL32 = dict(rtol=1e-5, atol=1e-6)


def _close(actual: float, expected: float, rtol: float, atol: float) -> None:
    assert abs(actual - expected) <= atol + rtol * abs(expected), f"got {actual}, expected {expected}, diff {abs(actual - expected)}"


# ---------------------------------------------------------------- naive references


def naive_normal_loss(pred: np.ndarray, target: np.ndarray) -> float:
    total = 0.0
    for b in range(pred.shape[0]):
        s = 0.0
        for c, i, j in itertools.product(*(range(n) for n in pred.shape[1:])):
            s += abs(pred[b, c, i, j] - target[b, c, i, j])
        total += s
    return total / pred.shape[0]


def naive_iou_loss(pred: np.ndarray, target: np.ndarray, eps: float = 1e-6) -> float:
    out = []
    for p, t in zip(pred, target):
        inter = sum(float(x * y) for x, y in zip(p.ravel(), t.ravel()))
        union = sum(float(x + y - x * y) for x, y in zip(p.ravel(), t.ravel()))
        out.append(1.0 - (inter + eps) / (union + eps))
    return sum(out) / len(out)


def naive_edge_loss(verts: np.ndarray, template: np.ndarray, faces: np.ndarray) -> float:
    edges = set()
    for f in faces:
        for a, b in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0])):
            edges.add((min(a, b), max(a, b)))
    total = 0.0
    for v in verts:
        s = 0.0
        for a, b in edges:
            s += abs(math.dist(v[a], v[b]) - math.dist(template[a], template[b]))
        total += s / len(edges)
    return total / len(verts)


def naive_dihedral_loss(verts: np.ndarray, faces: np.ndarray) -> float:
    """Brute-force pairs (faces sharing two vertices); cos of the interior dihedral = -n_i . n_j."""
    total = 0.0
    for v in verts:
        s = 0.0
        for i in range(len(faces)):
            for j in range(i + 1, len(faces)):
                if len(set(faces[i]) & set(faces[j])) != 2:
                    continue
                ni = np.cross(v[faces[i][1]] - v[faces[i][0]], v[faces[i][2]] - v[faces[i][0]])
                nj = np.cross(v[faces[j][1]] - v[faces[j][0]], v[faces[j][2]] - v[faces[j][0]])
                cos = -float(ni @ nj) / (np.linalg.norm(ni) * np.linalg.norm(nj))
                s += (1.0 + cos) ** 2
        total += s
    return total / len(verts)


def _random_sphere_batch(rng: np.random.Generator, batch: int, level: int = 1, noise: float = 0.05):
    mesh = icosphere(level)
    v = mesh.vertices.astype(np.float64)[None] + noise * rng.standard_normal((batch, mesh.num_vertices, 3))
    return mesh, v


# ---------------------------------------------------------------- Eq. 2


def test_normal_loss_matches_naive_sum_and_mean():
    rng = np.random.default_rng(0)
    pred, target = rng.random((2, 3, 5, 4)), rng.random((2, 3, 5, 4))
    got = normal_loss(torch.from_numpy(pred), torch.from_numpy(target))
    _close(float(got), naive_normal_loss(pred, target), **TOL64)
    got_mean = normal_loss(torch.from_numpy(pred), torch.from_numpy(target), reduction="mean")
    _close(float(got_mean), naive_normal_loss(pred, target) / (3 * 5 * 4), **TOL64)


def test_normal_loss_mask_keeps_only_masked_pixels():
    pred, target = torch.zeros(1, 3, 2, 2), torch.zeros(1, 3, 2, 2)
    pred[0, :, 0, 0] = torch.tensor([0.5, 0.25, 0.0])  # 0.75 inside the mask
    pred[0, :, 1, 1] = 1.0  # 3.0 outside
    mask = torch.tensor([[[1.0, 1.0], [0.0, 0.0]]])
    assert float(normal_loss(pred, target)) == pytest.approx(3.75)
    assert float(normal_loss(pred, target, mask=mask)) == pytest.approx(0.75)
    with pytest.raises(ValueError, match="mask"):
        normal_loss(pred, target, mask=torch.ones(1, 3, 3))


def test_mesh_loss_target_region_ignores_pixels_outside_the_target():
    mesh = icosphere(1)
    x = torch.from_numpy(mesh.vertices.copy())[None].float()
    target_sil = torch.zeros(1, 4, 4)
    target_sil[0, :2] = 1.0  # target covers the top half
    target_n = target_sil[:, None].expand(1, 3, 4, 4) * 0.5
    pred_n = torch.full((1, 3, 4, 4), 0.5)  # covers everything with the target's normal
    scale = 64 * 64 / 16
    image = MeshLoss(mesh)
    target = MeshLoss(mesh, normal_region="target")
    _, log_i = image(x, pred_n, target_n, torch.ones(1, 4, 4), target_sil)
    _, log_t = target(x, pred_n, target_n, torch.ones(1, 4, 4), target_sil)
    assert log_i["normal"] == pytest.approx(8 * 1.5 * scale)  # 8 over-covered pixels at 3 x 0.5
    assert log_t["normal"] == 0.0  # over-coverage is left to the IoU term
    # an uncovered target pixel still costs its full encoded normal
    _, log_u = target(x, torch.zeros(1, 3, 4, 4), target_n, torch.zeros(1, 4, 4), target_sil)
    assert log_u["normal"] == pytest.approx(8 * 1.5 * scale)
    with pytest.raises(ValueError, match="normal_region"):
        MeshLoss(mesh, normal_region="both")
    with pytest.raises(ValueError, match="target silhouette"):
        target(x, pred_n, target_n)


def test_normal_loss_rejects_bad_shapes_and_reduction():
    a = torch.zeros(1, 3, 4, 4)
    with pytest.raises(ValueError, match=r"got \(1, 3, 4, 4\) and \(1, 3, 4, 5\)"):
        normal_loss(a, torch.zeros(1, 3, 4, 5))
    with pytest.raises(ValueError, match="3 channels"):
        normal_loss(torch.zeros(1, 1, 4, 4), torch.zeros(1, 1, 4, 4))
    with pytest.raises(ValueError, match="reduction"):
        normal_loss(a, a, reduction="max")


# ---------------------------------------------------------------- Eq. 3


def test_iou_loss_matches_naive():
    rng = np.random.default_rng(1)
    pred, target = rng.random((3, 6, 5)), (rng.random((3, 6, 5)) > 0.5).astype(np.float64)
    got = silhouette_iou_loss(torch.from_numpy(pred), torch.from_numpy(target))
    _close(float(got), naive_iou_loss(pred, target), **TOL64)


def test_iou_loss_two_known_rectangles():
    # rectangle A: rows 2..5, cols 2..9 (4 x 8 = 32 px); B: rows 4..7, cols 6..11 (4 x 6 = 24 px)
    a = torch.zeros(1, 10, 12, dtype=torch.float64)
    b = torch.zeros_like(a)
    a[0, 2:6, 2:10] = 1
    b[0, 4:8, 6:12] = 1
    inter = 2 * 4  # rows 4..5, cols 6..9
    union = 32 + 24 - inter
    _close(float(silhouette_iou_loss(a, b)), 1.0 - inter / union, rtol=1e-6, atol=1e-7)
    _close(float(silhouette_iou_loss(a, a)), 0.0, rtol=0, atol=1e-12)
    c = torch.zeros_like(a)
    c[0, 0, 0] = 1
    _close(float(silhouette_iou_loss(a, c)), 1.0, rtol=0, atol=1e-6)  # disjoint


def test_iou_loss_empty_silhouettes_are_zero_with_finite_gradient():
    pred = torch.zeros(2, 8, 8, requires_grad=True)
    loss = silhouette_iou_loss(pred, torch.zeros(2, 8, 8))
    loss.backward()
    assert loss.item() == 0.0
    assert torch.isfinite(pred.grad).all()
    # one empty, the other not: maximal loss, finite gradient
    pred2 = torch.zeros(1, 8, 8, requires_grad=True)
    target = torch.zeros(1, 8, 8)
    target[0, 2:4, 2:4] = 1
    loss2 = silhouette_iou_loss(pred2, target)
    loss2.backward()
    _close(loss2.item(), 1.0, rtol=0, atol=1e-6)
    assert torch.isfinite(pred2.grad).all() and float(pred2.grad[0, 2, 2]) < 0  # growing into the target helps


def test_support_band_weights_mark_the_lowest_quarter_of_the_covered_rows():
    # a "table" covering rows 2..9 (8 rows): its lowest quarter is rows 8 and 9, every column of them
    t = torch.zeros(2, 12, 6)
    t[0, 2:4, :] = 1  # top
    t[0, 4:10, 0] = t[0, 4:10, 5] = 1  # two legs down to row 9
    w = support_band_weights(t, 3.0)
    expected = torch.ones(12)
    expected[8:10] = 4.0
    assert torch.equal(w[0], expected[:, None].expand(12, 6))
    assert torch.equal(w[1], torch.ones(12, 6))  # empty target: no band
    # a one-row silhouette is its own band; band 1 weights every covered row's span
    one = torch.zeros(1, 5, 5)
    one[0, 3, 1:3] = 1
    assert torch.equal(support_band_weights(one, 1.0)[0].sum(1), torch.tensor([5.0, 5, 5, 10, 5]))
    assert torch.equal(support_band_weights(t[:1], 1.0, band=1.0)[0, :, 0], torch.tensor([1.0, 1] + [2.0] * 8 + [1, 1]))
    assert torch.equal(support_band_weights(t, 0.0), torch.ones_like(t))
    for bad in (-1.0, float("nan"), float("inf"), True):
        with pytest.raises(ValueError, match="gain"):
            support_band_weights(t, bad)
    for bad in (0.0, 1.5, float("nan")):
        with pytest.raises(ValueError, match="band"):
            support_band_weights(t, 1.0, band=bad)


def test_weighted_iou_loss_counts_weighted_pixels_and_has_exact_gradients():
    # hand count: target 4 px in row 0 (weight 1) and 4 px in row 3 (weight 5); the prediction covers the row-0 pixels
    # and one of row 3: I = 4 + 5, U = 4 + 4 * 5 (eps, 1e-6 px, moves it by about 3e-8)
    target = torch.zeros(1, 4, 4, dtype=torch.float64)
    target[0, 0] = target[0, 3] = 1
    pred = torch.zeros_like(target)
    pred[0, 0] = 1
    pred[0, 3, 0] = 1
    weight = torch.ones_like(target)
    weight[0, 3] = 5.0
    _close(float(silhouette_iou_loss(pred, target, weight=weight)), 1.0 - 9.0 / 24.0, rtol=1e-6, atol=1e-7)
    # weights of one are Eq. 3; a scalar multiple of the weights changes nothing
    rng = np.random.default_rng(3)
    p = torch.from_numpy(rng.random((2, 7, 5))).requires_grad_(True)
    q = torch.from_numpy((rng.random((2, 7, 5)) > 0.5).astype(np.float64))
    w = torch.from_numpy(1.0 + 3.0 * rng.random((2, 7, 5)))
    d = p.detach()
    _close(float(silhouette_iou_loss(d, q, weight=torch.ones_like(q))), float(silhouette_iou_loss(d, q)), **TOL64)
    # (up to eps, which does not scale with the weights)
    _close(float(silhouette_iou_loss(d, q, weight=7 * w)), float(silhouette_iou_loss(d, q, weight=w)), rtol=1e-6, atol=1e-7)
    # autograd against central differences, every pixel
    loss = silhouette_iou_loss(p, q, weight=w)
    (grad,) = torch.autograd.grad(loss, p)
    h = 1e-6
    numeric = torch.zeros_like(grad)
    with torch.no_grad():
        for idx in itertools.product(*(range(n) for n in p.shape)):
            up, down = p.clone(), p.clone()
            up[idx] += h
            down[idx] -= h
            numeric[idx] = (silhouette_iou_loss(up, q, weight=w) - silhouette_iou_loss(down, q, weight=w)) / (2 * h)
    assert torch.allclose(grad, numeric, rtol=1e-6, atol=1e-9)
    with pytest.raises(ValueError, match="weight"):
        silhouette_iou_loss(p, q, weight=torch.ones(2, 7))


def test_mesh_loss_support_band_weight_reaches_the_silhouette_term():
    mesh = icosphere(1, 0.5)
    v = torch.from_numpy(mesh.vertices.astype(np.float32))[None]
    pred = torch.zeros(1, 8, 8)
    pred[0, 1:6, 2:6] = 1  # a skirt: covers the gap between the legs, misses nothing else
    target = torch.zeros(1, 8, 8)
    target[0, 1:4, 2:6] = 1
    target[0, 4:6, 2] = target[0, 4:6, 5] = 1  # rows 1..5; its band is rows 4 and 5
    plain = MeshLoss(mesh)(v, pred_silhouette=pred, target_silhouette=target)[1]["silhouette"]
    weighted = MeshLoss(mesh, support_band_weight=3.0)(v, pred_silhouette=pred, target_silhouette=target)[1]["silhouette"]
    _close(plain, 1.0 - 16.0 / 20.0, rtol=1e-6, atol=1e-7)  # 4 gap pixels of 20
    _close(weighted, 1.0 - (12.0 + 4 * 4.0) / (12.0 + 8 * 4.0), rtol=1e-6, atol=1e-7)  # the gap weighs 4x
    with pytest.raises(ValueError, match="support_band_weight"):
        MeshLoss(mesh, support_band_weight=-1.0)


# ---------------------------------------------------------------- Eq. 4


def test_edge_loss_matches_naive():
    rng = np.random.default_rng(2)
    mesh, v = _random_sphere_batch(rng, 2)
    edges = torch.from_numpy(unique_edges(mesh.faces))
    t = mesh.vertices.astype(np.float64)
    lengths = torch.from_numpy(np.linalg.norm(t[edges[:, 1]] - t[edges[:, 0]], axis=1))
    got = edge_loss(torch.from_numpy(v), edges, lengths)
    _close(float(got), naive_edge_loss(v, t, mesh.faces), **TOL64)


def test_edge_loss_coincident_vertices_finite():
    mesh = icosphere(1)
    loss_module = MeshLoss(mesh)
    v = torch.zeros(1, mesh.num_vertices, 3, requires_grad=True)  # every vertex at the origin
    loss = edge_loss(v, loss_module.edges, loss_module.template_lengths)
    loss.backward()
    _close(loss.item(), float(loss_module.template_lengths.mean()), **TOL32)
    assert torch.isfinite(v.grad).all()


def test_edge_loss_rejects_bad_input():
    v = torch.zeros(1, 4, 3)
    with pytest.raises(ValueError, match=r"vertices \(B, V, 3\), got \(4, 3\)"):
        edge_loss(torch.zeros(4, 3), torch.zeros(1, 2, dtype=torch.int64), torch.zeros(1))
    with pytest.raises(ValueError, match=r"in \[0, 4\)"):
        edge_loss(v, torch.tensor([[0, 7]]), torch.zeros(1))
    with pytest.raises(ValueError, match="template_lengths"):
        edge_loss(v, torch.tensor([[0, 1]]), torch.zeros(3))


# ---------------------------------------------------------------- Eq. 5


def _two_triangles(fold_deg: float) -> tuple[torch.Tensor, np.ndarray]:
    """Triangles (0, 1, 2) and (1, 0, 3) sharing edge 0-1 on the x axis; interior angle fold_deg."""
    th = math.radians(fold_deg)
    v = torch.tensor(
        [[[0.0, 0, 0], [1.0, 0, 0], [0.5, 1.0, 0], [0.5, math.cos(th), math.sin(th)]]], dtype=torch.float64
    )
    faces = np.array([[0, 1, 2], [1, 0, 3]])
    return v, faces


@pytest.mark.parametrize("fold_deg, expected", [(180.0, 0.0), (90.0, 1.0), (60.0, 2.25), (120.0, 0.25)])
def test_dihedral_hand_computed(fold_deg, expected):
    v, faces = _two_triangles(fold_deg)
    quads = torch.from_numpy(dihedral_indices(faces))
    assert quads.shape == (1, 4)
    _close(float(dihedral_smoothness_loss(v, quads)), expected, rtol=1e-7, atol=1e-8)


def test_dihedral_indices_shape_and_content():
    mesh = icosphere(1)
    quads = dihedral_indices(mesh.faces)
    assert quads.shape == (len(unique_edges(mesh.faces)), 4)  # closed manifold: one pair per edge
    faces = [set(f) for f in mesh.faces.tolist()]
    for a, b, c0, c1 in quads.tolist():
        assert {a, b, c0} in faces and {a, b, c1} in faces and c0 != c1


def test_dihedral_matches_naive_on_random_meshes():
    rng = np.random.default_rng(3)
    mesh, v = _random_sphere_batch(rng, 2, level=1, noise=0.08)
    quads = torch.from_numpy(dihedral_indices(mesh.faces))
    got = dihedral_smoothness_loss(torch.from_numpy(v), quads, eps=0.0)
    _close(float(got), naive_dihedral_loss(v, mesh.faces), rtol=1e-9, atol=1e-12)
    # the default eps changes the value only negligibly on a well-shaped mesh
    _close(float(dihedral_smoothness_loss(torch.from_numpy(v), quads)), float(got), rtol=1e-6, atol=1e-9)


def test_dihedral_scale_invariant_and_stable():
    rng = np.random.default_rng(4)
    mesh, v = _random_sphere_batch(rng, 1, level=1)
    quads = torch.from_numpy(dihedral_indices(mesh.faces))
    ref = float(dihedral_smoothness_loss(torch.from_numpy(v), quads))
    for scale in (1e-6, 1e6):
        for dtype, tol in ((torch.float64, 1e-9), (torch.float32, 1e-4)):
            x = (torch.from_numpy(v) * scale).to(dtype).requires_grad_(True)
            loss = dihedral_smoothness_loss(x, quads)
            loss.backward()
            _close(loss.item(), ref, rtol=tol, atol=tol)
            assert torch.isfinite(x.grad).all(), f"non-finite gradient at scale {scale} {dtype}"


def test_dihedral_degenerate_faces_and_coincident_vertices_finite():
    mesh = icosphere(1)
    quads = torch.from_numpy(dihedral_indices(mesh.faces))
    # all vertices coincident
    v = torch.zeros(1, mesh.num_vertices, 3, requires_grad=True)
    loss = dihedral_smoothness_loss(v, quads)
    loss.backward()
    assert torch.isfinite(loss) and torch.isfinite(v.grad).all()
    # two vertices coincident and one face collapsed to a line
    w = torch.from_numpy(mesh.vertices.astype(np.float32)).clone()[None]
    a, b, c = mesh.faces[0]
    w[0, b] = w[0, a]
    w[0, c] = 0.5 * (w[0, a] + w[0, c])
    w.requires_grad_(True)
    loss = dihedral_smoothness_loss(w, quads)
    loss.backward()
    assert torch.isfinite(loss) and torch.isfinite(w.grad).all()
    cos = dihedral_cosines(w.detach(), quads)
    assert float(cos.min()) >= -1.0 and float(cos.max()) <= 1.0
    # planar degenerate pair: opposite vertex on the shared edge line
    v2, faces = _two_triangles(90.0)
    v2 = v2.clone()
    v2[0, 2] = torch.tensor([0.5, 0.0, 0.0], dtype=torch.float64)
    v2.requires_grad_(True)
    loss = dihedral_smoothness_loss(v2, torch.from_numpy(dihedral_indices(faces)))
    loss.backward()
    assert torch.isfinite(loss) and torch.isfinite(v2.grad).all()


# ---------------------------------------------------------------- gradients (float64 finite differences)


def test_gradcheck_smooth_parts():
    rng = np.random.default_rng(5)
    mesh, v = _random_sphere_batch(rng, 2, level=0, noise=0.05)
    quads = torch.from_numpy(dihedral_indices(mesh.faces))
    edges = torch.from_numpy(unique_edges(mesh.faces))
    lengths = torch.from_numpy(rng.random(len(edges)) * 0.1)  # far from the current lengths: |.| is smooth there
    x = torch.from_numpy(v).requires_grad_(True)
    assert torch.autograd.gradcheck(lambda t: dihedral_smoothness_loss(t, quads), (x,), eps=1e-6, atol=1e-6)
    assert torch.autograd.gradcheck(lambda t: edge_loss(t, edges, lengths), (x,), eps=1e-6, atol=1e-6)
    p = torch.from_numpy(rng.random((2, 5, 4))).requires_grad_(True)
    s = torch.from_numpy(rng.random((2, 5, 4)))
    assert torch.autograd.gradcheck(lambda t: silhouette_iou_loss(t, s), (p,), eps=1e-6, atol=1e-6)
    n = torch.from_numpy(rng.random((1, 3, 3, 3))).requires_grad_(True)
    m = torch.from_numpy(rng.random((1, 3, 3, 3)))
    assert torch.autograd.gradcheck(lambda t: normal_loss(t, m), (n,), eps=1e-6, atol=1e-6)


# ---------------------------------------------------------------- Eq. 6


def test_loss_weights_validation_and_defaults():
    w = LossWeights()
    assert (w.normal, w.silhouette, w.edge, w.smoothness) == (0.002, 0.9, 0.9, 0.01)
    for bad in (-1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="normal"):
            LossWeights(normal=bad)


def test_mesh_loss_equals_weighted_sum_and_is_resolution_invariant():
    rng = np.random.default_rng(6)
    mesh, v = _random_sphere_batch(rng, 2, level=1)
    weights = LossWeights(normal=0.3, silhouette=0.7, edge=1.1, smoothness=0.05)
    module = MeshLoss(mesh, weights)
    x = torch.from_numpy(v).float()
    pn, tn = torch.rand(2, 3, 16, 16), torch.rand(2, 3, 16, 16)
    ps, ts = torch.rand(2, 16, 16), (torch.rand(2, 16, 16) > 0.5).float()
    total, log = module(x, pn, tn, ps, ts)
    expected = (
        0.3 * float(normal_loss(pn, tn)) * (64 * 64) / (16 * 16)
        + 0.7 * float(silhouette_iou_loss(ps, ts))
        + 1.1 * float(edge_loss(x, module.edges, module.template_lengths))
        + 0.05 * float(dihedral_smoothness_loss(x, module.quads))
    )
    _close(total.item(), expected, rtol=1e-5, atol=1e-6)
    assert set(log) == {"normal", "silhouette", "edge", "smoothness", "total"}
    assert all(isinstance(val, float) for val in log.values())
    # a constant error of 0.1 per value gives the same normal term at 16 x 16 and 32 x 32
    _, log16 = module(x, torch.full((2, 3, 16, 16), 0.1), torch.zeros(2, 3, 16, 16))
    _, log32 = module(x, torch.full((2, 3, 32, 32), 0.1), torch.zeros(2, 3, 32, 32))
    _close(log16["normal"], log32["normal"], rtol=1e-5, atol=0)
    _close(log16["normal"], 0.1 * 3 * 64 * 64, rtol=1e-5, atol=0)


def test_mesh_loss_template_has_zero_edge_loss_and_small_smoothness():
    mesh = icosphere(3)
    module = MeshLoss(mesh)
    x = torch.from_numpy(mesh.vertices.copy())[None]
    _, log = module(x)
    assert log["edge"] < 1e-6
    # the level-3 icosphere is nearly flat between neighbours: each pair bends by ~8-12 degrees
    assert 0 < log["smoothness"] < 1920 * (1 - math.cos(math.radians(15))) ** 2
    with pytest.raises(ValueError, match="642 vertices"):
        module(torch.zeros(1, 12, 3))


@pytest.mark.parametrize("weight", [0.0, 1e6])
def test_extreme_weights_stay_finite(weight):
    mesh = icosphere(1)
    module = MeshLoss(mesh, LossWeights(weight, weight, weight, weight))
    x = torch.zeros(1, mesh.num_vertices, 3, requires_grad=True)  # collapsed mesh: the worst case
    pn = torch.zeros(1, 3, 8, 8, requires_grad=True)
    ps = torch.zeros(1, 8, 8, requires_grad=True)
    total, log = module(x, pn, torch.ones(1, 3, 8, 8), ps, torch.zeros(1, 8, 8))
    total.backward()
    assert math.isfinite(total.item()) and all(math.isfinite(v) for v in log.values())
    for t in (x, pn, ps):
        assert t.grad is None or torch.isfinite(t.grad).all()


def test_total_loss_rejects_unknown_terms():
    with pytest.raises(ValueError, match="unknown loss terms"):
        total_loss({"bogus": torch.tensor(1.0)}, LossWeights())
    with pytest.raises(TypeError):
        MeshLoss("not a mesh")  # type: ignore[arg-type]
    assert isinstance(Mesh(np.zeros((3, 3)), np.array([[0, 1, 2]])), Mesh)
