"""Exported ONNX models back to training runs (training.export.from_onnx, `sketchmesh import-models`).

The expectations are independent of the importer: the torch networks the models were exported from
(float32: the same function to float precision; int8: within the export's int8 tolerance), batch
norm's own train-mode arithmetic on the calibration batch, and ONNX Runtime on the bundled files.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")
onnx = pytest.importorskip("onnx")

from engine import contract as C  # noqa: E402
from engine.errors import ModelError  # noqa: E402
from engine.models import resolve_models_dir  # noqa: E402
from training.export.from_onnx import calibration_inputs, import_models  # noqa: E402
from training.export.to_onnx import INT8_TOLERANCE, export_run  # noqa: E402
from training.loop.config import TrainConfig  # noqa: E402
from training.loop.trainer import Trainer, load_run  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from synthetic_data import train_tiny_joint_run, write_synthetic_dataset  # noqa: E402

torch.set_num_threads(2)


@pytest.fixture(scope="module")
def trained(tmp_path_factory) -> tuple[Path, Path]:
    """(data folder, joint run) trained a few iterations so batch-norm statistics and weights are not the initial ones."""
    root = tmp_path_factory.mktemp("import")
    data = write_synthetic_dataset(root / "data", splits=("train", "test"), views=2)
    train_tiny_joint_run(data, root / "run", iters=3, lr_mesh=1e-2, lr_warmup=0)
    return data, root / "run"


@pytest.fixture(scope="module")
def exported(trained, tmp_path_factory) -> dict[str, Path]:
    _, run = trained
    out = {}
    for quant in ("none", "int8", "fp16"):
        out[quant] = tmp_path_factory.mktemp(f"models_{quant}")
        export_run(run, out[quant], quantize=quant)
    return out


def _inputs(data: Path) -> tuple[torch.Tensor, torch.Tensor]:
    g = torch.Generator().manual_seed(3)
    sketches = (torch.rand(2, 1, 256, 256, generator=g) > 0.97).float()
    cfg = TrainConfig(mode="mesh", data_dir=str(data), augment_strength=0.0, extra_views=0)
    normals, _ = calibration_inputs(cfg, 6)
    return sketches, normals


def test_float32_import_is_the_exported_network(trained, exported, tmp_path):
    data, run = trained
    reports = import_models(exported["none"], tmp_path / "imp", data_dir=str(data))
    assert [r.role for r in reports] == ["generator", "predictor"]
    _, original, _ = load_run(run)
    _, gen_models, gen_state = load_run(tmp_path / "imp" / "generator")
    pcfg, pred_models, pred_state = load_run(tmp_path / "imp" / "predictor")
    assert pcfg.mode == "mesh" and pcfg.init_mesh == "" and pred_state["iteration"] == 0
    assert gen_state["extra"]["discriminator"] == "fresh"
    sketches, normals = _inputs(data)
    with torch.no_grad():
        np.testing.assert_allclose(gen_models["generator"](sketches).numpy(),
                                   original["generator"](sketches).numpy(), atol=1e-5)
        for a, b in zip(pred_models["predictor"](normals), original["predictor"](normals)):
            np.testing.assert_allclose(a.numpy(), b.numpy(), atol=1e-4)
    torch.testing.assert_close(pred_models["predictor"].basis, original["predictor"].basis)
    note = json.loads((tmp_path / "imp" / "IMPORTED.json").read_text())
    assert note["predictor"]["quantization"] == "none" and note["predictor"]["max_abs_error"] <= 1e-4


def test_int8_import_is_within_the_int8_tolerance_of_the_original(trained, exported, tmp_path):
    data, run = trained
    (rep,) = import_models(exported["int8"], tmp_path / "imp", data_dir=str(data), roles=("predictor",))
    assert rep.quantization == "int8-dynamic" and rep.max_abs_error <= INT8_TOLERANCE
    _, original, _ = load_run(run)
    _, models, _ = load_run(tmp_path / "imp" / "predictor")
    _, normals = _inputs(data)
    with torch.no_grad():
        for a, b in zip(models["predictor"](normals), original["predictor"](normals)):
            assert np.abs(a.numpy() - b.numpy()).max() <= INT8_TOLERANCE
    assert not (tmp_path / "imp" / "generator").exists()


def test_fp16_import_is_the_exported_network_with_half_precision_weights(trained, exported, tmp_path):
    from training.export.to_onnx import FP16_TOLERANCE

    data, run = trained
    (rep,) = import_models(exported["fp16"], tmp_path / "imp", data_dir=str(data), roles=("predictor",))
    assert rep.quantization == "fp16-weights" and rep.max_abs_error <= 1e-4  # the file's own weights: float precision
    _, original, _ = load_run(run)
    _, models, _ = load_run(tmp_path / "imp" / "predictor")
    _, normals = _inputs(data)
    with torch.no_grad():
        for a, b in zip(models["predictor"](normals), original["predictor"](normals)):
            assert 0 < np.abs(a.numpy() - b.numpy()).max() <= FP16_TOLERANCE


def test_int8_stored_weights_import_as_the_file_computes_them(trained, exported, tmp_path):
    """A predictor whose weights are stored in int8 (engine.bench.compact_model: Cast and Mul by per-channel scales)
    imports as the function ONNX Runtime computes from that file, to float precision, not as the original."""
    import onnxruntime as ort

    from engine.bench import compact_model

    data, run = trained
    folder = tmp_path / "int8w"
    compact_model(exported["fp16"] / C.PREDICTOR_FILE, folder / C.PREDICTOR_FILE)
    (folder / C.GENERATOR_FILE).write_bytes((exported["fp16"] / C.GENERATOR_FILE).read_bytes())
    (rep,) = import_models(folder, tmp_path / "imp", data_dir=str(data), roles=("predictor",))
    assert rep.quantization == "int8-weights" and rep.max_abs_error <= 1e-4
    _, models, _ = load_run(tmp_path / "imp" / "predictor")
    _, original, _ = load_run(run)
    _, normals = _inputs(data)
    session = ort.InferenceSession(str(folder / C.PREDICTOR_FILE), providers=["CPUExecutionProvider"])
    want = session.run(None, {C.PREDICTOR_INPUT: normals.numpy()})
    with torch.no_grad():
        got = [t.numpy() for t in models["predictor"](normals)]
        before = [t.numpy() for t in original["predictor"](normals)]
    for a, b in zip(got, want):
        np.testing.assert_allclose(a, b, atol=1e-4)
    for a, c in zip(got, before):
        assert np.abs(a - c).max() <= INT8_TOLERANCE
    # the weights are the file's rounded ones, not the original's: some differ by more than float16 would round
    orig_sd = original["predictor"].state_dict()
    moved = [k for k, v in models["predictor"].state_dict().items() if k in orig_sd and v.dtype == torch.float32
             and v.shape == orig_sd[k].shape and (v - orig_sd[k]).abs().max() > 1e-3 * orig_sd[k].abs().max()]
    assert moved


def test_batch_norms_compute_the_same_function_in_train_mode_on_the_calibration_batch(trained, exported, tmp_path):
    """Train mode normalises with the batch's own statistics: on the calibration batch itself, the imported predictor
    in train mode must give its eval-mode output (what the ONNX file computes), so training starts where it left off."""
    data, _ = trained
    import_models(exported["none"], tmp_path / "imp", data_dir=str(data), roles=("predictor",), calibration=8)
    cfg, models, _ = load_run(tmp_path / "imp" / "predictor")
    p = models["predictor"]
    calib, _ = calibration_inputs(cfg, 8)
    with torch.no_grad():
        evaluated = [t.clone() for t in p.eval()(calib)]
        trained_mode = p.train()(calib)
    for a, b in zip(trained_mode, evaluated):
        np.testing.assert_allclose(a.numpy(), b.numpy(), atol=1e-5)
    bn = p.encoder[1]
    assert torch.all(bn.running_var >= 0) and torch.all(torch.isfinite(bn.weight))


def test_training_continues_from_an_imported_run(trained, exported, tmp_path):
    from sketchmesh.cli import main

    data, _ = trained
    import_models(exported["int8"], tmp_path / "imp", data_dir=str(data))
    rc = main(["train", "mesh", "--data", str(data), "--out", str(tmp_path / "more"), "--init-mesh",
               str(tmp_path / "imp" / "predictor"), "--iters", "1", "--batch", "2", "--predictor-channels", "8",
               "--predictor-hidden", "32", "--predictor-latent", "16", "--template-level", "2", "--val-every", "0",
               "--plot-every", "0", "--quiet", "--threads", "1", "--augment-strength", "0", "--extra-views", "1"])
    assert rc == 0
    _, models, state = load_run(tmp_path / "more")
    assert state["iteration"] == 1 and all(torch.isfinite(t).all() for t in models["predictor"].state_dict().values())


def test_the_bundled_models_import_and_reproduce_onnx_runtime(trained, tmp_path):
    """The app's own files (the larger predictor and the width-16 resize generator with int8-stored weights): the graph layout the importer reads
    is the one the export writes, checked by the importer's parity test against ONNX Runtime."""
    data, _ = trained
    reports = import_models(resolve_models_dir(None), tmp_path / "imp", data_dir=str(data), calibration=16)
    by_role = {r.role: r for r in reports}
    assert by_role["generator"].max_abs_error <= 1e-4
    assert by_role["predictor"].max_abs_error <= INT8_TOLERANCE
    assert "true normal images" in by_role["predictor"].calibration  # the synthetic set has no generated inputs


def test_refusals_name_the_problem(trained, exported, tmp_path):
    from sketchmesh.cli import main

    data, _ = trained
    with pytest.raises(ModelError, match="does not exist"):
        import_models(tmp_path / "nowhere", tmp_path / "a", data_dir=str(data))
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(ModelError, match="has no generator.onnx"):
        import_models(empty, tmp_path / "a", data_dir=str(data))
    broken = tmp_path / "broken"
    broken.mkdir()
    (broken / C.PREDICTOR_FILE).write_bytes(b"not a protobuf at all")
    with pytest.raises(ModelError, match="not a readable ONNX model"):
        import_models(broken, tmp_path / "a", data_dir=str(data), roles=("predictor",))
    swapped = tmp_path / "swapped"
    swapped.mkdir()
    (swapped / C.PREDICTOR_FILE).write_bytes((exported["none"] / C.GENERATOR_FILE).read_bytes())
    with pytest.raises(ModelError, match="role"):
        import_models(swapped, tmp_path / "a", data_dir=str(data), roles=("predictor",))
    with pytest.raises(ModelError, match="cannot calibrate"):
        import_models(exported["none"], tmp_path / "a", data_dir=str(tmp_path / "no_data"), roles=("predictor",))
    assert not (tmp_path / "a").exists()  # nothing written by any refusal
    import_models(exported["none"], tmp_path / "b", data_dir=str(data), roles=("predictor",))
    with pytest.raises(ModelError, match="already holds a run"):
        import_models(exported["none"], tmp_path / "b", data_dir=str(data), roles=("predictor",))
    assert main(["import-models", str(tmp_path / "nowhere"), "--out", str(tmp_path / "c")]) != 0


def test_a_failed_write_leaves_no_half_import(trained, exported, tmp_path, monkeypatch):
    """Both runs or neither: a failure while writing the second run removes the first, so a retry is not refused."""
    import training.export.from_onnx as from_onnx

    data, _ = trained
    real = from_onnx._write_run

    def failing(run_dir, *args, **kwargs):
        if run_dir.name == "predictor":
            raise OSError("disk full")
        return real(run_dir, *args, **kwargs)

    monkeypatch.setattr(from_onnx, "_write_run", failing)
    with pytest.raises(OSError, match="disk full"):
        import_models(exported["none"], tmp_path / "imp", data_dir=str(data))
    assert not (tmp_path / "imp" / "generator").exists() and not (tmp_path / "imp" / "predictor").exists()
    monkeypatch.setattr(from_onnx, "_write_run", real)
    assert len(import_models(exported["none"], tmp_path / "imp", data_dir=str(data))) == 2


@pytest.mark.parametrize("quant", ["none", "fp16", "int8"])
def test_a_predictor_with_the_aligned_branch_imports_as_it_was_trained(trained, tmp_path, quant):
    """The aligned branch's weights come back from every export form: its first layer from the whole stored weight
    that the graph slices (the 1x1 projections of the small maps are not taken for encoder convolutions), its last
    from the folded, transposed MatMul constant; the imported network computes what the trained one does."""
    from training.export.to_onnx import FP16_TOLERANCE

    data, _ = trained
    cfg = TrainConfig(mode="mesh", data_dir=str(data), out_dir=str(tmp_path / "run"), iters=3, batch=2,
                      predictor_channels=8, predictor_hidden=32, predictor_latent=16, predictor_aligned=8,
                      template_level=2, augment_strength=0.0, log_every=1, val_every=0, ckpt_every=0, plot_every=0,
                      device="cpu", extra_views=0, lr_mesh=1e-2, lr_warmup=0)
    Trainer(cfg, progress=False).run()
    export_run(tmp_path / "run", tmp_path / "models", quantize=quant)
    (rep,) = import_models(tmp_path / "models", tmp_path / "imp", data_dir=str(data), roles=("predictor",))
    _, original, _ = load_run(tmp_path / "run")
    _, models, _ = load_run(tmp_path / "imp" / "predictor")
    got, want = models["predictor"], original["predictor"]
    assert float(want.aligned_mlp[2].weight.detach().abs().max()) > 0  # trained: the branch is not the zero it started as
    tol = {"none": 1e-5, "fp16": FP16_TOLERANCE, "int8": INT8_TOLERANCE}[quant]
    for k in ("aligned_mlp.0.weight", "aligned_mlp.0.bias", "aligned_mlp.2.weight", "aligned_mlp.2.bias"):
        np.testing.assert_allclose(got.state_dict()[k].numpy(), want.state_dict()[k].numpy(), atol=tol)
    _, normals = _inputs(data)
    with torch.no_grad():
        for a, b in zip(got(normals), want(normals)):
            assert np.abs(a.numpy() - b.numpy()).max() <= tol
    assert rep.max_abs_error <= tol
