"""Vector stroke data, as the app's canvas records it.

Coordinates are canvas pixels: x right, y down, origin top-left (the same orientation as
images, see :mod:`engine.camera`). The engine rasterises strokes into the generator's framed
256x256 input (:func:`engine.preprocess.rasterize_strokes`), so the app and the CLI agree.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.errors import SketchInputError


@dataclass(frozen=True, eq=False)
class Stroke:
    """One pen-down-to-pen-up stroke.

    Attributes:
        points: (N, 2) float64 canvas coordinates (x right, y down), N >= 1.
        pressure: (N,) float64 in [0, 1] or None (constant full pressure).
        width: nominal pen width in canvas pixels (> 0) at full pressure.
    """

    points: np.ndarray
    pressure: np.ndarray | None = None
    width: float = 3.0

    def __post_init__(self) -> None:
        p = np.array(self.points, dtype=np.float64)
        if p.ndim != 2 or p.shape[1] != 2 or len(p) == 0:
            raise SketchInputError(f"stroke points must be (N, 2) with N >= 1, got {p.shape}")
        if not np.all(np.isfinite(p)):
            raise SketchInputError("stroke points contain NaN or inf")
        pr = None
        if self.pressure is not None:
            pr = np.array(self.pressure, dtype=np.float64).reshape(-1)
            if pr.shape != (len(p),):
                raise SketchInputError(f"stroke pressure must be ({len(p)},), got {pr.shape}")
            if not np.all(np.isfinite(pr)):
                raise SketchInputError("stroke pressure contains NaN or inf")
            pr = np.clip(pr, 0.0, 1.0)
            pr.setflags(write=False)
        if not (np.isfinite(self.width) and self.width > 0):
            raise SketchInputError(f"stroke width must be finite and > 0, got {self.width}")
        p.setflags(write=False)
        object.__setattr__(self, "points", p)
        object.__setattr__(self, "pressure", pr)
        object.__setattr__(self, "width", float(self.width))

    def to_dict(self) -> dict:
        """JSON-ready form (for autosave and saved sketches)."""
        d = {"points": self.points.tolist(), "width": self.width}
        if self.pressure is not None:
            d["pressure"] = self.pressure.tolist()
        return d

    @staticmethod
    def from_dict(d: dict) -> Stroke:
        """Inverse of :meth:`to_dict`; raises SketchInputError on malformed data."""
        try:
            return Stroke(d["points"], d.get("pressure"), d.get("width", 3.0))
        except (KeyError, TypeError, ValueError) as exc:
            raise SketchInputError(f"malformed stroke data: {exc}") from None
