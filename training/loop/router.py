"""Training a category router (:mod:`training.model.router`): ``sketchmesh router train``.

Run folder: ``checkpoints/ckpt_*.pt`` (atomic, resumable: a killed run continues from its last checkpoint with the
same data order and learning rates), ``config.json``, ``log.jsonl`` (one line per epoch: loss, accuracy and, with a
validation set, its accuracy and routing table).
"""

from __future__ import annotations

import json
import math
import os
import time
from pathlib import Path

import numpy as np

from training._torch import require_torch
from training.model.router import ROUTER_FORMAT, RouterConfig, RouterNet, labelled_rows, routing_table

torch = require_torch()
F = torch.nn.functional


def _batch(sets: list, picks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inputs (B, 3, s, s) float32 and labels (B,) of (set index, position) picks, sorted rows for the map."""
    xs, ys = [], []
    for k, (g, rows, labels) in enumerate(sets):
        pos = picks[picks[:, 0] == k, 1]
        if len(pos):
            xs.append(g.rows(rows[pos]))
            ys.append(labels[pos])
    return np.concatenate(xs), np.concatenate(ys)


def _shift(x: torch.Tensor, max_shift: int, gen: torch.Generator) -> torch.Tensor:
    """Each image moved by up to ``max_shift`` pixels in x and y, the background (0) filling in."""
    if max_shift <= 0:
        return x
    n, _, h, w = x.shape
    pad = F.pad(x, (max_shift,) * 4)
    d = torch.randint(0, 2 * max_shift + 1, (n, 2), generator=gen)
    return torch.stack([pad[i, :, d[i, 0]:d[i, 0] + h, d[i, 1]:d[i, 1] + w] for i in range(n)])


def predict_probabilities(net: RouterNet, sets: list, batch: int = 512) -> tuple[np.ndarray, np.ndarray]:
    """(probabilities (M, K), labels (M,)) over every row of every set, in eval mode."""
    net.eval()
    probs, labels = [], []
    with torch.no_grad():
        for g, rows, lab in sets:
            for i in range(0, len(rows), batch):
                x = torch.from_numpy(g.rows(rows[i:i + batch]))
                probs.append(torch.softmax(net(x), 1).numpy())
                labels.append(lab[i:i + batch])
    return np.concatenate(probs), np.concatenate(labels)


def train_router(run: str | os.PathLike, cfg: RouterConfig, resume: bool = True, progress: bool = True,
                 group: list[str] | None = None) -> dict:
    """Train (or resume) a router run; returns the last epoch's log record.

    Every epoch is one pass over every (input set, row) pair in a seeded order (epoch ``e`` of seed ``s``
    is the same on every machine), Adam with a cosine decay over ``cfg.epochs``, cross-entropy; a
    checkpoint after each epoch.
    """
    from tqdm import tqdm

    from engine.fileio import atomic_write_text
    from training.loop.checkpoint import load_latest_checkpoint, remove_stale_checkpoint_files, save_checkpoint
    from training.loop.config import code_version

    run = Path(run)
    train_sets, cats = [], cfg.categories or None
    for root in cfg.data:
        sets, _, cats = labelled_rows(root, cfg.inputs, "train", cats)
        train_sets += sets
    cfg.categories = list(cats)
    val_sets = labelled_rows(cfg.val_data, cfg.inputs, "train", cats)[0] if cfg.val_data else []
    torch.manual_seed(cfg.seed)  # the initial weights: a resumed run replaces them, a fresh one is reproducible
    net = RouterNet(len(cats), tuple(cfg.channels))
    opt = torch.optim.AdamW(net.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    start, log = 0, []
    unknown = [c for c in (group or []) if c not in cats]
    if unknown:
        raise ValueError(f"--group {' '.join(unknown)}: not among the router's categories {list(cats)}")
    remove_stale_checkpoint_files(run)
    state = load_latest_checkpoint(run)
    if state is not None and not resume:
        raise ValueError(f"{run} already has checkpoints: resume it, or choose another --out")
    if state is not None:
        saved = json.loads(state["config"])
        if saved.get("categories") != cfg.categories or saved.get("channels") != list(cfg.channels):
            raise ValueError(f"{run}: its checkpoint is of another router (categories or channels differ); "
                             "pass another --out")
        now = json.loads(cfg.to_json())
        changed = [k for k in now if k != "val_data" and saved.get(k) != now[k]]  # the data order and rates hang on them
        if changed:
            raise ValueError(f"{run} was trained with other settings ({', '.join(f'{k} {saved.get(k)!r}' for k in changed)}): "
                             "resume it with the same ones, or choose another --out")
        net.load_state_dict(state["models"]["router"])
        opt.load_state_dict(state["optimizers"]["router"])
        start = int(state["iteration"])
        log = list(state["extra"].get("log", []))
    pairs = np.concatenate([np.stack([np.full(len(r), k), np.arange(len(r))], 1) for k, (_, r, _) in enumerate(train_sets)])
    steps_per_epoch = math.ceil(len(pairs) / cfg.batch)
    total = cfg.epochs * steps_per_epoch
    record: dict = log[-1] if log else {}
    t_start, earlier = time.perf_counter(), float(record.get("seconds", 0.0))  # training time over every call
    for epoch in range(start, cfg.epochs):
        order = np.random.default_rng([cfg.seed, epoch]).permutation(len(pairs))
        gen = torch.Generator().manual_seed(cfg.seed * 100_003 + epoch)
        net.train()
        loss_sum, right, seen = 0.0, 0, 0
        bar = tqdm(range(steps_per_epoch), desc=f"router epoch {epoch + 1}/{cfg.epochs}", unit="batch",
                   disable=not progress, leave=False)
        for b in bar:
            step = epoch * steps_per_epoch + b
            for group_ in opt.param_groups:
                group_["lr"] = cfg.lr * 0.5 * (1 + math.cos(math.pi * step / total))
            pick = pairs[order[b * cfg.batch:(b + 1) * cfg.batch]]
            x, y = _batch(train_sets, pick[np.lexsort((pick[:, 1], pick[:, 0]))])
            x = _shift(torch.from_numpy(x), cfg.shift, gen)
            y = torch.from_numpy(y)
            logits = net(x)
            loss = F.cross_entropy(logits, y)
            if not torch.isfinite(loss):
                raise FloatingPointError(f"router loss became {loss.item()} at epoch {epoch + 1}, batch {b}")
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            loss_sum += float(loss.detach()) * len(y)
            right += int((logits.argmax(1) == y).sum())
            seen += len(y)
            bar.set_postfix(loss=f"{loss_sum / seen:.3f}", acc=f"{right / seen:.3f}")
        record = {"epoch": epoch + 1, "loss": loss_sum / seen, "train_accuracy": right / seen,
                  "seconds": earlier + time.perf_counter() - t_start}
        if val_sets:
            probs, labels = predict_probabilities(net, val_sets)
            record["val_accuracy"] = float((probs.argmax(1) == labels).mean())
            if group:
                record["val_routing"] = routing_table(probs, labels, cats, group)
        log.append(record)
        if progress:
            line = f"epoch {epoch + 1}: loss {record['loss']:.4f}, train accuracy {record['train_accuracy']:.3f}"
            if "val_accuracy" in record:
                line += f", validation accuracy {record['val_accuracy']:.3f}"
            tqdm.write(line)
        save_checkpoint(run, epoch + 1, cfg.to_json(), code_version(), {"router": net}, {"router": opt},
                        extra={"log": log})
        atomic_write_text(run / "log.jsonl", "".join(json.dumps(r) + "\n" for r in log))
    return record


def load_router_run(run: str | os.PathLike) -> tuple[RouterNet, RouterConfig]:
    """The newest checkpoint of a router run as an eval-mode network and its config."""
    from engine.errors import ModelError
    from training.loop.checkpoint import require_checkpoint

    state = require_checkpoint(run)
    try:
        cfg = RouterConfig(**json.loads(state["config"]))
    except TypeError:
        raise ModelError(f"{run}: not a router run (its config is another network's)") from None
    if cfg.format != ROUTER_FORMAT or "router" not in state["models"]:
        raise ModelError(f"{run}: not a router run")
    net = RouterNet(len(cfg.categories), tuple(cfg.channels))
    net.load_state_dict(state["models"]["router"])
    return net.eval(), cfg
