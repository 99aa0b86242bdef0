"""``sketchmesh bench train``: end-to-end training throughput of the mesh predictor, stage by stage.

Runs the real training step (:meth:`training.loop.trainer.Trainer.train_step`, mode ``mesh``)
on batches from the real loader (the :class:`torch.utils.data.DataLoader` over the training
set that :meth:`training.loop.trainer.Trainer.run` builds), and times, per step:

* ``data``: getting the next batch from the loader and moving it to the device;
* ``predictor_forward``: the predictor's forward pass and its vertices (from its first layer
  to the rasterizer call);
* ``rasterizer_forward``: :func:`training.loop.trainer.render_views` (the input view and the
  K = ``extra_views`` other views of every sample);
* ``losses_forward``: Eq. 6 (:class:`training.model.losses.MeshLoss`);
* ``losses_backward``: from the end of the forward pass until the gradient of the rendered
  images is known;
* ``rasterizer_backward``: until the gradient of the predicted vertices is known;
* ``predictor_backward``: until the last parameter gradient is accumulated;
* ``optimizer``: the Adam update;
* ``step_other``: the rest of the guarded step (reseeding, BatchNorm snapshot, zeroing
  gradients, the finite checks, the gradient norm and clipping).

The boundaries come from module and tensor hooks on the running step, so the stages add up
to the measured step (``data`` + ``step``); nothing in the step is changed. Then, in the same
process, the rasterizer alone renders every timed step's meshes from the same cameras, forward
and backward of ``|normals - target|.mean() + |silhouette - target|.mean()`` against that
step's targets (the shape of ``bench renderer``'s loss; median of :data:`RENDERER_REPEATS`
runs per step), as ``renderer_views_per_s``: its cost follows the pixels the predicted meshes
cover, so it is measured on those meshes, not on a stand-in.

Figures: ``samples_per_s`` = batch x timed steps / their wall time (data included);
``views_per_s`` = ``samples_per_s`` x (1 + K), the rendered views per second end to end;
``stages_ms``: mean milliseconds per step of each stage. On a shared machine they move with
the load; the record carries ``os.getloadavg()`` taken before and after, and the same figures
in process CPU time (all threads: ``samples_per_cpu_s``, ``renderer_views_per_cpu_s``,
``step_cpu_ms``, ``stages_cpu_ms``), which other jobs disturb less, and the median and fastest
step (``step_ms_median``, ``step_ms_min``). With two torch threads, a job on the other core
can stall every parallel region of the rasterizer's many small operations: its time has been
seen to move ten-fold between runs on the same meshes.

Data: ``--data DIR`` (its train split), else ``--shapes-per-category`` procedural
train-split shapes of every category built once (resumably) into ``--data-out``. ``--loader
npz`` feeds the step the way the trainer did before the mesh-array cache (every field
decompressed from the shape files, the sketch augmented), to compare with.
"""

from __future__ import annotations

import json
import os
import statistics
import sys
import time
from pathlib import Path

from engine.errors import SketchmeshError

DEFAULT_BATCH = 64
DEFAULT_STEPS = 10
DEFAULT_WARMUP = 3
DEFAULT_SHAPES_PER_CATEGORY = 2
DEFAULT_DATA_OUT = "data/bench-train"
RENDERER_REPEATS = 3

STAGES = ("data", "predictor_forward", "rasterizer_forward", "losses_forward", "losses_backward",
          "rasterizer_backward", "predictor_backward", "optimizer", "step_other")


class BenchTrainError(SketchmeshError):
    """``bench train`` cannot run as asked."""


def bench_config(data_dir: str, out_dir: str, batch: int, seed: int, overrides: dict | None = None):
    """The training config measured: the defaults in mode ``mesh`` at ``batch``, plus ``--set`` overrides."""
    from training.loop.config import TrainConfig

    base = TrainConfig(mode="mesh", data_dir=str(data_dir), out_dir=str(out_dir), batch=int(batch), seed=int(seed),
                       log_every=0, val_every=0, ckpt_every=0, plot_every=0)
    if not overrides:
        return base
    bad = sorted(set(overrides) & {"mode", "data_dir", "out_dir"})
    if bad:
        raise BenchTrainError(f"--set cannot change {bad}: bench train measures mode 'mesh' on --data")
    try:
        return TrainConfig.from_dict({**base.to_dict(), **overrides})
    except (ValueError, TypeError) as exc:
        raise BenchTrainError(f"--set: {exc}") from None


LOADERS = ("cache", "npz")
"""``cache``: the training set the trainer builds (mesh mode: the dataset's mesh-array cache);
``npz``: every field read from the shape files, sketches augmented (the trainer's path before the cache)."""


def make_train_set(cfg, loader: str = "cache"):
    """The training set ``bench train`` feeds the step (see :data:`LOADERS`)."""
    from training.data.dataset import ShapeViewDataset
    from training.loop.trainer import make_dataset, step_fields

    if loader not in LOADERS:
        raise BenchTrainError(f"--loader must be one of {LOADERS}, got {loader!r}")
    if loader == "cache":
        return make_dataset(cfg, "train", step_fields(cfg))
    return ShapeViewDataset(cfg.data_dir, "train", extra_views=cfg.extra_views, augment_strength=cfg.augment_strength,
                            seed=cfg.seed, categories=list(cfg.categories) or None, fields="all")


def procedural_data(out: str | os.PathLike, shapes_per_category: int, progress: bool = True) -> Path:
    """``shapes_per_category`` train-split procedural shapes of every category in ``out`` (built once, resumably)."""
    from training.bench.overfit import overfit_jobs
    from training.data.dataset import BuildSettings, build_dataset, check_build_request
    from training.data.shapes import CATEGORIES

    jobs = overfit_jobs(shapes_per_category * len(CATEGORIES))
    settings = BuildSettings()
    check_build_request(out, len(jobs), settings, workers=2)
    res = build_dataset(out, jobs, settings, workers=2, progress=progress)
    if res["shapes"] == 0:
        raise BenchTrainError(f"could not build the procedural data in {out}: {res['failed'][:1]}")
    return Path(out)


class StageClock:
    """Timestamps of one step's stage boundaries, taken by hooks on the trainer's modules and tensors.

    Every mark is ``(wall seconds, process CPU seconds)`` (``time.perf_counter``, ``time.process_time``):
    the CPU time of all threads is disturbed less by other jobs on a shared machine than the wall time.
    """

    def __init__(self, device) -> None:
        import torch

        self._sync = torch.cuda.synchronize if device.type == "cuda" else (lambda: None)
        self.marks: dict[str, tuple[float, float]] = {}
        self.last_render = None  # (vertices, faces, cameras) of the last rasterizer call

    def now(self) -> tuple[float, float]:
        self._sync()
        return time.perf_counter(), time.process_time()

    def mark(self, name: str, last: bool = False) -> None:
        """Record ``name`` now (the first time per step, or every time with ``last``)."""
        if last or name not in self.marks:
            self.marks[name] = self.now()


def instrument(trainer, clock: StageClock) -> list:
    """Hook the trainer's step so ``clock`` sees every stage boundary; returns what to undo (handles, patches)."""
    import training.loop.trainer as trainer_module

    predictor = trainer.models["predictor"]
    undo: list = [predictor.register_forward_pre_hook(lambda m, a: clock.mark("predictor_start"))]
    undo.append(trainer.mesh_loss.register_forward_pre_hook(lambda m, a: clock.mark("losses_start")))
    undo.append(trainer.mesh_loss.register_forward_hook(lambda m, a, o: clock.mark("losses_end")))
    for p in predictor.parameters():
        if p.requires_grad:
            undo.append(p.register_post_accumulate_grad_hook(lambda p: clock.mark("backward_end", last=True)))

    original_render = trainer_module.render_views

    def render_views(vertices, faces, cameras, cfg):
        clock.mark("render_start")
        out = original_render(vertices, faces, cameras, cfg)
        clock.mark("render_end")
        if vertices.requires_grad:
            vertices.register_hook(lambda g: clock.mark("vertices_grad"))
        for image in (out.normals, out.silhouette):
            if image.requires_grad:
                image.register_hook(lambda g: clock.mark("images_grad", last=True))
        clock.last_render = (vertices.detach(), faces, cameras.detach())
        return out

    trainer_module.render_views = render_views
    undo.append(("render_views", original_render))

    original_compute = trainer._compute

    def compute(batch, it):
        result = original_compute(batch, it)
        clock.mark("forward_end")
        return result

    trainer._compute = compute
    undo.append(("_compute", None))
    optimizer = trainer.optimizers["predictor"]
    original_step = optimizer.step

    def step(*args, **kwargs):
        clock.mark("optimizer_start")
        out = original_step(*args, **kwargs)
        clock.mark("optimizer_end")
        return out

    optimizer.step = step
    undo.append(("step", optimizer))
    return undo


def uninstrument(trainer, undo: list) -> None:
    import training.loop.trainer as trainer_module

    for item in undo:
        if isinstance(item, tuple):
            what, value = item
            if what == "render_views":
                trainer_module.render_views = value
            elif what == "_compute":
                del trainer._compute
            elif what == "step":
                del value.step
        else:
            item.remove()


def stage_times(m: dict[str, tuple[float, float]], t_data0, t_step0, t_step1, j: int = 0) -> dict[str, float]:
    """Seconds per stage of one step from its marks (see the module docstring); ``j`` 0: wall, 1: CPU time."""
    def at(name: str, default: float) -> float:
        return m[name][j] if name in m else default

    fwd_end = at("forward_end", t_step1[j])
    img = at("images_grad", fwd_end)
    vert = at("vertices_grad", img)
    bwd = at("backward_end", vert)
    s = {
        "data": t_step0[j] - t_data0[j],
        "predictor_forward": at("render_start", fwd_end) - at("predictor_start", fwd_end),
        "rasterizer_forward": at("render_end", 0.0) - at("render_start", 0.0),
        "losses_forward": at("losses_end", 0.0) - at("losses_start", 0.0),
        "losses_backward": img - fwd_end,
        "rasterizer_backward": vert - img,
        "predictor_backward": bwd - vert,
        "optimizer": at("optimizer_end", bwd) - at("optimizer_start", bwd),
    }
    s["step_other"] = (t_step1[j] - t_step0[j]) - sum(v for k, v in s.items() if k != "data")
    return s


def renderer_throughput(scenes: list, cfg, repeats: int = RENDERER_REPEATS) -> tuple[float, float]:
    """(views per second, per CPU second) of the rasterizer alone, forward + backward, on the steps' scenes.

    Args:
        scenes: per step ``(vertices (B, V, 3), faces (F, 3), cameras (B, 1 + K, 16), (target normals
            (B * (1 + K), 3, H, W), target silhouettes (B * (1 + K), H, W)))``, as the step rendered them.
        repeats: runs per scene; its median counts.
    """
    import torch

    from training.loop.trainer import render_views

    sync = torch.cuda.synchronize if scenes[0][0].device.type == "cuda" else (lambda: None)

    def once(vertices, faces, cameras, targets) -> tuple[float, float]:
        w = vertices.clone().requires_grad_()
        sync()
        t0, c0 = time.perf_counter(), time.process_time()
        out = render_views(w, faces, cameras, cfg)
        loss = (out.normals - targets[0]).abs().mean() + (out.silhouette - targets[1]).abs().mean()
        loss.backward()
        sync()
        return time.perf_counter() - t0, time.process_time() - c0

    once(*scenes[0])  # warm-up
    wall = cpu = 0.0
    views = 0
    for scene in scenes:
        runs = [once(*scene) for _ in range(repeats)]
        wall += statistics.median(r[0] for r in runs)
        cpu += statistics.median(r[1] for r in runs)
        views += scene[2].shape[0] * scene[2].shape[1]
    return views / wall, views / max(cpu, 1e-9)


def run_bench(cfg, *, train_set=None, steps: int = DEFAULT_STEPS, warmup: int = DEFAULT_WARMUP,
              progress: bool = True) -> dict:
    """Measure ``steps`` training steps of ``cfg`` (mode ``mesh``) after ``warmup`` steps; returns the record.

    Args:
        cfg: the training config (``out_dir`` must be an empty or missing folder: nothing is written there).
        train_set: the training dataset (default: what the trainer itself builds from ``cfg.data_dir``).
        steps, warmup: timed steps and untimed steps before them.
    """
    import torch

    from training.loop.trainer import ResumableBatchSampler, Trainer, _to_device, mesh_targets

    if cfg.mode != "mesh":
        raise BenchTrainError(f"bench train measures mode 'mesh', got {cfg.mode!r}")
    trainer = Trainer(cfg, resume=False, progress=False, train_set=train_set, val_set=None)
    for m in trainer.models.values():
        m.train()
    sampler = ResumableBatchSampler(len(trainer.train_set), cfg.batch, cfg.seed, 0, trainer.info)
    loader = torch.utils.data.DataLoader(trainer.train_set, batch_sampler=sampler, num_workers=cfg.num_workers,
                                         generator=torch.Generator().manual_seed(cfg.seed), persistent_workers=False,
                                         pin_memory=trainer.device.type == "cuda")
    clock = StageClock(trainer.device)
    undo = instrument(trainer, clock)
    load0 = os.getloadavg()
    per_stage: dict[str, list[float]] = {k: [] for k in STAGES}
    per_stage_cpu: dict[str, list[float]] = {k: [] for k in STAGES}
    scenes = []
    skipped = 0
    data_iter = iter(loader)
    try:
        t_timed = None
        for it in range(warmup + steps):
            if it == warmup:
                t_timed = clock.now()
            clock.marks = {}
            t_data0 = clock.now()
            batch = _to_device(next(data_iter), trainer.device)
            t_step0 = clock.now()
            ok, _ = trainer.train_step(batch, it)
            t_step1 = clock.now()
            if it >= warmup:
                skipped += 0 if ok else 1
                for j, into in ((0, per_stage), (1, per_stage_cpu)):
                    for k, v in stage_times(clock.marks, t_data0, t_step0, t_step1, j).items():
                        into[k].append(v)
                if clock.last_render is not None:
                    scenes.append((*clock.last_render, mesh_targets(batch)))
            if progress:
                print(f"bench train: step {it + 1}/{warmup + steps} ({'warm-up' if it < warmup else 'timed'}) "
                      f"{t_step1[0] - t_data0[0]:.2f} s", file=sys.stderr)
        t_end = clock.now()
        wall, cpu = t_end[0] - t_timed[0], t_end[1] - t_timed[1]
        if len(scenes) < steps:
            raise BenchTrainError(f"only {len(scenes)} of {steps} timed steps reached the rasterizer "
                                  "(non-finite predicted vertices?)")
        renderer_vps, renderer_vpcs = renderer_throughput(scenes, cfg)
    finally:
        uninstrument(trainer, undo)
        del data_iter
    views_per_sample = 1 + cfg.extra_views
    samples_per_s = cfg.batch * steps / wall
    step_s = [sum(x) for x in zip(*per_stage.values())]  # data + step, per timed step
    stages_ms = {k: round(1000.0 * statistics.fmean(v), 2) for k, v in per_stage.items()}
    return {
        "benchmark": "train",
        "mode": cfg.mode,
        "batch": cfg.batch,
        "extra_views": cfg.extra_views,
        "views_per_sample": views_per_sample,
        "steps": steps,
        "warmup": warmup,
        "skipped_steps": skipped,
        "threads": torch.get_num_threads(),
        "num_workers": cfg.num_workers,
        "device": str(trainer.device),
        "samples_per_s": round(samples_per_s, 3),
        "views_per_s": round(samples_per_s * views_per_sample, 3),
        "renderer_views_per_s": round(renderer_vps, 3),
        "step_ms": round(1000.0 * wall / steps, 2),
        "step_ms_median": round(1000.0 * statistics.median(step_s), 2),
        "step_ms_min": round(1000.0 * min(step_s), 2),
        "stages_ms": stages_ms,
        "samples_per_cpu_s": round(cfg.batch * steps / max(cpu, 1e-9), 3),
        "renderer_views_per_cpu_s": round(renderer_vpcs, 3),
        "step_cpu_ms": round(1000.0 * cpu / steps, 2),
        "stages_cpu_ms": {k: round(1000.0 * statistics.fmean(v), 2) for k, v in per_stage_cpu.items()},
        "predictor_parameters": sum(p.numel() for p in trainer.models["predictor"].parameters()),
        "train_samples": len(trainer.train_set),
        "loadavg_before": [round(x, 2) for x in load0],
        "loadavg_after": [round(x, 2) for x in os.getloadavg()],
        "config": cfg.to_dict(),
    }


def format_record(r: dict) -> str:
    s = r["stages_ms"]
    groups = [("data", s["data"]),
              ("predictor fwd+bwd", s["predictor_forward"] + s["predictor_backward"]),
              ("rasterizer fwd+bwd", s["rasterizer_forward"] + s["rasterizer_backward"]),
              ("losses fwd+bwd", s["losses_forward"] + s["losses_backward"]),
              ("optimizer (Adam)", s["optimizer"]),
              ("rest of the step", s["step_other"])]
    total = sum(v for _, v in groups)
    lines = [f"bench train: mode mesh, batch {r['batch']}, K = {r['extra_views']} extra views, "
             f"{r['predictor_parameters']:,} predictor parameters, {r['threads']} threads, "
             f"{r['num_workers']} loader workers, {r['steps']} timed steps ({r['skipped_steps']} skipped)",
             f"  {'stage':<22} {'ms/step':>9} {'share':>7}"]
    for name, v in groups:
        lines.append(f"  {name:<22} {v:>9.1f} {100.0 * v / max(total, 1e-9):>6.1f}%")
    lines.append(f"  {'(stages in detail)':<22} " + ", ".join(f"{k} {v:.1f}" for k, v in s.items()))
    lines.append(f"  step {r['step_ms']:.1f} ms (median {r['step_ms_median']:.1f}, fastest {r['step_ms_min']:.1f}): "
                 f"{r['samples_per_s']:.1f} samples/s, {r['views_per_s']:.1f} views/s "
                 f"end to end; the rasterizer alone {r['renderer_views_per_s']:.1f} views/s (forward + backward, "
                 f"same meshes and cameras); end to end / rasterizer = "
                 f"{r['views_per_s'] / max(r['renderer_views_per_s'], 1e-9):.2f}")
    k = r["views_per_sample"]
    lines.append(f"  in process CPU time (all threads): step {r['step_cpu_ms']:.1f} ms, "
                 f"{r['samples_per_cpu_s'] * k:.1f} views per CPU second end to end, the rasterizer alone "
                 f"{r['renderer_views_per_cpu_s']:.1f}; data {r['stages_cpu_ms']['data']:.1f} ms")
    if "loader" in r:
        lines.append(f"  loader {r['loader']} (dataset opened in {r['dataset_open_s']:.2f} s)")
    lines.append(f"  load average (1, 5, 15 min) before {r['loadavg_before']}, after {r['loadavg_after']}")
    return "\n".join(lines)


def main_bench_train(args) -> int:
    """``sketchmesh bench train``; see the module docstring."""
    import tempfile

    import torch

    from engine.fileio import atomic_write_text
    from training.data.dataset import check_dataset

    torch.set_num_threads(int(args.threads))
    progress = not args.quiet
    if args.data:
        data_dir = Path(args.data)
    else:
        data_dir = procedural_data(args.data_out, args.shapes_per_category, progress=progress)
    with tempfile.TemporaryDirectory(prefix="bench-train-") as run_dir:
        cfg = bench_config(str(data_dir), str(Path(run_dir) / "run"), args.batch, args.seed, dict(args.set or []))
        check_dataset(data_dir, "train", cfg.categories or None, "--data")
        t0 = time.perf_counter()
        train_set = make_train_set(cfg, args.loader)
        open_s = time.perf_counter() - t0
        record = run_bench(cfg, train_set=train_set, steps=args.steps, warmup=args.warmup, progress=progress)
    record.update(data=str(data_dir), loader=args.loader, dataset_open_s=round(open_s, 3))
    print(format_record(record))
    if args.json:
        try:
            atomic_write_text(args.json, json.dumps(record, indent=2) + "\n")
        except OSError as exc:
            raise SketchmeshError(f"cannot write the benchmark record to {args.json}: {exc.strerror or exc}") from None
        print(f"wrote {args.json}")
    return 0
