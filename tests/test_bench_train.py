"""``sketchmesh bench train``: it runs end to end on a tiny predictor, writes its record, and refuses bad input.

The figures themselves are printed, never asserted (they depend on the machine and its load).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

pytest.importorskip("torch")

sys.path.insert(0, str(Path(__file__).resolve().parent))
from synthetic_data import write_synthetic_dataset  # noqa: E402

TINY_SET = ["--set", "predictor_channels=8", "--set", "predictor_hidden=32", "--set", "predictor_latent=16",
            "--set", "template_level=2"]


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> Path:
    return write_synthetic_dataset(tmp_path_factory.mktemp("bt") / "data", splits=("train", "train"), views=3)


def cli(argv: list[str]) -> int:
    from sketchmesh.cli import main

    return main(argv)


@pytest.mark.parametrize("loader", ["cache", "npz"])
def test_bench_train_writes_its_record(data, tmp_path, capsys, loader):
    out = tmp_path / "bench.json"
    rc = cli(["bench", "train", "--data", str(data), "--batch", "4", "--steps", "2", "--warmup", "1",
              "--loader", loader, "--json", str(out), "--quiet", *TINY_SET, "--set", "extra_views=2"])
    printed = capsys.readouterr()
    assert rc == 0, printed.err
    r = json.loads(out.read_text())
    assert r["batch"] == 4 and r["extra_views"] == 2 and r["loader"] == loader and r["steps"] == 2
    assert r["config"]["predictor_hidden"] == 32 and r["config"]["mode"] == "mesh"
    assert set(r["stages_ms"]) == {"data", "predictor_forward", "rasterizer_forward", "losses_forward",
                                   "losses_backward", "rasterizer_backward", "predictor_backward", "optimizer",
                                   "step_other"}
    assert all(v >= 0 for k, v in r["stages_ms"].items() if k != "step_other")
    # the stages add up to the measured steps (the data stage included)
    assert sum(r["stages_ms"].values()) == pytest.approx(r["step_ms"], rel=0.2)
    assert r["samples_per_s"] > 0 and r["renderer_views_per_s"] > 0
    assert r["samples_per_cpu_s"] > 0 and r["renderer_views_per_cpu_s"] > 0 and set(r["stages_cpu_ms"]) == set(r["stages_ms"])
    assert r["views_per_s"] == pytest.approx(3 * r["samples_per_s"], rel=1e-3)  # K = 2 extra views counted
    assert "views/s end to end" in printed.out and "rasterizer alone" in printed.out


def test_bench_train_bad_input_gives_one_line_errors(data, tmp_path, capsys):
    cases = [
        (["--data", str(tmp_path / "nope")], "does not exist"),
        (["--data", str(data), "--set", "extra_views=3"], "extra_views 3 is more than the 2 other views"),
        (["--data", str(data), "--set", "mode=normals"], "--set cannot change ['mode']"),
        (["--data", str(data), "--set", "predictor_hidden=0"], "predictor_hidden must be >= 1"),
        (["--data", str(data), "--set", "no_such_field=1"], "unknown training config keys"),
    ]
    empty = tmp_path / "empty"
    empty.mkdir()
    cases.append((["--data", str(empty)], "not a dataset folder"))
    for argv, needle in cases:
        rc = cli(["bench", "train", *argv, "--steps", "1", "--warmup", "0", "--batch", "2", "--quiet"])
        err = capsys.readouterr().err.strip()
        assert rc != 0 and needle in err and len(err.splitlines()) == 1, (argv, err)
