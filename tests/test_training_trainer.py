"""The bundled trainer: checkpoints, tiny end-to-end runs, resume, the non-finite guard, eval, CLI errors."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from engine.camera import look_at  # noqa: E402
from engine.errors import ModelError  # noqa: E402
from engine.icosphere import icosphere  # noqa: E402
from training.loop.checkpoint import (  # noqa: E402
    checkpoint_paths,
    load_latest_checkpoint,
    save_checkpoint,
)
from training.loop.config import TrainConfig  # noqa: E402
from training.loop.trainer import Trainer, TrainingError, _to_device  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from synthetic_data import write_synthetic_dataset  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
torch.set_num_threads(2)

TINY = dict(batch=2, base_channels=8, predictor_channels=8, predictor_hidden=32, predictor_latent=16,
            template_level=2, sobel_samples=64, augment_strength=0.0, log_every=1, val_every=0, ckpt_every=0,
            plot_every=0, device="cpu", extra_views=1)
TINY_FLAGS = ["--batch", "2", "--base-channels", "8", "--predictor-channels", "8", "--predictor-hidden", "32",
              "--predictor-latent", "16", "--template-level", "2", "--sobel-samples", "64", "--augment-strength", "0",
              "--quiet", "--threads", "2", "--extra-views", "1"]


@pytest.fixture(scope="module")
def data_dir(tmp_path_factory) -> Path:
    return write_synthetic_dataset(tmp_path_factory.mktemp("data"), splits=("train", "train", "test"), views=3)


def cli(argv: list[str]) -> int:
    from sketchmesh.cli import main

    return main(argv)


def read_log(run: Path) -> list[dict]:
    with open(run / "log.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def params(models: dict) -> dict[str, torch.Tensor]:
    return {f"{k}.{n}": p.detach().clone() for k, m in models.items() for n, p in m.state_dict().items()}


# ---------------------------------------------------------------------------- checkpoints


def _tiny_state():
    model = torch.nn.Linear(3, 2)
    opt = torch.optim.Adam(model.parameters(), lr=1e-3)
    model(torch.rand(4, 3)).sum().backward()
    opt.step()
    return model, opt


def test_checkpoint_round_trip_keeps_the_last_two(tmp_path):
    model, opt = _tiny_state()
    for it in (1, 2, 3):
        save_checkpoint(tmp_path, it, TrainConfig().to_json(), "v", {"m": model}, {"m": opt})
    assert [p.name for p in checkpoint_paths(tmp_path)] == ["ckpt_00000003.pt", "ckpt_00000002.pt"]
    state = load_latest_checkpoint(tmp_path)
    assert state["iteration"] == 3 and TrainConfig.from_json(state["config"]) == TrainConfig()
    fresh = torch.nn.Linear(3, 2)
    fresh.load_state_dict(state["models"]["m"])
    assert all(torch.equal(a, b) for a, b in zip(fresh.parameters(), model.parameters()))
    opt2 = torch.optim.Adam(fresh.parameters(), lr=1e-3)
    opt2.load_state_dict(state["optimizers"]["m"])
    assert torch.equal(opt2.state_dict()["state"][0]["exp_avg"], opt.state_dict()["state"][0]["exp_avg"])
    assert json.loads((tmp_path / "config.json").read_text())["iteration"] == 3


def test_interrupted_checkpoint_write_leaves_the_previous_one_loadable(tmp_path, monkeypatch):
    model, opt = _tiny_state()
    save_checkpoint(tmp_path, 1, TrainConfig().to_json(), "v", {"m": model}, {"m": opt})
    real_save = torch.save

    def failing_save(obj, fh, *a, **k):
        fh.write(b"PK\x03\x04 half a checkpoint")
        raise OSError("disk full (simulated)")

    monkeypatch.setattr(torch, "save", failing_save)
    with pytest.raises(OSError, match="simulated"):
        save_checkpoint(tmp_path, 2, TrainConfig().to_json(), "v", {"m": model}, {"m": opt})
    monkeypatch.setattr(torch, "save", real_save)
    assert [p.name for p in (tmp_path / "checkpoints").iterdir()] == ["ckpt_00000001.pt"]  # no temp file left
    assert load_latest_checkpoint(tmp_path)["iteration"] == 1


def test_corrupt_newest_checkpoint_falls_back_to_the_previous(tmp_path):
    model, opt = _tiny_state()
    for it in (1, 2):
        save_checkpoint(tmp_path, it, TrainConfig().to_json(), "v", {"m": model}, {"m": opt})
    newest = checkpoint_paths(tmp_path)[0]
    newest.write_bytes(newest.read_bytes()[:100])  # truncated by something outside our control
    with pytest.warns(UserWarning, match="unreadable"):
        assert load_latest_checkpoint(tmp_path)["iteration"] == 1
    checkpoint_paths(tmp_path)[1].write_bytes(b"garbage")
    with pytest.warns(UserWarning), pytest.raises(ModelError, match="no readable checkpoint"):
        load_latest_checkpoint(tmp_path)


def test_joint_with_a_frozen_predictor_moves_only_the_generator_and_by_the_mesh_loss_alone(data_dir, tmp_path):
    # the predictor's weights and batch-norm statistics stay exactly as initialised (eval mode, no optimiser), while
    # the mesh loss's gradient reaches the generator through it: with every generator loss of its own at weight 0
    # the generator still moves, and it does not move when the mesh loss's weight is 0 too
    base = Trainer(TrainConfig(mode="mesh", data_dir=str(data_dir), out_dir=str(tmp_path / "mesh"), iters=2, **TINY),
                   progress=False)
    base.run()
    start_pred = {k: v.clone() for k, v in base.models["predictor"].state_dict().items()}
    assert any("running_mean" in k for k in start_pred)

    def joint(name: str, weight: float) -> Trainer:
        t = Trainer(TrainConfig(mode="joint", data_dir=str(data_dir), out_dir=str(tmp_path / name), iters=2,
                                init_mesh=str(tmp_path / "mesh"), freeze_predictor=True, lambda_adv=0.0, lambda_g=0.0,
                                lambda_l=0.0, joint_mesh_weight=weight, lr_g=1e-3, **TINY), progress=False)
        t.run()
        return t

    start_gen = {k: v.clone() for k, v in Trainer(TrainConfig(mode="joint", data_dir=str(data_dir), out_dir=str(tmp_path / "g0"),
                                                             iters=1, **TINY), progress=False).models["generator"].state_dict().items()}
    moved = joint("frozen", 1.0)
    assert "predictor" not in moved.optimizers and not moved.models["predictor"].training
    for k, v in moved.models["predictor"].state_dict().items():
        assert torch.equal(v, start_pred[k]), k
    assert moved.iteration == 2
    assert any(not torch.equal(v, start_gen[k]) for k, v in moved.models["generator"].state_dict().items())
    still = joint("zero", 0.0)
    assert all(torch.equal(v, start_gen[k]) for k, v in still.models["generator"].state_dict().items())
    with pytest.raises(ValueError, match="freeze_predictor needs mode joint"):
        TrainConfig(mode="mesh", freeze_predictor=True)


def test_adversarial_weight_zero_leaves_the_discriminator_out_and_steps_on_the_l1_terms_alone(data_dir, tmp_path):
    # lambda_adv = 0: the discriminator is never called nor trained, the generator's gradient is that of the two L1
    # terms (Eq. 10 without the adversarial one) computed here by hand, and the log leaves its two terms blank
    from training.loop.trainer import _step_seed
    from training.model.networks import global_l1_loss, local_l1_loss, sample_edge_pixels

    tr = Trainer(TrainConfig(mode="normals", data_dir=str(data_dir), out_dir=str(tmp_path / "noadv"), iters=2,
                             lambda_adv=0.0, generator_dropout=False, **TINY), progress=False)
    batch = _to_device(torch.utils.data.default_collate([tr.train_set[i] for i in range(2)]), tr.device)
    G, D = tr.models["generator"], tr.models["discriminator"]
    d_before = {k: v.clone() for k, v in D.state_dict().items()}
    calls = []
    hook = D.register_forward_hook(lambda *a: calls.append(1))
    tr._train_modes()
    G.zero_grad(set_to_none=True)
    fake = G(batch["sketch"])
    gen = torch.Generator().manual_seed(_step_seed(tr.cfg.seed, 0, 0) + 1)
    idx = sample_edge_pixels(batch["normals"], tr.cfg.sobel_samples, tr.cfg.sobel_threshold, gen)
    by_hand = torch.autograd.grad(tr.cfg.lambda_g * global_l1_loss(fake, batch["normals"])
                                  + tr.cfg.lambda_l * local_l1_loss(fake, batch["normals"], idx), list(G.parameters()))
    backward, terms, _ = tr._compute(batch, 0)
    assert len(backward) == 1 and "d_loss" not in terms and "g_adv" not in terms
    backward[0].backward()
    for p, g in zip(G.parameters(), by_hand):
        torch.testing.assert_close(p.grad, g, rtol=1e-5, atol=1e-7)
    G.zero_grad(set_to_none=True)
    tr.run()
    hook.remove()
    assert tr.iteration == 2 and not calls
    assert all(torch.equal(v, d_before[k]) for k, v in D.state_dict().items())
    rows = read_log(tmp_path / "noadv")
    assert rows and all(r["d_loss"] == "" and r["g_adv"] == "" and np.isfinite(float(r["g_global"])) for r in rows)
    # the default weight still runs and trains it
    on = Trainer(TrainConfig(mode="normals", data_dir=str(data_dir), out_dir=str(tmp_path / "adv"), iters=1, **TINY),
                 progress=False)
    d0 = {k: v.clone() for k, v in on.models["discriminator"].state_dict().items()}
    on.run()
    assert any(not torch.equal(v, d0[k]) for k, v in on.models["discriminator"].state_dict().items())
    assert np.isfinite(float(read_log(tmp_path / "adv")[0]["d_loss"]))


def test_generator_dropout_off_trains_the_generator_as_it_runs_at_inference(data_dir, tmp_path):
    # pix2pix's dropout makes two training-mode passes over one sketch differ; without it a training-mode pass is
    # the inference pass (eval mode) exactly, while the rest of the generator stays in training mode
    sketch = torch.from_numpy(np.random.default_rng(0).random((1, 1, 256, 256), dtype=np.float32))
    outs = {}
    for flag in (True, False):
        t = Trainer(TrainConfig(mode="joint", data_dir=str(data_dir), out_dir=str(tmp_path / str(flag)), iters=1,
                                generator_dropout=flag, **TINY), progress=False)
        t._train_modes()
        g = t.models["generator"]
        assert g.training
        with torch.no_grad():
            a, b = g(sketch), g(sketch)
            g.eval()
            ref = g(sketch)
        outs[flag] = (a, b, ref)
    a, b, ref = outs[True]
    assert not torch.equal(a, b)
    a, b, ref = outs[False]
    assert torch.equal(a, b) and torch.equal(a, ref)


# ---------------------------------------------------------------------------- end to end


def test_cli_trains_every_mode_then_evaluates(data_dir, tmp_path, capsys):
    runs = {}
    for mode in ("normals", "mesh", "joint"):
        run = tmp_path / mode
        rc = cli(["train", mode, "--data", str(data_dir), "--out", str(run), "--iters", "2", "--log-every", "1",
                  "--val-every", "2", "--ckpt-every", "1", "--plot-every", "2", *TINY_FLAGS])
        assert rc == 0, capsys.readouterr().err
        runs[mode] = run
        assert (run / "checkpoints" / "ckpt_00000002.pt").is_file()
        assert (run / "val" / "iter_00002.png").stat().st_size > 0
        assert (run / "curves.png").stat().st_size > 0
        saved = json.loads((run / "config.json").read_text())
        assert saved["config"]["mode"] == mode and saved["code_version"].startswith("0.")
        rows = read_log(run)
        assert [int(r["iteration"]) for r in rows] == [1, 2]
        total = "mesh_total" if mode != "normals" else "g_total"
        assert all(np.isfinite(float(r[total])) for r in rows)
        assert all(float(r["samples_per_s"]) > 0 for r in rows)
    # a joint run can start from the normals run's generator and the mesh run's predictor
    init = Trainer(TrainConfig(mode="joint", data_dir=str(data_dir), out_dir=str(tmp_path / "init"), iters=1,
                               init_normals=str(runs["normals"]), init_mesh=str(runs["mesh"]), **TINY), progress=False)
    for name, run in (("generator", "normals"), ("discriminator", "normals"), ("predictor", "mesh")):
        saved = load_latest_checkpoint(runs[run])["models"][name]
        assert all(torch.equal(saved[k], v) for k, v in init.models[name].state_dict().items())
    assert "initialised" in (tmp_path / "init" / "events.log").read_text()
    # the validation image: sketch | GT | predicted normals | mesh from the input view | another view
    import cv2

    img = cv2.imread(str(runs["joint"] / "val" / "iter_00002.png"))
    assert img.shape[1] == 5 * 128 and img.shape[0] % 128 == 0

    out_json = tmp_path / "eval.json"
    rc = cli(["eval", str(runs["joint"]), "--data", str(data_dir), "--baseline-run", str(runs["mesh"]),
              "--json", str(out_json), "--quiet", "--max-samples", "4"])
    assert rc == 0, capsys.readouterr().err
    table = capsys.readouterr().out
    assert "| retrieval |" in table and "| mesh |" in table and "voxel_iou" in table
    res = json.loads(out_json.read_text())
    assert set(res["mean"]) >= {"voxel_iou", "chamfer_l1", "silhouette_iou", "normal_consistency"}
    assert set(res["per_category"]) == {"blob", "box"}
    for method in res["methods"].values():
        m = method["mean"]
        assert 0 <= m["voxel_iou"] <= 1 and 0 <= m["silhouette_iou"] <= 1 and 0 <= m["normal_consistency"] <= 1
        assert 0 <= m["chamfer_l1"] < 2 and method["ms_per_sample"] > 0
    for suffix in ("md", "json", "png"):
        assert (runs["joint"] / "eval" / f"eval_test.{suffix}").stat().st_size > 0
    # --voxel-centres: the same meshes (same Chamfer), voxel IoU by cell centres only, said in the table
    rc = cli(["eval", str(runs["joint"]), "--data", str(data_dir), "--no-retrieval", "--voxel-centres",
              "--json", str(tmp_path / "centres.json"), "--quiet", "--max-samples", "4", "--out", str(tmp_path / "c")])
    assert rc == 0, capsys.readouterr().err
    assert "voxels by cell centres only" in capsys.readouterr().out
    centres = json.loads((tmp_path / "centres.json").read_text())
    assert res["voxel_surface"] is True and centres["voxel_surface"] is False
    assert centres["mean"]["chamfer_l1"] == pytest.approx(res["mean"]["chamfer_l1"], abs=1e-12)


def test_retrieval_finds_the_query_itself_when_it_is_in_the_train_split(data_dir):
    """Evaluate the train split with ground-truth normals: retrieval returns the same shape and view, so
    its meshes are the ground truth (voxel IoU 1, Chamfer ~ sampling noise)."""
    from training.evaluation.evaluate import evaluate
    from training.loop.trainer import Trainer

    run = data_dir.parent / "retrieval_run"
    Trainer(TrainConfig(mode="mesh", data_dir=str(data_dir), out_dir=str(run), iters=1, **TINY), progress=False).run()
    res = evaluate(run, data_dir, "train", gt_normals=True, max_samples=3, progress=False)
    r = res["methods"]["retrieval"]["mean"]
    assert r["voxel_iou"] == pytest.approx(1.0) and r["chamfer_l1"] < 0.02 and r["silhouette_iou"] > 0.95
    centres = evaluate(run, data_dir, "train", gt_normals=True, max_samples=3, progress=False, voxel_surface=False)
    assert centres["methods"]["retrieval"]["mean"]["voxel_iou"] == pytest.approx(1.0)


def test_retrieval_data_searches_another_datasets_train_split(data_dir, tmp_path):
    """A run trained on a larger dataset is set against retrieval from that dataset (``--retrieval-data``): with a copy
    of the data whose every shape is in its train split, retrieval finds each test query itself (voxel IoU 1), which
    the data's own train split cannot (its test shapes are not in it)."""
    import shutil

    from training.cli.train import main as cli
    from training.evaluation.evaluate import evaluate
    from training.loop.trainer import Trainer

    everything = tmp_path / "everything_train"
    shutil.copytree(data_dir, everything, ignore=shutil.ignore_patterns(".cache", "eval"))
    manifest = json.loads((everything / "manifest.json").read_text())
    for rec in manifest["shapes"] + manifest["views"]:
        rec["split"] = "train"
    (everything / "manifest.json").write_text(json.dumps(manifest))
    run = tmp_path / "run"
    Trainer(TrainConfig(mode="mesh", data_dir=str(data_dir), out_dir=str(run), iters=1, **TINY), progress=False).run()
    own = evaluate(run, data_dir, "test", gt_normals=True, max_samples=3, progress=False)
    wider = evaluate(run, data_dir, "test", gt_normals=True, max_samples=3, progress=False, retrieval_data=everything)
    assert own["methods"]["retrieval"]["mean"]["voxel_iou"] < 0.99
    # the paired difference is the difference of the two means (every sample scored by both)
    assert own["methods"]["retrieval"]["vs_first"]["voxel_iou"] == pytest.approx(
        own["methods"]["retrieval"]["mean"]["voxel_iou"] - own["mean"]["voxel_iou"], abs=1e-12)
    assert "vs_first" not in own["methods"][own["method_order"][0]]
    assert wider["methods"]["retrieval"]["mean"]["voxel_iou"] == pytest.approx(1.0)
    assert wider["retrieval_data"] == str(everything) and own["retrieval_data"] == str(data_dir)
    # the run's own rows do not depend on where retrieval searches
    assert wider["mean"]["voxel_iou"] == pytest.approx(own["mean"]["voxel_iou"], abs=1e-9)
    out = tmp_path / "eval_out"
    assert cli(["eval", str(run), "--data", str(data_dir), "--gt-normals", "--max-samples", "3", "--quiet",
                "--retrieval-data", str(everything), "--out", str(out)]) == 0
    assert f"retrieval from the train split of {everything}" in (out / "eval_test.md").read_text()
    assert cli(["eval", str(run), "--data", str(data_dir), "--quiet", "--retrieval-data", str(tmp_path / "absent"),
                "--out", str(out)]) != 0


def test_view_frame_rendering_reproduces_the_dataset_targets(data_dir):
    """The mesh loss's plumbing: the ground-truth mesh moved to the input view frame and rendered with
    view_frame_cameras matches the dataset's normal images and silhouettes of the input view and the
    other view (which were rendered in the world frame with the views' own cameras)."""
    from training.data.dataset import ShapeViewDataset
    from training.loop.trainer import mesh_targets, render_views
    from training.model.networks import view_frame_cameras

    ds = ShapeViewDataset(data_dir, "train", extra_views=1, augment_strength=0.0)
    for i in (0, len(ds) - 1):
        item = torch.utils.data.default_collate([ds[i]])
        mesh = ds.load_mesh(item["category"][0], item["shape_id"][0])
        r_in = item["camera"][0, :9].reshape(3, 3)
        view = torch.from_numpy(np.array(mesh.vertices, np.float64)) @ r_in.T  # p_view = R_in p_world
        cams = view_frame_cameras(item["camera"], item["other_cameras"])
        out = render_views(view[None], torch.from_numpy(np.array(mesh.faces)), cams, TrainConfig(render_size=64))
        tn, ts = mesh_targets(item)
        assert out.normals.shape == tn.shape == (2, 3, 64, 64)
        mismatch = ((out.silhouette > 0.5) != (ts > 0.5)).float().mean()
        assert mismatch < 0.005, float(mismatch)
        assert (out.normals.float() - tn).abs().mean() < 2e-3


# ---------------------------------------------------------------------------- resume


def test_resumed_run_equals_an_uninterrupted_run(data_dir, tmp_path):
    """Joint mode covers every stateful piece: dropout and Sobel sampling (reseeded per step), RMSProp,
    Adam, BatchNorm statistics and the data order."""
    cfg = TrainConfig(mode="joint", data_dir=str(data_dir), iters=3, **TINY)
    straight = Trainer(cfg.replace(out_dir=str(tmp_path / "a")), progress=False)
    straight.run()
    first = Trainer(cfg.replace(out_dir=str(tmp_path / "b"), iters=1), progress=False)
    first.run()
    resumed = Trainer(cfg.replace(out_dir=str(tmp_path / "b")), progress=False)
    assert resumed.iteration == 1
    resumed.run()
    assert resumed.iteration == 3
    a, b = params(straight.models), params(resumed.models)
    assert a.keys() == b.keys()
    for k in a:
        assert torch.equal(a[k], b[k]), f"{k} differs by {float((a[k].float() - b[k].float()).abs().max())}"
    sa = straight.optimizers["predictor"].state_dict()["state"]
    sb = resumed.optimizers["predictor"].state_dict()["state"]
    assert all(torch.equal(sa[i]["exp_avg_sq"], sb[i]["exp_avg_sq"]) for i in sa)
    assert [int(r["iteration"]) for r in read_log(tmp_path / "b")] == [1, 2, 3]
    assert "resumed from" in (tmp_path / "b" / "events.log").read_text()


def test_killed_run_resumes_from_its_last_checkpoint(data_dir, tmp_path):
    run = tmp_path / "killed"
    cmd = [sys.executable, "-m", "sketchmesh", "train", "mesh", "--data", str(data_dir), "--out", str(run),
           "--iters", "6", "--ckpt-every", "1", "--log-every", "1", "--val-every", "0", "--plot-every", "0",
           "--debug-sleep", "0.4", *TINY_FLAGS]
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and not (run / "checkpoints" / "ckpt_00000002.pt").exists():
            if proc.poll() is not None:
                pytest.fail(f"training exited early: {proc.stderr.read().decode()[-2000:]}")
            time.sleep(0.1)
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.wait(timeout=30)
    assert proc.returncode == -signal.SIGKILL
    killed_at = int(checkpoint_paths(run)[0].name[5:13])
    assert 2 <= killed_at < 6
    # the checkpoint holds the training time up to it: at least the 0.4 s slept per iteration
    killed_seconds = load_latest_checkpoint(run)["extra"]["train_seconds"]
    assert killed_seconds >= 0.4 * killed_at
    done = subprocess.run([c for c in cmd if c != "--debug-sleep" and c != "0.4"], cwd=ROOT, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "resumed from" in (run / "events.log").read_text()
    assert load_latest_checkpoint(run)["iteration"] == 6
    assert load_latest_checkpoint(run)["extra"]["train_seconds"] > killed_seconds  # resumed, not restarted
    its = [int(r["iteration"]) for r in read_log(run)]
    assert its == list(range(1, 7)), its  # rows past the checkpoint were dropped, then continued


# ---------------------------------------------------------------------------- non-finite guard


def _trainer_and_batch(data_dir, tmp_path, name="g", **kw):
    tr = Trainer(TrainConfig(mode="mesh", data_dir=str(data_dir), out_dir=str(tmp_path / name), iters=5,
                             **(TINY | kw)), progress=False)
    items = [tr.train_set[i] for i in range(2)]
    return tr, _to_device(torch.utils.data.default_collate(items), tr.device)


def test_injected_nan_skips_the_step_and_is_logged(data_dir, tmp_path):
    tr, batch = _trainer_and_batch(data_dir, tmp_path, debug_nan_iters=(1,))
    assert tr.train_step(batch, 0)[0]
    before = params(tr.models)
    adam = {i: {k: v.clone() for k, v in s.items()} for i, s in tr.optimizers["predictor"].state_dict()["state"].items()}
    ok, terms = tr.train_step(batch, 1)
    assert not ok and not np.isfinite(terms["mesh_total"])
    after = params(tr.models)
    assert all(torch.equal(before[k], after[k]) for k in before)  # parameters and BN statistics untouched
    for i, s in tr.optimizers["predictor"].state_dict()["state"].items():
        assert all(torch.equal(s[k], adam[i][k]) for k in s)
    assert "skipped non-finite step" in (tmp_path / "g" / "events.log").read_text()
    assert tr.train_step(batch, 2)[0]  # the run continues
    assert any(not torch.equal(before[k], v) for k, v in params(tr.models).items())


def test_nan_from_the_network_is_caught_and_bad_streak_restores_the_good_state(data_dir, tmp_path):
    tr, batch = _trainer_and_batch(data_dir, tmp_path, max_bad_steps=2)
    good = params(tr.models)
    head = tr.models["predictor"].local_head
    with torch.no_grad():
        head.bias[0] = float("nan")  # a poisoned weight: NaN vertices, the rasterizer is never reached
    ok, _ = tr.train_step(batch, 0)
    assert not ok
    log = (tmp_path / "g" / "events.log").read_text()
    assert "mesh_total" in log and "1 in a row" in log
    ok, _ = tr.train_step(batch, 1)
    assert not ok
    assert "restored the last good state" in (tmp_path / "g" / "events.log").read_text()
    assert all(torch.equal(good[k], v) for k, v in params(tr.models).items())
    assert tr.train_step(batch, 2)[0]


@pytest.mark.parametrize("extreme", [
    dict(lambda_n=1e6, lambda_s=1e8),  # huge loss weights (clipped gradients)
    dict(delta=1e-6),  # a near-singular Eq. 1 gradient strength: edge gradients scale as 1 / delta
    dict(grad_clip=0.0, lambda_m=1e6, lr_mesh=10.0),  # no clipping, absurd smoothness weight and step size
])
def test_extreme_settings_never_leave_non_finite_weights(data_dir, tmp_path, extreme):
    tr, batch = _trainer_and_batch(data_dir, tmp_path, **extreme)
    taken = [tr.train_step(batch, it)[0] for it in range(3)]
    for name, p in tr.models["predictor"].state_dict().items():
        assert torch.isfinite(p.float()).all(), name
    if not all(taken):  # a step that went non-finite was skipped and said so
        assert "skipped non-finite step" in (tmp_path / "g" / "events.log").read_text()


def test_full_run_with_a_bad_step_completes_and_counts_it(data_dir, tmp_path):
    run = tmp_path / "nanrun"
    tr = Trainer(TrainConfig(mode="normals", data_dir=str(data_dir), out_dir=str(run), iters=3,
                             debug_nan_iters=(1,), **TINY), progress=False)
    tr.run()
    rows = read_log(run)
    assert [int(r["skipped"]) for r in rows] == [0, 1, 0]
    assert load_latest_checkpoint(run)["iteration"] == 3


def test_max_minutes_stops_the_run_with_a_checkpoint_and_resume_continues(data_dir, tmp_path):
    run = tmp_path / "timed"
    cfg = TrainConfig(mode="mesh", data_dir=str(data_dir), out_dir=str(run), iters=50, max_minutes=1e-9, **TINY)
    Trainer(cfg, progress=False).run()
    assert "--max-minutes" in (run / "events.log").read_text()
    assert load_latest_checkpoint(run)["iteration"] == 0  # stopped before any step, state saved
    resumed = Trainer(cfg.replace(iters=2, max_minutes=0.0), progress=False)
    # the resumed trainer continues the checkpoint's training time
    assert resumed.train_seconds == load_latest_checkpoint(run)["extra"]["train_seconds"] > 0.0
    resumed.run()  # resuming without the limit finishes
    assert load_latest_checkpoint(run)["iteration"] == 2
    # a limit given to run() overrides the config's
    Trainer(cfg.replace(iters=4, max_minutes=0.0), progress=False).run(max_minutes=1e-9)
    assert load_latest_checkpoint(run)["iteration"] == 2


# ---------------------------------------------------------------------------- bad input


def test_bad_input_gives_one_line_errors(data_dir, tmp_path, capsys):
    cases = [
        (["train", "mesh", "--data", str(tmp_path / "nope"), "--out", str(tmp_path / "r")], "does not exist"),
        (["train", "mesh", "--data", str(data_dir), "--out", str(tmp_path / "r"), "--batch", "-1"], "batch"),
        (["eval", str(tmp_path / "missing_run"), "--data", str(data_dir)], "does not exist"),
        (["export", str(tmp_path), "-o", str(tmp_path / "x")], "no checkpoint"),
    ]
    if not torch.cuda.is_available():
        cases.append((["train", "mesh", "--data", str(data_dir), "--out", str(tmp_path / "r"), "--device", "cuda",
                       "--extra-views", "1"],
                      "no CUDA device"))
    for argv, needle in cases:
        rc = cli(argv)
        err = capsys.readouterr().err.strip()
        assert rc != 0 and needle in err and len(err.splitlines()) == 1, (argv, err)
    run = tmp_path / "existing"
    assert cli(["train", "mesh", "--data", str(data_dir), "--out", str(run), "--iters", "1", *TINY_FLAGS]) == 0
    capsys.readouterr()
    rc = cli(["train", "mesh", "--data", str(data_dir), "--out", str(run), "--iters", "2", "--no-resume", *TINY_FLAGS])
    err = capsys.readouterr().err.strip()
    assert rc != 0 and "already has checkpoints" in err
    rc = cli(["train", "mesh", "--data", str(data_dir), "--out", str(run), "--iters", "2", "--base-channels", "8", "--extra-views", "1",
              "--template-level", "3", "--quiet"])
    err = capsys.readouterr().err.strip()
    assert rc != 0 and "config changed" in err and "template_level" in err


def test_lr_warmup_ramps_linearly_and_a_compact_run_resumes_bit_identically(data_dir, tmp_path):
    """Warm-up: step it runs at min(1, (it + 1) / lr_warmup) of the base rate (hand-computed), the
    rate the optimizer really used; the compact predictor resumes mid-warm-up exactly."""
    cfg = TrainConfig(mode="mesh", data_dir=str(data_dir), iters=3, lr_warmup=4, lr_mesh=2e-3, lr_schedule="constant",
                      **(TINY | {"predictor_arch": "compact", "predictor_modes": 20}))
    straight = Trainer(cfg.replace(out_dir=str(tmp_path / "a")), progress=False)
    seen = []
    real_step = straight.optimizers["predictor"].step
    straight.optimizers["predictor"].step = lambda *a, **k: (seen.append(
        straight.optimizers["predictor"].param_groups[0]["lr"]), real_step(*a, **k))[1]
    straight.run()
    np.testing.assert_allclose(seen, [0.5e-3, 1.0e-3, 1.5e-3])
    Trainer(cfg.replace(out_dir=str(tmp_path / "b"), iters=1), progress=False).run()
    resumed = Trainer(cfg.replace(out_dir=str(tmp_path / "b")), progress=False)
    resumed.run()
    a, b = params(straight.models), params(resumed.models)
    assert all(torch.equal(a[k], b[k]) for k in a)
    # the architecture is part of what a checkpoint fixes: resuming as softras is refused
    with pytest.raises(TrainingError, match="predictor_arch"):
        Trainer(cfg.replace(out_dir=str(tmp_path / "b"), predictor_arch="softras", iters=5), progress=False)


def test_cosine_schedule_follows_the_hand_computed_rates_after_the_warm_up(data_dir, tmp_path):
    """lr_schedule=cosine: step it runs at warm-up(it) * (f + (1 - f)(1 + cos(pi it / iters)) / 2)
    of lr_mesh, the rate the optimizer really used; bad schedule settings are refused by name."""
    cfg = TrainConfig(mode="mesh", data_dir=str(data_dir), iters=4, lr_warmup=2, lr_mesh=1e-3,
                      lr_schedule="cosine", lr_final=0.2, out_dir=str(tmp_path / "c"),
                      **(TINY | {"predictor_arch": "compact", "predictor_modes": 20}))
    trainer = Trainer(cfg, progress=False)
    seen = []
    real_step = trainer.optimizers["predictor"].step
    trainer.optimizers["predictor"].step = lambda *a, **k: (seen.append(
        trainer.optimizers["predictor"].param_groups[0]["lr"]), real_step(*a, **k))[1]
    trainer.run()
    # it = 0..3, iters = 4: cos(0)=1, cos(pi/4), cos(pi/2)=0, cos(3pi/4); warm-up 0.5 then 1
    c = [1.0, 0.5 + 0.5 * 2 ** -0.5, 0.5, 0.5 - 0.5 * 2 ** -0.5]
    expected = [1e-3 * w * (0.2 + 0.8 * ci) for w, ci in zip([0.5, 1, 1, 1], c)]
    np.testing.assert_allclose(seen, expected, rtol=1e-12)
    for bad, field in (({"lr_schedule": "step"}, "lr_schedule"), ({"lr_final": 1.5}, "lr_final")):
        with pytest.raises(ValueError, match=field):
            cfg.replace(**bad)


def test_silhouette_variants_reach_the_mesh_loss_renders(data_dir, tmp_path):
    """silhouette="soft" renders the loss's silhouettes with SoftRas's soft silhouette (values
    strictly between 0 and 1 at the outline, equal to soft_silhouette's), edge_range reaches the
    Eq. 1 backward; both train with finite losses; bad values are refused by name."""
    from training.loop.trainer import render_views
    from training.render import cameras_to_tensor
    from training.render.soft import soft_silhouette

    mesh = icosphere(2)
    v = torch.tensor(np.asarray(mesh.vertices), dtype=torch.float32)[None] * 0.7
    f = torch.tensor(np.asarray(mesh.faces))
    cams = cameras_to_tensor([look_at(30.0, 30.0), look_at(120.0, 30.0)])[None]  # (1, 2, 16)
    base = TrainConfig(mode="mesh", render_size=32)
    soft = render_views(v, f, cams, base.replace(silhouette="soft", soft_sigma=3e-4)).silhouette
    assert bool(((soft > 0.05) & (soft < 0.95)).any())
    torch.testing.assert_close(soft, soft_silhouette(v.expand(2, -1, -1), f, cams[0], 32, sigma=3e-4))
    grads = []
    for er in (1, 3):
        w = v.clone().requires_grad_()
        (render_views(w, f, cams, base.replace(edge_range=er)).silhouette * torch.linspace(-1, 1, 32)).sum().backward()
        grads.append(w.grad)
    assert float((grads[0] - grads[1]).abs().max()) > 0
    for variant in ({"silhouette": "soft"}, {"edge_range": 4}):
        cfg = TrainConfig(mode="mesh", data_dir=str(data_dir), out_dir=str(tmp_path / str(variant)), iters=2,
                          **(TINY | variant))
        metrics = Trainer(cfg, progress=False).run()
        assert all(np.isfinite(x) for x in metrics.values()), metrics
    for bad, field in (({"silhouette": "hard"}, "silhouette"), ({"edge_range": 0}, "edge_range"),
                       ({"soft_sigma": 0.0}, "soft_sigma")):
        with pytest.raises(ValueError, match=field):
            base.replace(**bad)


def test_generator_arch_binds_a_resume_only_where_there_is_a_generator(data_dir, tmp_path):
    """A mesh run (no generator) resumes whatever generator_arch says (old mesh checkpoints load as
    'pix2pix'); a normals run refuses to resume with another generator architecture."""
    mesh_cfg = TrainConfig(mode="mesh", data_dir=str(data_dir), out_dir=str(tmp_path / "m"), iters=1,
                           generator_arch="pix2pix", **TINY)
    Trainer(mesh_cfg, progress=False).run()
    resumed = Trainer(mesh_cfg.replace(generator_arch="resize", iters=2), progress=False)
    assert resumed.iteration == 1
    norm_cfg = TrainConfig(mode="normals", data_dir=str(data_dir), out_dir=str(tmp_path / "n"), iters=1,
                           generator_arch="pix2pix", **TINY)
    Trainer(norm_cfg, progress=False).run()
    with pytest.raises(TrainingError, match="generator_arch"):
        Trainer(norm_cfg.replace(generator_arch="resize", iters=2), progress=False)


def test_init_mesh_widens_a_narrower_compact_predictor(data_dir, tmp_path, capsys):
    """--init-mesh from a run with smaller fully connected layers: the wider predictor starts as the same function."""
    small = tmp_path / "small"
    assert cli(["train", "mesh", "--data", str(data_dir), "--out", str(small), "--iters", "1", "--ckpt-every", "1",
                *TINY_FLAGS]) == 0, capsys.readouterr().err
    wide = Trainer(TrainConfig(mode="mesh", data_dir=str(data_dir), out_dir=str(tmp_path / "wide"), iters=1,
                               init_mesh=str(small), **{**TINY, "predictor_hidden": 48, "predictor_latent": 24}),
                   progress=False)
    narrow = Trainer(TrainConfig(mode="mesh", data_dir=str(data_dir), out_dir=str(tmp_path / "narrow"), iters=1,
                                 init_mesh=str(small), **TINY), progress=False)
    a, b = wide.models["predictor"].eval(), narrow.models["predictor"].eval()
    assert a.decoder[0].out_features == 48 and b.decoder[0].out_features == 32
    x = torch.rand(2, 3, 64, 64)
    for u, v in zip(a(x), b(x)):
        torch.testing.assert_close(u, v, rtol=1e-5, atol=1e-6)
    assert "widened" in (tmp_path / "wide" / "events.log").read_text()
    # narrower than the run's is refused up front, in one line
    rc = cli(["train", "mesh", "--data", str(data_dir), "--out", str(tmp_path / "bad"), "--iters", "1",
              "--init-mesh", str(small), *TINY_FLAGS, "--predictor-hidden", "16"])
    err = capsys.readouterr().err
    assert rc == 2 and "predictor_hidden 32 there, 16 here" in err and "Traceback" not in err


def test_init_mesh_deepens_a_compact_predictor_and_it_exports(data_dir, tmp_path, capsys):
    """--init-mesh from a run without encoder blocks into --predictor-blocks 1: same function at the start; the deeper
    predictor exports to ONNX (parity-checked against torch); the other way round is refused in one line."""
    from training.export.to_onnx import export_models

    small = tmp_path / "small"
    assert cli(["train", "mesh", "--data", str(data_dir), "--out", str(small), "--iters", "1", "--ckpt-every", "1",
                *TINY_FLAGS]) == 0, capsys.readouterr().err
    deep = Trainer(TrainConfig(mode="mesh", data_dir=str(data_dir), out_dir=str(tmp_path / "deep"), iters=1,
                               init_mesh=str(small), **{**TINY, "predictor_blocks": 1}), progress=False)
    plain = Trainer(TrainConfig(mode="mesh", data_dir=str(data_dir), out_dir=str(tmp_path / "plain"), iters=1,
                                init_mesh=str(small), **TINY), progress=False)
    a, b = deep.models["predictor"].eval(), plain.models["predictor"].eval()
    assert a.num_blocks == 1 and b.blocks is None
    x = torch.rand(2, 3, 64, 64)
    for u, v in zip(a(x), b(x)):
        torch.testing.assert_close(u, v, rtol=1e-5, atol=1e-6)
    deep.run()
    reports = export_models(None, deep.models["predictor"], tmp_path / "onnx", config_json=deep.cfg.to_json(),
                            code_version="t", sketches=torch.zeros(1, 1, 256, 256), normals64=torch.rand(2, 3, 64, 64))
    assert len(reports) == 1 and (tmp_path / "onnx" / "mesh_predictor.onnx").stat().st_size > 0
    rc = cli(["train", "mesh", "--data", str(data_dir), "--out", str(tmp_path / "bad"), "--iters", "1",
              "--init-mesh", str(tmp_path / "deep"), *TINY_FLAGS])
    err = capsys.readouterr().err
    assert rc == 2 and "predictor_blocks 1 there, 0 here" in err and "Traceback" not in err


def test_render_views_passes_normal_edges_to_the_rasterizer():
    """cfg.normal_edges reaches the loss's renders: the same normal image, and without the edge gradient the normal
    image's gradient is the interior one (the rasterizer's own normal_edges=False), with it the Eq. 1 one."""
    from training.loop.trainer import render_views
    from training.render import cameras_to_tensor, rasterize

    m = icosphere(1, 0.35)
    cams = cameras_to_tensor([look_at(20.0, 15.0)], dtype=torch.float64)
    faces = torch.as_tensor(np.array(m.faces))
    for edges in (True, False):
        v = torch.as_tensor(np.array(m.vertices), dtype=torch.float64)[None].requires_grad_(True)
        out = render_views(v, faces, cams.view(1, 1, 16), TrainConfig(render_size=32, normal_edges=edges))
        g, = torch.autograd.grad(out.normals.sum(), v)
        v2 = v.detach().clone().requires_grad_(True)
        ref = rasterize(v2, faces, cams, 32, normal_edges=edges)
        g2, = torch.autograd.grad(ref.normals.sum(), v2)
        torch.testing.assert_close(out.normals, ref.normals)
        torch.testing.assert_close(g, g2)
        if edges:
            g_edges = g
    assert (g_edges - g).abs().max() > 1e-3  # the two settings differ


def test_normal_edges_is_off_by_default_and_old_runs_keep_the_papers_gradient():
    """New runs keep the normal image's edge gradient off the outline; a config saved before the field existed
    (no key) ran with the paper's Eq. 1 gradient on the normal image and loads so; the flag sets either."""
    from sketchmesh.cli import build_parser
    from training.cli.train import config_from_args

    assert TrainConfig().normal_edges is False
    old = TrainConfig(normal_edges=True).to_dict()
    del old["normal_edges"]
    assert TrainConfig.from_dict(old).normal_edges is True
    for saved in (True, False):  # a saved value is kept either way
        assert TrainConfig.from_json(TrainConfig(normal_edges=saved).to_json()).normal_edges is saved
    for flags, want in (([], False), (["--normal-edges"], True), (["--normal-edges", "--no-normal-edges"], False)):
        args = build_parser().parse_args(["train", "mesh", "--data", "d", "--out", "o", *flags])
        assert config_from_args(args).normal_edges is want


def test_slim_copy_keeps_the_models_and_drops_the_optimiser(tmp_path):
    from training.loop.checkpoint import save_slim_copy

    model, opt = _tiny_state()
    assert save_slim_copy(tmp_path / "run", tmp_path / "none.pt") is None and not (tmp_path / "none.pt").exists()
    for it in (4, 7):
        save_checkpoint(tmp_path / "run", it, TrainConfig().to_json(), "v", {"m": model}, {"m": opt})
    assert save_slim_copy(tmp_path / "run", tmp_path / "slim.pt") == 7
    slim = torch.load(tmp_path / "slim.pt", weights_only=True)
    full = load_latest_checkpoint(tmp_path / "run")
    assert slim["optimizers"] == {} and "rng" not in slim and "path" not in slim
    assert slim["iteration"] == 7 and slim["config"] == full["config"]
    assert all(torch.equal(slim["models"]["m"][k], v) for k, v in model.state_dict().items())
    placed = tmp_path / "placed" / "checkpoints"  # fetch-gpu's layout: loadable as a run
    placed.mkdir(parents=True)
    (placed / "ckpt_00000007.pt").write_bytes((tmp_path / "slim.pt").read_bytes())
    assert load_latest_checkpoint(tmp_path / "placed")["iteration"] == 7
    assert (tmp_path / "slim.pt").stat().st_size < checkpoint_paths(tmp_path / "run")[0].stat().st_size


def test_init_mesh_resmooths_a_predictor_trained_with_another_damping(data_dir, tmp_path, capsys):
    """--init-mesh from a run with basis damping 16 into --predictor-smoothing 4: the same function at the start, the
    basis rescaled per mode, and the event logged; the re-smoothed run then trains and resumes in its own damping."""
    src = tmp_path / "src"
    assert cli(["train", "mesh", "--data", str(data_dir), "--out", str(src), "--iters", "1", "--ckpt-every", "1",
                *TINY_FLAGS]) == 0, capsys.readouterr().err
    same = Trainer(TrainConfig(mode="mesh", data_dir=str(data_dir), out_dir=str(tmp_path / "same"), iters=1,
                               init_mesh=str(src), **TINY), progress=False)
    soft = Trainer(TrainConfig(mode="mesh", data_dir=str(data_dir), out_dir=str(tmp_path / "soft"), iters=1,
                               init_mesh=str(src), predictor_smoothing=4.0, **TINY), progress=False)
    a, b = same.models["predictor"].eval(), soft.models["predictor"].eval()
    x = torch.rand(2, 3, 64, 64)
    for u, v in zip(a(x), b(x)):
        torch.testing.assert_close(u, v, rtol=1e-5, atol=1e-6)
    gain_a, gain_b = a.basis.norm(dim=0), b.basis.norm(dim=0)
    assert torch.all(gain_b >= gain_a * (1 - 1e-6)) and gain_b[-1] > 3 * gain_a[-1]
    assert "re-smoothed" in (tmp_path / "soft" / "events.log").read_text()
    assert "re-smoothed" not in (tmp_path / "same" / "events.log").read_text()
    soft.run()
    assert cli(["train", "mesh", "--data", str(data_dir), "--out", str(tmp_path / "soft"), "--iters", "2",
                *TINY_FLAGS, "--predictor-smoothing", "4"]) == 0, capsys.readouterr().err


def test_aligned_branch_samples_the_image_where_each_vertex_lands(data_dir):
    """The grid the aligned branch samples with puts a dataset mesh's vertices on its own silhouette in the input
    view: the silhouette sampled (bilinear) at the projected vertices is on or inside it; a quarter of the image to the
    side many are not."""
    from training.data.dataset import ShapeViewDataset
    from training.model.networks import framed_ndc

    ds = ShapeViewDataset(data_dir, "train", extra_views=0, augment_strength=0.0)
    for i in (0, len(ds) - 1):
        item = ds[i]
        mesh = ds.load_mesh(item["category"], item["shape_id"])
        r_in = np.asarray(item["camera"])[:9].reshape(3, 3)
        view = torch.from_numpy(np.asarray(mesh.vertices, np.float64) @ r_in.T)[None]
        uv = framed_ndc(view)
        grid = torch.stack([uv[..., 0], -uv[..., 1]], dim=-1).unsqueeze(2)
        sil = torch.as_tensor(np.asarray(item["silhouette64"]), dtype=torch.float64).reshape(1, 1, 64, 64)
        on = torch.nn.functional.grid_sample(sil, grid, align_corners=False).flatten()
        shifted = torch.nn.functional.grid_sample(sil, grid + torch.tensor([0.5, 0.0], dtype=grid.dtype),
                                                  align_corners=False).flatten()
        # a vertex on the outline samples about 0.5 (bilinear across the edge); all but a corner or two are on or inside
        assert (on > 0.2).double().mean() > 0.97 and on.mean() > 0.8, (float((on > 0.2).double().mean()), float(on.mean()))
        assert (shifted > 0.2).double().mean() < 0.9, float((shifted > 0.2).double().mean())

