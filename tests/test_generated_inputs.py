"""Generated predictor inputs (training.data.generated): what is stored, resuming, and training on them."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from engine.pipeline import SketchEngine, downsample_normals  # noqa: E402
from training.data.augment import render_sketch  # noqa: E402
from training.data.dataset import DatasetError, ShapeViewDataset  # noqa: E402
from training.data.generated import ROW_SEED, build_generated, generated_dir, open_generated  # noqa: E402
from training.data.mesh_cache import open_mesh_cache  # noqa: E402
from training.data.render import view_polylines  # noqa: E402
from training.loop.config import TrainConfig  # noqa: E402
from training.loop.trainer import Trainer, make_dataset  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from onnx_fixtures import write_fixture_models  # noqa: E402
from synthetic_data import write_synthetic_dataset  # noqa: E402

TINY = dict(batch=3, predictor_channels=8, predictor_hidden=32, predictor_latent=16, template_level=2, extra_views=1,
            log_every=1, val_every=0, ckpt_every=0, plot_every=0, device="cpu", lambda_n=0.002)
torch.set_num_threads(2)


def _with_strokes(root: Path) -> None:
    """Give every view of every shape file one stroke (the synthetic files have none), so sketches differ per view."""
    for f in sorted(root.glob("shapes/*/*.npz")):
        with np.load(f) as z:
            arrays = {k: z[k] for k in z.files}
        n = arrays["sketch"].shape[0]
        pts = np.array([[[40.0 + 30 * v, 60.0], [200.0, 90.0 + 25 * v]] for v in range(n)]).reshape(-1, 2)
        arrays["poly_points"] = pts.astype(np.float32)
        arrays["poly_offsets"] = np.arange(0, 2 * n + 1, 2, dtype=np.int64)
        arrays["poly_kinds"] = np.zeros(n, np.int8)
        arrays["view_poly_offsets"] = np.arange(n + 1, dtype=np.int64)
        np.savez_compressed(f, **arrays)


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    base = tmp_path_factory.mktemp("gen")
    data = write_synthetic_dataset(base / "data", splits=("train", "train", "val"), views=3)
    _with_strokes(data)
    from training.data.dataset import write_manifest

    write_manifest(data)
    return data, write_fixture_models(base / "models", level=2)


def test_stored_rows_are_the_app_engines_normals_of_the_augmented_sketch(setup):
    """Row r holds what the app's engine draws from view r's sketch, area-averaged to 64; only the split's rows."""
    data, models = setup
    r = build_generated(data, models, "fx", split="train", augment_strength=0.7, seed=3, progress=False)
    assert r["written"] == r["done"] == r["views"] == 12  # 2 categories x 2 train shapes x 3 views
    g = open_generated(data, "fx")
    arrays = open_mesh_cache(data)
    engine = SketchEngine(models, threads=1)
    engine.load()
    manifest = json.loads((data / "manifest.json").read_text())
    for s in manifest["shapes"]:
        first, nv = arrays.rows[s["file"]]
        assert bool(g.done[first:first + nv].all()) == (s["split"] == "train")
        if s["split"] != "train":
            with pytest.raises(DatasetError, match="was not generated"):
                g.rows(np.array([first]))
            continue
        with np.load(data / s["file"]) as z:
            polys = {k: z[k] for k in ("view_poly_offsets", "poly_offsets", "poly_points")}
        for v in range(nv):
            sketch = render_sketch(view_polylines(polys, v), 256, 0.7, [3, ROW_SEED, first + v])
            assert sketch.max() > 0.5  # a stroke was drawn
            x = sketch[None, None].astype(np.float32)
            (normals,) = engine._generator.session.run(None, {engine._generator.input_name: x})
            want = downsample_normals(np.clip(normals, 0, 1))[0]
            got = g.rows(np.array([first + v]))[0]
            np.testing.assert_allclose(got, want, atol=2e-3)  # float16 storage
    assert not np.allclose(g.rows(np.array([0])), g.rows(np.array([1])))  # views differ


def test_a_stopped_build_resumes_and_other_settings_are_refused(setup):
    data, models = setup
    first = build_generated(data, models, "resume", max_shapes=1, progress=False)
    assert first["written"] == 3 and first["done"] == 3
    rest = build_generated(data, models, "resume", progress=False)
    assert rest["written"] == 9 and rest["done"] == 12
    again = build_generated(data, models, "resume", progress=False)
    assert again["written"] == 0
    whole = build_generated(data, models, "whole", progress=False)
    a, b = open_generated(data, "resume"), open_generated(data, "whole")
    np.testing.assert_array_equal(a.normals64[a.done], b.normals64[b.done])
    with pytest.raises(DatasetError, match="other seed"):
        build_generated(data, models, "resume", seed=1, progress=False)
    with pytest.raises(DatasetError, match="plain folder name"):
        generated_dir(data, "../x")
    assert whole["done"] == 12


def test_dataset_items_carry_the_generated_input_and_keep_true_targets(setup):
    data, models = setup
    build_generated(data, models, "items", progress=False)
    g = open_generated(data, "items")
    full = ShapeViewDataset(data, "train", extra_views=1, fields="mesh", input_normals="items")
    plain = ShapeViewDataset(data, "train", extra_views=1, fields="mesh")
    rows = [full._arrays.row(full._shapes[si]["file"]) + v for si, v in full._items]
    batch = full.__getitems__(list(range(len(full))))
    for i, item in enumerate(batch):
        np.testing.assert_array_equal(item["input64"].numpy(), g.rows(np.array([rows[i]]))[0])
        np.testing.assert_array_equal(item["normals64"].numpy(), plain[i]["normals64"].numpy())  # the target
        np.testing.assert_array_equal(full[i]["input64"].numpy(), item["input64"].numpy())
    half = ShapeViewDataset(data, "train", extra_views=1, fields="mesh", input_normals="items", input_share=0.5, seed=1)
    picked = [half.uses_generated(i) for i in range(len(half))]
    assert 0 < sum(picked) < len(half)
    for i, item in enumerate(half.__getitems__(list(range(len(half))))):
        want = g.rows(np.array([rows[i]]))[0] if picked[i] else item["normals64"].numpy()
        np.testing.assert_array_equal(item["input64"].numpy(), want)
    with pytest.raises(DatasetError, match="no generated normals 'nope'"):
        ShapeViewDataset(data, "train", fields="mesh", input_normals="nope")
    with pytest.raises(DatasetError, match="needs fields='mesh'"):
        ShapeViewDataset(data, "train", input_normals="items")
    with pytest.raises(DatasetError, match="was not generated"):  # the val split was not built
        ShapeViewDataset(data, "val", extra_views=1, fields="mesh", input_normals="items").__getitems__([0])


def test_several_sets_make_every_view_set_pair(setup):
    """Two sets (other seeds): item i is view i % V with set i // V's input; targets stay the view's true images."""
    data, models = setup
    build_generated(data, models, "pair0", seed=0, progress=False)
    build_generated(data, models, "pair1", seed=1, augment_strength=1.0, progress=False)
    sets = [open_generated(data, n) for n in ("pair0", "pair1")]
    one = ShapeViewDataset(data, "train", extra_views=1, fields="mesh", input_normals="pair0")
    both = ShapeViewDataset(data, "train", extra_views=1, fields="mesh", input_normals="pair0,pair1")
    listed = ShapeViewDataset(data, "train", extra_views=1, fields="mesh", input_normals=["pair0", "pair1"])
    V = len(one)
    assert len(both) == len(listed) == 2 * V
    rows = [one._arrays.row(one._shapes[si]["file"]) + v for si, v in one._items]
    assert not np.array_equal(sets[0].rows(np.array(rows)), sets[1].rows(np.array(rows)))  # the sets differ
    batch = both.__getitems__(list(range(2 * V)))
    for i, item in enumerate(batch):
        k, j = divmod(i, V)
        np.testing.assert_array_equal(item["input64"].numpy(), sets[k].rows(np.array([rows[j]]))[0])
        np.testing.assert_array_equal(item["normals64"].numpy(), one[j]["normals64"].numpy())
        assert (item["shape_id"], item["view"]) == (one[j]["shape_id"], one[j]["view"])
        np.testing.assert_array_equal(both[i]["input64"].numpy(), item["input64"].numpy())
        np.testing.assert_array_equal(listed[i]["input64"].numpy(), item["input64"].numpy())
    for bad in ("pair0,pair0", "pair0,"):
        with pytest.raises(DatasetError, match="distinct sets"):
            ShapeViewDataset(data, "train", fields="mesh", input_normals=bad)
    with pytest.raises(DatasetError, match="no generated normals 'nope'"):
        ShapeViewDataset(data, "train", fields="mesh", input_normals="pair0,nope")


def test_mesh_training_reads_the_generated_input(setup, tmp_path, monkeypatch):
    """With generated inputs equal to the true images a run is the plain run; with other inputs it differs."""
    data, models = setup
    build_generated(data, models, "train_in", progress=False)
    cfg = TrainConfig(mode="mesh", data_dir=str(data), iters=2, **TINY)
    plain = Trainer(cfg.replace(out_dir=str(tmp_path / "plain")), progress=False)
    plain.run()
    gen = Trainer(cfg.replace(out_dir=str(tmp_path / "gen"), input_normals="train_in"), progress=False)
    assert gen.train_set._inputs is not None
    assert make_dataset(gen.cfg, "val", "mesh")._inputs is None  # validation reads the true images
    gen.run()
    a, b = plain.models["predictor"].state_dict(), gen.models["predictor"].state_dict()
    assert not all(torch.equal(a[k], b[k]) for k in a)
    # the same run with the generated rows replaced by the true images is the plain run, bit for bit
    g = open_generated(data, "train_in")
    arrays = open_mesh_cache(data)
    monkeypatch.setattr(type(g), "rows", lambda self, rows: np.ascontiguousarray(
        arrays.normals64[np.asarray(rows)].transpose(0, 3, 1, 2), np.float32))
    same = Trainer(cfg.replace(out_dir=str(tmp_path / "same"), input_normals="train_in"), progress=False)
    same.run()
    c = same.models["predictor"].state_dict()
    assert all(torch.equal(a[k], c[k]) for k in a)


def test_config_and_cli_errors_are_one_line(setup, tmp_path):
    data, _ = setup
    with pytest.raises(ValueError, match="input_normals .* mesh mode only"):
        TrainConfig(mode="normals", data_dir=str(data), input_normals="x")
    with pytest.raises(ValueError, match="input_share must be in"):
        TrainConfig(mode="mesh", data_dir=str(data), input_normals="x", input_share=0.0)
    cli = [sys.executable, "-m", "sketchmesh", "data", "generated", str(data), "--name", "cli"]
    r = subprocess.run([*cli, "--models", str(tmp_path / "missing")], capture_output=True, text=True, timeout=120)
    assert r.returncode != 0 and "Traceback" not in r.stderr and "does not exist" in r.stderr
    r = subprocess.run([*cli, "--models", str(tmp_path), "--workers", "0"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "Traceback" not in r.stderr and "--workers" in r.stderr


BUNDLED = Path(__file__).resolve().parents[1] / "assets" / "models"


def test_the_torch_runner_stores_what_onnx_runtime_stores(setup, tmp_path):
    """data generated --torch-device (the GPU machine's path): the generator rebuilt from the bundled file runs in
    torch; every row, plain and mirrored, equals ONNX Runtime's row within the float16 storage."""
    from engine.errors import ModelError
    from training.export.from_onnx import generator_from_onnx

    data, fixture_models = setup
    net = generator_from_onnx(BUNDLED / "generator.onnx")
    for mirror in (False, True):
        ort = build_generated(data, BUNDLED, f"ort{mirror}", progress=False, mirror=mirror)
        tch = build_generated(data, BUNDLED, f"torch{mirror}", progress=False, mirror=mirror, torch_generator=net,
                              workers=2)
        assert ort["done"] == tch["done"] == tch["views"] == 12
        done = open_generated(data, f"ort{mirror}").done
        rows = np.flatnonzero(done)
        a = open_generated(data, f"ort{mirror}").rows(rows).astype(np.float32)
        b = open_generated(data, f"torch{mirror}").rows(rows).astype(np.float32)
        assert a.max() > 0.3 and a.std() > 0.01  # the generator painted something: not a constant image
        np.testing.assert_allclose(b, a, atol=2e-3)
    with pytest.raises(ModelError, match="training config"):  # a file that is no exported generator
        generator_from_onnx(fixture_models / "generator.onnx")
    cli = [sys.executable, "-m", "sketchmesh", "data", "generated", str(data), "--models", str(BUNDLED), "--name", "c"]
    r = subprocess.run([*cli, "--torch-device", "banana"], capture_output=True, text=True, timeout=120)
    assert r.returncode != 0 and "Traceback" not in r.stderr and "not a torch device" in r.stderr


def test_a_mirrored_set_is_the_engine_on_the_flipped_drawing(setup):
    """--mirror rows: the app engine's normals of the same augmented drawing flipped left to right."""
    data, models = setup
    build_generated(data, models, "flip", augment_strength=0.7, seed=3, mirror=True, progress=False)
    build_generated(data, models, "noflip", augment_strength=0.7, seed=3, progress=False)
    g, plain = open_generated(data, "flip"), open_generated(data, "noflip")
    assert g.info["mirror"] is True and plain.info["mirror"] is False
    engine = SketchEngine(models, threads=1)
    engine.load()
    arrays = open_mesh_cache(data)
    s = next(s for s in json.loads((data / "manifest.json").read_text())["shapes"] if s["split"] == "train")
    first, nv = arrays.rows[s["file"]]
    with np.load(data / s["file"]) as z:
        polys = {k: z[k] for k in ("view_poly_offsets", "poly_offsets", "poly_points")}
    for v in range(nv):
        sketch = render_sketch(view_polylines(polys, v), 256, 0.7, [3, ROW_SEED, first + v])
        x = np.ascontiguousarray(sketch[:, ::-1], np.float32)[None, None]
        (normals,) = engine._generator.session.run(None, {engine._generator.input_name: x})
        np.testing.assert_allclose(g.rows(np.array([first + v]))[0], downsample_normals(np.clip(normals, 0, 1))[0],
                                   atol=2e-3)
        assert not np.allclose(g.rows(np.array([first + v])), plain.rows(np.array([first + v])), atol=1e-2)
    with pytest.raises(DatasetError, match="other mirror"):  # a mirrored folder is not resumed as a plain one
        build_generated(data, models, "flip", augment_strength=0.7, seed=3, progress=False)


def test_mirrored_items_read_their_exact_inputs(setup):
    """input64_mirror: the mirrored set's row (generated items) or the true image mirrored exactly (true items);
    mirror_batch puts it in place of a flagged item's flipped input and drops it."""
    from training.data.mirror import mirror_batch, mirror_normal_image

    data, models = setup
    build_generated(data, models, "m_in", progress=False)
    build_generated(data, models, "m_in_flip", mirror=True, progress=False)
    gm = open_generated(data, "m_in_flip")
    ds = ShapeViewDataset(data, "train", extra_views=1, fields="mesh", input_normals="m_in", mirror_inputs="m_in_flip")
    rows = [ds._arrays.row(ds._shapes[si]["file"]) + v for si, v in ds._items]
    items = ds.__getitems__(list(range(len(ds))))
    for i, item in enumerate(items):
        np.testing.assert_array_equal(item["input64_mirror"].numpy(), gm.rows(np.array([rows[i]]))[0])
        np.testing.assert_array_equal(ds[i]["input64_mirror"].numpy(), item["input64_mirror"].numpy())
    half = ShapeViewDataset(data, "train", extra_views=1, fields="mesh", input_normals="m_in",
                            mirror_inputs="m_in_flip", input_share=0.5, seed=1)
    picked = [half.uses_generated(i) for i in range(len(half))]
    assert 0 < sum(picked) < len(half)
    for i, item in enumerate(half.__getitems__(list(range(len(half))))):
        want = (gm.rows(np.array([rows[i]]))[0] if picked[i]
                else mirror_normal_image(item["normals64"], item["silhouette64"]).numpy())
        np.testing.assert_allclose(item["input64_mirror"].numpy(), want, atol=1e-6)
    batch = torch.utils.data.default_collate(items[:2])
    out = mirror_batch(batch, torch.tensor([False, True]))
    assert "input64_mirror" not in out and "input64_mirror" not in mirror_batch(batch, torch.tensor([False, False]))
    assert torch.equal(out["input64"][0], batch["input64"][0])
    assert torch.equal(out["input64"][1], batch["input64_mirror"][1])
    build_generated(data, models, "m_in_flip_s1", mirror=True, seed=1, progress=False)
    for bad, match in (("m_in", "must be a mirrored set"), ("m_in_flip_s1", "differ in seed"),
                       ("m_in_flip,m_in_flip_s1", "one mirrored set per input set")):
        with pytest.raises(DatasetError, match=match):
            ShapeViewDataset(data, "train", fields="mesh", input_normals="m_in", mirror_inputs=bad)
    with pytest.raises(DatasetError, match="needs input_normals"):
        ShapeViewDataset(data, "train", fields="mesh", mirror_inputs="m_in_flip")
    with pytest.raises(DatasetError, match="is a mirrored set"):  # a mirrored set named as the items' own input
        ShapeViewDataset(data, "train", fields="mesh", input_normals="m_in_flip")
    build_generated(data, models, "m_in_part", mirror=True, max_shapes=1, progress=False)
    with pytest.raises(DatasetError, match="lacks rows"):  # a stopped mirrored build is refused up front
        ShapeViewDataset(data, "train", fields="mesh", input_normals="m_in", mirror_inputs="m_in_part")
    with pytest.raises(ValueError, match="mirror_inputs .* needs mirror > 0"):
        TrainConfig(mode="mesh", data_dir=str(data), input_normals="m_in", mirror_inputs="m_in_flip")


def test_training_with_exact_mirrored_inputs(setup, tmp_path, monkeypatch):
    """A run with mirror_inputs whose rows are the flipped generated images is the run without them, bit for bit;
    with the real mirrored rows it differs."""
    from training.data.mirror import mirror_normal_image

    data, models = setup
    build_generated(data, models, "t_in", progress=False)
    build_generated(data, models, "t_in_flip", mirror=True, progress=False)
    cfg = TrainConfig(mode="mesh", data_dir=str(data), iters=2, input_normals="t_in", mirror=1.0, **TINY)
    approx = Trainer(cfg.replace(out_dir=str(tmp_path / "approx")), progress=False)
    approx.run()
    exact = Trainer(cfg.replace(out_dir=str(tmp_path / "exact"), mirror_inputs="t_in_flip"), progress=False)
    exact.run()
    a, b = approx.models["predictor"].state_dict(), exact.models["predictor"].state_dict()
    assert not all(torch.equal(a[k], b[k]) for k in a)
    g, gm = open_generated(data, "t_in"), open_generated(data, "t_in_flip")
    monkeypatch.setattr(type(gm), "rows", lambda self, rows: mirror_normal_image(
        torch.from_numpy(_stored_rows(g, rows))).numpy() if self.info["mirror"] else _stored_rows(g, rows))
    assert exact.train_set._mirrors is not None
    assert make_dataset(exact.cfg, "val", "mesh")._mirrors is None  # validation reads the true images
    same = Trainer(cfg.replace(out_dir=str(tmp_path / "same"), mirror_inputs="t_in_flip"), progress=False)
    same.run()
    c = same.models["predictor"].state_dict()
    assert all(torch.equal(a[k], c[k]) for k in a)


def _stored_rows(g, rows):  # the unpatched rows of a generated set (the test above patches the method)
    rows = np.asarray(rows, np.int64)
    return np.ascontiguousarray(g.normals64[rows].transpose(0, 3, 1, 2), np.float32)


def test_folders_from_before_mirrored_sets_are_unmirrored(setup):
    """An info.json without "mirror" (built before mirrored sets existed) resumes as unmirrored and pairs as one."""
    data, models = setup
    build_generated(data, models, "old", max_shapes=1, progress=False)
    info_path = generated_dir(data, "old") / "info.json"
    info = json.loads(info_path.read_text())
    del info["mirror"]
    info_path.write_text(json.dumps(info))
    assert build_generated(data, models, "old", progress=False)["written"] == 9  # resumed, not refused
    with pytest.raises(DatasetError, match="other mirror"):
        build_generated(data, models, "old", mirror=True, progress=False)
    build_generated(data, models, "old_flip", mirror=True, progress=False)
    ds = ShapeViewDataset(data, "train", fields="mesh", input_normals="old", mirror_inputs="old_flip")
    assert "input64_mirror" in ds[0]


def test_calibrating_an_import_ignores_the_mirrored_inputs(setup):
    """import-models' calibration reads the inputs the predictor trained on; a run's mirrored set is not needed."""
    from training.export.from_onnx import calibration_inputs

    data, models = setup
    build_generated(data, models, "cal_in", progress=False)
    cfg = TrainConfig(mode="mesh", data_dir=str(data), input_normals="cal_in", mirror=0.5, mirror_inputs="absent",
                      **TINY)
    x, what = calibration_inputs(cfg, count=4)
    assert x.shape == (4, 3, 64, 64) and "generated set cal_in" in what
    rows = open_generated(data, "cal_in")
    assert any(np.allclose(x[0].numpy(), rows.rows(np.array([r]))[0]) for r in np.nonzero(rows.done)[0])


def test_a_grown_dataset_copies_the_rows_of_the_shapes_it_shares(setup, tmp_path):
    """--reuse: rows of shapes held in equal files come from the other dataset's set (its draws, at its row numbers);
    a changed file is generated again, and the result does not depend on what an earlier call had written."""
    import shutil

    from training.data.dataset import write_manifest

    data, models = setup
    build_generated(data, models, "grow", seed=2, progress=False)
    grown = tmp_path / "grown"
    shutil.copytree(data / "shapes", grown / "shapes")  # equal bytes, not links: the content check decides
    manifest = json.loads((data / "manifest.json").read_text())
    train = [s["file"] for s in manifest["shapes"] if s["split"] == "train"]
    (grown / train[0]).unlink()  # every later row moves up: a fresh build would draw other sketches for them
    changed = train[1]
    with np.load(grown / changed) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["poly_points"] = arrays["poly_points"][:, ::-1].copy()  # another drawing
    np.savez_compressed(grown / changed, **arrays)
    write_manifest(grown)

    partial = build_generated(grown, models, "grow", seed=2, max_shapes=2, progress=False)  # an earlier, stopped call
    assert partial["written"] == 6 and partial["reused"] == 0
    r = build_generated(grown, models, "grow", seed=2, reuse_from=data, progress=False)
    shared = len(train) - 2
    assert r["reused"] == 3 * shared and r["done"] == r["views"] == 3 * (len(train) - 1)
    assert r["written"] == 0  # the changed shape was among the two the stopped call generated
    fresh = build_generated(grown, models, "fresh", seed=2, progress=False)
    assert fresh["written"] == 3 * (len(train) - 1)
    a, b, f = open_generated(data, "grow"), open_generated(grown, "grow"), open_generated(grown, "fresh")
    rows_a, rows_b = open_mesh_cache(data).rows, open_mesh_cache(grown).rows
    for file in train[1:]:
        (fa, nv), (fb, _) = rows_a[file], rows_b[file]
        if file == changed:  # generated here, as a fresh build does
            np.testing.assert_array_equal(b.normals64[fb:fb + nv], f.normals64[fb:fb + nv])
        else:  # the other dataset's rows, not this dataset's own draw
            np.testing.assert_array_equal(b.normals64[fb:fb + nv], a.normals64[fa:fa + nv])
            assert not np.array_equal(b.normals64[fb:fb + nv], f.normals64[fb:fb + nv])
    assert json.loads((generated_dir(grown, "grow") / "info.json").read_text())["reused_from"] == \
        [str(generated_dir(data, "grow").resolve())]
    other = tmp_path / "other"
    shutil.copytree(grown / "shapes", other / "shapes")
    write_manifest(other)
    with pytest.raises(DatasetError, match="other seed than"):  # the other set's settings, not this folder's
        build_generated(other, models, "grow", seed=3, reuse_from=data, progress=False)
    with pytest.raises(DatasetError, match="being built"):
        build_generated(grown, models, "grow", seed=2, reuse_from=grown, progress=False)
    with pytest.raises(DatasetError, match="no generated normals"):
        build_generated(grown, models, "nowhere", seed=2, reuse_from=data, progress=False)
