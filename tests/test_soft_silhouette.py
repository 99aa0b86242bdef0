"""The SoftRas-style soft silhouette (the outside reference of the edge-gradient comparison)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from engine.camera import look_at, view_camera
from engine.icosphere import icosphere
from training.render import cameras_to_tensor, rasterize
from training.render.rasterize import project_vertices
from training.render.soft import reach_px, soft_silhouette

SQUARE_FACES = torch.tensor([[0, 1, 2], [0, 2, 3]])


def _square(cx: float, cy: float, half: float) -> torch.Tensor:
    return torch.tensor([[[cx - half, cy - half, 0.0], [cx + half, cy - half, 0.0],
                          [cx + half, cy + half, 0.0], [cx - half, cy + half, 0.0]]], dtype=torch.float64)


def test_one_triangle_pixel_values_are_the_hand_computed_sigmoids():
    """A pixel outside one triangle gets sigmoid(-d^2 / sigma) with d its distance to the outline
    in NDC units; one inside gets sigmoid(+d^2 / sigma); far pixels are exactly 0."""
    cam = cameras_to_tensor([view_camera(3.0)], dtype=torch.float64)
    S, sigma = 16, 4e-3
    v = _square(0.0, 0.0, 0.1)[:, :3]
    f = torch.tensor([[0, 1, 2]])
    sil = soft_silhouette(v, f, cam, S, sigma=sigma)[0]
    scr = project_vertices(v, cam, S)[1][0].numpy()  # pixel coordinates of the 3 corners
    px_to_ndc = 2.0 / S
    a, b, c = scr
    for (row, col) in [(7, 9), (8, 7), (3, 3), (7, 7)]:
        p = np.array([col + 0.5, row + 0.5])
        dists = []
        for u, w in ((a, b), (b, c), (c, a)):
            t = np.clip(np.dot(p - u, w - u) / np.dot(w - u, w - u), 0, 1)
            dists.append(np.linalg.norm(p - (u + t * (w - u))))
        d = min(dists) * px_to_ndc
        cross = [(w - u)[0] * (p - u)[1] - (w - u)[1] * (p - u)[0] for u, w in ((a, b), (b, c), (c, a))]
        inside = all(x > 0 for x in cross) or all(x < 0 for x in cross)
        x = (d * d if inside else -d * d) / sigma
        expected = 1.0 / (1.0 + math.exp(-x))
        if expected < 1e-4:  # beyond the reach: dropped
            expected = 0.0
        assert float(sil[row, col]) == pytest.approx(expected, abs=1e-12), (row, col)
    assert float(sil[0, 0]) == 0.0


def test_small_sigma_tends_to_the_hard_silhouette():
    mesh = icosphere(2)
    v = torch.tensor(np.asarray(mesh.vertices), dtype=torch.float64)[None] * 0.8
    f = torch.tensor(np.asarray(mesh.faces))
    cam = cameras_to_tensor([look_at(30.0, 20.0)], dtype=torch.float64)
    hard = rasterize(v, f, cam, 32).silhouette[0]
    soft = soft_silhouette(v, f, cam, 32, sigma=1e-7)[0]
    assert torch.equal(soft > 0.5, hard > 0.5)
    assert float((soft - hard).abs().max()) < 0.05  # only pixel centres within ~0.01 px of the outline differ
    assert float((soft - hard).abs().sum()) < 0.01 * float(hard.sum())
    assert reach_px(1e-7, 32) < 0.05


def test_gradient_matches_finite_differences():
    """It is an ordinary smooth function: autograd equals central differences (torch.autograd.gradcheck)."""
    cam = cameras_to_tensor([view_camera(3.0)], dtype=torch.float64)
    v = (_square(0.02, -0.01, 0.12) + 0.01 * torch.randn(1, 4, 3, generator=torch.Generator().manual_seed(0),
                                                          dtype=torch.float64)).requires_grad_()
    w = torch.randn(1, 12, 12, generator=torch.Generator().manual_seed(1), dtype=torch.float64)
    assert torch.autograd.gradcheck(lambda x: (soft_silhouette(x, SQUARE_FACES, cam, 12, sigma=2e-2) * w).sum(), (v,))


def test_iou_gradient_grows_towards_a_disjoint_target():
    """Where the adjacent-pixel Eq. 1 sees nothing (a target 2 px away), a wide soft silhouette pulls."""
    cam = cameras_to_tensor([view_camera(3.0)], dtype=torch.float64)
    target = rasterize(_square(0.45, 0.0, 0.15), SQUARE_FACES, cam, 32).silhouette.detach()
    v = _square(0.0, 0.0, 0.15).requires_grad_()
    sil = soft_silhouette(v, SQUARE_FACES, cam, 32, sigma=5e-3)
    (-(sil * target).sum() / target.sum()).backward()
    assert float(v.grad[0, [1, 2], 0].sum()) < 0  # the right edge moves right


@pytest.mark.parametrize("case", ["degenerate", "behind", "tiny", "huge", "offscreen"])
def test_extreme_inputs_give_finite_values_and_gradients(case):
    cam = cameras_to_tensor([view_camera(3.0)], dtype=torch.float64)
    v = _square(0.0, 0.0, 0.2)
    if case == "degenerate":
        v[0, :, 1] = 0.0  # every face has zero area
    elif case == "behind":
        v[0, :, 2] = 10.0  # behind the camera
    elif case == "tiny":
        v = v * 1e-9
    elif case == "huge":
        v = v * 1e6
        v[0, :, 2] = -1e3
    elif case == "offscreen":
        v[0, :, 0] += 50.0
    v.requires_grad_()
    sil = soft_silhouette(v, SQUARE_FACES, cam, 16)
    sil.sum().backward()
    assert torch.isfinite(sil).all() and torch.isfinite(v.grad).all()
    assert float(sil.detach().min()) >= 0.0 and float(sil.detach().max()) <= 1.0


def test_bad_sigma_and_too_many_pairs_are_refused():
    cam = cameras_to_tensor([view_camera(3.0)], dtype=torch.float64)
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="sigma"):
            soft_silhouette(_square(0, 0, 0.2), SQUARE_FACES, cam, 16, sigma=bad)
    with pytest.raises(ValueError, match="pairs"):
        soft_silhouette(_square(0, 0, 0.2), SQUARE_FACES, cam, 4096, sigma=10.0)
