"""The 3D-supervised diagnostic ceiling: Chamfer term, differentiable surface sampling, and the
trainer's ``supervision="3d"`` mode (true surface points in the input view's frame)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

torch = pytest.importorskip("torch")

from training.loop.config import TrainConfig  # noqa: E402
from training.model.losses import chamfer_loss, sample_mesh_points  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from synthetic_data import write_synthetic_dataset  # noqa: E402


def test_chamfer_loss_hand_computed_and_finite_differences():
    p = torch.tensor([[[0.0, 0, 0], [1, 0, 0]]], dtype=torch.float64)
    t = torch.tensor([[[0.0, 0, 0], [0, 2, 0], [3, 0, 0]]], dtype=torch.float64)
    # p -> t: 0 and 1 (mean 0.5); t -> p: 0, 2, 2 (mean 4/3); half their sum
    assert float(chamfer_loss(p, t)) == pytest.approx(0.5 * (0.5 + 4.0 / 3.0))
    # batch mean, and symmetric
    both = torch.cat([p, p]), torch.cat([t, t])
    assert float(chamfer_loss(*both)) == pytest.approx(float(chamfer_loss(p, t)))
    assert float(chamfer_loss(t, p)) == pytest.approx(float(chamfer_loss(p, t)))
    g = torch.Generator().manual_seed(0)
    a = torch.rand(2, 7, 3, dtype=torch.float64, generator=g).requires_grad_()
    b = torch.rand(2, 5, 3, dtype=torch.float64, generator=g)
    assert torch.autograd.gradcheck(lambda x: chamfer_loss(x, b), (a,))
    # coincident points: value 0, finite gradient
    z = torch.zeros(1, 3, 3, requires_grad=True)
    loss = chamfer_loss(z, torch.zeros(1, 2, 3))
    loss.backward()
    assert loss.item() < 1e-12 and torch.isfinite(z.grad).all()
    with pytest.raises(ValueError, match="chamfer_loss"):
        chamfer_loss(torch.zeros(2, 3), torch.zeros(2, 3))


def test_sample_mesh_points_lie_on_faces_by_area_and_carry_gradients():
    # two triangles in z = 0: area 0.5 (x in [0, 1]) and 1.5 (x in [2, 5], scaled)
    v = torch.tensor([[[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0], [5, 0, 0], [2, 1, 0]]], requires_grad=True)
    f = torch.tensor([[0, 1, 2], [3, 4, 5]])
    pts = sample_mesh_points(v, f, 4000, torch.Generator().manual_seed(1))
    assert pts.shape == (1, 4000, 3)
    x, y = pts[0, :, 0].detach(), pts[0, :, 1].detach()
    first = x <= 1.0
    assert abs(float(first.float().mean()) - 0.25) < 0.03  # by area: 0.5 / 2.0
    # inside their triangles: x + y <= 1 for the first, (x - 2) / 3 + y <= 1 for the second
    assert bool((x[first] + y[first] <= 1 + 1e-6).all() and ((x[~first] - 2) / 3 + y[~first] <= 1 + 1e-6).all())
    assert pts[0, :, 2].abs().max().item() == 0.0
    # uniform inside a face: the mean of the first triangle's points is its centroid (1/3, 1/3)
    assert torch.allclose(torch.stack([x[first].mean(), y[first].mean()]), torch.tensor([1 / 3, 1 / 3]), atol=0.03)
    # the gradient of the points' sum w.r.t. each vertex is how many points it weighs (sum of weights)
    pts.sum().backward()
    weights = v.grad[0, :, 0]
    assert float(weights.sum()) == pytest.approx(4000, rel=1e-5)
    assert float(weights[:3].sum()) == pytest.approx(float(first.sum()), rel=1e-5)
    # every face of zero area: faces drawn uniformly, finite output
    flat = torch.zeros(1, 6, 3)
    assert torch.isfinite(sample_mesh_points(flat, f, 10)).all()
    with pytest.raises(ValueError, match="n >= 1"):
        sample_mesh_points(v, f, 0)


def test_config_keeps_3d_supervision_a_mesh_mode_diagnostic():
    assert TrainConfig(mode="mesh", supervision="3d").supervision == "3d"
    with pytest.raises(ValueError, match="mesh mode only"):
        TrainConfig(mode="joint", supervision="3d")
    with pytest.raises(ValueError, match="supervision"):
        TrainConfig(mode="mesh", supervision="2.5d")


def test_3d_supervised_step_uses_the_true_surface_in_the_view_frame(tmp_path):
    from training.evaluation.evaluate import world_vertices
    from training.evaluation.metrics import sample_surface
    from training.loop.trainer import SURFACE_POINTS, Trainer, _to_device

    data = write_synthetic_dataset(tmp_path / "data", views=4)
    cfg = TrainConfig(mode="mesh", data_dir=str(data), out_dir=str(tmp_path / "run"), iters=3, batch=2,
                      supervision="3d", predictor_channels=4, predictor_hidden=16, predictor_latent=8,
                      template_level=2, log_every=1, ckpt_every=0, val_every=0, plot_every=0)
    trainer = Trainer(cfg, progress=False)
    batch = _to_device(next(iter(torch.utils.data.DataLoader(trainer.train_set, batch_size=2))), trainer.device)
    pts = trainer._true_surface_points(batch)
    assert pts.shape == (2, SURFACE_POINTS, 3)
    for k in range(2):
        mesh = trainer.train_set.load_mesh(batch["category"][k], batch["shape_id"][k])
        # mapped back to the world frame, every point lies on the true surface (distance ~ 0) and
        # the points cover it (the mean distance from independent surface samples to them is small)
        back = world_vertices(pts[k].numpy(), batch["camera"][k].numpy())
        tm = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False)
        assert np.abs(trimesh.proximity.signed_distance(tm, back)).max() < 1e-4
        other, _ = sample_surface(mesh, 2000, seed=7)
        gaps = np.linalg.norm(other[:, None] - back[None], axis=-1).min(1)
        assert gaps.mean() < 0.05
    trainer.run()
    log = (tmp_path / "run" / "log.csv").read_text().splitlines()
    assert "mesh_chamfer" in log[0].split(",")
    chamfer = [float(r.split(",")[log[0].split(",").index("mesh_chamfer")]) for r in log[1:]]
    assert len(chamfer) == 3 and all(0 < c < 1 for c in chamfer)
