"""Stiff and extreme inputs for the rasterizer: outputs and gradients stay finite, or a clear
ValueError names the problem."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from engine.camera import NEAR, Camera, look_at, view_camera
from engine.icosphere import icosphere
from training.render import cameras_to_tensor, rasterize

torch.set_num_threads(min(2, torch.get_num_threads()))


def _run(v, f, cams, size=16, **kw):
    """Render, back-propagate an L1 + silhouette loss, return (output, vertex gradient)."""
    v = v.clone().requires_grad_()
    out = rasterize(v, f, cams, size, **kw)
    g = torch.Generator().manual_seed(0)
    target = torch.rand(out.normals.shape, generator=g, dtype=out.normals.dtype)
    loss = (out.normals - target).abs().mean() + (1 - out.silhouette).mean()
    loss.backward()
    return out, v.grad


def _assert_finite(out, grad):
    assert torch.isfinite(out.normals).all() and torch.isfinite(out.silhouette).all()
    covered = out.face_index >= 0
    assert torch.isfinite(out.depth[covered]).all() and torch.isinf(out.depth[~covered]).all()
    assert torch.equal(out.silhouette.detach() > 0.5, covered)
    assert bool((out.normals.detach().permute(0, 2, 3, 1)[~covered] == 0).all())
    assert grad is None or torch.isfinite(grad).all(), "non-finite gradient"


def _sphere(dtype=torch.float32, B=1):
    m = icosphere(1)
    return torch.tensor(np.array(m.vertices), dtype=dtype)[None].repeat(B, 1, 1), torch.tensor(np.array(m.faces))


# ---- degenerate geometry -------------------------------------------------------------------


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_zero_area_and_edge_on_faces_are_dropped_and_finite(dtype):
    v = torch.tensor([[
        [-0.3, -0.3, 0.0], [0.3, -0.3, 0.0], [0.0, 0.3, 0.0],  # a proper triangle
        [-0.2, 0.0, 0.1], [0.0, 0.0, 0.1], [0.2, 0.0, 0.1],  # collinear
        [0.0, -0.4, -0.2], [0.0, 0.4, 0.2], [0.0, 0.0, 0.4],  # plane x = 0: edge-on to the camera on +z
    ]], dtype=dtype)
    f = torch.tensor([[0, 1, 2], [3, 4, 5], [3, 3, 4], [6, 7, 8], [2, 2, 2]])
    for shading in ("flat", "smooth"):
        out, grad = _run(v, f, cameras_to_tensor([view_camera(3.0)], dtype=dtype), 24, shading=shading)
        _assert_finite(out, grad)
        assert set(out.face_index[out.face_index >= 0].unique().tolist()) == {0}


def test_sliver_triangles_finite():
    """Extremely thin but non-degenerate faces: finite normals and gradients."""
    v = torch.tensor([[[-0.5, 0.0, 0.0], [0.5, 1e-7, 0.0], [0.5, -1e-7, 1e-9], [0.0, 0.3, 0.0]]], dtype=torch.float32)
    f = torch.tensor([[0, 1, 2], [0, 2, 3], [0, 1, 3]])
    out, grad = _run(v, f, cameras_to_tensor([view_camera(3.0)]), 32, shading="smooth")
    _assert_finite(out, grad)


# ---- near plane ---------------------------------------------------------------------------


def test_vertices_on_and_behind_the_near_plane():
    # camera at the origin looking down -z: depth = -z
    cam = cameras_to_tensor([Camera(np.eye(3), np.zeros(3), 1.0)], dtype=torch.float64)
    v = torch.tensor([[
        [-0.5, -0.5, -2.0], [0.5, -0.5, -2.0], [0.0, 0.5, -2.0],  # in front
        [-0.5, 0.5, 1.0], [0.5, 0.5, 1.0],  # behind the camera
        [0.0, -0.5, -NEAR],  # exactly on the near plane
        [0.2, 0.2, 0.0],  # at the camera centre (w = 0)
    ]], dtype=torch.float64)
    f = torch.tensor([[0, 1, 2], [0, 1, 3], [3, 4, 2], [0, 5, 2], [6, 0, 1], [5, 6, 4]])
    for shading in ("flat", "smooth"):
        out, grad = _run(v, f, cam, 16, shading=shading)
        _assert_finite(out, grad)
        assert set(out.face_index[out.face_index >= 0].unique().tolist()) == {0}
        if shading == "flat":  # smooth vertex normals legitimately average in the dropped faces
            assert torch.all(grad[0, 3:] == 0)  # dropped vertices get exactly zero gradient


def test_camera_inside_the_mesh():
    v, f = _sphere(torch.float64)
    out, grad = _run(v, f, cameras_to_tensor([view_camera(3.0, distance=0.1)], dtype=torch.float64), 16)
    _assert_finite(out, grad)


# ---- scales ---------------------------------------------------------------------------------


@pytest.mark.parametrize("scale", [1e-4, 1e-2, 1.0, 1e2, 1e4])
@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_scale_mesh_and_camera_together(scale, dtype):
    """Scaling the world uniformly gives the same image (up to a few rounding-sensitive pixels)."""
    v, f = _sphere(dtype)
    base = rasterize(v, f, cameras_to_tensor([look_at(20, 15)], dtype=dtype), 24)
    cam = look_at(20, 15, distance=2.732 * scale)
    out, grad = _run(v * scale, f, cameras_to_tensor([cam], dtype=dtype), 24)
    _assert_finite(out, grad)
    if 2.732 * scale - 0.5 * scale <= NEAR:
        # the whole scene is nearer than the absolute near plane (engine.camera.NEAR): empty image
        assert int((out.face_index >= 0).sum()) == 0 and torch.all(grad == 0)
        return
    assert float(grad.abs().max()) > 0
    differ = int((out.face_index != base.face_index).sum())
    assert differ <= 3, f"{differ} pixels changed face at scale {scale}"
    both = (out.face_index >= 0) & (base.face_index >= 0)
    assert torch.allclose(out.normals.detach()[:, :, both[0]], base.normals[:, :, both[0]], atol=1e-3)


@pytest.mark.parametrize("scale", [1e-4, 1e4])
def test_scale_mesh_alone(scale):
    v, f = _sphere(torch.float32)
    out, grad = _run(v * scale, f, cameras_to_tensor([look_at(20, 15)]), 24, shading="smooth")
    _assert_finite(out, grad)


# ---- gradient strength --------------------------------------------------------------------


@pytest.mark.parametrize("delta", [1e-4, 1e-2, 1.0, 1e2])
def test_delta_range_gives_finite_gradients(delta):
    v, f = _sphere(torch.float32, B=2)
    cams = cameras_to_tensor([look_at(0, 0), look_at(90, 45)])
    out, grad = _run(v, f, cams, 16, delta=delta)
    _assert_finite(out, grad)
    assert float(grad.abs().max()) > 0


# ---- empty images ---------------------------------------------------------------------------


@pytest.mark.parametrize("where", ["right", "behind", "tiny"])
def test_empty_image(where):
    v, f = _sphere(torch.float32)
    if where == "right":
        v = v + torch.tensor([50.0, 0.0, 0.0])
    elif where == "behind":
        v = v + torch.tensor([0.0, 0.0, 10.0])  # behind the camera at z = 2.732
    else:
        v = v * 1e-7
    out, grad = _run(v, f, cameras_to_tensor([look_at(0, 0)]), 16)
    _assert_finite(out, grad)
    if where != "tiny":
        assert int((out.face_index >= 0).sum()) == 0
        assert torch.all(grad == 0)


def test_no_faces():
    v, _ = _sphere(torch.float32)
    out, grad = _run(v, torch.zeros(0, 3, dtype=torch.int64), cameras_to_tensor([look_at(0, 0)]), 8)
    _assert_finite(out, grad)
    assert int((out.face_index >= 0).sum()) == 0


# ---- invalid arguments ----------------------------------------------------------------------


def _good():
    v, f = _sphere(torch.float32)
    return v, f, cameras_to_tensor([look_at(0, 0)])


@pytest.mark.parametrize("delta", [0.0, -1.0, float("nan"), float("inf"), "big", None])
def test_bad_delta(delta):
    v, f, c = _good()
    with pytest.raises(ValueError, match="delta"):
        rasterize(v, f, c, 8, delta=delta)


@pytest.mark.parametrize(
    "case, match",
    [
        ("nan_vertices", "NaN"),
        ("inf_vertices", "NaN or inf"),
        ("vertices_2d", r"\(B, V, 3\)"),
        ("vertices_int", "float32 or float64"),
        ("faces_1d", r"\(F, 3\)"),
        ("faces_float", "integer"),
        ("face_out_of_range", r"in \[0, 42\)"),
        ("face_negative", r"in \[0, 42\)"),
        ("camera_shape", "cameras must be"),
        ("camera_batch", "cameras must be"),
        ("camera_nan", "cameras contain"),
        ("focal_zero", "focal"),
        ("size_zero", "image_size"),
        ("size_float", "image_size"),
        ("shading", "shading"),
    ],
)
def test_bad_inputs_raise_clear_errors(case, match):
    v, f, c = _good()
    size, shading = 8, "flat"
    if case == "nan_vertices":
        v = v.clone()
        v[0, 3, 1] = float("nan")
    elif case == "inf_vertices":
        v = v.clone()
        v[0, 0, 0] = float("inf")
    elif case == "vertices_2d":
        v = v[0]
    elif case == "vertices_int":
        v = v.long()
    elif case == "faces_1d":
        f = f.reshape(-1)
    elif case == "faces_float":
        f = f.float()
    elif case == "face_out_of_range":
        f = f.clone()
        f[5, 2] = 42
    elif case == "face_negative":
        f = f.clone()
        f[0, 0] = -1
    elif case == "camera_shape":
        c = c[:, :12]
    elif case == "camera_batch":
        c = c.repeat(3, 1)
    elif case == "camera_nan":
        c = c.clone()
        c[0, 10] = float("nan")
    elif case == "focal_zero":
        c = c.clone()
        c[0, 12] = 0.0
    elif case == "size_zero":
        size = 0
    elif case == "size_float":
        size = 8.5
    elif case == "shading":
        shading = "phong"
    with pytest.raises(ValueError, match=match):
        rasterize(v, f, c, size, shading=shading)


# ---- random triangle soups ----------------------------------------------------------------

_coord = st.floats(min_value=-2.0, max_value=2.0, allow_nan=False, width=32)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    pts=st.lists(st.tuples(_coord, _coord, _coord), min_size=3, max_size=9),
    tris=st.lists(st.tuples(st.integers(0, 8), st.integers(0, 8), st.integers(0, 8)), min_size=1, max_size=8),
    log_scale=st.floats(min_value=-4, max_value=4),
    log_delta=st.floats(min_value=-4, max_value=2),
    shading=st.sampled_from(["flat", "smooth"]),
    cull=st.booleans(),
    azimuth=st.floats(0, 360),
)
def test_random_triangle_soups_finite(pts, tris, log_scale, log_delta, shading, cull, azimuth):
    V = len(pts)
    f = torch.tensor([[a % V, b % V, c % V] for a, b, c in tris])
    v = torch.tensor([pts], dtype=torch.float32) * (10.0**log_scale)
    cam = cameras_to_tensor([look_at(azimuth, 20.0, distance=2.732)])
    out, grad = _run(v, f, cam, 12, delta=10.0**log_delta, shading=shading, cull_backfaces=cull)
    _assert_finite(out, grad)
    F = f.shape[0]
    assert int(out.face_index.max()) < F and int(out.face_index.min()) >= -1
    assert math.isfinite(float(grad.abs().sum()))
