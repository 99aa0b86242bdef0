"""Hand-drawn augmentation of clean line drawings (after Smirnov et al., as the paper does).

Works on polylines ((N, 2) float64 pixel coordinates, x = col, y = row) so it can be redone
at load time with any strength and seed. Effects, each scaled by ``strength`` in [0, 1]:

* missing strokes (a polyline dropped; the longest one always survives),
* broken strokes (gaps cut into a polyline),
* wobble (smooth low-frequency sideways drift) and jitter (small per-point noise),
* over-sketching (a second, slightly offset and trimmed copy of a stroke),
* overshoot / undershoot at stroke ends,
* varying thickness and ink darkness per stroke,
* a small global shift, scale and rotation about the image centre.

``strength == 0`` returns the clean drawing exactly (same polylines, nominal width, full ink).
Everything is deterministic in the seed: ``numpy.random.default_rng(seed)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.contract import SKETCH_STROKE_WIDTH_PX
from training.data.lines import rasterize_polylines

RESAMPLE_SPACING_PX = 2.0
"""Point spacing (pixels at 256) after resampling, before wobble and jitter (scaled with the image size)."""
WIDTH_STEP_PX = 0.25
"""Augmented stroke widths are multiples of this (pixels)."""
INK_STEP = 0.1
"""Augmented ink intensities are multiples of this."""
REFERENCE_SIZE = 256
"""Pixel amplitudes below are for a 256 image and scale linearly with the image size."""


@dataclass(frozen=True)
class AugmentSettings:
    """Maxima of each effect at strength 1 (pixels at 256x256; probabilities per stroke)."""

    p_missing: float = 0.12
    breaks_per_100px: float = 0.8
    gap_px: tuple[float, float] = (2.0, 7.0)
    wobble_px: float = 1.6
    jitter_px: float = 0.35
    p_double: float = 0.35
    double_offset_px: float = 1.6
    overshoot_px: float = 4.0
    width_spread: float = 0.45
    ink_min: float = 0.65
    shift_px: float = 5.0
    scale_spread: float = 0.06
    rotate_deg: float = 3.0


@dataclass(frozen=True, eq=False)
class Strokes:
    """Polylines with per-stroke width (pixels) and ink intensity in (0, 1]."""

    polylines: list
    widths: np.ndarray
    intensities: np.ndarray


def _resample(p: np.ndarray, spacing: float) -> np.ndarray:
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    total = s[-1]
    if total <= 1e-9:
        return p.copy()
    n = max(2, int(np.ceil(total / spacing)) + 1)
    t = np.linspace(0.0, total, n)
    return np.stack([np.interp(t, s, p[:, 0]), np.interp(t, s, p[:, 1])], axis=1)


def _normals(p: np.ndarray) -> np.ndarray:
    d = np.gradient(p, axis=0) if len(p) > 2 else np.repeat(p[-1:] - p[:1], len(p), axis=0)
    n = np.stack([-d[:, 1], d[:, 0]], axis=1)
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-9)


def _smooth_noise(rng: np.random.Generator, s: np.ndarray, amplitude: float, wavelength: tuple[float, float]) -> np.ndarray:
    """Sum of two random sinusoids along arclength s: (N,) values with |v| <= amplitude."""
    out = np.zeros_like(s)
    for _ in range(2):
        lam = rng.uniform(*wavelength)
        out += 0.5 * amplitude * np.sin(2 * np.pi * s / lam + rng.uniform(0, 2 * np.pi))
    return out


def augment_strokes(polylines: list, strength: float, seed, size: int = REFERENCE_SIZE,
                    width: float = SKETCH_STROKE_WIDTH_PX, settings: AugmentSettings = AugmentSettings()) -> Strokes:
    """Make a clean line drawing look hand-drawn.

    Args:
        polylines: list of (N_i, 2) pixel coordinates of the clean drawing.
        strength: in [0, 1]; 0 returns the clean polylines unchanged.
        seed: anything ``numpy.random.default_rng`` accepts (int or sequence of ints).
        size: image size the coordinates refer to (effects scale with size / 256).
        width: nominal stroke width in pixels at ``size``.
        settings: maxima of the effects at strength 1.

    Returns:
        :class:`Strokes` with the augmented polylines, per-stroke widths and ink intensities.
    """
    if not (np.isfinite(strength) and 0.0 <= strength <= 1.0):
        raise ValueError(f"augmentation strength must be in [0, 1], got {strength}")
    clean = [np.asarray(p, np.float64) for p in polylines]
    for i, p in enumerate(clean):
        if p.ndim != 2 or p.shape[1] != 2 or len(p) == 0:
            raise ValueError(f"polyline {i} must be (N, 2), got {p.shape}")
    if strength == 0.0 or not clean:
        return Strokes([p.copy() for p in clean], np.full(len(clean), float(width)), np.ones(len(clean)))
    rng = np.random.default_rng(seed)
    k = size / REFERENCE_SIZE
    st, cfg = float(strength), settings
    lengths = np.array([np.linalg.norm(np.diff(p, axis=0), axis=1).sum() for p in clean])
    keep = rng.random(len(clean)) >= cfg.p_missing * st
    keep[int(np.argmax(lengths))] = True
    out: list[np.ndarray] = []
    widths: list[float] = []
    inks: list[float] = []
    for p, L, kept in zip(clean, lengths, keep):
        if not kept:
            continue
        q = _resample(p, RESAMPLE_SPACING_PX * k)
        # overshoot (+) or undershoot (-) at both ends
        if len(q) >= 2 and L > 4 * k:
            for end in (0, -1):
                ext = rng.uniform(-0.5, 1.0) * cfg.overshoot_px * k * st
                d = q[end] - q[1 if end == 0 else -2]
                d /= max(np.linalg.norm(d), 1e-9)
                if ext > 0:
                    q = np.concatenate([q[:1] + d * ext, q]) if end == 0 else np.concatenate([q, q[-1:] + d * ext])
                elif len(q) > 3:
                    q = q[1:] if end == 0 else q[:-1]
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(q, axis=0), axis=1))])
        nrm = _normals(q)
        wob = _smooth_noise(rng, s, cfg.wobble_px * k * st, (40.0 * k, 160.0 * k))
        q = q + nrm * wob[:, None] + rng.normal(0.0, cfg.jitter_px * k * st, q.shape)
        # broken strokes: cut gaps
        pieces = [q]
        nbreaks = rng.poisson(cfg.breaks_per_100px * st * s[-1] / (100.0 * k)) if s[-1] > 0 else 0
        if nbreaks and len(q) > 6:
            cuts = np.sort(rng.uniform(0.15, 0.85, nbreaks) * s[-1])
            gaps = rng.uniform(*cfg.gap_px, nbreaks) * k * st
            mask = np.ones(len(q), bool)
            for c, g in zip(cuts, gaps):
                mask &= ~((s > c - g / 2) & (s < c + g / 2))
            idx = np.nonzero(mask)[0]
            if len(idx):
                runs = np.split(idx, np.nonzero(np.diff(idx) > 1)[0] + 1)
                pieces = [q[r] for r in runs if len(r) >= 2]
        # widths in steps of WIDTH_STEP_PX and inks in steps of INK_STEP, so strokes batch into few draw calls
        w = max(WIDTH_STEP_PX, np.round(width * (1.0 + rng.uniform(-1.0, 1.0) * cfg.width_spread * st) / WIDTH_STEP_PX) * WIDTH_STEP_PX)
        ink = np.round((1.0 - rng.uniform(0.0, 1.0 - cfg.ink_min) * st) / INK_STEP) * INK_STEP
        for piece in pieces:
            out.append(piece)
            widths.append(w)
            inks.append(ink)
        # over-sketched double stroke
        if rng.random() < cfg.p_double * st and len(q) >= 4:
            a, b = sorted(rng.uniform(0.0, 0.35, 2) * np.array([1, -1]) + np.array([0.0, 1.0]))
            lo, hi = int(a * (len(q) - 1)), int(np.ceil(b * (len(q) - 1))) + 1
            dup = q[lo:hi]
            if len(dup) >= 2:
                off = rng.normal(0.0, cfg.double_offset_px * k * st, 2)
                dup = dup + off + nrm[lo:hi] * _smooth_noise(rng, s[lo:hi], cfg.wobble_px * k * st, (30.0 * k, 120.0 * k))[:, None]
                out.append(dup)
                widths.append(max(WIDTH_STEP_PX, np.round(w * rng.uniform(0.7, 1.0) / WIDTH_STEP_PX) * WIDTH_STEP_PX))
                inks.append(np.round(ink * rng.uniform(0.7, 1.0) / INK_STEP) * INK_STEP)
    # global similarity about the image centre
    c = np.array([size / 2.0, size / 2.0])
    ang = np.radians(rng.uniform(-1, 1) * cfg.rotate_deg * st)
    sc = 1.0 + rng.uniform(-1, 1) * cfg.scale_spread * st
    R = sc * np.array([[np.cos(ang), -np.sin(ang)], [np.sin(ang), np.cos(ang)]])
    shift = rng.uniform(-1, 1, 2) * cfg.shift_px * k * st
    out = [(p - c) @ R.T + c + shift for p in out]
    return Strokes(out, np.asarray(widths, np.float64), np.asarray(inks, np.float64))


def render_sketch(polylines: list, size: int, strength: float = 0.0, seed=0,
                  width: float = SKETCH_STROKE_WIDTH_PX, settings: AugmentSettings = AugmentSettings()) -> np.ndarray:
    """Augment (if strength > 0) and rasterise: (H, W) float32 in [0, 1], 1 = ink.

    With ``strength == 0`` this is exactly ``rasterize_polylines(polylines, size, width)``.
    """
    strokes = augment_strokes(polylines, strength, seed, size, width, settings)
    return rasterize_polylines(strokes.polylines, size, strokes.widths, strokes.intensities)
