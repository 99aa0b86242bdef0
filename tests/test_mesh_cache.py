"""The mesh-array cache (training.data.mesh_cache): the batches it gives, staleness, atomic writes, errors."""

from __future__ import annotations

import json
import os
import pickle
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from training.data import mesh_cache as mc  # noqa: E402
from training.data.dataset import MANIFEST, DatasetError, ShapeViewDataset  # noqa: E402
from training.loop.config import TrainConfig  # noqa: E402
from training.loop.trainer import DistInfo, ResumableBatchSampler, Trainer  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from synthetic_data import write_synthetic_dataset  # noqa: E402

MESH_KEYS = ("normals64", "silhouette64", "camera", "other_normals64", "other_silhouette64", "other_cameras",
             "category", "shape_id", "view")
TINY = dict(batch=3, predictor_channels=8, predictor_hidden=32, predictor_latent=16, template_level=2, extra_views=1,
            log_every=1, val_every=0, ckpt_every=0, plot_every=0, device="cpu")
torch.set_num_threads(2)


@pytest.fixture(scope="module")
def source(tmp_path_factory) -> Path:
    return write_synthetic_dataset(tmp_path_factory.mktemp("mc") / "data", splits=("train", "train", "val"), views=3)


@pytest.fixture
def data(source, tmp_path) -> Path:
    """A private copy (tests here rewrite shape files and caches)."""
    root = tmp_path / "data"
    shutil.copytree(source, root)
    return root


def _batches(ds, n: int, batch: int = 4, seed: int = 0) -> list[dict]:
    sampler = ResumableBatchSampler(len(ds), batch, seed, 0, DistInfo())
    loader = torch.utils.data.DataLoader(ds, batch_sampler=sampler, num_workers=0)
    it = iter(loader)
    return [next(it) for _ in range(n)]


def _assert_same(a: dict, b: dict) -> None:
    for k in MESH_KEYS:
        if isinstance(a[k], torch.Tensor):
            assert a[k].dtype == b[k].dtype and a[k].shape == b[k].shape, k
            assert torch.equal(a[k], b[k]), f"{k} differs by {float((a[k] - b[k]).abs().max())}"
        else:
            assert a[k] == b[k], k


@pytest.mark.parametrize("location", ["auto", "memory"])
def test_cached_batches_equal_the_shape_file_batches(data, location):
    """Batches of a mesh step from the cache (memory map, or in memory) are bit for bit those of the shape files."""
    npz = ShapeViewDataset(data, "all", extra_views=2, augment_strength=0.0, seed=5)
    cached = ShapeViewDataset(data, "all", extra_views=2, augment_strength=0.5, seed=5, fields="mesh",
                              mesh_cache=location)
    assert (cached._arrays.path is not None) == (location == "auto")
    assert (mc.cache_path(data).is_file()) == (location == "auto")
    for a, b in zip(_batches(npz, 4), _batches(cached, 4)):  # 4 batches of 4 cover every one of the 18 views
        _assert_same(a, b)
    assert "sketch" not in cached[0] and "normals" not in cached[0]  # mesh mode never loads a sketch
    full = cached.item(1, "all")  # ...unless asked (validation images)
    assert full["sketch"].shape == npz[1]["sketch"].shape and torch.equal(full["normals"], npz[1]["normals"])
    # a spawned DataLoader worker maps the file again rather than receiving a copy of the arrays
    again = pickle.loads(pickle.dumps(cached))
    _assert_same(torch.utils.data.default_collate(again.__getitems__([0, 5, -1])),
                 torch.utils.data.default_collate([npz[0], npz[5], npz[-1]]))


def test_mesh_mode_trains_on_the_cache_exactly_as_on_the_shape_files(data, tmp_path, monkeypatch):
    """The trainer's mesh-mode train set is the cached one, it never draws a sketch (even with augmentation
    on), and two steps on it leave the same weights as two steps on the shape-file path."""
    import training.data.augment as augment

    cfg = TrainConfig(mode="mesh", data_dir=str(data), iters=2, augment_strength=0.5, **TINY)

    def no_sketch(*a, **k):
        raise AssertionError("mesh mode drew a sketch")

    monkeypatch.setattr(augment, "render_sketch", no_sketch)
    cached = Trainer(cfg.replace(out_dir=str(tmp_path / "cache")), progress=False)
    assert cached.train_set.fields == "mesh" and cached.train_set._arrays is not None
    cached.run()
    monkeypatch.undo()
    npz = ShapeViewDataset(data, "train", extra_views=1, augment_strength=0.0, seed=cfg.seed)
    plain = Trainer(cfg.replace(out_dir=str(tmp_path / "npz")), progress=False, train_set=npz)
    plain.run()
    a, b = cached.models["predictor"].state_dict(), plain.models["predictor"].state_dict()
    assert all(torch.equal(a[k], b[k]) for k in a)
    cached.validate()  # the validation grid asks the mesh-only train set for full items
    assert (tmp_path / "cache" / "val" / "iter_00002.png").stat().st_size > 0


def test_stale_cache_is_detected_and_rebuilt(data):
    first = ShapeViewDataset(data, "all", extra_views=1, fields="mesh")
    path = mc.cache_path(data)
    mtime = path.stat().st_mtime_ns
    ShapeViewDataset(data, "all", extra_views=1, fields="mesh")  # reused, not rebuilt
    assert path.stat().st_mtime_ns == mtime
    # a shape file re-rendered with other content
    rec = first._shapes[0]
    shape = data / rec["file"]
    with np.load(shape) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["normals64"] = arrays["normals64"][::-1].copy()
    from training.data.dataset import write_shape_file

    write_shape_file(shape, arrays)
    os.utime(shape, ns=(mtime + 10**9, mtime + 10**9))
    with pytest.warns(mc.StaleCacheWarning, match="1 shape file changed"):
        second = ShapeViewDataset(data, "all", extra_views=1, fields="mesh")
    np.testing.assert_array_equal(second[0]["normals64"].numpy(), arrays["normals64"][0].transpose(2, 0, 1))
    # the dataset's settings changed since the cache was built
    manifest = json.loads((data / MANIFEST).read_text())
    manifest["settings"]["seed"] = 7
    (data / MANIFEST).write_text(json.dumps(manifest))
    with pytest.warns(mc.StaleCacheWarning, match="other settings"):
        ShapeViewDataset(data, "all", extra_views=1, fields="mesh")
    # a cache file cut short (a disk that filled up under another tool)
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    with pytest.warns(mc.StaleCacheWarning, match="cut short or corrupt"):
        third = ShapeViewDataset(data, "all", extra_views=1, fields="mesh")
    _assert_same(torch.utils.data.default_collate([third[2]]),
                 torch.utils.data.default_collate([ShapeViewDataset(data, "all", extra_views=1)[2]]))


def test_an_interrupted_cache_write_leaves_the_old_cache_and_no_temporary(data, monkeypatch):
    ShapeViewDataset(data, "all", extra_views=1, fields="mesh")
    path = mc.cache_path(data)
    old = path.read_bytes()
    manifest = json.loads((data / MANIFEST).read_text())
    manifest["settings"]["seed"] = 3
    (data / MANIFEST).write_text(json.dumps(manifest))
    calls = []
    real = mc._read_shape

    def failing(root, rec, arrays):
        calls.append(rec["file"])
        if len(calls) == 3:
            raise KeyboardInterrupt  # killed midway through the shapes
        return real(root, rec, arrays)

    monkeypatch.setattr(mc, "_read_shape", failing)
    with pytest.warns(mc.StaleCacheWarning), pytest.raises(KeyboardInterrupt):
        ShapeViewDataset(data, "all", extra_views=1, fields="mesh")
    assert path.read_bytes() == old
    assert sorted(p.name for p in path.parent.iterdir()) == [path.name]


def test_unwritable_folder_keeps_the_arrays_in_memory(data, monkeypatch):
    def refuse(*a, **k):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(mc, "_write", refuse)
    with pytest.warns(mc.StaleCacheWarning, match="keeping the arrays in memory"):
        ds = ShapeViewDataset(data, "all", extra_views=1, fields="mesh")
    assert ds._arrays.path is None and not mc.cache_path(data).exists()
    with pytest.raises(DatasetError, match="cannot write the mesh-array cache"):
        mc.open_mesh_cache(data, location="disk")


def test_bad_datasets_give_one_line_errors(data, tmp_path):
    def message(call) -> str:
        with pytest.raises(DatasetError) as info:
            call()
        text = str(info.value)
        assert "\n" not in text
        return text

    assert "no manifest.json" in message(lambda: ShapeViewDataset(tmp_path / "nothing", fields="mesh"))
    empty = tmp_path / "empty"
    empty.mkdir()
    manifest = json.loads((data / MANIFEST).read_text())
    (empty / MANIFEST).write_text(json.dumps({**manifest, "shapes": [], "views": []}))
    assert "has no shapes" in message(lambda: mc.open_mesh_cache(empty))
    assert "extra_views 3 is more than the 2 other views" in message(
        lambda: ShapeViewDataset(data, "train", extra_views=3, fields="mesh"))
    assert "fields must be one of" in message(lambda: ShapeViewDataset(data, fields="normals"))
    victim = data / manifest["shapes"][1]["file"]
    victim.unlink()
    assert f"shape file {manifest['shapes'][1]['file']} is missing" in message(
        lambda: ShapeViewDataset(data, "all", extra_views=1, fields="mesh"))
    victim.write_bytes(b"not a zip")
    assert "cannot read shape file" in message(lambda: ShapeViewDataset(data, "all", extra_views=1, fields="mesh"))
