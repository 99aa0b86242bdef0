"""`sketchmesh eval --models DIR --data DATA`: exported ONNX models scored on a folder of the user's own meshes."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

pytest.importorskip("torch")  # `sketchmesh data` renders with the training layer

from onnx_fixtures import write_corrupt_model, write_fixture_models  # noqa: E402

from engine.icosphere import icosphere  # noqa: E402
from engine.mesh import Mesh  # noqa: E402
from engine.pipeline import SketchEngine  # noqa: E402
from sketchmesh.cli import main  # noqa: E402
from training.evaluation.metrics import solid_voxels, support_count, voxel_iou  # noqa: E402
from training.evaluation.models_eval import SKETCH_PATHS, markdown_report, pick_views, supports_summary  # noqa: E402

MESHES = ("ball", "brick", "rod")
BRICK = (1.0, 0.5, 0.3)


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    """Three simple meshes as OBJ files, rendered by `sketchmesh data --source meshes:DIR` (4 views), and a tiny model folder."""
    import trimesh

    root = tmp_path_factory.mktemp("evalmodels")
    folder = root / "meshes" / "parts"
    folder.mkdir(parents=True)
    trimesh.creation.icosphere(subdivisions=2, radius=0.5).export(folder / "ball.obj")
    trimesh.creation.box(extents=BRICK).export(folder / "brick.obj")
    trimesh.creation.cylinder(radius=0.2, height=1.0, sections=16).export(folder / "rod.obj")
    data = root / "data"
    assert main(["data", "--source", f"meshes:{root / 'meshes'}", "--out", str(data), "--views", "4",
                 "--small-size", "32", "--no-progress"]) == 0
    small = root / "small"  # the same meshes at 64x64: not the models' input, but fine to retrieve from
    assert main(["data", "--source", f"meshes:{root / 'meshes'}", "--out", str(small), "--views", "4", "--size", "64",
                 "--small-size", "16", "--no-progress"]) == 0
    return {"root": root, "data": data, "small": small, "tiny": write_fixture_models(root / "tiny")}


@pytest.fixture(scope="module")
def result(world):
    out = world["root"] / "report"
    rc = main(["eval", "--models", "bundled", "--models", str(world["tiny"]), "--data", str(world["data"]),
               "--split", "all", "--threads", "1", "--quiet", "--out", str(out), "--json", str(world["root"] / "r.json")])
    assert rc == 0
    return json.loads((world["root"] / "r.json").read_text()), out


def _shape_file(world, name):
    return np.load(world["data"] / "shapes" / "parts" / f"{name}.npz")


def test_pick_views_spreads_them_evenly():
    assert pick_views(24, 4) == [3, 9, 15, 21]
    assert pick_views(4, 4) == [0, 1, 2, 3] == pick_views(4, 0) == pick_views(4, 9)
    assert pick_views(24, 1) == [12]


def test_one_row_per_mesh_with_ious_in_range(result, world):
    res, out = result
    assert res["columns"] == ["bundled", "tiny", "retrieval", "template"]
    assert sorted(r["shape_id"] for r in res["rows"]) == sorted(MESHES)
    assert res["meshes"] == 3 and res["split"] == "all" and res["notes"] == []
    for r in res["rows"]:
        assert r["category"] == "parts" and r["views"] == [0, 1, 2, 3] and len(r["per_view"]) == 4
        for c in res["columns"]:
            assert 0.0 <= r["iou"][c] <= 1.0
        for v in r["per_view"]:
            assert not v["retrieved"].startswith(f"parts/{r['shape_id']} ")  # leave-one-out
    # means are the means of the rows
    for c in res["columns"]:
        assert res["mean"][c] == pytest.approx(np.mean([r["iou"][c] for r in res["rows"]]), abs=1e-12)
        assert res["counted"][c] == 3
        assert res["se"][c] == pytest.approx(np.std([r["iou"][c] for r in res["rows"]], ddof=1) / np.sqrt(3), abs=1e-12)
    # each column's paired difference from the first model, mesh by mesh
    assert res["paired"]["first"] == "bundled"
    for c in res["columns"][1:]:
        d = [r["iou"][c] - r["iou"]["bundled"] for r in res["rows"]]
        got = res["paired"]["differences"][c]
        assert got["mean"] == pytest.approx(np.mean(d), abs=1e-12) and got["meshes"] == 3
        assert got["se"] == pytest.approx(np.std(d, ddof=1) / np.sqrt(3), abs=1e-12)
    # JSON round trip: the --json file and OUT's copy hold the same record; the markdown has a row per mesh
    assert json.loads((out / "eval_models_all.json").read_text()) == res
    md = (out / "eval_models_all.md").read_text()
    for r in res["rows"]:
        assert f"| {r['shape_id']} | parts | {r['iou']['bundled']:.3f} | {r['iou']['tiny']:.3f} |" in md
    assert f"**{res['mean']['template']:.3f}**" in md
    assert "| standard error | | " + " | ".join(f"{res['se'][c]:.3f}" for c in res["columns"]) + " |" in md
    tiny = res["paired"]["differences"]["tiny"]
    assert f"Minus bundled's on the same meshes (paired, mean +- standard error): tiny {tiny['mean']:+.3f} +- {tiny['se']:.3f};" in md


def test_template_floor_is_the_voxel_iou_of_the_template_sphere(result, world):
    res, _ = result
    rows = {r["shape_id"]: r for r in res["rows"]}
    assert res["template"] == {"level": 3, "radius": 0.5, "vertices": 642}
    sphere = icosphere(3, 0.5)
    for name in MESHES:
        with _shape_file(world, name) as z:
            gt = Mesh(z["vertices"], z["faces"])
        assert rows[name]["iou"]["template"] == pytest.approx(voxel_iou(sphere, gt, 32), abs=1e-12)
    # and that is about the true overlap of the sphere and the (already normalised) 1 x 0.5 x 0.3 brick
    g = (np.arange(160) + 0.5) / 160 - 0.5
    x, y, z = np.meshgrid(g, g, g, indexing="ij")
    ball = x**2 + y**2 + z**2 <= 0.25
    brick = (np.abs(x) <= BRICK[0] / 2) & (np.abs(y) <= BRICK[1] / 2) & (np.abs(z) <= BRICK[2] / 2)
    assert rows["brick"]["iou"]["template"] == pytest.approx((ball & brick).sum() / (ball | brick).sum(), abs=0.03)
    assert rows["ball"]["iou"]["template"] > 0.9


def _brick_view(world, res, k):
    """Row and k-th scored view of the brick in an eval result, with that view's stored drawing, rotation and true mesh."""
    row = next(r for r in res["rows"] if r["shape_id"] == "brick")
    view = row["per_view"][k]
    with _shape_file(world, "brick") as z:
        assert view["azimuth"] == z["azimuths"][view["view"]]
        return (row, view, z["sketch"][view["view"]].astype(np.float32) / 255.0,
                z["cameras"][view["view"]][:9].reshape(3, 3), Mesh(z["vertices"], z["faces"]))


def _world_iou(mesh, rot, gt) -> float:
    """Voxel IoU of a view-frame mesh against the true one: p_world = R^T p_view."""
    world_verts = (rot.T @ np.asarray(mesh.vertices, np.float64).T).T
    return voxel_iou(Mesh(world_verts, mesh.faces), gt, 32)


def test_a_model_iou_is_the_engines_mesh_rotated_back_to_the_world(result, world):
    """Redo one view by hand: the stored line drawing through the engine, p_world = R^T p_view, voxel IoU."""
    res, _ = result
    row, view, sketch, rot, gt = _brick_view(world, res, 1)
    for label, folder in (("bundled", None), ("tiny", world["tiny"])):
        pred = SketchEngine(folder, threads=1, cache_size=0).predict(sketch).mesh
        assert view["iou"][label] == pytest.approx(_world_iou(pred, rot, gt), abs=1e-12)
        world_mesh = Mesh((rot.T @ np.asarray(pred.vertices, np.float64).T).T, pred.faces)
        assert view["supports"][label] == support_count(solid_voxels(world_mesh, 32))
        assert row["iou"][label] == pytest.approx(np.mean([v["iou"][label] for v in row["per_view"]]), abs=1e-12)
    assert row["true_supports"] == support_count(solid_voxels(gt, 32)) == 1  # a brick stands on itself
    # no shape of the three stands on two or more supports: nothing to share out
    assert res["supports"]["parts"] == {"shapes": 3, "standing": 0, "drawings": 0, "columns": {
        c: {"separate": None, "same": None} for c in res["columns"]}}


def test_voxel_centres_flag_scores_with_cell_centres_only(world, result):
    """--voxel-centres reproduces the earlier tables' measure: the template floor is the centre-only IoU."""
    res_surface, _ = result
    out = world["root"] / "report_centres"
    rc = main(["eval", "--models", "bundled", "--data", str(world["data"]), "--split", "all", "--threads", "1",
               "--quiet", "--no-retrieval", "--voxel-centres", "--out", str(out)])
    assert rc == 0
    res = json.loads((out / "eval_models_all.json").read_text())
    assert res["voxel_surface"] is False and res_surface["voxel_surface"] is True
    assert "voxels by cell centres only" in (out / "eval_models_all.md").read_text()
    sphere = icosphere(3, 0.5)
    for row in res["rows"]:
        with _shape_file(world, row["shape_id"]) as z:
            gt = Mesh(z["vertices"], z["faces"])
        assert row["iou"]["template"] == pytest.approx(voxel_iou(sphere, gt, 32, surface=False), abs=1e-12)
    surface_rows = {r["shape_id"]: r["iou"]["template"] for r in res_surface["rows"]}
    assert any(abs(surface_rows[r["shape_id"]] - r["iou"]["template"]) > 1e-3 for r in res["rows"])


def test_no_train_split_skips_retrieval_with_a_note(world, capsys):
    data = world["root"] / "all_test"
    shutil.copytree(world["data"], data)
    manifest = json.loads((data / "manifest.json").read_text())
    for rec in manifest["shapes"] + manifest["views"]:
        rec["split"] = "test"
    (data / "manifest.json").write_text(json.dumps(manifest))
    capsys.readouterr()
    rc = main(["eval", "--models", "bundled", "--data", str(data), "--views", "1", "--max-samples", "2",
               "--threads", "1", "--quiet", "--out", str(world["root"] / "r2")])
    assert rc == 0
    printed = capsys.readouterr().out
    res = json.loads((world["root"] / "r2" / "eval_models_test.json").read_text())
    assert res["columns"] == ["bundled", "template"] and res["meshes"] == 2
    assert all(len(r["per_view"]) == 1 for r in res["rows"])
    assert len(res["notes"]) == 1 and "retrieval skipped" in res["notes"][0]
    assert "note: retrieval skipped" in printed


def test_retrieval_from_another_dataset(world):
    out = world["root"] / "r3"
    assert main(["eval", "--models", str(world["tiny"]), "--data", str(world["data"]), "--split", "all", "--views", "2",
                 "--retrieval-data", str(world["small"]), "--threads", "1", "--quiet", "--out", str(out)]) == 0
    res = json.loads((out / "eval_models_all.json").read_text())
    assert res["columns"] == ["tiny", "retrieval", "template"]
    assert res["retrieval_data"] == str(world["small"]) and res["retrieval_views"] == 12
    for r in res["rows"]:
        assert r["views"] == [1, 3] and 0.0 <= r["iou"]["retrieval"] <= 1.0


@pytest.mark.parametrize("argv, needle", [
    (lambda w: ["--models", w["root"] / "nope", "--data", w["data"], "--split", "all"], "nope does not exist"),
    (lambda w: ["--models", w["root"] / "meshes", "--data", w["data"], "--split", "all"], "no generator.onnx"),
    (lambda w: ["--models", w["corrupt"], "--data", w["data"], "--split", "all"], "cannot load model"),
    (lambda w: ["--models", "bundled", "--data", w["root"] / "empty"], "not a dataset folder"),
    (lambda w: ["--models", "bundled", "--data", w["root"] / "absent"], "does not exist"),
    (lambda w: ["--models", "bundled", "--data", w["data"]], "the test split has no shapes (it has 3 train)"),
    (lambda w: ["--models", "bundled", "--data", w["small"], "--split", "all"], "holds 64x64 line drawings"),
    (lambda w: ["--models", "bundled", "--data", w["data"], "--split", "all", "--retrieval-data", w["root"] / "empty"],
     "--retrieval-data"),
    (lambda w: ["--models", "bundled", "--models", "bundled", "--data", w["data"]], "given twice"),
    (lambda w: [w["root"], "--models", "bundled", "--data", w["data"]], "not both"),
    (lambda w: ["--data", w["data"]], "give a RUN folder"),
    (lambda w: ["--models", "bundled", "--data", w["data"], "--gt-normals"], "--gt-normals applies to a RUN"),
    (lambda w: [w["root"], "--data", w["data"], "--views", "2"], "--views applies to --models"),
    (lambda w: [w["root"], "--data", w["data"], "--split", "all"], "--split all applies to --models"),
], ids=["no models folder", "folder without models", "corrupt model", "empty data dir", "missing data dir",
        "split with no shapes", "64x64 dataset", "empty retrieval data", "same folder twice", "RUN and --models", "neither",
        "run flag with --models", "--views with RUN", "--split all with RUN"])
def test_bad_input_is_one_line_and_non_zero(world, argv, needle, capsys):
    (world["root"] / "empty").mkdir(exist_ok=True)
    corrupt = world["root"] / "corrupt"
    if not corrupt.exists():
        shutil.copytree(world["tiny"], corrupt)
        write_corrupt_model(corrupt / "generator.onnx")
    w = {**world, "corrupt": corrupt}
    capsys.readouterr()
    rc = main(["eval", *[str(a) for a in argv(w)], "--quiet", "--threads", "1"])
    err = capsys.readouterr().err.strip()
    assert rc != 0
    assert needle in err and len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert not (world["data"] / "eval").exists()


def test_bad_split_value_is_refused_by_the_parser(world, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["eval", "--models", "bundled", "--data", str(world["data"]), "--split", "bogus"])
    assert exc.value.code != 0
    err = capsys.readouterr().err.strip()
    assert "invalid choice: 'bogus'" in err and len(err.splitlines()) == 1


def test_elevation_keeps_only_the_views_at_that_elevation(world, capsys):
    """--elevation 0 scores the side views only (the dataset has 0 and 30 degrees); an elevation the
    data lacks is one clear line; the dataset's per-item elevations are the manifest's."""
    from training.data.dataset import ShapeViewDataset

    data = world["root"] / "two_elevations"
    assert main(["data", "--source", f"meshes:{world['root'] / 'meshes'}", "--out", str(data), "--views", "2",
                 "--elevations", "0", "30", "--small-size", "32", "--no-progress"]) == 0
    ds = ShapeViewDataset(data, "all", extra_views=0, augment_strength=0.0)
    by_view = {(r["shape_id"], r["view"]): r["elevation"] for r in ds.manifest["views"]}
    assert sorted(set(ds.elevations().tolist())) == [0.0, 30.0]
    assert [by_view[(ds.shapes()[si][1], v)] for si, v in ds._items] == ds.elevations().tolist()
    out = world["root"] / "side"
    assert main(["eval", "--models", str(world["tiny"]), "--data", str(data), "--split", "all", "--views", "0",
                 "--elevation", "0", "--no-retrieval", "--threads", "1", "--quiet", "--out", str(out)]) == 0
    res = json.loads((out / "eval_models_all.json").read_text())
    assert len(res["rows"]) == 3
    for r in res["rows"]:
        assert [pv["elevation"] for pv in r["per_view"]] == [0.0, 0.0]
    capsys.readouterr()
    assert main(["eval", "--models", str(world["tiny"]), "--data", str(data), "--split", "all", "--elevation", "45",
                 "--quiet", "--threads", "1", "--out", str(world["root"] / "none")]) != 0
    err = capsys.readouterr().err.strip()
    assert "elevation 45" in err and len(err.splitlines()) == 1


def test_mirror_average_adds_a_row_per_folder_scored_as_the_engine_with_it_on(world, tmp_path):
    """`eval --models DIR --mirror-average`: 'LABEL +mirror' is the engine with mirror averaging on (same sessions)."""
    out = tmp_path / "m.json"
    assert main(["eval", "--models", str(world["tiny"]), "--mirror-average", "--data", str(world["data"]), "--split",
                 "all", "--no-retrieval", "--threads", "1", "--quiet", "--out", str(tmp_path), "--json", str(out)]) == 0
    _, view, sketch, rot, gt = _brick_view(world, json.loads(out.read_text()), 0)
    for label, on in (("tiny", False), ("tiny +mirror", True)):
        pred = SketchEngine(world["tiny"], threads=1, cache_size=0, mirror_average=on).predict(sketch)
        assert pred.mirror_average is on
        assert view["iou"][label] == pytest.approx(_world_iou(pred.mesh, rot, gt), abs=1e-12)


def test_mirror_only_scores_the_app_default_alone_and_a_routed_folder_records_its_routes(world, tmp_path):
    """`--mirror-only`: one 'LABEL +mirror' column per folder and no plain one; a folder with router.onnx (a fixed
    router that is sure of 'bench') scores the specialist's meshes and says, per drawing, where it sent them."""
    from onnx_fixtures import make_predictor, make_router, write_model

    routed = tmp_path / "routed"
    shutil.copytree(world["tiny"], routed)
    write_model(make_predictor(3, seed=7), routed / "mesh_predictor_legged.onnx")
    write_model(make_router([0.96, 0.02, 0.02]), routed / "router.onnx")
    out = tmp_path / "r.json"
    assert main(["eval", "--models", str(world["tiny"]), "--models", str(routed), "--mirror-only", "--data",
                 str(world["data"]), "--split", "all", "--no-retrieval", "--threads", "1", "--quiet", "--out",
                 str(tmp_path), "--json", str(out)]) == 0
    res = json.loads(out.read_text())
    _, view, sketch, rot, gt = _brick_view(world, res, 0)
    assert set(view["iou"]) == {"tiny +mirror", "routed +mirror"}
    assert view["routes"] == {"routed +mirror": {"route": "mesh_predictor_legged.onnx", "category": "bench"}}
    for label, folder in (("tiny +mirror", world["tiny"]), ("routed +mirror", routed)):
        pred = SketchEngine(folder, threads=1, cache_size=0, mirror_average=True).predict(sketch)
        assert view["iou"][label] == pytest.approx(_world_iou(pred.mesh, rot, gt), abs=1e-12)
    assert view["iou"]["tiny +mirror"] != view["iou"]["routed +mirror"]  # the specialist's mesh is another one


@pytest.mark.parametrize("path", ["image", "canvas"])
def test_sketch_path_feeds_the_engine_the_drawing_as_that_app_path_makes_it(world, tmp_path, path):
    """`--sketch-path image`: the stored drawing through the engine's image-file preprocessing; `canvas`: its
    polylines drawn as the canvas draws strokes. Redo one view by hand each way."""
    from engine.preprocess import preprocess_raster, rasterize_strokes
    from engine.strokes import Stroke
    from training.data.render import view_polylines

    out = tmp_path / "p.json"
    assert main(["eval", "--models", str(world["tiny"]), "--sketch-path", path, "--data", str(world["data"]), "--split",
                 "all", "--no-retrieval", "--threads", "1", "--quiet", "--out", str(tmp_path), "--json", str(out)]) == 0
    res = json.loads(out.read_text())
    assert res["sketch_path"] == path
    assert "image-file" in (tmp_path / "eval_models_all.md").read_text() or path == "canvas"
    assert SKETCH_PATHS[path] in (tmp_path / "eval_models_all.md").read_text().splitlines()[0]
    _, view, sketch, rot, gt = _brick_view(world, res, 1)
    if path == "image":
        fed = preprocess_raster(sketch)
    else:
        with _shape_file(world, "brick") as z:
            arrays = {k: z[k] for k in ("view_poly_offsets", "poly_offsets", "poly_points")}
        fed = rasterize_strokes([Stroke(p) for p in view_polylines(arrays, view["view"])])
    assert not np.array_equal(fed, sketch)
    pred = SketchEngine(world["tiny"], threads=1, cache_size=0).predict(fed).mesh
    assert view["iou"]["tiny"] == pytest.approx(_world_iou(pred, rot, gt), abs=1e-12)


def test_supports_summary_shares_hand_computed():
    """Two tables (4 legs and 2 end panels) and a blob-shaped one, drawn twice each, as eval rows."""
    def row(cat, gt, per_view):
        return {"category": cat, "true_supports": gt, "per_view": [{"supports": s} for s in per_view]}
    rows = [row("table", 4, [{"a": 4, "b": 1, "retrieval": 2}, {"a": 2, "b": 1, "retrieval": None}]),
            row("table", 2, [{"a": 2, "b": 2, "retrieval": 2}, {"a": 1, "b": 3, "retrieval": 4}]),
            row("table", 1, [{"a": 1, "b": 1, "retrieval": 1}, {"a": 1, "b": 1, "retrieval": 1}]),
            row("lamp", 1, [{"a": 2, "b": 1, "retrieval": 1}])]
    got = supports_summary(rows, ["a", "b", "retrieval", "template"], template_supports=1)
    t, shares = got["table"], got["table"]["columns"]
    assert (t["shapes"], t["standing"], t["drawings"]) == (3, 2, 4)
    assert shares["a"] == {"separate": 3 / 4, "same": 2 / 4}  # 4 ok, 2 (of 4) separate only, 2 ok, 1 neither
    assert shares["b"] == {"separate": 2 / 4, "same": 1 / 4}  # 1, 1, 2 (same), 3 (separate)
    assert shares["retrieval"] == {"separate": 1.0, "same": 1 / 3}  # a miss is left out: 2, 2 (same), 4
    assert shares["template"] == {"separate": 0.0, "same": 0.0}
    assert got["lamp"]["standing"] == 0 and got["lamp"]["columns"]["a"] == {"separate": None, "same": None}
    # the markdown lists the categories with standing shapes, as separate / same
    result = {"columns": ["a", "b", "retrieval", "template"], "augment_strength": 0.0, "views_per_mesh": 2,
              "voxel_resolution": 32, "split": "test", "data": "d", "meshes": 0, "rows": [],
              "mean": dict.fromkeys(["a", "b", "retrieval", "template"]), "retrieval_views": 0, "retrieval_data": None,
              "template": {"vertices": 642, "radius": 0.5}, "notes": [], "supports": got}
    md = markdown_report(result)
    assert "| table | 2 of 3 | 0.750 / 0.500 | 0.500 / 0.250 | 1.000 / 0.333 | 0.000 / 0.000 |" in md
    assert "| lamp |" not in md


def test_a_shape_on_legs_is_counted_end_to_end(tmp_path):
    """A stool (a seat on four legs) rendered and scored: its own count is 4 and the supports table lists it."""
    import trimesh

    folder = tmp_path / "meshes" / "stools"
    folder.mkdir(parents=True)
    seat = trimesh.creation.box((0.8, 0.08, 0.8)).apply_translation((0, 0.3, 0))
    legs = [trimesh.creation.box((0.08, 0.7, 0.08)).apply_translation((x, -0.08, z)) for x in (-0.33, 0.33) for z in (-0.33, 0.33)]
    trimesh.util.concatenate([seat, *legs]).export(folder / "stool.obj")
    data = tmp_path / "data"
    assert main(["data", "--source", f"meshes:{tmp_path / 'meshes'}", "--out", str(data), "--views", "4",
                 "--small-size", "32", "--no-progress"]) == 0
    out = tmp_path / "report"
    assert main(["eval", "--models", "bundled", "--data", str(data), "--split", "all", "--views", "2", "--no-retrieval",
                 "--threads", "1", "--quiet", "--out", str(out)]) == 0
    res = json.loads((out / "eval_models_all.json").read_text())
    (row,) = res["rows"]
    assert row["true_supports"] == 4
    counts = [v["supports"]["bundled"] for v in row["per_view"]]
    e = res["supports"]["stools"]
    assert (e["shapes"], e["standing"], e["drawings"]) == (1, 1, 2)
    assert e["columns"]["bundled"] == {"separate": np.mean([c >= 2 for c in counts]), "same": np.mean([c == 4 for c in counts])}
    assert e["columns"]["template"] == {"separate": 0.0, "same": 0.0}  # the sphere stands on one
    md = (out / "eval_models_all.md").read_text()
    b = e["columns"]["bundled"]
    assert f"| stools | 1 of 1 | {b['separate']:.3f} / {b['same']:.3f} | 0.000 / 0.000 |" in md
