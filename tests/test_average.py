"""Weight averaging of runs (training.export.average, `sketchmesh average`).

Expectations are computed independently of the averaging code: the weighted mean of the two runs'
tensors by hand, the first batch norm's input captured by a forward hook on the averaged network in
eval mode (its mean and unbiased variance are what training-mode statistics over those inputs give),
and the runs' own outputs.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from engine.errors import ModelError  # noqa: E402
from training.export.average import average_runs  # noqa: E402
from training.export.from_onnx import calibration_inputs  # noqa: E402
from training.loop.config import TrainConfig  # noqa: E402
from training.loop.trainer import Trainer, load_run  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from synthetic_data import write_synthetic_dataset  # noqa: E402

torch.set_num_threads(2)


def _train(data: Path, out: Path, seed: int, **changes) -> Path:
    settings = dict(mode="mesh", data_dir=str(data), out_dir=str(out), iters=2, batch=2, predictor_channels=8,
                    predictor_hidden=32, predictor_latent=16, template_level=2, augment_strength=0.0, log_every=1,
                    val_every=0, ckpt_every=0, plot_every=0, device="cpu", extra_views=0, lr_mesh=1e-2, lr_warmup=0,
                    seed=seed)
    cfg = TrainConfig(**{**settings, **changes})
    Trainer(cfg, progress=False).run()
    return out


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> tuple[Path, Path, Path]:
    """(data folder, run A, run B): one network, two seeds, so every weight and statistic differs."""
    root = tmp_path_factory.mktemp("average")
    data = write_synthetic_dataset(root / "data", splits=("train", "test"), views=2)
    return data, _train(data, root / "a", seed=1), _train(data, root / "b", seed=2)


def _state(run: Path) -> dict[str, torch.Tensor]:
    _, models, _ = load_run(run)
    return models["predictor"].state_dict()


def test_weighted_mean_of_parameters_and_statistics(runs, tmp_path):
    _, a, b = runs
    report = average_runs([a, b], tmp_path / "avg", weights=[1.0, 3.0], bn_samples=0)
    assert report.weights == pytest.approx((0.25, 0.75))
    sa, sb, got = _state(a), _state(b), _state(tmp_path / "avg")
    differs = 0
    for name, t in got.items():
        if name.endswith("num_batches_tracked"):
            assert int(t) == max(int(sa[name]), int(sb[name]))
        elif t.is_floating_point():
            np.testing.assert_allclose(t.numpy(), 0.25 * sa[name].numpy() + 0.75 * sb[name].numpy(), rtol=1e-6,
                                       atol=1e-7, err_msg=name)
            differs += not torch.equal(sa[name], sb[name])
    assert differs > 10  # the two runs really differ: the test can fail


def test_batch_norms_set_from_the_averaged_networks_own_statistics(runs, tmp_path):
    data, a, b = runs
    average_runs([a, b], tmp_path / "avg", bn_samples=8)
    cfg, models, state = load_run(tmp_path / "avg")
    net = models["predictor"]
    bn = next(m for m in net.modules() if isinstance(m, torch.nn.BatchNorm2d))
    inputs, _ = calibration_inputs(cfg, 8)
    seen = []
    handle = bn.register_forward_hook(lambda _m, inp, _out: seen.append(inp[0].detach()))
    with torch.no_grad():
        net.eval()(inputs)  # the first batch norm's input does not depend on any batch norm's statistics
    handle.remove()
    x = seen[0].double()
    np.testing.assert_allclose(bn.running_mean.numpy(), x.mean(dim=(0, 2, 3)).numpy(), rtol=1e-4, atol=1e-6)
    np.testing.assert_allclose(bn.running_var.numpy(), x.var(dim=(0, 2, 3), unbiased=True).numpy(), rtol=1e-4,
                               atol=1e-6)
    name = next(n for n, m in net.named_modules() if m is bn) + ".running_var"
    mean_of_runs = 0.5 * (_state(a)[name] + _state(b)[name])
    assert state["extra"]["batch_norm"].startswith(f"set from {len(inputs)} train inputs")
    assert not torch.allclose(bn.running_var, mean_of_runs, rtol=1e-3)  # not merely the runs' mean


def test_a_run_averaged_with_itself_is_the_same_network(runs, tmp_path):
    data, a, _ = runs
    average_runs([a, a], tmp_path / "same", bn_samples=0)
    cfg, original, _ = load_run(a)
    _, twin, _ = load_run(tmp_path / "same")
    inputs, _ = calibration_inputs(cfg, 4)
    with torch.no_grad():
        for x, y in zip(original["predictor"](inputs), twin["predictor"](inputs)):
            np.testing.assert_allclose(y.numpy(), x.numpy(), rtol=1e-5, atol=1e-6)


def test_runs_of_other_networks_are_refused_and_nothing_written(runs, tmp_path):
    data, a, _ = runs
    other = _train(data, tmp_path / "wide", seed=1, predictor_hidden=48)
    with pytest.raises(ModelError, match="not the same network"):
        average_runs([a, other], tmp_path / "avg", bn_samples=0)
    assert not (tmp_path / "avg").exists()


@pytest.mark.parametrize("argv, needle", [
    (lambda a, b, out: ["average", a, "--out", out], "at least two runs"),
    (lambda a, b, out: ["average", a, a.parent / "absent", "--out", out], "absent: run folder does not exist"),
    (lambda a, b, out: ["average", a, b, "--out", out, "--weights", "1"], "gives 1 weight(s) for 2 run(s)"),
    (lambda a, b, out: ["average", a, b, "--out", out, "--weights", "1", "-1"], "non-negative"),
    (lambda a, b, out: ["average", a, b, "--out", a], "already holds a run"),
    (lambda a, b, out: ["average", a, b, "--out", out, "--bn-samples", "-3"], "--bn-samples"),
])
def test_cli_bad_input_is_one_line_and_non_zero(runs, tmp_path, capsys, argv, needle):
    from sketchmesh.cli import main

    _, a, b = runs
    before = sorted(p.name for p in tmp_path.iterdir())
    try:
        code = main([str(x) for x in argv(a, b, tmp_path / "avg")])
    except SystemExit as exc:  # argparse's own errors
        code = exc.code
    err = capsys.readouterr().err.strip().splitlines()
    assert code != 0 and len(err) == 1 and needle in err[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_cli_writes_a_run_that_eval_and_export_read(runs, tmp_path, capsys):
    from sketchmesh.cli import main

    _, a, b = runs
    assert main(["average", str(a), str(b), "--out", str(tmp_path / "avg"), "--bn-samples", "4"]) == 0
    assert "batch norms: set from 4 train inputs" in capsys.readouterr().out
    assert main(["export", str(tmp_path / "avg"), "-o", str(tmp_path / "models")]) == 0
    assert (tmp_path / "models" / "mesh_predictor.onnx").is_file()
