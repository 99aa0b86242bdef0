"""Mirrored training items (training.data.mirror, `train mesh --mirror P`).

The independent expectation is the renderer: the ground-truth mesh reflected in the world and rendered
with the mirrored cameras must reproduce the mirrored item's images, for the input view and the others.
"""

from __future__ import annotations

import csv
import sys
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from engine.camera import Camera, frame_camera, look_at  # noqa: E402
from training.data.mirror import mirror_batch, mirror_cameras, mirror_normal_image, mirror_points  # noqa: E402
from training.loop.config import TrainConfig  # noqa: E402
from training.loop.trainer import Trainer, mesh_targets, render_views  # noqa: E402
from training.model.networks import view_frame_cameras  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from synthetic_data import write_synthetic_dataset  # noqa: E402


@pytest.fixture(scope="module")
def data_dir(tmp_path_factory) -> Path:
    return write_synthetic_dataset(tmp_path_factory.mktemp("mirror"), splits=("train", "test"), views=3)


def _batch(ds, i: int) -> dict:
    return torch.utils.data.default_collate([ds[i]])


def test_the_mirrored_mesh_renders_the_mirrored_images(data_dir):
    from training.data.dataset import ShapeViewDataset

    ds = ShapeViewDataset(data_dir, "train", extra_views=2, augment_strength=0.0, fields="mesh")
    for i in (0, len(ds) - 1):
        item = _batch(ds, i)
        flipped = mirror_batch(item, torch.tensor([True]))
        mesh = ds.load_mesh(ds[i]["category"], ds[i]["shape_id"])
        world = mirror_points(item["camera"][0], torch.from_numpy(np.array(mesh.vertices, np.float64)))
        faces = torch.from_numpy(np.array(mesh.faces))[:, [0, 2, 1]]  # a reflection turns the winding over
        r_in = flipped["camera"][0, :9].reshape(3, 3)
        cams = view_frame_cameras(flipped["camera"], flipped["other_cameras"])
        out = render_views((world @ r_in.T)[None], faces, cams, TrainConfig(render_size=64))
        tn, ts = mesh_targets(flipped)
        assert out.normals.shape == tn.shape == (3, 3, 64, 64)
        mismatch = ((out.silhouette > 0.5) != (ts > 0.5)).float().mean()
        assert mismatch < 0.005, float(mismatch)
        assert (out.normals.float() - tn).abs().mean() < 2e-3
        # and the images really changed: an item is not its own mirror image
        assert (tn - mesh_targets(item)[0]).abs().mean() > 1e-3


def test_cameras_by_hand():
    """A look-at camera at azimuth a mirrors to the one at -a (relative to the input at azimuth 0), principal x negated."""
    inp = look_at(0.0, 20.0).to_array()
    for az in (35.0, -80.0, 170.0):
        other = look_at(az, 10.0)
        other = Camera(other.R, other.t, other.focal, (0.1, -0.05)).to_array()
        got = mirror_cameras(torch.from_numpy(inp)[None], torch.from_numpy(other)[None, None])[0, 0].numpy()
        want = look_at(-az, 10.0)
        np.testing.assert_allclose(got[:9], want.R.ravel(), atol=1e-12)
        np.testing.assert_allclose(got[9:12], want.t, atol=1e-12)
        np.testing.assert_allclose(got[12:15], [other[12], -0.1, -0.05], atol=1e-12)
    # a camera off the mirror plane (t_x != 0): points still map to M times their original camera coordinates
    cam = look_at(30.0, 15.0)
    off = Camera(cam.R, cam.t + np.array([0.2, 0.0, 0.0]), cam.focal)
    rng = np.random.default_rng(0)
    pts = torch.from_numpy(rng.normal(size=(5, 3)))
    oth = look_at(-60.0, 40.0)
    inp_t, oth_t = torch.from_numpy(off.to_array()), torch.from_numpy(oth.to_array())
    mirrored = mirror_cameras(inp_t[None], torch.stack([inp_t, oth_t])[None])[0]
    for c, m in ((off, mirrored[0]), (oth, mirrored[1])):
        mc = Camera.from_array(m.numpy())
        before = pts.numpy() @ c.R.T + c.t
        after = mirror_points(inp_t, pts).numpy() @ mc.R.T + mc.t
        np.testing.assert_allclose(after, before * [-1, 1, 1], atol=1e-12)


def test_normal_images_by_hand_and_twice_is_once_undone():
    n = torch.zeros(1, 3, 2, 3)
    sil = torch.tensor([[[1.0, 1.0, 0.0], [0.0, 1.0, 0.0]]])
    n[0, :, 0, 0] = torch.tensor([0.9, 0.5, 0.6])  # n_x = 0.8
    n[0, :, 0, 1] = torch.tensor([0.2, 0.4, 0.9])
    n[0, :, 1, 1] = torch.tensor([0.5, 0.5, 1.0])
    got = mirror_normal_image(n, sil)
    assert torch.allclose(got[0, :, 0, 2], torch.tensor([0.1, 0.5, 0.6]))  # moved to the mirrored column, x negated
    assert torch.allclose(got[0, :, 0, 1], torch.tensor([0.8, 0.4, 0.9]))
    assert torch.all(got[0, :, :, 0] == 0)  # background stays background
    # coverage estimated from blue: an outline pixel covered by 0.4 with n_z = 0 holds 0.4 (n + 1) / 2
    edge = torch.zeros(1, 3, 1, 1)
    edge[0, :, 0, 0] = 0.4 * (torch.tensor([0.6, 0.8, 0.0]) + 1) / 2
    assert torch.allclose(mirror_normal_image(edge)[0, :, 0, 0], 0.4 * (torch.tensor([-0.6, 0.8, 0.0]) + 1) / 2)
    assert torch.allclose(mirror_normal_image(mirror_normal_image(n, sil), sil.flip(-1)), n)


def test_unflagged_items_are_untouched(data_dir):
    from training.data.dataset import ShapeViewDataset

    ds = ShapeViewDataset(data_dir, "train", extra_views=1, augment_strength=0.0, fields="mesh")
    batch = torch.utils.data.default_collate([ds[0], ds[1]])
    same = mirror_batch(batch, torch.tensor([False, False]))
    assert same is batch
    half = mirror_batch(batch, torch.tensor([False, True]))
    for k in ("normals64", "silhouette64", "camera", "other_cameras"):
        assert torch.equal(half[k][0], batch[k][0])
        assert not torch.equal(half[k][1], batch[k][1])
    assert torch.equal(half["silhouette64"][1], batch["silhouette64"][1].flip(-1))


def test_training_with_mirrored_items_runs_and_resumes_identically(data_dir, tmp_path):
    tiny = dict(mode="mesh", data_dir=str(data_dir), batch=4, predictor_channels=8, predictor_hidden=32,
                predictor_latent=16, template_level=2, augment_strength=0.0, log_every=1, val_every=0, ckpt_every=0,
                plot_every=0, device="cpu", extra_views=1, mirror=0.5, iters=2)
    a = Trainer(TrainConfig(out_dir=str(tmp_path / "a"), **tiny), progress=False)
    a.run()
    Trainer(TrainConfig(out_dir=str(tmp_path / "b"), **{**tiny, "iters": 1}), progress=False).run()
    b = Trainer(TrainConfig(out_dir=str(tmp_path / "b"), **tiny), progress=False)
    b.run()
    for (k, x), (_, y) in zip(a.models["predictor"].state_dict().items(), b.models["predictor"].state_dict().items()):
        assert torch.equal(x, y), k
    with open(tmp_path / "a" / "log.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert all(np.isfinite(float(r["mesh_total"])) for r in rows)
    with pytest.raises(ValueError, match="mirror"):
        TrainConfig(mode="joint", mirror=0.5)
    with pytest.raises(ValueError, match="mirror"):
        TrainConfig(mode="mesh", mirror=1.5)
    with pytest.raises(ValueError, match="mirror"):
        TrainConfig(mode="mesh", mirror=0.5, supervision="3d")


def test_framed_cameras_keep_the_mirror_exact():
    """Framing moves the principal point off centre; the mirrored camera's is negated in x, so projecting a mirrored
    point gives the original's u negated (a flipped image) and the same v."""
    cam = look_at(25.0, 30.0)
    rng = np.random.default_rng(1)
    pts = rng.uniform(-0.5, 0.5, size=(50, 3))
    framed = frame_camera(cam, pts)
    assert abs(framed.principal[0]) > 1e-3
    c = torch.from_numpy(framed.to_array())
    mc = Camera.from_array(mirror_cameras(c[None], c[None, None])[0, 0].numpy())
    mp = mirror_points(c, torch.from_numpy(pts)).numpy()

    def uv(camera, p):
        q = p @ camera.R.T + camera.t
        x = q @ camera.projection().T
        return x[:, :2] / x[:, 2:]

    np.testing.assert_allclose(uv(mc, mp), uv(framed, pts) * [-1, 1], atol=1e-12)


def test_eval_mirror_average_is_the_flipped_prediction_mirrored_back_and_averaged(data_dir, tmp_path):
    """`sketchmesh eval --mirror-average` on true normal images: redo one batch by hand (the image mirrored with numpy,
    the template's partners found by brute force), and the table gets a '+mirror' row per run."""
    from engine.icosphere import icosphere
    from training.data.dataset import ShapeViewDataset
    from training.evaluation.evaluate import _load_models, _RunMethod, evaluate

    tiny = dict(mode="mesh", data_dir=str(data_dir), batch=2, predictor_channels=8, predictor_hidden=32,
                predictor_latent=16, template_level=2, augment_strength=0.0, log_every=1, val_every=0, ckpt_every=0,
                plot_every=0, device="cpu", extra_views=1, iters=3, out_dir=str(tmp_path / "run"))
    Trainer(TrainConfig(**tiny), progress=False).run()
    cfg, gen, pred = _load_models(tmp_path / "run", False)
    ds = ShapeViewDataset(data_dir, "test", extra_views=0, augment_strength=0.0)
    batch = {k: torch.as_tensor(np.stack([np.asarray(ds[i][k]) for i in (0, 1)])) for k in ("normals64", "silhouette64")}
    got, _ = _RunMethod("r", gen, pred, cfg, gt_normals=True, mirror=True).predict(batch)

    n = batch["normals64"].numpy().astype(np.float64)
    sil = batch["silhouette64"].numpy().astype(np.float64)
    flipped = np.concatenate([(sil - n[:, 0])[:, None], n[:, 1:]], axis=1)[..., ::-1]
    with torch.no_grad():
        plain = pred.vertices(*pred(torch.from_numpy(n).float())).numpy()
        other = pred.vertices(*pred(torch.from_numpy(flipped.copy()).float())).numpy()
    t = icosphere(2).vertices.astype(np.float64)
    partner = np.linalg.norm(t[:, None] - (t * [-1, 1, 1])[None], axis=-1).argmin(axis=1)
    expected = (plain + (other * [-1, 1, 1])[:, partner]) / 2
    np.testing.assert_allclose(got, expected, atol=1e-5)
    assert np.abs(expected - plain).max() > 1e-4

    res = evaluate(tmp_path / "run", data_dir, "test", gt_normals=True, retrieval=False, max_samples=2, progress=False,
                   mirror=True)
    assert res["method_order"] == ["run", "run +mirror"] and res["mirror_average"] is True
    assert all(np.isfinite(res["methods"][m]["mean"]["voxel_iou"]) for m in res["method_order"])


def test_mirror_consistency_by_hand_and_its_gradient():
    """Zero for a prediction whose counterpart is its exact mirror image; a counterpart shifted by (0.1, 0.2, 0)
    comes back shifted by (-0.1, 0.2, 0), a squared distance of 0.05; the gradient matches finite differences."""
    from engine.icosphere import icosphere, mirror_permutation
    from training.data.mirror import mirror_consistency

    t = torch.from_numpy(icosphere(1).vertices.astype(np.float64))[None]
    perm = torch.from_numpy(np.array(mirror_permutation(1)))
    rng = np.random.default_rng(2)
    v = t + torch.from_numpy(rng.normal(0, 0.05, size=t.shape))
    exact = (v * torch.tensor([-1.0, 1.0, 1.0], dtype=v.dtype))[:, perm]
    assert float(mirror_consistency(v, exact, perm)) == pytest.approx(0.0, abs=1e-24)
    assert float(mirror_consistency(t, t + torch.tensor([0.1, 0.2, 0.0], dtype=t.dtype), perm)) == pytest.approx(0.05)
    a = v.clone().requires_grad_(True)
    b = (v + 0.01 * torch.from_numpy(rng.normal(size=t.shape))).requires_grad_(True)
    assert torch.autograd.gradcheck(lambda x, y: mirror_consistency(x, y, perm), (a, b))


def test_counterpart_inputs_pick_the_other_image_of_each_item():
    from training.data.mirror import counterpart_inputs

    plain = torch.rand(2, 3, 4, 4)
    exact = torch.rand(2, 3, 4, 4)
    before = {"input64": plain, "input64_mirror": exact}
    after = {"input64": torch.stack([plain[0], exact[1]])}  # what mirror_batch gives for flags (False, True)
    got = counterpart_inputs(before, after, torch.tensor([False, True]))
    assert torch.equal(got[0], exact[0]) and torch.equal(got[1], plain[1])
    # without the generator's images of the flipped drawings: the input mirrored (flipped, red = coverage - red)
    got = counterpart_inputs({"input64": plain}, after, torch.tensor([False, True]))
    assert torch.equal(got[0], mirror_normal_image(plain[:1])[0]) and torch.equal(got[1], plain[1])
    # a run on true normal images: its current images mirrored exactly
    n, s = torch.rand(2, 3, 4, 4), (torch.rand(2, 4, 4) > 0.5).float()
    assert torch.equal(counterpart_inputs({}, {"normals64": n, "silhouette64": s}, torch.tensor([True, False])),
                       mirror_normal_image(n, s))


def test_training_with_mirror_consistency_logs_the_term_and_lowers_it(data_dir, tmp_path):
    """The term is logged, finite, and a run that weighs it heavily makes the predictor more mirror-consistent
    than the same run without it (same seed, same steps)."""
    from engine.icosphere import mirror_permutation
    from training.data.dataset import ShapeViewDataset
    from training.data.mirror import mirror_consistency
    from training.evaluation.evaluate import _load_models

    tiny = dict(mode="mesh", data_dir=str(data_dir), batch=4, predictor_channels=8, predictor_hidden=32,
                predictor_latent=16, template_level=2, augment_strength=0.0, log_every=1, val_every=0, ckpt_every=0,
                plot_every=0, device="cpu", extra_views=1, mirror=0.5, iters=12, lr_mesh=2e-2)
    Trainer(TrainConfig(out_dir=str(tmp_path / "with"), mirror_consistency=1e4, **tiny), progress=False).run()
    Trainer(TrainConfig(out_dir=str(tmp_path / "without"), **tiny), progress=False).run()
    with open(tmp_path / "with" / "log.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert all(np.isfinite(float(r["mesh_mirror"])) for r in rows)

    ds = ShapeViewDataset(data_dir, "train", extra_views=0, augment_strength=0.0)
    batch = {k: torch.as_tensor(np.stack([np.asarray(ds[i][k]) for i in range(len(ds))])) for k in ("normals64", "silhouette64")}
    perm = torch.from_numpy(np.array(mirror_permutation(2)))
    gaps = {}
    for name in ("with", "without"):
        _, _, pred = _load_models(tmp_path / name, False)
        with torch.no_grad():
            v = pred.vertices(*pred(batch["normals64"].float()))
            w = pred.vertices(*pred(mirror_normal_image(batch["normals64"].float(), batch["silhouette64"].float())))
        gaps[name] = float(mirror_consistency(v, w, perm))
    assert gaps["with"] < 0.25 * gaps["without"], gaps
    for bad in (dict(mirror=0.0), dict(supervision="3d"), dict(mirror_consistency=-1.0)):
        with pytest.raises(ValueError, match="mirror_consistency"):
            TrainConfig(mode="mesh", **{"mirror_consistency": 1.0, "mirror": 0.5, **bad})
    # a run trained with the term is scored with the retrieval floor, whose train set is read unmirrored (the term
    # must not make that reading an invalid config: the tenth bundled pair's import hit it)
    from training.evaluation.evaluate import evaluate

    result = evaluate(tmp_path / "with", data_dir, "train", gt_normals=True, retrieval=True, max_samples=2,
                      progress=False)
    assert np.isfinite(result["methods"]["retrieval"]["mean"]["voxel_iou"])


def test_eval_mirror_average_flips_the_drawing_for_the_generator(data_dir, tmp_path):
    """From sketches: the +mirror method's second pass reads the generator's image of the drawing flipped left to
    right (done here with numpy), and it reuses the plain method's pass on the same batch."""
    from engine.icosphere import icosphere
    from training.evaluation.evaluate import _load_models, _RunMethod
    from training.model.networks import downsample_normals

    tiny = dict(mode="mesh", data_dir=str(data_dir), batch=2, predictor_channels=8, predictor_hidden=32,
                predictor_latent=16, template_level=2, augment_strength=0.0, log_every=1, val_every=0, ckpt_every=0,
                plot_every=0, device="cpu", extra_views=1, iters=2, out_dir=str(tmp_path / "run"))
    Trainer(TrainConfig(**tiny), progress=False).run()
    cfg, _, pred = _load_models(tmp_path / "run", False)
    torch.manual_seed(0)
    gen = torch.nn.Sequential(torch.nn.Conv2d(1, 3, 5, padding=2), torch.nn.Sigmoid()).eval()  # not mirror-equivariant
    sketch = torch.rand(2, 1, 64, 64)
    batch = {"sketch": sketch}
    plain = _RunMethod("r", gen, pred, cfg, gt_normals=False)
    mirror = _RunMethod("r +mirror", gen, pred, cfg, gt_normals=False, mirror=True, plain=plain)
    p, _ = plain.predict(batch)
    got, _ = mirror.predict(batch)

    flipped = torch.from_numpy(sketch.numpy()[..., ::-1].copy())
    with torch.no_grad():
        other = pred.vertices(*pred(downsample_normals(gen(flipped), pred.input_size))).numpy()
    t = icosphere(2).vertices.astype(np.float64)
    partner = np.linalg.norm(t[:, None] - (t * [-1, 1, 1])[None], axis=-1).argmin(axis=1)
    np.testing.assert_allclose(got, (p + (other * [-1, 1, 1])[:, partner]) / 2, atol=1e-5)
    assert np.abs(got - p).max() > 1e-5
    assert mirror.seconds >= plain.seconds and mirror.count == plain.count == 2
