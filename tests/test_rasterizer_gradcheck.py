"""The Eq. 1 silhouette gradient against finite differences of the silhouette area.

Growing and shrinking, on coarse to fine spheres and on a non-convex mesh: the approximate
gradient must point where the area's finite differences point, and be about as strong for
shrinking as for growing (the old first-exit-edge rule moved interior edges next to the
outline and overstated shrinking 10-20x, more as meshes got finer).
"""

from __future__ import annotations

import numpy as np
import pytest

from engine.camera import frame_camera, look_at
from engine.icosphere import icosphere
from engine.mesh import Mesh
from training.render.gradcheck import silhouette_gradient_check


def _waisted(level: int = 3) -> Mesh:
    """A sphere squeezed into two waists and a bulge: concave outlines from most views."""
    m = icosphere(level)
    v = np.array(m.vertices, dtype=np.float64)
    v[:, 0] *= 1.0 + 0.8 * np.sin(3.0 * np.pi * v[:, 1])
    return Mesh(v.astype(np.float32), np.asarray(m.faces))


@pytest.mark.parametrize("name", ["ico2", "ico3", "ico4", "waisted"])
def test_silhouette_gradient_matches_area_finite_differences(name):
    mesh = _waisted() if name == "waisted" else icosphere(int(name[-1]))
    cam = frame_camera(look_at(30.0, 20.0), np.asarray(mesh.vertices, np.float64))
    grow, shrink = silhouette_gradient_check(mesh, cam, num_vertices=10, window_res=128)
    for r in (grow, shrink):
        assert r.components >= 10, f"{name} {r.direction}: only {r.components} components compared"
        assert r.sign_agreement >= 0.9, f"{name} {r.direction}: signs agree on {r.sign_agreement:.2f}"
        assert r.cosine >= 0.5, f"{name} {r.direction}: cosine {r.cosine:.2f}"
        # Eq. 1's 1/D weighting makes it ~1 + ln(100) = 5.6x the area derivative on average
        assert 2.0 <= r.scale <= 25.0, f"{name} {r.direction}: |approx|/|fd| = {r.scale:.2f}"
    ratio = shrink.scale / grow.scale
    assert 1 / 2.5 <= ratio <= 2.5, f"{name}: shrink/grow strength ratio {ratio:.2f} (grow {grow.scale:.2f})"


@pytest.mark.parametrize("name", ["ico3", "waisted"])
def test_far_range_gradient_keeps_the_signs_and_the_balance(name):
    """edge_range 4 adds the events of pixels up to 4 px from the outline: the same directions,
    growing and shrinking alike, somewhat stronger (each far pixel adds 1 / D, D = 1.5 .. 3.5)."""
    mesh = _waisted() if name == "waisted" else icosphere(3)
    cam = frame_camera(look_at(30.0, 20.0), np.asarray(mesh.vertices, np.float64))
    near, = silhouette_gradient_check(mesh, cam, num_vertices=10, window_res=128)[:1]
    grow, shrink = silhouette_gradient_check(mesh, cam, num_vertices=10, window_res=128, edge_range=4)
    for r in (grow, shrink):
        assert r.components >= 10
        assert r.sign_agreement >= 0.9, f"{name} {r.direction}: signs agree on {r.sign_agreement:.2f}"
        assert r.cosine >= 0.5, f"{name} {r.direction}: cosine {r.cosine:.2f}"
        assert 2.0 <= r.scale <= 40.0, f"{name} {r.direction}: |approx|/|fd| = {r.scale:.2f}"
    assert grow.scale > near.scale, "the far events add nothing"
    assert 1 / 2.5 <= shrink.scale / grow.scale <= 2.5
