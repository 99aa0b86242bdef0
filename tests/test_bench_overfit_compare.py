"""``sketchmesh bench overfit-compare``: bench overfit runs side by side, figures checked by hand."""

from __future__ import annotations

import json

import numpy as np
import pytest


def _write_run(folder, pred, fit, log_rows, batch=32, shapes=("chair_00000", "table_00000"), fit_iters=1000):
    """A bench overfit folder: overfit.json with (silhouette, voxel) pairs per shape, run/log.csv."""
    (folder / "run").mkdir(parents=True)

    def rows(pairs):
        return [{"shape_id": s, "silhouette_iou": a, "voxel_iou": b} for s, (a, b) in zip(shapes, pairs)]

    (folder / "overfit.json").write_text(json.dumps({
        "benchmark": "overfit", "config": {"batch": batch}, "fit": rows(fit), "predictor": rows(pred),
        "fit_iters": fit_iters}))
    lines = ["iteration,wall_s,it_per_s,samples_per_s,skipped,mesh_normal,mesh_silhouette"]
    lines += [f"{it},{w},1,1,0,100,{s}" for it, w, s in log_rows]
    (folder / "run" / "log.csv").write_text("\n".join(lines) + "\n")
    return folder


def test_figures_from_the_files(tmp_path):
    from training.bench.overfit_compare import compare, markdown_table

    a = _write_run(tmp_path / "a", pred=[(0.6, 0.2), (0.5, 0.1)], fit=[(0.7, 0.35), (0.9, 0.7)],
                   log_rows=[(10, 30.0, 0.5), (20, 60.0, 0.4)])
    # a resumed run: wall_s restarts at the second call, the minutes before are carried over
    b = _write_run(tmp_path / "b", pred=[(0.65, 0.3), (0.85, 0.6)], fit=[(0.7, 0.35), (0.9, 0.7)], batch=8,
                   log_rows=[(10, 30.0, 0.5), (20, 90.0, 0.4), (30, 15.0, 0.3), (40, 45.0, 0.2)])
    rec = compare([("a", a), ("b", b)])
    va, vb = rec["variants"]
    assert rec["shapes"] == ["chair_00000", "table_00000"]
    assert va["minutes"] == pytest.approx(1.0) and va["iterations"] == 20 and va["samples"] == 640
    assert vb["minutes"] == pytest.approx((90 + 45) / 60) and vb["iterations"] == 40 and vb["samples"] == 320
    assert vb["curve"]["minutes"] == pytest.approx([0.5, 1.5, 1.75, 2.25])
    # gaps by hand: a (0.1, 0.4) -> 0.25, worst the table; b (0.05, 0.05) -> 0.05
    assert va["gap"] == pytest.approx(0.25) and va["worst_shape"] == "table_00000"
    assert va["worst_gap"] == pytest.approx(0.4)
    assert vb["gap"] == pytest.approx(0.05)
    assert va["pred_voxel"] == pytest.approx(0.15) and vb["pred_voxel"] == pytest.approx(0.45)
    assert va["fit_voxel"] == pytest.approx(0.525)
    table = markdown_table(rec)
    # a: 640 samples in 60 s, 320 per shape; b: 320 in 135 s (2.4 a second), 160 per shape
    assert "| a | 1.0 | 20 | 640 | 11 | 320 | 0.250 | 0.550 | 0.150 | 0.525 | table_00000 (0.400) |" in table
    assert "| b | 2.2 | 40 | 320 | 2 | 160 | 0.050 |" in table


def test_cli_writes_table_json_and_plot(tmp_path, capsys):
    from PIL import Image

    from sketchmesh.cli import main

    a = _write_run(tmp_path / "a", pred=[(0.6, 0.2), (0.5, 0.1)], fit=[(0.7, 0.35), (0.9, 0.7)],
                   log_rows=[(i * 10, i * 3.0, 1.0 / i) for i in range(1, 60)])
    b = _write_run(tmp_path / "b", pred=[(0.7, 0.3), (0.8, 0.5)], fit=[(0.7, 0.35), (0.9, 0.7)],
                   log_rows=[(i * 10, i * 3.0, 0.8 / i) for i in range(1, 60)])
    out = tmp_path / "cmp"
    assert main(["bench", "overfit-compare", f"base={a}", str(b), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "2 variants on the same 2 shapes" in text and "| base |" in text and "| b |" in text
    rec = json.loads((out / "compare.json").read_text())
    assert [v["name"] for v in rec["variants"]] == ["base", "b"]
    assert rec["variants"][1]["gap"] == pytest.approx(0.05)
    assert (out / "compare.md").read_text().count("\n") == 4
    img = np.asarray(Image.open(out / "compare.png").convert("L"))
    assert img.shape[0] > 300 and img.shape[1] > 800 and img.std() > 10  # drawn, not blank


def test_bad_inputs_are_clear_errors(tmp_path, capsys):
    from sketchmesh.cli import main

    good = _write_run(tmp_path / "good", pred=[(0.6, 0.2), (0.5, 0.1)], fit=[(0.7, 0.35), (0.9, 0.7)],
                      log_rows=[(10, 30.0, 0.5)])
    other = _write_run(tmp_path / "other", pred=[(0.6, 0.2)], fit=[(0.7, 0.35)], shapes=("car_00000",),
                       log_rows=[(10, 30.0, 0.5)])
    empty = tmp_path / "empty"
    empty.mkdir()
    corrupt = _write_run(tmp_path / "corrupt", pred=[(0.6, 0.2), (0.5, 0.1)], fit=[(0.7, 0.35), (0.9, 0.7)],
                         log_rows=[(10, 30.0, 0.5)])
    (corrupt / "overfit.json").write_text("{not json")
    nolog = _write_run(tmp_path / "nolog", pred=[(0.6, 0.2), (0.5, 0.1)], fit=[(0.7, 0.35), (0.9, 0.7)],
                       log_rows=[])
    nan = _write_run(tmp_path / "nan", pred=[(float("nan"), 0.2), (0.5, 0.1)], fit=[(0.7, 0.35), (0.9, 0.7)],
                     log_rows=[(10, 30.0, 0.5)])
    cases = [([str(empty)], "has no overfit.json"), ([str(good), str(other)], "scored other shapes"),
             ([str(corrupt)], "is not a bench overfit result"), ([str(nolog)], "has no logged iterations"),
             ([f"x={good}", f"x={good}"], "names repeat"), ([str(nan)], "not a finite number")]
    for runs, message in cases:
        assert main(["bench", "overfit-compare", *runs, "--out", str(tmp_path / "o")]) != 0
        err = capsys.readouterr().err
        assert message in err and "Traceback" not in err
    file_out = tmp_path / "file"
    file_out.write_text("x")
    assert main(["bench", "overfit-compare", str(good), "--out", str(file_out)]) != 0
    assert "is a file" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["bench", "overfit-compare", "=nothing", "--out", str(tmp_path / "o")])


def _write_sheet(folder, shades, size=4):
    """A bench overfit sheet: per shape a row of views (shade 10 * (shape + 1)) over the predicted row (its
    shade from ``shades``), then a 2-pixel white gap."""
    from PIL import Image

    blocks = []
    for i, shade in enumerate(shades):
        views = np.full((size, 3 * size, 3), 10 * (i + 1), np.uint8)
        pred = np.full((size, 3 * size, 3), shade, np.uint8)
        blocks += [views, pred, np.full((2, 3 * size, 3), 255, np.uint8)]
    Image.fromarray(np.concatenate(blocks, 0)).save(folder / "overfit.png")


def test_shape_sheet_cuts_each_variants_row(tmp_path, capsys):
    from PIL import Image

    from sketchmesh.cli import main
    from training.bench.overfit_compare import LABEL_WIDTH

    args = dict(pred=[(0.6, 0.2), (0.5, 0.1)], fit=[(0.7, 0.35), (0.9, 0.7)], log_rows=[(10, 30.0, 0.5)])
    a = _write_run(tmp_path / "a", **args)
    b = _write_run(tmp_path / "b", **args)
    _write_sheet(a, shades=(100, 110))
    _write_sheet(b, shades=(200, 210))
    out = tmp_path / "cmp"
    assert main(["bench", "overfit-compare", str(a), str(b), "--out", str(out), "--shape", "table_00000"]) == 0
    img = np.asarray(Image.open(out / "compare_table_00000.png").convert("RGB"))
    # rows of 4-pixel tiles enlarged twice: the table's views (shade 20), then a's prediction (110), then b's (210)
    assert img.shape == (3 * 8, LABEL_WIDTH + 3 * 8, 3)
    tiles = img[:, LABEL_WIDTH:, 0]
    assert (tiles[:8] == 20).all() and (tiles[8:16] == 110).all() and (tiles[16:] == 210).all()
    assert (img[:, :LABEL_WIDTH] < 255).any()  # the rows are named
    # a shape that was not compared is refused before anything is written; a sheet of another layout too
    capsys.readouterr()
    assert main(["bench", "overfit-compare", str(a), "--out", str(tmp_path / "c2"), "--shape", "sofa_00000"]) != 0
    assert "not among the compared shapes" in capsys.readouterr().err and not (tmp_path / "c2").exists()
    Image.fromarray(np.zeros((11, 12, 3), np.uint8)).save(b / "overfit.png")
    assert main(["bench", "overfit-compare", str(a), str(b), "--out", str(out), "--shape", "chair_00000"]) != 0
    assert "is not a bench overfit sheet" in capsys.readouterr().err
