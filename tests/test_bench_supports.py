"""``sketchmesh bench supports``: where a drawing's legs are lost, end to end on a dataset with a four-legged table."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))
from onnx_fixtures import write_fixture_models  # noqa: E402
from synthetic_data import write_synthetic_dataset  # noqa: E402

pytest.importorskip("torch")


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    return write_synthetic_dataset(tmp_path_factory.mktemp("sup") / "data", categories=("table", "box"),
                                   splits=("test",), views=3)


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    return write_fixture_models(tmp_path_factory.mktemp("sup_models"))


def test_bench_supports_counts_the_table_views_only(data, models, tmp_path):
    from sketchmesh.cli import main
    from training.data.dataset import ShapeViewDataset
    from training.evaluation.metrics import image_support_count

    out = tmp_path / "out"
    assert main(["bench", "supports", "--data", str(data), "--out", str(out), "--models", str(models),
                 "--categories", "table", "box", "--quiet"]) == 0
    result = json.loads((out / "supports.json").read_text())
    rows = result["rows"]
    # the box stands on one support, the table on its four legs: only the table's three views are measured
    assert [(r["category"], r["view"]) for r in rows] == [("table", 0), ("table", 1), ("table", 2)]
    assert all(r["shape_supports"] == 4 for r in rows)
    ds = ShapeViewDataset(data, "test", extra_views=0)
    by_key = {ds.view_key(i): i for i in range(len(ds))}
    # seen from the front, 30 degrees above, a table on four corner legs shows its two front legs apart at the bottom
    # (from three quarters round the nearest leg reaches lowest, and the lowest quarter may hold it alone)
    assert rows[0]["true"] == 2
    for r in rows:
        stored = ds[by_key[("table", r["shape_id"], r["view"])]]["silhouette"][0].numpy() > 0.5
        assert r["true"] == image_support_count(stored)
        for stage in ("generator", "mesh", "mesh_true_input", "mesh_3d", "mesh_true_input_3d"):
            assert isinstance(r[stage], int) and r[stage] >= 0
    table = result["summary"]["table"]
    assert table["views"] == 3
    assert table["two_or_more"]["true"] == pytest.approx(np.mean([r["true"] >= 2 for r in rows]))
    assert result["summary"]["mean"]["views"] == 3 and set(result["summary"]) == {"table", "mean"}
    shares = [v for k in ("two_or_more", "as_true", "three_d_two_or_more", "three_d_own") for v in table[k].values()]
    assert all(0.0 <= v <= 1.0 for v in shares)
    # the shares are the rows' own: the mesh's count kept as the drawing shows it
    assert table["as_true"]["mesh"] == pytest.approx(np.mean([r["mesh"] == r["true"] for r in rows]))
    md = (out / "supports.md").read_text()
    assert f"| table | 3 | {table['two_or_more']['true']:.2f} |" in md and "mesh_predictor.onnx" in md
    assert (out / "supports.png").stat().st_size > 0
    # --max-samples spreads the views evenly
    assert main(["bench", "supports", "--data", str(data), "--out", str(tmp_path / "two"), "--models", str(models),
                 "--categories", "table", "--max-samples", "2", "--quiet"]) == 0
    two = json.loads((tmp_path / "two" / "supports.json").read_text())["rows"]
    assert [r["view"] for r in two] == [0, 2]


def test_bench_supports_says_what_is_missing(data, models, tmp_path, capsys):
    from sketchmesh.cli import main

    # no standing shape among the views asked for: one line naming it, no traceback
    assert main(["bench", "supports", "--data", str(data), "--out", str(tmp_path / "box"), "--models", str(models),
                 "--categories", "box", "--quiet"]) != 0
    err = capsys.readouterr().err
    assert "two or more separate supports" in err and "Traceback" not in err
    # a predictor file the folder lacks
    assert main(["bench", "supports", "--data", str(data), "--out", str(tmp_path / "none"), "--models", str(models),
                 "--predictor", "mesh_predictor_legged.onnx", "--quiet"]) != 0
    err = capsys.readouterr().err
    assert "mesh_predictor_legged.onnx" in err and "Traceback" not in err
    assert not (tmp_path / "box").exists() and not (tmp_path / "none").exists()
