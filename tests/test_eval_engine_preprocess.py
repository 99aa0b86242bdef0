"""`sketchmesh eval --sketch-path image|canvas`: test sketches scored as the app's two input paths make them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from synthetic_data import train_tiny_joint_run, write_synthetic_dataset  # noqa: E402

from engine.preprocess import preprocess_raster  # noqa: E402


@pytest.fixture(scope="module")
def world(tmp_path_factory) -> dict:
    root = tmp_path_factory.mktemp("enginepre")
    data = write_synthetic_dataset(root / "data", splits=("train", "test"), views=3)
    train_tiny_joint_run(data, root / "run", iters=2)
    import trimesh

    from sketchmesh.cli import main

    folder = root / "meshes" / "parts"  # real line drawings with their polylines (the synthetic set has none)
    folder.mkdir(parents=True)
    trimesh.creation.box(extents=(1.0, 0.5, 0.3)).export(folder / "brick.obj")
    trimesh.creation.cylinder(radius=0.2, height=1.0, sections=16).export(folder / "rod.obj")
    drawn = root / "drawn"
    assert main(["data", "--source", f"meshes:{root / 'meshes'}", "--out", str(drawn), "--views", "4",
                 "--no-progress"]) == 0
    return {"data": Path(data), "run": root / "run", "drawn": drawn}


def _drawn(world, strength: float = 0.0, seed: int = 0):
    """Every view of the rendered meshes (whichever split they landed in) as a test set."""
    from training.data.dataset import ShapeViewDataset

    return ShapeViewDataset(world["drawn"], "all", extra_views=0, augment_strength=strength, seed=seed)


class _Redrawn:
    """A test split whose sketches are replaced by ``fn(sketch)``; everything else is the wrapped dataset's."""

    def __init__(self, ds, fn) -> None:
        self.ds, self.fn = ds, fn

    def __len__(self) -> int:
        return len(self.ds)

    def __getitem__(self, i: int) -> dict:
        item = dict(self.ds[i])
        item["sketch"] = self.fn(np.asarray(item["sketch"], np.float32)[0])[None]
        return item

    def __getattr__(self, name):
        return getattr(self.ds, name)


def test_the_image_path_is_the_engines_preprocessing_of_each_sketch():
    from training.evaluation.evaluate import app_path_sketches

    rng = np.random.default_rng(0)
    sketches = np.zeros((3, 1, 256, 256), np.float32)
    sketches[0, 0, 40:200, 60:63] = 0.7  # one grey vertical stroke, off centre
    sketches[1, 0, 100:103, 20:240] = 1.0
    sketches[2, 0] = (rng.random((256, 256)) > 0.995) * 0.9  # scattered dots
    got = app_path_sketches("image", torch.from_numpy(sketches))
    assert got.shape == (3, 1, 256, 256) and got.dtype == torch.float32
    for i in range(3):
        np.testing.assert_array_equal(got[i, 0].numpy(), preprocess_raster(sketches[i, 0]))
    # the grey, off-centre stroke comes back in full ink and centred, as the engine feeds it to the generator
    assert got[0].max() == pytest.approx(1.0) and not np.array_equal(got[0, 0].numpy(), sketches[0, 0])
    cols = np.nonzero(got[0, 0].numpy().max(axis=0) > 0.5)[0]
    assert abs((cols.min() + cols.max()) / 2 - 127.5) < 2


def test_a_sketch_the_engine_refuses_is_a_clear_error_naming_it():
    from training.evaluation.evaluate import EvaluationError, app_path_sketches

    sketches = torch.zeros((2, 1, 256, 256))
    sketches[0, 0, 10:20, 10:200] = 1.0
    sketches[1, 0, 50:60, 50:60] = 0.3  # ink below the engine's threshold only: a blank drawing to the engine
    with pytest.raises(EvaluationError, match=r"chair.*7.*refuses"):
        app_path_sketches("image", sketches, names=[("table", "a", 1), ("chair", "b", 7)])


def test_eval_image_path_scores_the_preprocessed_sketches(world):
    """The flag is the same as scoring a test split whose stored sketches were preprocessed by the engine beforehand."""
    from training.evaluation.evaluate import evaluate

    ds = _drawn(world)
    kw = dict(retrieval=False, max_samples=4, progress=False, mirror=True)
    flagged = evaluate(world["run"], world["data"], "test", sketch_path="image", test_set=ds, **kw)
    by_hand = evaluate(world["run"], world["data"], "test", test_set=_Redrawn(ds, preprocess_raster), **kw)
    plain = evaluate(world["run"], world["data"], "test", test_set=ds, **kw)
    assert flagged["sketch_path"] == "image" and plain["sketch_path"] == "stored"
    for m in flagged["method_order"]:
        for metric in ("voxel_iou", "chamfer_l1", "silhouette_iou"):
            assert flagged["methods"][m]["mean"][metric] == pytest.approx(by_hand["methods"][m]["mean"][metric], abs=1e-9)
    # and the preprocessing changed what the networks saw (the stored sketches are not already in the engine's form)
    sk = np.asarray(ds[0]["sketch"], np.float32)[0]
    assert np.abs(preprocess_raster(sk) - sk).max() > 0.1


def _ink_far_from(sketch: np.ndarray, polylines: list, radius: float) -> float:
    """Share of the sketch's ink pixels (> 0.5) farther than ``radius`` pixels from every polyline segment."""
    rows, cols = np.nonzero(sketch > 0.5)
    q = np.stack([cols + 0.5, rows + 0.5], axis=1)  # pixel centres, x = col, y = row
    a = np.concatenate([p[:-1] if len(p) > 1 else p for p in polylines])
    b = np.concatenate([p[1:] if len(p) > 1 else p for p in polylines])
    ab = b - a
    t = np.clip(((q[:, None] - a[None]) * ab[None]).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-12)[None], 0, 1)
    d = np.linalg.norm(q[:, None] - (a[None] + t[..., None] * ab[None]), axis=-1).min(axis=1)
    return float(np.mean(d > radius))


@pytest.mark.parametrize("strength", [0.0, 1.0])
def test_view_strokes_are_the_polylines_the_items_sketch_is_drawn_from(world, strength):
    """Every ink pixel of item i's sketch lies on its view_strokes (points 2 px apart, strokes a few px wide);
    the strokes of the next item's seed do not fit it (the test can tell a wrong seed)."""
    from training.data.augment import augment_strokes
    from training.data.render import view_polylines

    ds = _drawn(world, strength, seed=3)
    for i in (0, len(ds) - 1):
        sketch = np.asarray(ds[i]["sketch"], np.float32)[0]
        assert _ink_far_from(sketch, ds.view_strokes(i), 2.8) == 0.0
    if strength > 0:
        cat, sid, v = ds[0]["category"], ds[0]["shape_id"], ds[0]["view"]
        arrays = {k: ds.shape_array(cat, sid, k) for k in ("view_poly_offsets", "poly_offsets", "poly_points")}
        wrong = augment_strokes(view_polylines(arrays, v), strength, [3, 1], ds.size).polylines
        assert _ink_far_from(np.asarray(ds[0]["sketch"], np.float32)[0], wrong, 2.8) > 0.05


def test_the_canvas_path_draws_the_strokes_as_the_engine_does_and_a_clean_drawing_stays_itself(world):
    from engine.preprocess import rasterize_strokes
    from engine.strokes import Stroke
    from training.evaluation.evaluate import EvaluationError, app_path_sketches

    ds = _drawn(world)
    drawings = [ds.view_strokes(i) for i in (0, 1)]
    got = app_path_sketches("canvas", torch.zeros((2, 1, 256, 256)), drawings)
    assert got.shape == (2, 1, 256, 256)
    for k in (0, 1):
        np.testing.assert_array_equal(got[k, 0].numpy(), rasterize_strokes([Stroke(p) for p in drawings[k]]))
        stored = np.asarray(ds[k]["sketch"], np.float32)[0] > 0.5
        drawn = got[k, 0].numpy() > 0.5
        assert (stored & drawn).sum() / (stored | drawn).sum() > 0.8  # the same drawing, the same framing
    with pytest.raises(EvaluationError, match="refuses"):
        app_path_sketches("canvas", torch.zeros((1, 1, 256, 256)), [[]], [("chair", "b", 7)])


def test_eval_canvas_path_scores_the_strokes_drawn_by_the_engine(world):
    from engine.preprocess import rasterize_strokes
    from engine.strokes import Stroke
    from training.evaluation.evaluate import evaluate

    ds = _drawn(world, 1.0)

    class _Canvas(_Redrawn):
        def __getitem__(self, i: int) -> dict:
            item = dict(self.ds[i])
            item["sketch"] = rasterize_strokes([Stroke(p) for p in self.ds.view_strokes(i)])[None]
            return item

    kw = dict(retrieval=False, max_samples=4, progress=False)
    flagged = evaluate(world["run"], world["data"], "test", sketch_path="canvas", test_set=ds, **kw)
    by_hand = evaluate(world["run"], world["data"], "test", test_set=_Canvas(ds, None), **kw)
    assert flagged["sketch_path"] == "canvas"
    assert flagged["mean"]["voxel_iou"] == pytest.approx(by_hand["mean"]["voxel_iou"], abs=1e-9)
    assert flagged["mean"]["silhouette_iou"] == pytest.approx(by_hand["mean"]["silhouette_iou"], abs=1e-9)


def test_eval_reads_no_raster_the_canvas_redraws_and_no_256px_image(world, monkeypatch):
    """The evaluator asks the dataset only for what it reads: through the canvas no augmented raster is drawn (the
    strokes are drawn instead), and no path reads the 256 px normal images or silhouettes; the scores stay those of
    the full items (a caller's own test set, served as it serves them)."""
    import training.data.augment as augment
    from training.data.dataset import ShapeFileCache
    from training.evaluation.evaluate import evaluate

    ds = _drawn(world, 1.0)
    kw = dict(retrieval=False, max_samples=4, progress=False)
    as_served = evaluate(world["run"], world["data"], "test", sketch_path="canvas", test_set=_Redrawn(ds, lambda s: s),
                         **kw)
    real_get, read = ShapeFileCache.get, []
    monkeypatch.setattr(ShapeFileCache, "get", lambda self, p, k: read.append(k) or real_get(self, p, k))

    def no_raster(*a, **k):
        raise AssertionError("the canvas path drew the augmented raster it replaces")

    with monkeypatch.context() as m:
        m.setattr(augment, "render_sketch", no_raster)
        lean = evaluate(world["run"], world["data"], "test", sketch_path="canvas", test_set=ds, **kw)
    for metric in ("voxel_iou", "chamfer_l1", "silhouette_iou"):
        assert lean["mean"][metric] == pytest.approx(as_served["mean"][metric], abs=1e-9)
    evaluate(world["run"], world["data"], "test", sketch_path="image", test_set=ds, **kw)
    assert {"normals64", "silhouette64", "cameras"} <= set(read)
    assert not {"normals256", "silhouette256"} & set(read)


def test_a_bad_sketch_path_or_one_with_true_normals_is_refused(world):
    from training.evaluation.evaluate import EvaluationError, evaluate

    with pytest.raises(EvaluationError, match="sketch path must be one of"):
        evaluate(world["run"], world["data"], "test", sketch_path="pen", retrieval=False, progress=False)
    with pytest.raises(EvaluationError, match="ground-truth normals"):
        evaluate(world["run"], world["data"], "test", sketch_path="image", gt_normals=True, retrieval=False,
                 progress=False)


def test_scale_about_box_centre_by_hand():
    from training.evaluation.evaluate import scale_about_box_centre

    v = np.array([[[0.0, 0.0, 0.0], [2.0, 1.0, 4.0], [1.0, 0.5, 1.0]]])  # box centre (1, 0.5, 2)
    got = scale_about_box_centre(v, 0.5)
    np.testing.assert_allclose(got[0], [[0.5, 0.25, 1.0], [1.5, 0.75, 3.0], [1.0, 0.5, 1.5]])
    np.testing.assert_array_equal(scale_about_box_centre(v, 1.0), v)


def test_mesh_scale_scores_the_scaled_meshes(world, tmp_path, capsys):
    """--mesh-scale S is the same as scoring a run whose predictions were scaled by hand; the CLI refuses it for
    --models and a bad value on one line."""
    from sketchmesh.cli import main
    from training.evaluation import evaluate as ev

    ds = _drawn(world)
    kw = dict(retrieval=False, max_samples=4, progress=False, test_set=ds)
    scaled = ev.evaluate(world["run"], world["data"], "test", mesh_scale=0.7, **kw)
    plain = ev.evaluate(world["run"], world["data"], "test", **kw)
    original = ev._RunMethod.predict

    def by_hand(self, batch):
        verts, retrieved = original(self, batch)
        c = (verts.min(axis=1, keepdims=True) + verts.max(axis=1, keepdims=True)) / 2
        return c + 0.7 * (verts - c), retrieved

    ev._RunMethod.predict = by_hand
    try:
        expected = ev.evaluate(world["run"], world["data"], "test", **kw)
    finally:
        ev._RunMethod.predict = original
    assert scaled["mesh_scale"] == 0.7
    for metric in ("voxel_iou", "chamfer_l1", "silhouette_iou"):
        assert scaled["mean"][metric] == pytest.approx(expected["mean"][metric], abs=1e-9)
    assert scaled["mean"]["silhouette_iou"] != pytest.approx(plain["mean"]["silhouette_iou"], abs=1e-6)
    with pytest.raises(SystemExit) as exc:  # refused by the parser
        main(["eval", str(world["run"]), "--data", str(world["data"]), "--mesh-scale", "0", "--quiet"])
    assert exc.value.code != 0
    assert main(["eval", "--models", "bundled", "--data", str(world["data"]), "--mesh-scale", "0.9", "--quiet",
                 "--out", str(tmp_path / "o")]) != 0
    assert "--mesh-scale applies to a RUN" in capsys.readouterr().err
