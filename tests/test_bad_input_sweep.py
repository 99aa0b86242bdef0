"""Bad input and faults, swept across the command-line entry points (issue 18, part 3).

Every case runs ``sketchmesh`` in-process (``sketchmesh.cli.main(argv)``) as a hostile user
would call it and asserts the contract of every entry point:

* a non-zero exit and exactly one stderr line, ``sketchmesh...: error: ...``, that contains the
  words naming the problem (``needle``), never a traceback;
* no output left behind: every file under the test's folder is the same before and after
  (no mesh without its report, no run folder with a header-only log, no temporary file);
* fast: the size of a request and every output location are checked before any work starts, so
  each case fails in well under a few seconds (the absurd ``data`` requests used to grow memory
  by ~100 MB/s, forever).

The app's File > Open and Load models are swept in tests/test_app_bad_input.py, the kill tests
(SIGKILL mid-checkpoint, mid-autosave) are in tests/test_kill.py.
"""

from __future__ import annotations

import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from bad_inputs import write_images, write_meshes
from onnx_fixtures import write_corrupt_model, write_fixture_models

from engine import contract as C

ROOT = Path(__file__).resolve().parents[1]
CASE_SECONDS = 8.0
"""Slowest acceptable bad-input case (model loading and dataset checks included), on 2 shared cores."""


# ----------------------------------------------------------------------------------------- harness


@dataclass(frozen=True)
class Case:
    """One bad input: the argv (built from the world's paths) and the words the error must contain."""

    id: str
    argv: Callable[[dict], list]
    needle: str


def snapshot(root: Path) -> dict[str, int]:
    """Every path under ``root`` and its size (-1 for folders); derived caches (``.cache/``) left out:
    a dataset's cache, made while reading it, is not an output of the failed command."""
    return {str(p.relative_to(root)): (p.stat().st_size if p.is_file() else -1) for p in root.rglob("*")
            if ".cache" not in p.relative_to(root).parts}


def run_case(case: Case, world: dict, capsys) -> str:
    """Run one case in-process; assert the contract; return its error line."""
    from sketchmesh.cli import main

    before = snapshot(world["root"])
    argv = [str(a) for a in case.argv(world)]
    capsys.readouterr()
    t0 = time.perf_counter()
    try:
        rc = main(argv)
    except SystemExit as exc:  # argparse errors
        rc = exc.code
    seconds = time.perf_counter() - t0
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert rc not in (0, None), f"{case.id}: exit {rc}, stderr {err!r}"
    assert len(lines) == 1 and "Traceback" not in err, f"{case.id}: expected one line, got {err!r}"
    assert lines[0].startswith("sketchmesh") and ": error: " in lines[0], f"{case.id}: {lines[0]!r}"
    assert case.needle in lines[0], f"{case.id}: {case.needle!r} not in {lines[0]!r}"
    after = snapshot(world["root"])
    added = sorted(set(after) - set(before))
    changed = sorted(k for k in before if after.get(k) != before[k])
    assert not added and not changed, f"{case.id}: left {added} / changed {changed}"
    assert seconds < CASE_SECONDS, f"{case.id}: took {seconds:.1f} s"
    return lines[0]


@pytest.fixture(scope="module")
def engine_world(tmp_path_factory) -> dict:
    root = tmp_path_factory.mktemp("sweep")
    w = {"root": root, "img": write_images(root / "images")}
    w["models"] = write_fixture_models(root / "models")
    w["models-missing-one"] = root / "models_missing_one"
    w["models-missing-one"].mkdir()
    shutil.copy(w["models"] / C.GENERATOR_FILE, w["models-missing-one"] / C.GENERATOR_FILE)
    w["models-swapped"] = root / "models_swapped"
    w["models-swapped"].mkdir()
    shutil.copy(w["models"] / C.GENERATOR_FILE, w["models-swapped"] / C.PREDICTOR_FILE)
    shutil.copy(w["models"] / C.PREDICTOR_FILE, w["models-swapped"] / C.GENERATOR_FILE)
    w["models-corrupt"] = root / "models_corrupt"
    write_corrupt_model(w["models-corrupt"] / C.GENERATOR_FILE)
    shutil.copy(w["models"] / C.PREDICTOR_FILE, w["models-corrupt"] / C.PREDICTOR_FILE)
    w["afile"] = root / "afile"  # a regular file where a folder is needed: read-only even for root
    w["afile"].write_text("I am a file\n")
    w["out"] = root / "out"  # outputs that must never appear
    return w


def _infer(image: str, *extra, models: str = "models", out: str = "x.obj"):
    return lambda w: ["infer", w["img"][image] if image in w["img"] else image, "-o", w["out"] / out,
                      "--models", w[models], *extra]


INFER_CASES = [
    Case("truncated PNG", _infer("truncated"), "truncated.png: PNG file is truncated"),
    Case("zero-byte PNG", _infer("zero-byte"), "zero.png: file is empty"),
    Case("1x1 image", _infer("1x1"), "image is 1x1 pixels, too small"),
    Case("20000x20000 image", _infer("20000x20000"), "image is 20000x20000 pixels, larger than the limit"),
    Case("all ink", _infer("all-ink"), "all_ink.png: the sketch is blank"),
    Case("all paper", _infer("all-paper"), "all_paper.png: the sketch is blank"),
    Case("non-image with an image suffix", _infer("not-an-image"), "notes.png: not a supported image"),
    Case("missing sketch file", lambda w: ["infer", w["root"] / "absent.png", "-o", w["out"] / "x.obj",
                                           "--models", w["models"]], "absent.png: no such file"),
    Case("model folder with one ONNX missing", _infer("good", models="models-missing-one"),
         "no mesh_predictor.onnx in"),
    Case("model folder with the ONNX files swapped", _infer("good", models="models-swapped"), "files swapped?"),
    Case("corrupt ONNX", _infer("good", models="models-corrupt"), "generator.onnx: cannot load model"),
    Case("model folder is a file", _infer("good", models="afile"), "is not a folder"),
    Case("-o under a file", lambda w: ["infer", w["img"]["good"], "-o", w["afile"] / "x.obj", "--models", w["models"]],
         "afile is a file, not a folder"),
    Case("--report is a folder", lambda w: [*_infer("good")(w), "--report", w["root"] / "images"],
         "images: is a folder, expected a file name"),
    Case("-o without suffix", _infer("good", out="mesh"), "the file name has no suffix"),
    Case("-o in /proc", lambda w: ["infer", w["img"]["good"], "-o", "/proc/sketchmesh/x.obj", "--models", w["models"]],
         "cannot write in /proc"),
    Case("--report under a file (mesh must not be left)", lambda w: [
        *_infer("good")(w), "--report", w["afile"] / "r.json"], "--report"),
    Case("--normals under a file (mesh must not be left)", lambda w: [
        *_infer("good")(w), "--normals", w["afile"] / "n.png"], "afile is a file, not a folder"),
    Case("--normals not a PNG", _infer("good", "--normals", "n.jpg"), "--normals must name a .png file"),
    Case("bad flag value", _infer("good", "--subdivide", "9"), "--subdivide: must be in [0, 4], got 9"),
    Case("non-numeric flag value", _infer("good", "--smooth", "lots"), "expected an integer, got 'lots'"),
    Case("unknown flag", _infer("good", "--frobnicate"), "unrecognized arguments: --frobnicate"),
]


@pytest.mark.parametrize("case", INFER_CASES, ids=[c.id for c in INFER_CASES])
def test_infer_bad_input(case, engine_world, capsys):
    run_case(case, engine_world, capsys)


@pytest.mark.parametrize("kind", ["16-bit", "cmyk", "palette", "alpha-only"])
def test_infer_exotic_but_valid_images_give_the_same_mesh_as_the_plain_png(kind, engine_world, capsys, tmp_path):
    """16-bit, CMYK, palette and alpha-only encodings of a drawing are not errors: same raster, same mesh."""
    from engine.pipeline import to_raster
    from sketchmesh.cli import main

    np.testing.assert_array_equal(to_raster(engine_world["img"][kind]), to_raster(engine_world["img"]["good"]))
    out = tmp_path / f"{kind}.obj"
    assert main(["infer", str(engine_world["img"][kind]), "-o", str(out), "--models", str(engine_world["models"])]) == 0
    assert out.stat().st_size > 0 and f"-> {out}" in capsys.readouterr().out


# ----------------------------------------------------------------------------------------- training world


def _write_dataset(root: Path, size: int = 256, small_size: int = 64, views: int = 2) -> Path:
    """A tiny dataset in the real format (tests/synthetic_data.py), at any image size."""
    import json

    from synthetic_data import make_mesh, render_shape_arrays

    from training.data.dataset import BuildSettings, shape_file, write_manifest, write_shape_file

    settings = BuildSettings(size=size, small_size=small_size, num_azimuths=views)
    for i, (cat, split) in enumerate([("blob", "train"), ("box", "train"), ("blob", "test")]):
        sid = f"{cat}_{i:05d}"
        arrays = render_shape_arrays(make_mesh(cat, i), views, size=size, small_size=small_size)
        meta = {"category": cat, "shape_id": sid, "split": split, "source": "synthetic", "path": "", "index": i,
                "settings": json.loads(settings.to_json())}
        arrays["meta"] = np.array(json.dumps(meta, sort_keys=True))
        write_shape_file(shape_file(root, cat, sid), arrays)
    write_manifest(root, settings)
    return root


TINY_CONFIG = dict(batch=2, base_channels=8, predictor_channels=8, predictor_hidden=32, predictor_latent=16,
                   template_level=2, sobel_samples=64, augment_strength=0.0, device="cpu")
TINY_FLAGS = ["--batch", "2", "--base-channels", "8", "--predictor-channels", "8", "--predictor-hidden", "32",
              "--predictor-latent", "16", "--template-level", "2", "--sobel-samples", "64", "--augment-strength", "0",
              "--quiet", "--threads", "2", "--val-every", "0", "--plot-every", "0", "--device", "cpu", "--extra-views", "1"]


def _write_run(run: Path, data: Path, mode: str = "joint", **changes) -> Path:
    """A run folder with one checkpoint of untrained tiny networks (no training: only the format matters)."""
    from training.loop.checkpoint import save_checkpoint
    from training.loop.config import TrainConfig
    from training.loop.trainer import build_models, build_optimizers

    cfg = TrainConfig(mode=mode, data_dir=str(data), out_dir=str(run), iters=1, **(TINY_CONFIG | changes))
    models = build_models(cfg)
    save_checkpoint(run, 1, cfg.to_json(), "test", models, build_optimizers(cfg, models))
    return run


@pytest.fixture(scope="module")
def world(engine_world) -> dict:
    """engine_world plus datasets, runs and meshes (needs torch)."""
    pytest.importorskip("torch")
    import json

    w = dict(engine_world)
    root = w["root"]
    w["meshes"] = write_meshes(root / "meshes")
    w["data"] = _write_dataset(root / "data")
    w["data64"] = _write_dataset(root / "data64", size=64, small_size=64)
    w["empty-folder"] = root / "empty_folder"
    w["empty-folder"].mkdir()
    w["empty-dataset"] = root / "empty_dataset"  # a manifest that lists nothing
    w["empty-dataset"].mkdir()
    manifest = json.loads((w["data"] / "manifest.json").read_text())
    (w["empty-dataset"] / "manifest.json").write_text(json.dumps(manifest | {"shapes": [], "views": [],
                                                                             "categories": []}))
    w["half-written"] = root / "half_written"  # a shape file cut short: a build killed by a full disk
    shutil.copytree(w["data"], w["half-written"])
    victim = sorted((w["half-written"] / "shapes").rglob("*.npz"))[0]
    victim.write_bytes(victim.read_bytes()[:1000])
    w["no-manifest"] = root / "no_manifest"  # a build killed before its manifest
    shutil.copytree(w["data"] / "shapes", w["no-manifest"] / "shapes")
    w["run"] = _write_run(root / "run", w["data"])
    w["mesh-run"] = _write_run(root / "mesh_run", w["data"], mode="mesh")
    w["wide-run"] = _write_run(root / "wide_run", w["data"], mode="mesh", predictor_channels=16)
    w["bad-config-run"] = _write_run(root / "bad_config_run", w["data"], mode="mesh")
    ckpt = next((w["bad-config-run"] / "checkpoints").glob("*.pt"))  # weights of one config, config of another
    import torch

    state = torch.load(ckpt, weights_only=True)
    state["config"] = json.dumps(json.loads(state["config"]) | {"predictor_hidden": 64})
    torch.save(state, ckpt)
    return w


def _data(*extra):
    return lambda w: ["data", "--out", w["out"] / "d", *extra]


DATA_FLAGS = ["--no-progress", "--size", "32", "--small-size", "16", "--views", "1"]

DATA_CASES = [
    Case("10^9 shapes per category", _data("--shapes-per-category", "1000000000", "--views", "1"), "GB on disk"),
    Case("10^9 views", _data("--views", "1000000000"), "GB of memory per shape"),
    Case("10^6-pixel images", _data("--size", "1000000"), "1000000x1000000 need"),
    Case("10^5 workers", _data("--workers", "100000"), "--workers: must be in [1, 256]"),
    Case("elevation out of range", _data("--elevations", "95"), "elevation must be in (-90, 90)"),
    Case("a shard with no shapes", _data("--categories", "chair", "--shapes-per-category", "2", "--shard", "5/8"),
         "has only 2 shapes, so shard 5 of 8 would render none"),
    Case("--out under a file", lambda w: ["data", "--out", w["afile"] / "d", "--categories", "chair"],
         "afile is a file, not a folder"),
    Case("--out is a file", lambda w: ["data", "--out", w["afile"], "--categories", "chair"],
         "afile: is a file, expected a folder"),
    Case("--out in /proc", lambda w: ["data", "--out", "/proc/sketchmesh", "--categories", "chair"],
         "cannot write in /proc"),
    Case("mesh source is a file", _data("--source", lambda w: f"meshes:{w['afile']}"),
         "afile: is a file, expected a mesh folder"),
    Case("mesh source missing", _data("--source", lambda w: f"meshes:{w['root'] / 'nowhere'}"),
         "nowhere: mesh folder does not exist"),
    Case("mesh with no faces", _data("--source", lambda w: f"meshes:{w['meshes']['no-faces']}", *DATA_FLAGS),
         "flat.obj: mesh has no triangles"),
    Case("mesh with NaN vertices", _data("--source", lambda w: f"meshes:{w['meshes']['nan-vertices']}", *DATA_FLAGS),
         "nan.obj: mesh has NaN or infinite vertices"),
    Case("truncated mesh", _data("--source", lambda w: f"meshes:{w['meshes']['truncated']}", *DATA_FLAGS),
         "cut.ply: cannot read mesh"),
    Case("non-mesh with a mesh suffix", _data("--source", lambda w: f"meshes:{w['meshes']['not-a-mesh']}", *DATA_FLAGS),
         "photo.stl: mesh has no triangles"),
    Case("preview of an empty folder", lambda w: ["data", "preview", w["empty-folder"], "-o", w["out"] / "p.png"],
         "not a dataset folder (no manifest.json"),
    Case("preview of a build killed before its manifest", lambda w: ["data", "preview", w["no-manifest"], "-o",
                                                                     w["out"] / "p.png"], "not a dataset folder"),
    Case("preview of a half-written dataset", lambda w: ["data", "preview", w["half-written"], "-o", w["out"] / "p.png"],
         "cannot open shape file"),
    Case("preview -o under a file", lambda w: ["data", "preview", w["data"], "-o", w["afile"] / "p.png"],
         "afile is a file, not a folder"),
    Case("samples -o under a file", lambda w: ["data", "samples", w["data"], "-o", w["afile"] / "s"],
         "afile is a file, not a folder"),
    Case("merge into a file", lambda w: ["data", "merge", w["afile"], w["data"]], "afile: is a file, expected a folder"),
]


def _resolve(argv: list, w: dict) -> list:
    return [a(w) if callable(a) else a for a in argv]


@pytest.mark.parametrize("case", DATA_CASES, ids=[c.id for c in DATA_CASES])
def test_data_bad_input(case, world, capsys):
    run_case(Case(case.id, lambda w: _resolve(case.argv(w), w), case.needle), world, capsys)


def test_a_non_manifold_mesh_is_rendered_not_refused(world, capsys, tmp_path):
    """ShapeNet is full of non-manifold meshes (edges shared by three faces, fins): they render fine."""
    from sketchmesh.cli import main

    src = tmp_path / "meshes" / "fins"
    src.mkdir(parents=True)
    (src / "fin.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 1 1 1\nv -1 -1 0.5\n"
                                 "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\nf 1 2 5\nf 1 2 6\n")  # edge 1-2 has four faces
    out = tmp_path / "d"
    assert main(["data", "--out", str(out), "--source", f"meshes:{tmp_path / 'meshes'}", *DATA_FLAGS]) == 0
    assert "1 shapes rendered" in capsys.readouterr().out and (out / "manifest.json").is_file()


def _train(mode: str = "mesh", data: str = "data", *extra):
    return lambda w: ["train", mode, "--data", w[data], "--out", w["out"] / "run", "--iters", "1", *TINY_FLAGS, *extra]


TRAIN_CASES = [
    Case("normals on a 64-px dataset", _train("normals", "data64"), "holds 64x64 sketches, but the normals run"),
    Case("--data is a file", _train("mesh", "afile"), "afile: is a file, expected a dataset folder"),
    Case("--data missing", lambda w: _train()(w)[:3] + [w["root"] / "nowhere"] + _train()(w)[4:], "nowhere: does not exist"),
    Case("empty dataset folder", _train("mesh", "empty-folder"), "not a dataset folder (no manifest.json"),
    Case("dataset with no shapes", _train("mesh", "empty-dataset"), "the train split has no shapes"),
    Case("half-written dataset", _train("mesh", "half-written"), "is cut short or corrupt"),
    Case("dataset killed before its manifest", _train("mesh", "no-manifest"), "not a dataset folder"),
    Case("--out under a file", lambda w: ["train", "mesh", "--data", w["data"], "--out", w["afile"] / "run", *TINY_FLAGS],
         "afile is a file, not a folder"),
    Case("resume a checkpoint of another configuration", lambda w: [
        "train", "mesh", "--data", w["data"], "--out", w["wide-run"], "--iters", "2", *TINY_FLAGS],
        "the config changed (predictor_channels: checkpoint 16 vs now 8)"),
    Case("--init-mesh from another configuration", _train("mesh", "data", "--init-mesh", lambda w: w["wide-run"]),
         "its predictor was trained with another configuration (predictor_channels 16 there, 8 here)"),
    Case("--init-normals from a mesh run", _train("normals", "data", "--init-normals", lambda w: w["mesh-run"]),
         "it has no generator to initialise from"),
    Case("--init-mesh missing", _train("mesh", "data", "--init-mesh", lambda w: w["root"] / "nowhere"),
         "--init-mesh", ),
    Case("10^9 batch", _train("mesh", "data", "--batch", "1000000000"), "GB of memory"),
    Case("10^9-wide predictor", _train("mesh", "data", "--predictor-hidden", "1000000000"), "GB of memory"),
    Case("10^9 extra views", _train("mesh", "data", "--extra-views", "1000000000"), "have only 2 views"),
    Case("10^5 loader workers", _train("mesh", "data", "--num-workers", "100000"), "--num-workers must be at most 256"),
    Case("non-numeric --iters", _train("mesh", "data", "--iters", "many"), "--iters: invalid int value: 'many'"),
    Case("negative learning rate", _train("mesh", "data", "--lr-mesh", "-1"), "lr_mesh must be finite and > 0"),
    Case("NaN loss weight", _train("mesh", "data", "--lambda-s", "nan"), "lambda_s must be finite and >= 0"),
    Case("negative support band weight", _train("mesh", "data", "--support-band-weight", "-2"),
         "support_band_weight must be finite and >= 0"),
    Case("unknown mode", lambda w: ["train", "sculpt", "--data", w["data"], "--out", w["out"] / "run"],
         "invalid choice: 'sculpt'"),
]

EVAL_CASES = [
    Case("--json under a file", lambda w: ["eval", w["run"], "--data", w["data"], "--quiet", "--json", w["afile"] / "e.json"],
         "--json"),
    Case("--out under a file", lambda w: ["eval", w["run"], "--data", w["data"], "--quiet", "--out", w["afile"] / "ev"],
         "afile is a file, not a folder"),
    Case("run is a file", lambda w: ["eval", w["afile"], "--data", w["data"], "--quiet"], "is a file, expected a run folder"),
    Case("run missing", lambda w: ["eval", w["root"] / "nowhere", "--data", w["data"], "--quiet"],
         "run folder does not exist"),
    Case("--data is a file", lambda w: ["eval", w["run"], "--data", w["afile"], "--quiet"], "expected a dataset folder"),
    Case("empty dataset", lambda w: ["eval", w["run"], "--data", w["empty-dataset"], "--quiet"],
         "the test split has no shapes"),
    Case("half-written dataset", lambda w: ["eval", w["run"], "--data", w["half-written"], "--quiet",
                                            "--split", "train"], "is cut short or corrupt"),
    Case("checkpoint of another configuration", lambda w: ["eval", w["bad-config-run"], "--data", w["data"], "--quiet",
                                                            "--gt-normals"], "weights do not fit"),
    Case("10^5 voxel resolution", lambda w: ["eval", w["run"], "--data", w["data"], "--voxel-resolution", "100000"],
         "--voxel-resolution: must be in [4, 256]"),
    Case("augment strength out of range", lambda w: ["eval", w["run"], "--data", w["data"], "--augment-strength", "7"],
         "--augment-strength: must be a finite number in [0.0, 1.0]"),
]

EXPORT_CASES = [
    Case("-o under a file", lambda w: ["export", w["run"], "-o", w["afile"] / "models"], "afile is a file, not a folder"),
    Case("-o is a file", lambda w: ["export", w["run"], "-o", w["afile"]], "is a file, expected a folder"),
    Case("run is a file", lambda w: ["export", w["afile"], "-o", w["out"] / "m"], "is a file, expected a run folder"),
    Case("run with no checkpoint", lambda w: ["export", w["empty-folder"], "-o", w["out"] / "m"], "has no checkpoint"),
    Case("checkpoint of another configuration", lambda w: ["export", w["bad-config-run"], "-o", w["out"] / "m"],
         "predictor weights do not fit"),
    Case("bad --quantize", lambda w: ["export", w["run"], "-o", w["out"] / "m", "--quantize", "int4"],
         "invalid choice: 'int4'"),
]


@pytest.mark.parametrize("case", TRAIN_CASES + EVAL_CASES + EXPORT_CASES,
                         ids=[f"train: {c.id}" for c in TRAIN_CASES] + [f"eval: {c.id}" for c in EVAL_CASES]
                         + [f"export: {c.id}" for c in EXPORT_CASES])
def test_train_eval_export_bad_input(case, world, capsys):
    run_case(Case(case.id, lambda w: _resolve(case.argv(w), w), case.needle), world, capsys)


def test_the_sweep_is_wide():
    """At least 60 bad inputs over the five commands (the app adds its own in test_app_bad_input.py)."""
    cases = INFER_CASES + DATA_CASES + TRAIN_CASES + EVAL_CASES + EXPORT_CASES
    assert len(INFER_CASES) >= 20 and len(DATA_CASES) >= 15 and len(TRAIN_CASES) >= 15
    assert len(EVAL_CASES) >= 8 and len(EXPORT_CASES) >= 5 and len(cases) >= 60


def test_a_run_that_fails_before_its_first_checkpoint_leaves_no_run_folder(world, capsys, monkeypatch):
    """An error the checks cannot foresee (here: inside the first step) still leaves no header-only run."""
    import training.loop.trainer as trainer
    from sketchmesh.cli import main

    def broken_step(self, batch, it):
        raise ValueError("Expected input of size 256, got 64 (an internal error)")

    monkeypatch.setattr(trainer.Trainer, "train_step", broken_step)
    before = snapshot(world["root"])
    rc = main([str(a) for a in _train()(world)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 1 and len(err) == 1 and "ValueError: Expected input of size 256" in err[0]
    assert snapshot(world["root"]) == before and not (world["out"] / "run").exists()
