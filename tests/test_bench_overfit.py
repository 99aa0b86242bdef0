"""``sketchmesh bench overfit``: its scoring agrees with the dataset, and the command runs end to end."""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))
from synthetic_data import write_synthetic_dataset  # noqa: E402

from training.bench.overfit import overfit_jobs, silhouette_ious  # noqa: E402
from training.data.dataset import ShapeViewDataset  # noqa: E402
from training.evaluation.evaluate import world_vertices  # noqa: E402


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    return write_synthetic_dataset(tmp_path_factory.mktemp("ov") / "data", splits=("train", "train"), views=4)


def test_ground_truth_scores_one_from_world_and_view_frames(data):
    """The pixel check against the dataset: each shape's own mesh, rendered by the training
    rasterizer from the stored cameras, reproduces the stored silhouettes, and so does the same
    mesh expressed in an input view's frame (what the predictor outputs) rotated back."""
    ds = ShapeViewDataset(data, "train", extra_views=0, augment_strength=0.0)
    for cat, sid, _ in ds.shapes():
        rec = ds._by_id[(cat, sid)]
        cams = ds._cache.get(ds._path(rec), "cameras")
        sils = ds._cache.get(ds._path(rec), "silhouette64")
        mesh = ds.load_mesh(cat, sid)
        assert silhouette_ious(mesh.vertices, mesh.faces, cams, sils).min() >= 0.99
        r = np.asarray(cams[1][:9], np.float64).reshape(3, 3)
        view = np.asarray(mesh.vertices, np.float64) @ r.T  # p_view = R p_world
        back = world_vertices(view, cams[1])
        assert silhouette_ious(back, mesh.faces, cams, sils).min() >= 0.99
        # and a wrong frame does not: the check can fail
        assert silhouette_ious(view, mesh.faces, cams, sils).mean() < 0.95


def test_overfit_jobs_are_train_shapes_one_per_category_in_turn():
    from training.data.shapes import CATEGORIES, split_of

    jobs = overfit_jobs(15)
    assert [j.category for j in jobs[:13]] == list(CATEGORIES)
    assert jobs[13].category == CATEGORIES[0] and jobs[13].index > jobs[0].index
    assert all(split_of(j.category, j.index) == "train" and j.split == "train" for j in jobs)


def test_bench_overfit_cli_end_to_end(data, tmp_path, capsys):
    from sketchmesh.cli import main

    out = tmp_path / "ov"
    rc = main(["bench", "overfit", "--out", str(out), "--data", str(data), "--shapes", "2", "--minutes", "0.02",
               "--batch", "2", "--fit-iters", "40", "--quiet", "--set", "extra_views=1",
               "--set", "predictor_hidden=64", "--set", "predictor_channels=8", "--set", "predictor_latent=32"])
    assert rc == 0
    text = capsys.readouterr().out
    assert "fit sil" in text and "mean" in text and ("PASS" in text or "FAIL" in text)
    rec = json.loads((out / "overfit.json").read_text())
    assert len(rec["fit"]) == len(rec["predictor"]) == 2
    assert rec["config"]["extra_views"] == 1 and rec["config"]["mode"] == "mesh"
    for row in rec["fit"] + rec["predictor"]:
        assert 0.0 <= row["silhouette_iou"] <= 1.0 and 0.0 <= row["voxel_iou"] <= 1.0
    # the supports: the shape's own count as the metric gives it, the shares of predicted views in [0, 1]
    from training.evaluation.metrics import solid_voxels, support_count

    ds = ShapeViewDataset(data, "train", extra_views=0, augment_strength=0.0)
    for row in rec["predictor"]:
        assert row["true_supports"] == support_count(solid_voxels(ds.load_mesh(row["category"], row["shape_id"])))
        assert 0.0 <= row["same"] <= 1.0 and 0.0 <= row["separate"] <= 1.0
    assert all(isinstance(r["supports"], int) and r["supports"] >= 0 for r in rec["fit"])
    assert re.search(r"\d+: fit \d+, pred \d\.\d\d / \d\.\d\d", text)  # a shape's row: its count, the fit's, the shares
    # 40 direct-fit iterations already match these simple shapes' outlines closely
    assert min(r["silhouette_iou"] for r in rec["fit"]) > 0.8
    assert abs(rec["gap"] - (np.mean([r["silhouette_iou"] for r in rec["fit"]])
                             - np.mean([r["silhouette_iou"] for r in rec["predictor"]]))) < 1e-9
    # the sheet: per shape, the dataset's views (0 and 3 of 4) above the predicted mesh from the same views
    from PIL import Image

    sheet = np.asarray(Image.open(out / "overfit.png"))
    assert sheet.shape == (2 * (2 * 64 + 2), 2 * 64, 3)
    # a second call fits nothing again: the fit rows come from the dataset's cache, identical
    out2 = tmp_path / "ov2"
    assert main(["bench", "overfit", "--out", str(out2), "--data", str(data), "--shapes", "2", "--minutes", "0.01",
                 "--batch", "2", "--fit-iters", "40", "--quiet", "--set", "extra_views=1", "--set", "predictor_hidden=64",
                 "--set", "predictor_channels=8", "--set", "predictor_latent=32", "--set", "predictor_arch=compact"]) == 0
    rec2 = json.loads((out2 / "overfit.json").read_text())
    assert rec2["fit"] == rec["fit"] and rec2["config"]["predictor_arch"] == "compact"


def test_format_table_shows_the_supports_it_has():
    """A fit row without a support count (a row format before they were counted) leaves the fit's count out; a
    predictor row without them leaves the column empty."""
    from training.bench.overfit import format_table

    fit = {"shape_id": "chair_00000", "silhouette_iou": 0.9, "voxel_iou": 0.5}
    pred = {"shape_id": "chair_00000", "silhouette_iou": 0.8, "voxel_iou": 0.4, "true_supports": 4, "separate": 0.5,
            "same": 0.25}
    row = format_table([{**fit, "supports": 3}], [pred]).splitlines()[1]
    assert row.endswith("4: fit 3, pred 0.50 / 0.25") and " 0.100 " in row  # the gap 0.9 - 0.8
    assert format_table([fit], [pred]).splitlines()[1].endswith("4: pred 0.50 / 0.25")
    bare = {k: pred[k] for k in ("shape_id", "silhouette_iou", "voxel_iou")}
    assert format_table([fit], [bare]).splitlines()[1].endswith("0.400  ")


def test_bench_overfit_bad_input(tmp_path, capsys):
    from sketchmesh.cli import main

    f = tmp_path / "file"
    f.write_text("x")
    assert main(["bench", "overfit", "--out", str(f), "--minutes", "0"]) != 0
    assert "is a file" in capsys.readouterr().err
    assert main(["bench", "overfit", "--out", str(tmp_path / "o"), "--data", str(tmp_path), "--minutes", "0"]) != 0
    assert "not a dataset" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["bench", "overfit", "--out", str(tmp_path / "o"), "--set", "nonsense"])
