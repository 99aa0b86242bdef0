"""Training, resuming and exporting the category router (training.model.router, `sketchmesh router`)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from engine import contract as C  # noqa: E402
from engine.models import load_router  # noqa: E402
from engine.pipeline import SketchEngine  # noqa: E402
from training.data.dataset import write_manifest  # noqa: E402
from training.data.generated import build_generated, generated_dir  # noqa: E402
from training.data.mesh_cache import open_mesh_cache  # noqa: E402
from training.export.router import export_router, parse_routes  # noqa: E402
from training.loop.router import load_router_run, train_router  # noqa: E402
from training.model.router import RouterConfig, RouterNet, labelled_rows, routing_table  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from onnx_fixtures import make_predictor, write_fixture_models, write_model  # noqa: E402
from synthetic_data import write_synthetic_dataset  # noqa: E402

torch.set_num_threads(2)
CATS = ("blob", "box")


def _pattern(category: str, rng: np.random.Generator) -> np.ndarray:
    """(64, 64, 3) a category's stand-in normal image: the blob lit on the left, the box on the right, plus noise."""
    img = rng.uniform(0.0, 0.3, (64, 64, 3))
    if category == "blob":
        img[:, :24] += 0.6
    else:
        img[:, 40:] += 0.6
    return img.astype(np.float16)


def _dataset(root: Path, models: Path, seed: int) -> Path:
    """A synthetic dataset (2 categories x 3 train shapes x 2 views) with two generated sets holding the patterns."""
    data = write_synthetic_dataset(root, categories=CATS, splits=("train", "train", "train"), views=2)
    write_manifest(data)
    cache = open_mesh_cache(data)
    manifest = json.loads((data / "manifest.json").read_text())
    rng = np.random.default_rng(seed)
    for name in ("normals16", "normals16_mirror"):
        build_generated(data, models, name, mirror=name.endswith("mirror"), progress=False)
        folder = generated_dir(data, name)
        arr = np.load(folder / "normals64.npy")
        for s in manifest["shapes"]:
            first, nv = cache.rows[s["file"]]
            for v in range(nv):
                arr[first + v] = _pattern(s["category"], rng)
        np.save(folder / "normals64.npy", arr)
    return data


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    base = tmp_path_factory.mktemp("router")
    models = write_fixture_models(base / "models", level=3)
    return _dataset(base / "train", models, 0), _dataset(base / "val", models, 1), models


@pytest.fixture(scope="module")
def trained(setup, tmp_path_factory) -> Path:
    """A router run trained 12 epochs on the patterns (the tests only read it)."""
    train, val, _ = setup
    run = tmp_path_factory.mktemp("trained") / "run"
    train_router(run, _cfg(train, val, 12), progress=False)
    return run


def _box_folder(folder: Path) -> Path:
    """The fixture pair and a specialist for the box category, mesh_predictor_box.onnx (another predictor's weights)."""
    write_fixture_models(folder)
    write_model(make_predictor(3, seed=5), folder / "mesh_predictor_box.onnx")
    return folder


def _cfg(train: Path, val: Path, epochs: int) -> RouterConfig:
    return RouterConfig(data=[str(train)], val_data=str(val), epochs=epochs, batch=8, lr=5e-3, channels=[4, 8, 8, 8])


def test_labels_follow_the_manifest(setup):
    train, _, _ = setup
    sets, rows, cats = labelled_rows(train, ["normals16"])
    assert cats == list(CATS) and len(rows) == 12
    g, r, lab = sets[0]
    x = g.rows(r)
    left, right = x[:, :, :, :24].mean((1, 2, 3)), x[:, :, :, 40:].mean((1, 2, 3))
    np.testing.assert_array_equal(lab, (right > left).astype(int))  # each label is its pattern's category


def test_the_router_learns_separable_categories_and_a_resumed_run_is_the_straight_run(setup, tmp_path, monkeypatch):
    train, val, _ = setup
    last = train_router(tmp_path / "straight", _cfg(train, val, 12), progress=False, group=["box"])
    assert last["val_accuracy"] == 1.0 and last["loss"] < 0.3
    box = last["val_routing"][0]
    assert box["recall"] == 1.0 and box["false_routes"] == 0.0 and box["group"] == box["others"] == 12
    import training.loop.checkpoint as ckpt

    save = ckpt.save_checkpoint

    def killed_after_five(run, iteration, *args, **kwargs):
        path = save(run, iteration, *args, **kwargs)
        if iteration == 5:
            raise KeyboardInterrupt  # the process dies right after its fifth checkpoint
        return path

    monkeypatch.setattr(ckpt, "save_checkpoint", killed_after_five)
    with pytest.raises(KeyboardInterrupt):
        train_router(tmp_path / "resumed", _cfg(train, val, 12), progress=False)
    monkeypatch.setattr(ckpt, "save_checkpoint", save)
    train_router(tmp_path / "resumed", _cfg(train, val, 12), progress=False)  # ...and is started again
    a, _ = load_router_run(tmp_path / "straight")
    b, cfg = load_router_run(tmp_path / "resumed")
    for (name, p), q in zip(a.state_dict().items(), b.state_dict().values()):
        torch.testing.assert_close(p, q, rtol=0, atol=1e-6, msg=name)
    log = [json.loads(line) for line in (tmp_path / "resumed" / "log.jsonl").read_text().splitlines()]
    assert [r["epoch"] for r in log] == list(range(1, 13)) and cfg.categories == list(CATS)


def test_a_checkpoint_of_another_router_is_refused(setup, tmp_path):
    train, val, _ = setup
    train_router(tmp_path / "run", _cfg(train, val, 1), progress=False)
    other = _cfg(train, val, 2)
    other.channels = [4, 8, 8, 16]
    with pytest.raises(ValueError, match="another router"):
        train_router(tmp_path / "run", other, progress=False)


def test_routing_table_by_hand():
    probs = np.array([[0.95, 0.05, 0.0], [0.5, 0.3, 0.2], [0.1, 0.1, 0.8], [0.0, 0.02, 0.98]])
    labels = np.array([0, 1, 2, 2])
    t = routing_table(probs, labels, ["bench", "chair", "car"], ["bench", "chair"], thresholds=(0.5, 0.9))
    # group sums 1.0, 0.8, 0.2, 0.02: at 0.5 both group drawings go, at 0.9 only the first; no car goes
    assert [(r["recall"], r["false_routes"]) for r in t] == [(1.0, 0.0), (0.5, 0.0)]


def test_an_export_the_engine_would_refuse_leaves_the_folder_as_it_was(trained, tmp_path):
    folder = _box_folder(tmp_path / "models")
    before = sorted(p.name for p in folder.iterdir())
    with pytest.raises(Exception, match="route"):
        export_router(trained, folder, {"mesh_predictor_box.onnx": ["box", "box"]}, 0.8)  # what parse_routes refuses
    assert sorted(p.name for p in folder.iterdir()) == before  # no router.onnx, no temporary left


def test_export_matches_torch_and_the_engine_routes_by_it(trained, tmp_path):
    run = trained
    folder = _box_folder(tmp_path / "models")
    report = export_router(run, folder, {"mesh_predictor_box.onnx": ["box"]}, 0.8)
    assert report["parity_max_abs"] < 1e-5 and report["bytes"] < 60_000
    router = load_router(folder / C.ROUTER_FILE, threads=1)
    assert router.categories == list(CATS) and router.route_threshold == 0.8
    net, _ = load_router_run(run)
    rng = np.random.default_rng(3)
    x = np.stack([_pattern(c, rng).astype(np.float32).transpose(2, 0, 1) for c in CATS])
    (got,) = router.session.run(None, {C.ROUTER_INPUT: x})
    with torch.no_grad():
        want = torch.softmax(net(torch.from_numpy(x)), 1).numpy()
    np.testing.assert_allclose(got, want, atol=1e-5)
    assert got[0].argmax() == 0 and got[1].argmax() == 1
    assert SketchEngine(folder, threads=1).model_info()["router"]["routes"] == {"mesh_predictor_box.onnx": ["box"]}


def test_parse_routes():
    assert parse_routes(["a.onnx=bench,chair", "a.onnx=table"], ["bench", "chair", "table"]) == {
        "a.onnx": ["bench", "chair", "table"]}
    for bad, match in (("a.onnx", "expected FILE="), ("a.onnx=sofa", "sofa not among"), ("=bench", "expected"),
                       ("mesh_predictor.onnx=bench", "another .onnx"), ("sub/a.onnx=bench", "another .onnx"),
                       ("a.onnx=bench,bench", "already routed")):
        with pytest.raises(ValueError, match=match):
            parse_routes([bad], ["bench", "chair"])
    with pytest.raises(ValueError, match="bench already routed"):
        parse_routes(["a.onnx=bench", "b.onnx=bench"], ["bench", "chair"])


def test_no_resume_on_a_run_and_an_unknown_group_are_refused(setup, tmp_path):
    train, val, _ = setup
    train_router(tmp_path / "run", _cfg(train, val, 1), progress=False)
    with pytest.raises(ValueError, match="already has checkpoints"):
        train_router(tmp_path / "run", _cfg(train, val, 2), resume=False, progress=False)
    other_lr = _cfg(train, val, 1)
    other_lr.lr = 1e-3
    with pytest.raises(ValueError, match="other settings .lr 0.005"):
        train_router(tmp_path / "run", other_lr, progress=False)
    with pytest.raises(ValueError, match="sofa: not among"):
        train_router(tmp_path / "other", _cfg(train, val, 1), progress=False, group=["sofa"])
    assert not (tmp_path / "other" / "checkpoints").exists()  # refused before any training


def test_router_net_guards():
    with pytest.raises(ValueError, match="at least 2"):
        RouterNet(1)
    with pytest.raises(ValueError, match="must be"):
        RouterNet(3)(torch.zeros(1, 1, 64, 64))


def _cli(*args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "sketchmesh", "router", *args], capture_output=True, text=True, timeout=300)


def test_cli_errors_are_one_line_and_nonzero(setup, trained, tmp_path):
    train, val, _ = setup
    run = trained
    folder = write_fixture_models(tmp_path / "models")
    cases = [
        (["export", str(run), "--models", str(folder), "--route", "missing.onnx=box"], "no missing.onnx"),
        (["export", str(run), "--models", str(folder), "--route", "x.onnx=sofa"], "sofa not among"),
        (["export", str(run), "--models", str(folder), "--route", "x.onnx=box", "--threshold", "1.5"], "between 0 and 1"),
        (["export", str(tmp_path / "nope"), "--models", str(folder), "--route", "x.onnx=box"], "does not exist"),
        (["train", "--data", str(tmp_path / "nope"), "--out", str(tmp_path / "r")], "does not exist"),
        (["train", "--data", str(train), "--out", str(tmp_path / "r"), "--group", "box"], "give --val-data"),
        (["eval", str(run), "--data", str(val), "--group", "sofa"], "sofa: not among"),
        (["train", "--data", str(train), "--out", str(tmp_path / "r"), "--channels", "0"], "must be in [1, 1024]"),
        (["train", "--data", str(train), "--out", str(tmp_path / "r"), "--weight-decay=-1"], "finite number >= 0"),
        (["train", "--data", str(train), "--out", str(tmp_path / "r"), "--weight-decay", "nan"], "finite number >= 0"),
    ]
    for args, match in cases:
        r = _cli(*args)
        assert r.returncode != 0, args
        assert match in r.stderr and "Traceback" not in r.stderr, (args, r.stderr)
    r = _cli("eval", str(run), "--data", str(val), "--group", "box")
    assert r.returncode == 0 and "category right for" in r.stdout, r.stderr


def test_cli_trains_the_router_of_the_given_widths(setup, tmp_path):
    train, val, _ = setup
    r = _cli("train", "--data", str(train), "--val-data", str(val), "--out", str(tmp_path / "wide"), "--epochs", "2",
             "--batch", "8", "--channels", "4", "8", "8", "12", "--weight-decay", "0", "--quiet", "--threads", "1")
    assert r.returncode == 0, r.stderr
    net, cfg = load_router_run(tmp_path / "wide")
    assert cfg.channels == [4, 8, 8, 12] and cfg.weight_decay == 0.0 and net.channels == (4, 8, 8, 12)
    assert net.head.in_features == 12 * 4  # the last width, pooled to 2 x 2


def test_router_set_rewrites_only_the_threshold_and_mirror_routing(trained, tmp_path):
    import onnx

    folder = _box_folder(tmp_path / "models")
    export_router(trained, folder, {"mesh_predictor_box.onnx": ["box"]}, 0.8, mirror=True)
    before = load_router(folder / C.ROUTER_FILE, threads=1)
    assert before.route_mirror is True and before.route_threshold == 0.8
    graph = onnx.load(str(folder / C.ROUTER_FILE)).graph.SerializeToString()
    r = _cli("set", str(folder), "--no-mirror", "--threshold", "0.6")
    assert r.returncode == 0 and "0.8 -> 0.6" in r.stdout and "on -> off" in r.stdout, r.stderr
    after = load_router(folder / C.ROUTER_FILE, threads=1)
    assert after.route_mirror is False and after.route_threshold == 0.6
    assert after.routes == before.routes and after.categories == before.categories
    assert onnx.load(str(folder / C.ROUTER_FILE)).graph.SerializeToString() == graph  # the network as it was
    assert sorted(p.name for p in folder.iterdir() if p.name.startswith(".")) == []  # no temporary left
    r = _cli("set", str(folder), "--mirror")  # the threshold stays
    assert r.returncode == 0, r.stderr
    again = load_router(folder / C.ROUTER_FILE, threads=1)
    assert again.route_mirror is True and again.route_threshold == 0.6
    model = onnx.load(str(folder / C.ROUTER_FILE))  # a router the engine refuses (route_mirror "yes") is mended
    next(p for p in model.metadata_props if p.key == C.META_ROUTE_MIRROR).value = "yes"
    onnx.save(model, str(folder / C.ROUTER_FILE))
    with pytest.raises(Exception, match="true or false"):
        load_router(folder / C.ROUTER_FILE, threads=1)
    r = _cli("set", str(folder), "--no-mirror")
    assert r.returncode == 0 and "'yes' -> off" in r.stdout, r.stderr
    assert load_router(folder / C.ROUTER_FILE, threads=1).route_mirror is False
    plain = write_fixture_models(tmp_path / "plain")
    for args, match in ((["set", str(folder)], "nothing to change"),
                        (["set", str(plain), "--mirror"], "no router.onnx"),
                        (["set", str(tmp_path / "nope"), "--mirror"], "does not exist"),
                        (["set", str(folder), "--threshold", "0"], "between 0 and 1")):
        r = _cli(*args)
        assert r.returncode != 0 and match in r.stderr and "Traceback" not in r.stderr, (args, r.stderr)
