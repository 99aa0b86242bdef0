"""Data-parallel training: two torchrun processes (gloo on CPU) keep identical replicas."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

torch = pytest.importorskip("torch")

sys.path.insert(0, str(Path(__file__).resolve().parent))
from synthetic_data import write_synthetic_dataset  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def test_two_process_ddp_replicas_stay_identical(tmp_path):
    data = write_synthetic_dataset(tmp_path / "data", splits=("train", "train"), views=2)
    out = tmp_path / "out"
    out.mkdir()
    env = dict(os.environ, OMP_NUM_THREADS="1")
    cmd = [sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc_per_node", "2",
           str(ROOT / "tests" / "synthetic_data.py"), "ddp", str(data), str(out)]
    done = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=400)
    assert done.returncode == 0, done.stderr[-3000:]
    ranks = [json.loads((out / f"rank{r}.json").read_text()) for r in (0, 1)]
    assert [r["world_size"] for r in ranks] == [2, 2]
    # each rank trained on its own shard of the data ...
    assert ranks[0]["first_batch"] != ranks[1]["first_batch"]
    assert not set(ranks[0]["first_batch"]) & set(ranks[1]["first_batch"])
    # ... yet the replicas are bit-identical after the all-reduced updates
    assert ranks[0]["sha256"] == ranks[1]["sha256"], (ranks[0]["sum"], ranks[1]["sum"])
    # only rank 0 wrote the run folder, and training really changed the weights
    run = out / "run"
    assert (run / "checkpoints" / "ckpt_00000003.pt").is_file()
    from training.loop.checkpoint import load_latest_checkpoint
    from training.loop.config import TrainConfig
    from training.loop.trainer import build_models

    state = load_latest_checkpoint(run)
    assert state["extra"]["world_size"] == 2
    torch.manual_seed(TrainConfig.from_json(state["config"]).seed)
    init = build_models(TrainConfig.from_json(state["config"]))
    changed = [not torch.equal(init["predictor"].state_dict()[k], v) for k, v in state["models"]["predictor"].items()
               if v.is_floating_point()]
    assert any(changed)
    rows = (run / "log.csv").read_text().splitlines()
    assert len(rows) == 4  # header + 3 iterations, written once (rank 0)
