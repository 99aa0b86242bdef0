"""``sketchmesh bench renderer``: speed, memory and accuracy of the differentiable rasterizer.

Scene: the paper's 642-vertex icosphere (level 3), made bumpy (each vertex's radius scaled
by ``1 + 0.12 * n`` with n a smooth random field) and seen from random views (azimuth in
[0, 360), elevation in [-60, 60], distance 2.732), float32, one bumpy sphere per batch item.

For each (resolution, batch):

* ``forward_ms``: median wall time of ``rasterize`` (flat shading) after warm-up;
* ``forward_backward_ms``: median of forward + backward of ``L1(normals, target) +
  mean(1 - silhouette)`` (the training losses' shape); ``forward_backward_cpu_ms`` the
  median process CPU time of the same (all threads), a figure a busy machine disturbs less;
* ``peak_mb``: peak resident memory increase during the timed runs, from
  ``resource.getrusage(RUSAGE_SELF).ru_maxrss`` measured in a fresh subprocess per
  configuration (``ru_maxrss`` after building the scene is subtracted), in MiB;
* ``silhouette_iou_error``: ``1 - IoU`` between the render and a 4x-supersampled render of
  the same scene, box-downsampled and thresholded at 0.5;
* ``normal_error``: mean absolute difference of the encoded normal images (all three
  channels) over pixels covered in both, the supersampled normals averaged over their
  covered sub-pixels. Both errors use the first ``min(batch, 4)`` images.
* the dense every-face-against-every-pixel baseline (:mod:`training.render.dense`) where
  its estimated memory fits ``--dense-max-mb`` and the batch ``--dense-max-batch``, and its
  speed ratio to the fast path (``dense_speedup`` = dense / fast forward+backward time).
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import time
from dataclasses import asdict, dataclass

from engine.errors import SketchmeshError

ERROR_IMAGES = 4
"""Images per configuration used for the accuracy figures."""

SUPERSAMPLE = 4


@dataclass
class BenchRecord:
    resolution: int
    batch: int
    threads: int
    forward_ms: float
    forward_backward_ms: float
    forward_backward_cpu_ms: float
    peak_mb: float
    silhouette_iou_error: float
    normal_error: float
    boundary_pairs: int
    dense_forward_backward_ms: float | None = None
    dense_speedup: float | None = None


def make_scene(batch: int, seed: int = 0):
    """Bumpy 642-vertex spheres and random cameras.

    Returns:
        vertices: (B, 642, 3) float32; faces: (1280, 3) int64; cameras: (B, 16) float32.
    """
    import numpy as np
    import torch

    from engine.camera import look_at
    from engine.icosphere import icosphere
    from training.render import cameras_to_tensor

    m = icosphere(3)
    base = np.array(m.vertices, dtype=np.float64)
    rng = np.random.default_rng(seed)
    verts, cams = [], []
    unit = base / np.linalg.norm(base, axis=1, keepdims=True)
    for _ in range(batch):
        dirs = rng.normal(size=(6, 3))
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        field = np.sin(3.0 * unit @ dirs.T + rng.uniform(0, 2 * np.pi, 6)).mean(1)
        verts.append(base * (1.0 + 0.12 * field[:, None] / max(np.abs(field).max(), 1e-9)))
        cams.append(look_at(rng.uniform(0, 360), rng.uniform(-60, 60)))
    v = torch.tensor(np.stack(verts), dtype=torch.float32)
    return v, torch.tensor(np.array(m.faces)), cameras_to_tensor(cams, dtype=torch.float32)


def accuracy(vertices, faces, cameras, resolution: int) -> tuple[float, float]:
    """(1 - IoU, mean |normal difference|) of a render against the 4x-supersampled render."""
    import torch

    from training.render import rasterize

    with torch.no_grad():
        lo = rasterize(vertices, faces, cameras, resolution)
        hi = rasterize(vertices, faces, cameras, resolution * SUPERSAMPLE)
        B = vertices.shape[0]
        k = SUPERSAMPLE
        cov = hi.silhouette.view(B, resolution, k, resolution, k).mean((2, 4))
        sil_ref = cov >= 0.5
        sil = lo.silhouette > 0.5
        inter = (sil & sil_ref).sum().item()
        union = (sil | sil_ref).sum().item()
        iou_err = 1.0 - inter / union if union else 0.0
        n_sum = (hi.normals * hi.silhouette[:, None]).view(B, 3, resolution, k, resolution, k).sum((3, 5))
        cnt = hi.silhouette.view(B, resolution, k, resolution, k).sum((2, 4))
        n_ref = n_sum / cnt.clamp(min=1)[:, None]
        both = sil & (cnt > 0)
        if both.any():
            normal_err = (lo.normals - n_ref).abs().permute(0, 2, 3, 1)[both].mean().item()
        else:
            normal_err = 0.0
    return iou_err, normal_err


def _time(fn, repeats: int, warmup: int = 2) -> tuple[float, float]:
    """(median wall ms, median process CPU ms) over ``repeats`` runs after ``warmup`` runs."""
    for _ in range(warmup):
        fn()
    times, cpu = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return 1000.0 * statistics.median(times), 1000.0 * statistics.median(cpu)


def run_config(
    resolution: int, batch: int, repeats: int, threads: int, dense_max_mb: float, seed: int = 0, dense_max_batch: int = 16
) -> dict:
    """Measure one configuration in this process (call it in a fresh subprocess for peak_mb)."""
    import resource

    import torch

    from training.render import rasterize
    from training.render.dense import dense_bytes_per_image, dense_rasterize

    torch.set_num_threads(threads)
    v, f, c = make_scene(batch, seed)
    g = torch.Generator().manual_seed(seed)
    target = torch.rand(batch, 3, resolution, resolution, generator=g)
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss

    def fwd():
        with torch.no_grad():
            return rasterize(v, f, c, resolution)

    def make_fb(render):
        def fb():
            w = v.clone().requires_grad_()
            out = render(w, f, c, resolution)
            loss = (out.normals - target).abs().mean() + (1.0 - out.silhouette).mean()
            loss.backward()
            return w.grad

        return fb

    fwd_ms, _ = _time(fwd, repeats)
    fb_ms, fb_cpu = _time(make_fb(rasterize), repeats)
    peak_mb = max(0.0, (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - rss0) / 1024.0)
    fi = fwd().face_index
    pairs = int((fi[:, :, 1:] != fi[:, :, :-1]).sum() + (fi[:, 1:] != fi[:, :-1]).sum())
    n_err = min(batch, ERROR_IMAGES)
    iou_err, normal_err = accuracy(v[:n_err], f, c[:n_err], resolution)
    rec = BenchRecord(resolution, batch, threads, round(fwd_ms, 2), round(fb_ms, 2), round(fb_cpu, 2),
                      round(peak_mb, 1), round(iou_err, 5), round(normal_err, 5), pairs)
    if dense_bytes_per_image(f.shape[0], resolution) / 2**20 <= dense_max_mb and batch <= dense_max_batch:
        dense_ms, _ = _time(make_fb(dense_rasterize), max(1, min(repeats, 3)), warmup=1)
        rec.dense_forward_backward_ms = round(dense_ms, 2)
        rec.dense_speedup = round(dense_ms / fb_ms, 1) if fb_ms > 0 else None
    return asdict(rec)


def _run_in_subprocess(args: list[str], timeout: float) -> dict:
    code = (
        "import json, sys; from training.bench.renderer import run_config; "
        "print('RESULT ' + json.dumps(run_config(*[float(a) if '.' in a else int(a) for a in sys.argv[1:]])))"
    )
    env = dict(os.environ, OMP_NUM_THREADS=args[3])
    proc = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, timeout=timeout, env=env)
    for line in proc.stdout.splitlines():
        if line.startswith("RESULT "):
            return json.loads(line[len("RESULT "):])
    tail = (proc.stderr or proc.stdout).strip().splitlines()[-1:] or ["no output"]
    raise SketchmeshError(f"benchmark worker failed (exit {proc.returncode}): {tail[0]}")


def format_table(records: list[dict]) -> str:
    head = (f"{'res':>5} {'batch':>5} {'fwd ms':>9} {'fwd+bwd ms':>11} {'(cpu ms)':>9} {'peak MB':>8} {'1-IoU':>8} "
            f"{'normal err':>10} {'pairs':>8} {'dense f+b ms':>13} {'speedup':>8}")
    lines = [head, "-" * len(head)]
    for r in records:
        dense = f"{r['dense_forward_backward_ms']:>13.1f}" if r.get("dense_forward_backward_ms") is not None else f"{'-':>13}"
        speed = f"{r['dense_speedup']:>7.1f}x" if r.get("dense_speedup") is not None else f"{'-':>8}"
        lines.append(
            f"{r['resolution']:>5} {r['batch']:>5} {r['forward_ms']:>9.1f} {r['forward_backward_ms']:>11.1f} "
            f"{r['forward_backward_cpu_ms']:>9.1f} "
            f"{r['peak_mb']:>8.1f} {r['silhouette_iou_error']:>8.4f} {r['normal_error']:>10.4f} "
            f"{r['boundary_pairs']:>8d} {dense} {speed}"
        )
    return "\n".join(lines)


def main_bench_renderer(args) -> int:
    """Entry point of ``sketchmesh bench renderer`` (args from :mod:`training.cli.bench`)."""
    from tqdm import tqdm

    from engine.fileio import atomic_write_text

    configs = [(r, b) for r in args.resolutions for b in args.batches]
    records = []
    for res, batch in tqdm(configs, desc="bench renderer", unit="config", file=sys.stderr):
        worker_args = [str(res), str(batch), str(args.repeats), str(args.threads), f"{float(args.dense_max_mb):.1f}",
                       str(args.seed), str(args.dense_max_batch)]
        if args.in_process:
            rec = run_config(res, batch, args.repeats, args.threads, args.dense_max_mb, args.seed, args.dense_max_batch)
        else:
            rec = _run_in_subprocess(worker_args, timeout=args.timeout)
        records.append(rec)
    print(format_table(records))
    print(
        f"threads={args.threads}; times are medians of {args.repeats} runs after warm-up (cpu ms: process CPU time, "
        "all threads, less sensitive to a busy machine); peak_mb is the ru_maxrss "
        "increase in a fresh process per row; errors are against a 4x-supersampled render "
        f"(first {ERROR_IMAGES} images)."
    )
    if args.json:
        try:
            atomic_write_text(args.json, json.dumps(records, indent=2) + "\n")
        except OSError as exc:
            raise SketchmeshError(f"cannot write the benchmark records to {args.json}: {exc.strerror or exc}") from None
        print(f"wrote {len(records)} records to {args.json}")
    return 0
