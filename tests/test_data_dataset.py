"""The dataset on disk (training.data.dataset), its loader, and the `sketchmesh data` commands."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from engine.camera import frame_camera, look_at  # noqa: E402
from training.data import dataset as ds  # noqa: E402
from training.data.shapes import make_shape  # noqa: E402

SIZE, SMALL, VIEWS = 64, 32, 3
SETTINGS = ds.BuildSettings(size=SIZE, small_size=SMALL, num_azimuths=VIEWS, elevations=(30.0,))
CATS = ["lamp", "table"]


@pytest.fixture(autouse=True)
def _threads():
    torch.set_num_threads(2)


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    root = tmp_path_factory.mktemp("data")
    jobs = ds.make_jobs("procedural", 2, CATS)
    summary = ds.build_dataset(root, jobs, SETTINGS, progress=False)
    return root, jobs, summary


def test_build_writes_one_file_per_shape_and_a_manifest_record_per_view(built):
    root, jobs, summary = built
    assert summary["rendered"] == 4 and summary["skipped"] == 0 and not summary["failed"]
    manifest = json.loads((root / ds.MANIFEST).read_text())
    assert manifest["format"] == ds.FORMAT_ID
    assert manifest["settings"]["size"] == SIZE and manifest["settings"]["num_azimuths"] == VIEWS
    assert len(manifest["shapes"]) == 4 and len(manifest["views"]) == 4 * VIEWS
    for job in jobs:
        path = ds.shape_file(root, job.category, job.shape_id)
        with np.load(path) as z:
            assert set(ds.SHAPE_KEYS) <= set(z.files)
            assert z["sketch"].shape == (VIEWS, SIZE, SIZE) and z["sketch"].dtype == np.uint8
            assert z["normals256"].shape == (VIEWS, SIZE, SIZE, 3) and z["normals256"].dtype == np.uint8
            assert z["normals64"].shape == (VIEWS, SMALL, SMALL, 3) and z["normals64"].dtype == np.float32
            assert z["cameras"].shape == (VIEWS, 16) and z["cameras"].dtype == np.float64
            np.testing.assert_allclose(z["azimuths"], [0.0, 120.0, 240.0])
            assert z["view_poly_offsets"][-1] == len(z["poly_offsets"]) - 1 == len(z["poly_kinds"])
            assert z["poly_offsets"][-1] == len(z["poly_points"])
            assert z["sketch"].max() == 255  # every view has ink
    views = [(v["shape_id"], v["view"], v["azimuth"]) for v in manifest["views"] if v["shape_id"] == jobs[0].shape_id]
    assert views == [(jobs[0].shape_id, k, 120.0 * k) for k in range(VIEWS)]


def test_rerun_skips_complete_shapes_and_redoes_a_corrupt_one(built, tmp_path):
    root, jobs, _ = built
    victim = ds.shape_file(root, jobs[1].category, jobs[1].shape_id)
    other = ds.shape_file(root, jobs[0].category, jobs[0].shape_id)
    mtime_other = other.stat().st_mtime_ns
    data = victim.read_bytes()
    victim.write_bytes(data[: len(data) // 2])  # a crash mid-copy
    summary = ds.build_dataset(root, jobs, SETTINGS, progress=False)
    assert summary["rendered"] == 1 and summary["skipped"] == 3
    assert other.stat().st_mtime_ns == mtime_other
    assert ds.read_meta(victim) is not None
    # other settings -> nothing is "complete"
    assert ds._is_complete(other, SETTINGS) and not ds._is_complete(other, ds.BuildSettings(size=SIZE + 1))


def test_loader_items_have_the_trainer_layout(built):
    root, _, _ = built
    data = ds.ShapeViewDataset(root, "all", extra_views=2, augment_strength=0.0, seed=0)
    assert len(data) == 4 * VIEWS and data.categories == CATS
    item = data[4]
    expected = {
        "sketch": ((1, SIZE, SIZE), torch.float32), "normals": ((3, SIZE, SIZE), torch.float32),
        "silhouette": ((1, SIZE, SIZE), torch.float32), "normals64": ((3, SMALL, SMALL), torch.float32),
        "silhouette64": ((SMALL, SMALL), torch.float32), "camera": ((16,), torch.float64),
        "other_normals64": ((2, 3, SMALL, SMALL), torch.float32), "other_silhouette64": ((2, SMALL, SMALL), torch.float32),
        "other_cameras": ((2, 16), torch.float64),
    }
    for key, (shape, dtype) in expected.items():
        assert tuple(item[key].shape) == shape and item[key].dtype == dtype, key
        assert torch.isfinite(item[key]).all()
    for key in ("sketch", "normals", "silhouette", "normals64", "silhouette64"):
        assert 0.0 <= float(item[key].min()) and float(item[key].max()) <= 1.0
    assert isinstance(item["category"], str) and isinstance(item["shape_id"], str) and isinstance(item["view"], int)
    # the camera is this view's framed camera, from an independent computation
    mesh = make_shape(item["category"], int(item["shape_id"].split("_")[-1]))
    cam = frame_camera(look_at(360.0 * item["view"] / VIEWS, 30.0), mesh.vertices)
    np.testing.assert_allclose(item["camera"].numpy(), cam.to_array(), atol=1e-12)
    # other views: other views of the same shape, consistent with their own items
    others = data.other_views(4)
    assert item["view"] not in others.tolist() and len(set(others.tolist())) == 2
    base = 4 - item["view"]
    for k, o in enumerate(others.tolist()):
        other_item = data[base + o]
        assert torch.equal(item["other_normals64"][k], other_item["normals64"])
        assert torch.equal(item["other_cameras"][k], other_item["camera"])
    # background normals are 0 exactly where the silhouette is 0
    bg = item["silhouette"][0] == 0
    assert float(item["normals"][:, bg].abs().max()) == 0.0
    # the trainer batches items with the default collate
    batch = next(iter(torch.utils.data.DataLoader(data, batch_size=3)))
    assert tuple(batch["sketch"].shape) == (3, 1, SIZE, SIZE) and len(batch["category"]) == 3


def test_augmented_items_are_deterministic_in_seed_and_index(built):
    root, _, _ = built
    a = ds.ShapeViewDataset(root, "all", extra_views=1, augment_strength=0.7, seed=3)
    b = ds.ShapeViewDataset(root, "all", extra_views=1, augment_strength=0.7, seed=3)
    c = ds.ShapeViewDataset(root, "all", extra_views=1, augment_strength=0.7, seed=4)
    clean = ds.ShapeViewDataset(root, "all", extra_views=1, augment_strength=0.0, seed=3)
    assert torch.equal(a[2]["sketch"], a[2]["sketch"]) and torch.equal(a[2]["sketch"], b[2]["sketch"])
    assert not torch.equal(a[2]["sketch"], c[2]["sketch"])
    assert not torch.equal(a[2]["sketch"], clean[2]["sketch"])
    assert torch.equal(a[2]["normals"], clean[2]["normals"])  # only the sketch is augmented
    assert np.array_equal(a.other_views(5), b.other_views(5))
    # strength 0 gives the stored clean sketch
    path = ds.shape_file(root, clean[2]["category"], clean[2]["shape_id"])
    with np.load(path) as z:
        assert torch.equal(clean[2]["sketch"][0], torch.from_numpy(z["sketch"][clean[2]["view"]] / np.float32(255.0)))


@pytest.mark.parametrize("strength", [0.0, 0.7])
def test_sketch_fields_are_the_full_item_without_its_256px_images(built, strength):
    # fields="sketch" (what an evaluation reads): every key of the full item but the 256 px normal image and
    # silhouette, equal to it (the augmented sketch too); a dataset built with it serves that from __getitem__
    root, _, _ = built
    data = ds.ShapeViewDataset(root, "all", extra_views=1, augment_strength=strength, seed=3)
    lean = ds.ShapeViewDataset(root, "all", extra_views=1, augment_strength=strength, seed=3, fields="sketch")
    for i in (0, 5):
        full, got = data[i], data.item(i, "sketch")
        assert set(got) == set(full) - {"normals", "silhouette"}
        for k, v in got.items():
            assert torch.equal(v, full[k]) if isinstance(v, torch.Tensor) else v == full[k], k
        assert set(lean[i]) == set(got) and torch.equal(lean[i]["sketch"], full["sketch"])
    with pytest.raises(ds.DatasetError, match="fields must be one of"):
        data.item(0, "normals")


def test_splits_categories_shapes_and_meshes(built):
    root, jobs, _ = built
    expected = {(j.category, j.shape_id, j.split) for j in jobs}
    full = ds.ShapeViewDataset(root, "all", extra_views=0)
    assert set(full.shapes()) == expected
    total = 0
    for split in ("train", "val", "test"):
        part = ds.ShapeViewDataset(root, split, extra_views=0)
        assert all(s[2] == split for s in part.shapes())
        total += len(part)
    assert total == len(full)
    lamps = ds.ShapeViewDataset(root, "all", extra_views=0, categories=["lamp"])
    assert lamps.categories == ["lamp"] and all(s[0] == "lamp" for s in lamps.shapes())
    j = jobs[0]
    m = full.load_mesh(j.category, j.shape_id)
    ref = make_shape(j.category, j.index)
    assert np.array_equal(m.vertices, ref.vertices) and np.array_equal(m.faces, ref.faces)
    item = full[0]
    assert tuple(item["other_cameras"].shape) == (0, 16)


def test_loader_errors_are_clear(built, tmp_path):
    root, _, _ = built
    with pytest.raises(ds.DatasetError, match="no manifest.json"):
        ds.ShapeViewDataset(tmp_path)
    with pytest.raises(ds.DatasetError, match="not in"):
        ds.ShapeViewDataset(root, categories=["spaceship"])
    with pytest.raises(ds.DatasetError, match="split"):
        ds.ShapeViewDataset(root, "training")
    with pytest.raises(ds.DatasetError, match="augment_strength"):
        ds.ShapeViewDataset(root, augment_strength=2.0)
    (tmp_path / ds.MANIFEST).write_text("{not json")
    with pytest.raises(ds.DatasetError, match="cannot read manifest"):
        ds.ShapeViewDataset(tmp_path)


def test_shards_merge_into_the_full_dataset(built, tmp_path):
    root, jobs, _ = built
    for k in range(2):
        ds.build_dataset(tmp_path / f"s{k}", jobs, SETTINGS, shard=(k, 2), progress=False)
    a = json.loads((tmp_path / "s0" / ds.MANIFEST).read_text())
    b = json.loads((tmp_path / "s1" / ds.MANIFEST).read_text())
    ids_a, ids_b = {s["shape_id"] for s in a["shapes"]}, {s["shape_id"] for s in b["shapes"]}
    assert not ids_a & ids_b and len(ids_a) == len(ids_b) == 2
    result = ds.merge_datasets(tmp_path / "merged", [tmp_path / "s0", tmp_path / "s1"])
    assert result["shapes"] == 4
    merged = json.loads((tmp_path / "merged" / ds.MANIFEST).read_text())
    full = json.loads((root / ds.MANIFEST).read_text())
    assert merged["views"] == full["views"] and merged["settings"] == full["settings"]
    with np.load(tmp_path / "merged" / merged["shapes"][0]["file"]) as z1, np.load(root / full["shapes"][0]["file"]) as z2:
        assert np.array_equal(z1["normals64"], z2["normals64"]) and np.array_equal(z1["sketch"], z2["sketch"])
    (tmp_path / "empty").mkdir()
    with pytest.raises(ds.DatasetError, match="not a dataset folder"):
        ds.merge_datasets(tmp_path / "m2", [tmp_path / "empty"])


def test_cli_builds_only_the_splits_asked_for_and_completes_them_later(tmp_path, capsys):
    # what a bare machine needs first for evaluation (val, test) in a fifth of the time; a later full build into the
    # same folder renders only the rest, and the evaluation shapes are the ones a full build makes
    from sketchmesh.cli import main
    from training.data.shapes import split_of

    n = 20
    want = {f"bench_{i:05d}" for i in range(n) if split_of("bench", i) in ("val", "test")}
    assert 0 < len(want) < n  # the hash split puts some of 20 shapes in each
    out = tmp_path / "d"
    flags = ["data", "--source", "procedural", "--shapes-per-category", str(n), "--categories", "bench", "--views", "2",
             "--size", "64", "--small-size", "32", "--out", str(out), "--no-progress"]
    assert main([*flags, "--splits", "val", "test"]) == 0
    manifest = json.loads((out / ds.MANIFEST).read_text())
    assert {s["shape_id"] for s in manifest["shapes"]} == want
    assert {s["split"] for s in manifest["shapes"]} <= {"val", "test"}
    capsys.readouterr()
    assert main(flags) == 0
    assert f"{n - len(want)} shapes rendered, {len(want)} already complete" in capsys.readouterr().out
    assert len(json.loads((out / ds.MANIFEST).read_text())["shapes"]) == n
    job = next(j for j in ds.make_jobs("procedural", n, ["bench"]) if j.shape_id in want)
    settings = ds.BuildSettings(size=64, small_size=32, num_azimuths=2, elevations=(30.0,))
    ds.build_dataset(tmp_path / "one", [job], settings, progress=False)
    name = f"shapes/bench/{job.shape_id}.npz"
    with np.load(out / name) as z1, np.load(tmp_path / "one" / name) as z2:
        assert np.array_equal(z1["sketch"], z2["sketch"]) and np.array_equal(z1["normals64"], z2["normals64"])
    assert split_of("bench", 0) == "train"  # shape 0 alone has no val shape: a clear error, not an empty dataset
    capsys.readouterr()
    assert main([*flags, "--shapes-per-category", "1", "--splits", "val"]) != 0
    assert "no shapes in the split(s) val" in capsys.readouterr().err


def test_cli_build_preview_merge_and_bad_input(tmp_path, capsys):
    import cv2

    from sketchmesh.cli import main

    out = tmp_path / "d"
    rc = main(["data", "--source", "procedural", "--shapes-per-category", "1", "--categories", "bench",
               "--views", "2", "--elevations", "10", "40", "--size", "64", "--small-size", "32", "--out", str(out),
               "--no-progress", "--augment-strength", "0.5", "--seed", "1"])
    assert rc == 0
    assert "1 shapes rendered" in capsys.readouterr().out
    with np.load(out / "shapes" / "bench" / "bench_00000.npz") as z:
        assert z["sketch_aug"].shape == (4, 64, 64) and not np.array_equal(z["sketch_aug"], z["sketch"])
        np.testing.assert_allclose(z["elevations"], [10.0, 10.0, 40.0, 40.0])  # elevation-major
        np.testing.assert_allclose(z["azimuths"], [0.0, 180.0, 0.0, 180.0])
    sheet = tmp_path / "sheet.png"
    assert main(["data", "preview", str(out), "-o", str(sheet)]) == 0
    img = cv2.imread(str(sheet))
    assert img is not None and img.shape[0] > 64 and img.shape[1] > 3 * 64
    assert main(["data", "merge", str(tmp_path / "m"), str(out)]) == 0
    assert (tmp_path / "m" / ds.MANIFEST).is_file()
    capsys.readouterr()
    # bad inputs: one line, non-zero, no traceback
    for argv, needle in [
        (["data", "--source", "bogus", "--out", str(tmp_path / "x")], "bad --source"),
        (["data", "--source", f"shapenet:{tmp_path / 'nope'}", "--out", str(tmp_path / "x")], "does not exist"),
        (["data", "--source", "procedural", "--shard", "3/2", "--out", str(tmp_path / "x")], "bad --shard"),
        (["data", "--source", "procedural", "--categories", "spaceship", "--out", str(tmp_path / "x")], "unknown categories"),
        (["data", "preview", str(tmp_path / "nope"), "-o", str(sheet)], "not a dataset folder"),
        (["data", "--source", "procedural"], "missing --out"),
    ]:
        assert main(argv) != 0
        err = capsys.readouterr().err.strip()
        assert needle in err and len(err.splitlines()) == 1 and "Traceback" not in err, err
    with pytest.raises(SystemExit) as exc:
        main(["data", "--views", "0", "--out", str(tmp_path / "x")])
    assert exc.value.code != 0
    assert "must be > 0" in capsys.readouterr().err


def test_views_per_shape_renders_a_per_shape_draw_of_the_grid_views(tmp_path, capsys):
    from sketchmesh.cli import main

    grid = ds.BuildSettings(size=32, small_size=16, num_azimuths=4, elevations=(0.0, 30.0))
    sub = ds.BuildSettings(size=32, small_size=16, num_azimuths=4, elevations=(0.0, 30.0), views_per_shape=4)
    # every view (0) is recorded as before the option existed, so datasets built then stay complete
    assert "views_per_shape" not in json.loads(grid.to_json()) and json.loads(sub.to_json())["views_per_shape"] == 4
    jobs = ds.make_jobs("procedural", 3, ["lamp"])
    ds.build_dataset(tmp_path / "grid", jobs, grid, progress=False)
    assert ds.build_dataset(tmp_path / "sub", jobs, sub, progress=False)["views"] == 3 * 4
    drawn = []
    for job in jobs:
        picks = sub.grid_views(job.category, job.shape_id)
        assert picks == sub.grid_views(job.category, job.shape_id) and len(set(picks)) == 4  # the same draw every time
        assert sorted(i // 4 for i in picks) == [0, 0, 1, 1]  # 2 azimuths at each of the 2 elevations
        drawn.append(tuple(picks))
        with np.load(ds.shape_file(tmp_path / "grid", job.category, job.shape_id)) as full, \
                np.load(ds.shape_file(tmp_path / "sub", job.category, job.shape_id)) as part:
            # each stored view is the full grid's view at that index: same camera, angles, images, drawing
            for key in ("cameras", "azimuths", "elevations", "normals64", "silhouette64", "sketch"):
                np.testing.assert_array_equal(part[key], full[key][picks], err_msg=key)
    assert len(set(drawn)) > 1  # drawn per shape, not one subset for all
    data = ds.ShapeViewDataset(tmp_path / "sub", "all", extra_views=3, augment_strength=0.0, seed=0)
    assert len(data) == 3 * 4
    # an odd count draws from the whole grid; more than the grid is refused before anything is rendered
    assert len(ds.BuildSettings(num_azimuths=4, elevations=(0.0, 30.0), views_per_shape=3).grid_views("lamp", "x")) == 3
    with pytest.raises(ValueError, match="between 1 and the grid's 8 views"):
        ds.BuildSettings(num_azimuths=4, elevations=(0.0, 30.0), views_per_shape=9).check()
    capsys.readouterr()
    assert main(["data", "--categories", "lamp", "--views", "4", "--views-per-shape", "9",
                 "--out", str(tmp_path / "x")]) != 0
    err = capsys.readouterr().err.strip()
    assert "between 1 and the grid's 4 views" in err and len(err.splitlines()) == 1, err
    assert not (tmp_path / "x").exists()


def test_mesh_folder_source_with_a_broken_file(tmp_path):
    import trimesh

    src = tmp_path / "meshes" / "mugs"
    src.mkdir(parents=True)
    trimesh.creation.cylinder(radius=0.3, height=1.0, sections=16).export(src / "mug.ply")
    (src / "bad.obj").write_text("f 1 2 3\nthis is not an obj\n")
    jobs = ds.make_jobs(f"meshes:{tmp_path / 'meshes'}")
    assert {(j.category, j.shape_id) for j in jobs} == {("mugs", "mug"), ("mugs", "bad")}
    with pytest.warns(UserWarning) as record:
        summary = ds.build_dataset(tmp_path / "out", jobs, ds.BuildSettings(size=32, small_size=16, num_azimuths=1),
                                   progress=False)
    messages = [str(w.message) for w in record]
    assert any("mugs/bad" in m for m in messages) and any("1 of 2 shapes failed" in m for m in messages)
    assert summary["rendered"] == 1 and len(summary["failed"]) == 1
    assert os.path.isfile(tmp_path / "out" / "shapes" / "mugs" / "mug.npz")


def test_samples_export_split_sketches_that_the_engine_reads_back(built, tmp_path):
    from engine.preprocess import load_sketch_image
    from training.data.dataset import load_manifest
    from training.data.preview import write_samples

    root = built[0]
    shapes = load_manifest(root)["shapes"]
    split = shapes[0]["split"]
    written = write_samples(root, tmp_path / "samples", split=split, per_category=1, view=1)
    assert {p.name.split("_")[0] for p in written} == {s["category"] for s in shapes if s["split"] == split}
    for p in written:
        ink = load_sketch_image(p)  # dark-on-white file -> 1 = ink, and the same drawing as stored
        rec = next(s for s in shapes if p.name.startswith(f"{s['category']}_{s['shape_id']}_"))
        stored = np.load(root / rec["file"])["sketch"][1].astype(np.float32) / 255.0
        assert np.abs(ink - stored).max() <= 1.0 / 255.0 + 1e-6
