"""``sketchmesh bench variants``: equal-time training chunks, test scoring, resume, plot and bad input."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))
from synthetic_data import write_synthetic_dataset  # noqa: E402

from training.bench.variants import markdown_table, parse_variant  # noqa: E402

TINY = ["--set", "batch=2", "--set", "predictor_arch=compact", "--set", "predictor_channels=4",
        "--set", "predictor_hidden=16", "--set", "predictor_latent=8", "--set", "template_level=2",
        "--set", "log_every=1", "--set", "ckpt_every=1"]


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    return write_synthetic_dataset(tmp_path_factory.mktemp("var") / "data", views=4)


def test_parse_variant():
    assert parse_variant("k3:extra_views=3,lr_mesh=1e-3,normal_region=target") == (
        "k3", {"extra_views": 3, "lr_mesh": 1e-3, "normal_region": "target"})
    assert parse_variant("base") == ("base", {})
    for bad in ("", "a b:x=1", "k:extra_views", "k:=3"):
        with pytest.raises(Exception, match="variant"):
            parse_variant(bad)


def test_labels_mark_the_diagnostic_and_the_reference():
    from training.bench.variants import label

    assert label("d", {"supervision": "3d"}) == "d (3D-supervised diagnostic)"
    assert label("s", {"silhouette": "soft"}) == "s (SoftRas silhouette, reference)"
    assert label("far", {"edge_range": 8, "silhouette": "eq1", "supervision": "2d"}) == "far"


def test_bench_variants_end_to_end_resumes_and_plots(data, tmp_path, capsys):
    from sketchmesh.cli import main

    out = tmp_path / "v"
    args = ["bench", "variants", "--data", str(data), "--out", str(out), "--minutes", "0.04", "--points", "2",
            "--max-samples", "4", "--quiet", "--variant", "k1:extra_views=1", "--variant", "k2:extra_views=2", *TINY]
    assert main(args) == 0
    rec = json.loads((out / "variants.json").read_text())
    pts = rec["points"]
    assert [(p["variant"], p["chunk"]) for p in pts] == [("k1", 1), ("k1", 2), ("k2", 1), ("k2", 2)]
    for name in ("k1", "k2"):
        mine = [p for p in pts if p["variant"] == name]
        # training time accumulates over the chunks and each chunk trained (and checkpointed) further
        assert 0 < mine[0]["train_minutes"] < mine[1]["train_minutes"]
        assert 0 < mine[0]["iteration"] <= mine[1]["iteration"]
        assert 0 < mine[0]["run_seconds"] < mine[1]["run_seconds"]  # the runs' own cumulative training time
        # the second chunk trains its own 1.2 s: it is not taken for a killed chunk's leftover (it was, when the
        # first chunk's training time was measured against no earlier point)
        assert mine[1]["run_seconds"] - mine[0]["run_seconds"] >= 0.5 * 0.04 / 2 * 60
        assert mine[0]["config"]["extra_views"] == int(name[1])
        for p in mine:
            assert 0.0 <= p["voxel_iou"] <= 1.0 and 0.0 <= p["silhouette_iou"] <= 1.0 and p["samples"] == 4
    assert set(rec["template"]) == {"voxel_iou", "silhouette_iou", "chamfer_l1"}
    table = (out / "variants.md").read_text()
    assert table == markdown_table(rec) and table.count("\n| k") == 4
    from PIL import Image

    assert Image.open(out / "variants.png").size[0] > 600
    # a rerun trains and scores nothing more: the record is unchanged
    capsys.readouterr()
    assert main(args) == 0
    assert json.loads((out / "variants.json").read_text()) == rec
    # one more point per variant continues from the checkpoints
    assert args[8:10] == ["--points", "2"]
    assert main([*args[:9], "3", *args[10:]]) == 0
    rec3 = json.loads((out / "variants.json").read_text())
    assert [p["chunk"] for p in rec3["points"] if p["variant"] == "k2"] == [1, 2, 3]
    # the same name with another config is refused, naming the variant
    capsys.readouterr()
    assert main([*args[:-len(TINY) - 4], "--variant", "k1:extra_views=3", *TINY]) != 0
    err = capsys.readouterr().err
    assert "k1" in err and "another config" in err and "Traceback" not in err
    assert np.isfinite([p["voxel_iou"] for p in rec3["points"]]).all()


def test_a_chunk_killed_after_a_checkpoint_counts_its_training():
    """The training a killed chunk checkpointed is counted towards the next chunk, not lost or free."""
    from training.bench.variants import _already_trained

    assert _already_trained(0.0, None) == 0.0  # no run yet
    assert _already_trained(130.0, None) == 130.0  # killed inside the first chunk
    assert _already_trained(130.0, {"run_seconds": 100.5}) == 29.5  # 29.5 s past the last scored point
    assert _already_trained(130.0, {"run_seconds": 131.0}) == 0.0  # the checkpoint that ended the last chunk
    assert _already_trained(130.0, {"train_minutes": 2.0}) == 0.0  # a point from before run_seconds: unknown


def test_bench_variants_bad_input(data, tmp_path, capsys):
    from sketchmesh.cli import main

    base = ["bench", "variants", "--out", str(tmp_path / "o"), "--minutes", "0.01", "--quiet"]
    cases = [
        ([*base, "--data", str(tmp_path / "nope"), "--variant", "a"], "not a dataset"),
        ([*base, "--data", str(data), "--variant", "a", "--variant", "a"], "names must differ"),
        ([*base, "--data", str(data), "--variant", "a:extra_views=-1"], "extra_views"),
        ([*base, "--data", str(data), "--variant", "a:nope=1"], "unknown"),
        ([*base, "--data", str(data), "--variant", "a", "--set", "mode=normals"], "mesh"),
    ]
    for argv, words in cases:
        assert main(argv) != 0
        err = capsys.readouterr().err
        assert words in err and "Traceback" not in err, (argv, err)
    # a record scored with one voxel measure is not resumed with the other (old records: cell centres)
    old = tmp_path / "old"
    old.mkdir()
    (old / "variants.json").write_text(json.dumps({"format": 1, "points": [], "template": {"voxel_iou": 0.1}}))
    assert main(["bench", "variants", "--out", str(old), "--data", str(data), "--variant", "a", "--quiet"]) != 0
    err = capsys.readouterr().err
    assert "scored with voxels by cell centres" in err and "add --voxel-centres" in err and "Traceback" not in err
