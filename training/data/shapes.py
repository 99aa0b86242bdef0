"""A procedural shape library: the 13 ShapeNet categories the paper reports.

Every category is a family of sub-types with wide continuous parameters (proportions,
thicknesses, angles, placements) and discrete variants (part counts, optional parts, profiles):
airliners, cargo planes, jets, propeller planes (monoplane or biplane, wheels or floats) and
gliders; chairs on four or three legs, a swivel star, a sled, a cantilever or a pedestal with
solid, slatted, ladder, round or gap backs; sedans, hatchbacks, SUVs, coupes, convertibles,
micro cars, off-roaders, vans and pickups; and so on (each generator's docstring lists its
variants). Every sub-type keeps its category recognisable. Parts are solid primitives (boxes,
cylinders, cones, spheres, convex hulls, extruded and revolved profiles) joined with a
**boolean union** (and differences for cut-outs) in manifold3d, so every shape is one closed,
watertight, consistently oriented (outward, counter-clockwise) triangle mesh with positive
volume -- never a set of overlapping shells.

Variety is measured by :mod:`training.evaluation.variety` (the mean best voxel IoU of held-out
shapes against the train shapes of their category, the bound on the retrieval baseline):
0.66 with 100 shapes per category, against 0.83 for the less varied library before it.

Orientation and scale follow :mod:`engine.camera`: +Y up, the shape's front faces +Z
(a car's bonnet, an airplane's nose, a rifle's muzzle, a chair's seat edge, a display's
screen point to +Z), and the result is normalised with
:func:`engine.camera.normalize_vertices` (longest bounding-box side 1, centred).

Determinism: ``make_shape(category, index)`` draws every parameter from
``numpy.random.default_rng([crc32(category), index])``, so the same (category, index) gives
bit-identical arrays on every machine (manifold3d's booleans are deterministic for fixed
inputs). The split (train / val / test, 80 / 10 / 10) is a hash of (category, index) too.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable

import numpy as np

from engine.camera import normalize_vertices
from engine.mesh import Mesh

LIBRARY_VERSION = 2
"""Bumped whenever the generators change what a (category, index) gives (2: the variety rework).
Recorded in a dataset's settings, so a rebuild into an older folder renders the shapes anew."""

CATEGORIES: tuple[str, ...] = (
    "airplane",
    "bench",
    "cabinet",
    "car",
    "chair",
    "display",
    "lamp",
    "loudspeaker",
    "rifle",
    "sofa",
    "table",
    "telephone",
    "watercraft",
)
"""The 13 ShapeNet categories the paper reports (cabinet = ShapeNet's "dresser")."""

SPLITS: tuple[str, ...] = ("train", "val", "test")
SPLIT_FRACTIONS: tuple[float, float, float] = (0.8, 0.1, 0.1)

MIN_FACES = 1000
"""Shapes with fewer faces are refined (edges split, geometry unchanged) up to at least this many."""
MAX_FACES = 20000
"""Upper bound on a procedural shape's face count (a test checks every category stays below it)."""

SEGMENTS = 20
"""Circular segments of round parts (cylinders, cones); spheres use the same."""

SLIVER_VOLUME = 1e-7
"""Disconnected fragments of a union with less than this fraction of the largest piece's volume are dropped
(degenerate slivers from coincident faces); any real floating part is far larger and fails the tests."""


def _rng(category: str, index: int) -> np.random.Generator:
    return np.random.default_rng([zlib.crc32(category.encode("utf-8")), int(index)])


def split_of(category: str, index: int) -> str:
    """Deterministic 80/10/10 split by shape: "train", "val" or "test".

    A hash of (category, index), independent of how many shapes are generated, so a shape
    never changes split when the library grows.
    """
    h = zlib.crc32(f"split:{category}:{int(index)}".encode()) % 1000
    if h < 1000 * SPLIT_FRACTIONS[0]:
        return "train"
    if h < 1000 * (SPLIT_FRACTIONS[0] + SPLIT_FRACTIONS[1]):
        return "val"
    return "test"


# --------------------------------------------------------------------------- primitives
def _m3d():
    import manifold3d

    return manifold3d


def box(size, center=(0.0, 0.0, 0.0)):
    """Axis-aligned solid box: size (3,) full extents, centred at ``center``."""
    M = _m3d().Manifold
    return M.cube(tuple(float(s) for s in size), True).translate(tuple(float(c) for c in center))


def _frame_to(direction: np.ndarray) -> np.ndarray:
    """(3, 3) rotation mapping +Z to the unit ``direction``."""
    d = direction / np.linalg.norm(direction)
    z = np.array([0.0, 0.0, 1.0])
    c = float(np.dot(z, d))
    if c > 1 - 1e-12:
        return np.eye(3)
    if c < -1 + 1e-12:
        return np.diag([1.0, -1.0, -1.0])
    axis = np.cross(z, d)
    s = np.linalg.norm(axis)
    k = axis / s
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * K + (1 - c) * K @ K


def cylinder(p0, p1, r0, r1=None, segments: int = SEGMENTS):
    """Solid cylinder (or cone frustum) from point p0 (radius r0) to p1 (radius r1)."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    r1 = r0 if r1 is None else r1
    d = p1 - p0
    h = float(np.linalg.norm(d))
    c = _m3d().Manifold.cylinder(h, float(r0), float(r1), segments, False)
    R = _frame_to(d)
    T = np.concatenate([R, p0[:, None]], axis=1)
    return c.transform(T.tolist())


def sphere(center, radius, scale=(1.0, 1.0, 1.0), segments: int = SEGMENTS):
    """Solid sphere (ellipsoid with ``scale``) at ``center``."""
    s = _m3d().Manifold.sphere(float(radius), segments)
    return s.scale(tuple(float(x) for x in scale)).translate(tuple(float(c) for c in center))


def hull(points):
    """Convex hull of (N, 3) points as a solid."""
    return _m3d().Manifold.hull_points(np.asarray(points, dtype=np.float64))


def rounded_box(size, center, radius, segments: int = 12):
    """Box with rounded edges: hull of 8 corner spheres (radius clipped to half the smallest side)."""
    size = np.asarray(size, float)
    r = float(min(radius, 0.49 * size.min()))
    h = size / 2 - r
    M = _m3d().Manifold
    corners = [
        M.sphere(r, segments).translate((sx * h[0] + center[0], sy * h[1] + center[1], sz * h[2] + center[2]))
        for sx in (-1, 1)
        for sy in (-1, 1)
        for sz in (-1, 1)
    ]
    return M.batch_hull(corners)


def union(parts):
    """Boolean union of solids (one closed manifold)."""
    m3 = _m3d()
    return m3.Manifold.batch_boolean(list(parts), m3.OpType.Add)


def _drop_slivers(solid):
    """Remove zero-volume fragments a boolean can leave where faces coincide (a few degenerate triangles)."""
    comps = solid.decompose()
    if len(comps) <= 1:
        return solid
    vols = [abs(c.volume()) for c in comps]
    keep = [c for c, v in zip(comps, vols) if v > SLIVER_VOLUME * max(vols)]
    return _m3d().Manifold.compose(keep) if len(keep) > 1 else keep[0]


def _split_edges(v: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Split every edge at its midpoint (each triangle into four): 4x the faces, same surface, still closed."""
    F, V = len(f), len(v)
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    _, first, inv = np.unique(e[:, 0] * V + e[:, 1], return_index=True, return_inverse=True)  # 1D keys: fast
    uniq = e[first]
    inv = inv.reshape(-1) + V
    m01, m12, m20 = inv[:F], inv[F:2 * F], inv[2 * F:]
    a, b, c = f[:, 0], f[:, 1], f[:, 2]
    faces = np.concatenate([np.stack(t, axis=1) for t in ((a, m01, m20), (m01, b, m12), (m20, m12, c), (m01, m12, m20))])
    return np.concatenate([v, (v[uniq[:, 0]] + v[uniq[:, 1]]) / 2.0]), faces


def _to_mesh(solid, min_faces: int = MIN_FACES) -> Mesh:
    m = _drop_slivers(solid).to_mesh()
    v = np.asarray(m.vert_properties, dtype=np.float64)[:, :3]
    f = np.asarray(m.tri_verts, dtype=np.int64)
    if len(f) == 0:
        raise RuntimeError("procedural shape came out empty (a generator bug)")
    while len(f) < min_faces:
        v, f = _split_edges(v, f)
    return Mesh(normalize_vertices(v).astype(np.float32), f)


def _square_prism(p0, p1, half):
    """8 corner points of a square-section prism between p0 and p1 (axis mostly vertical)."""
    pts = []
    for p in (p0, p1):
        for dx in (-half, half):
            for dz in (-half, half):
                pts.append((p[0] + dx, p[1], p[2] + dz))
    return pts


def _poly2d(points):
    """CrossSection of one simple polygon, re-ordered counter-clockwise."""
    p = np.asarray(points, dtype=np.float64)
    x, y = p[:, 0], p[:, 1]
    if np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) < 0:
        p = p[::-1].copy()
    return _m3d().CrossSection([p])


def side_extrude(zy, width, x_center=0.0):
    """Solid extruded along X (``width``, centred at ``x_center``) from a simple polygon of (z, y) points.

    The polygon may be concave (a car's side, a rifle stock, a sofa's L-shaped section).
    """
    e = _m3d().Manifold.extrude(_poly2d(zy), float(width))
    # extrusion axis -> X, polygon (u, v) -> (z, y): (u, v, w) -> (x_c + W/2 - w, v, u), a proper rotation
    return e.transform([[0.0, 0.0, -1.0, float(x_center) + width / 2], [0.0, 1.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]])


def front_extrude(xy, depth, z_center=0.0):
    """Solid extruded along Z (``depth``, centred at ``z_center``) from a simple polygon of (x, y) points."""
    return _m3d().Manifold.extrude(_poly2d(xy), float(depth)).translate((0.0, 0.0, float(z_center) - depth / 2))


def lathe(profile, center=(0.0, 0.0, 0.0), segments: int = SEGMENTS):
    """Solid of revolution about the vertical (+Y) axis through ``center``.

    ``profile``: a simple polygon of (radius >= 0, height) points; edges on radius 0 close the solid.
    """
    s = _m3d().Manifold.revolve(_poly2d(profile), int(segments))  # axis +Z
    cx, cy, cz = (float(c) for c in center)
    # (x, y, z) -> (x, z, -y): height (revolve's +Z) becomes +Y
    return s.transform([[1.0, 0.0, 0.0, cx], [0.0, 0.0, 1.0, cy], [0.0, -1.0, 0.0, cz]])


def rotated(solid, degrees, pivot=(0.0, 0.0, 0.0)):
    """``solid`` rotated by Euler ``degrees`` (x, then y, then z) about ``pivot``."""
    p = tuple(float(c) for c in pivot)
    return solid.translate(tuple(-c for c in p)).rotate(tuple(float(d) for d in degrees)).translate(p)


def bar(p0, p1, half):
    """Square-section bar (about 2 x ``half`` wide) between two points, any direction."""
    return cylinder(p0, p1, half * np.sqrt(2.0), segments=4)


def difference(solid, cuts):
    """``solid`` minus the union of ``cuts``."""
    m3 = _m3d()
    return m3.Manifold.batch_boolean([solid] + list(cuts), m3.OpType.Subtract)


def _pick(rng, options, p=None):
    """One of ``options`` (strings), with optional probabilities."""
    return str(options[int(rng.choice(len(options), p=p))])


def _ring(z, rx, ry, yc=0.0, n=12):
    """n points of an ellipse in the plane at ``z`` (half-axes rx along X, ry along Y, centre height yc)."""
    a = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    return [(rx * np.cos(t), yc + ry * np.sin(t), z) for t in a]


def _panel_pair(z_root, y_root, root_chord, tip_chord, half_span, sweep, dihedral, t_root, t_tip=None):
    """Two mirrored tapered panels (wings, stabilisers) from x = 0 to |x| = half_span.

    ``sweep``: how far the tip's chord centre lies behind (-Z) the root's; ``dihedral``: tip rise.
    """
    t_tip = t_root * 0.6 if t_tip is None else t_tip
    parts = []
    for s in (-1, 1):
        pts = [(0.0, y_root + dy, z_root + dz) for dy in (-t_root / 2, t_root / 2) for dz in (-root_chord / 2, root_chord / 2)]
        pts += [(s * half_span, y_root + dihedral + dy, z_root - sweep + dz) for dy in (-t_tip / 2, t_tip / 2)
                for dz in (-tip_chord / 2, tip_chord / 2)]
        parts.append(hull(pts))
    return parts


def _legs(points_top, y_top, y_bottom, r, splay=0.0, square=False, taper=1.0):
    """Legs from (x, y_top, z) down to the floor, each pushed outwards from the centre by ``splay``."""
    parts = []
    for x, z in points_top:
        n = np.hypot(x, z)
        ox, oz = (x / n * splay, z / n * splay) if n > 1e-9 else (0.0, 0.0)
        top, bot = (x, y_top, z), (x + ox, y_bottom, z + oz)
        if square:
            parts.append(hull([(p[0] + dx * k, p[1], p[2] + dz * k) for p, k in ((top, r), (bot, r * taper))
                               for dx in (-1, 1) for dz in (-1, 1)]))
        else:
            parts.append(cylinder(bot, top, r * taper, r, segments=12))
    return parts


def _corners(x, z):
    return [(sx * x, sz * z) for sx in (-1, 1) for sz in (-1, 1)]


def _leg_at(x, z, splay, f):
    """(x, z) of a leg of :func:`_legs` (top at (x, z), pushed out by ``splay`` at the floor) a fraction f down."""
    n = np.hypot(x, z)
    if n <= 1e-9:
        return x, z
    return x + x / n * splay * f, z + z / n * splay * f


# --------------------------------------------------------------------------- categories
def _airplane(rng):
    """Airliner, cargo transport, jet fighter, light propeller plane (monoplane or biplane, wheels or floats)
    or glider: fuselage, wings, tail (conventional, T, twin or fin only), engines on the wings, at the rear,
    in the nose or none."""
    kind = _pick(rng, ("airliner", "cargo", "jet", "prop", "glider"), [0.32, 0.12, 0.23, 0.23, 0.1])
    u = rng.uniform
    biplane = False
    if kind == "airliner":
        L = u(1.5, 2.6)
        R, span, rc, taper = L * u(0.04, 0.105), L * u(0.65, 1.25), L * u(0.12, 0.22), u(0.2, 0.5)
        sweep_k, wz, wing_y = u(0.15, 0.65), L * u(-0.06, 0.12), _pick(rng, ("low", "low", "high"))
        nose_len, tail_len, tail_r, tail_up = L * u(0.07, 0.14), L * u(0.18, 0.32), u(0.1, 0.3), u(0.2, 0.6)
        tail = _pick(rng, ("conv", "T"), [0.7, 0.3])
        engines = _pick(rng, ("wing2", "wing4", "rear2", "none"), [0.45, 0.3, 0.15, 0.1])
    elif kind == "cargo":  # a fat fuselage, high straight wing, upswept tail, four engines
        L = u(1.3, 2.2)
        R, span, rc, taper = L * u(0.08, 0.12), L * u(0.85, 1.25), L * u(0.1, 0.16), u(0.4, 0.7)
        sweep_k, wz, wing_y = u(0.0, 0.25), L * u(0.0, 0.12), "high"
        nose_len, tail_len, tail_r, tail_up = L * u(0.06, 0.1), L * u(0.25, 0.35), u(0.15, 0.3), u(0.6, 0.9)
        tail = _pick(rng, ("T", "conv"), [0.7, 0.3])
        engines = "wing4"
    elif kind == "jet":
        L = u(1.4, 2.4)
        R, span, rc, taper = L * u(0.045, 0.1), L * u(0.4, 0.8), L * u(0.25, 0.45), u(0.05, 0.35)
        sweep_k, wz, wing_y = u(0.55, 1.1), -L * u(0.08, 0.22), "mid"
        nose_len, tail_len, tail_r, tail_up = L * u(0.18, 0.3), L * u(0.12, 0.2), u(0.55, 0.85), u(0.0, 0.3)
        tail = _pick(rng, ("twin", "conv", "fin"), [0.45, 0.3, 0.25])
        engines = _pick(rng, ("intakes", "none"), [0.6, 0.4])
    elif kind == "prop":
        L = u(1.0, 1.7)
        biplane = rng.random() < 0.3
        R, span, rc, taper = L * u(0.06, 0.1), L * u(1.0, 1.6), L * u(0.11, 0.18), u(0.55, 1.0)
        sweep_k, wz, wing_y = u(-0.05, 0.1), L * u(0.05, 0.2), "low" if biplane else _pick(rng, ("low", "high"))
        nose_len, tail_len, tail_r, tail_up = L * u(0.06, 0.12), L * u(0.3, 0.45), u(0.12, 0.3), u(0.2, 0.6)
        tail = _pick(rng, ("conv", "T"), [0.75, 0.25]) if not biplane else "conv"
        engines = _pick(rng, ("nose", "wing2"), [0.65, 0.35]) if not biplane else "nose"
    else:  # glider
        L = u(1.0, 1.5)
        R, span, rc, taper = L * u(0.035, 0.055), L * u(1.8, 2.7), L * u(0.06, 0.1), u(0.3, 0.6)
        sweep_k, wz, wing_y = u(-0.02, 0.08), L * u(0.05, 0.18), _pick(rng, ("high", "mid"))
        nose_len, tail_len, tail_r, tail_up = L * u(0.1, 0.18), L * u(0.45, 0.6), u(0.15, 0.3), u(0.1, 0.4)
        tail = _pick(rng, ("T", "conv"), [0.7, 0.3])
        engines = "none"
    prop_engines = kind == "prop" or (kind == "cargo" and rng.random() < 0.5)
    hr = u(0.9, 1.25)  # fuselage height / width
    zt, zn = -L / 2, L / 2
    tip_r = 0.35 if engines == "nose" else u(0.05, 0.2)
    parts = [
        hull(_ring(zn, R * tip_r, R * tip_r * hr) + _ring(zn - nose_len * 0.45, R * 0.82, R * 0.82 * hr)
             + _ring(zn - nose_len, R, R * hr) + _ring(zt + tail_len - 0.01, R, R * hr)),
        hull(_ring(zt + tail_len, R, R * hr) + _ring(zt, R * tail_r, R * tail_r * hr, R * hr * tail_up)),
    ]
    if kind not in ("airliner", "cargo"):  # canopy
        cl = nose_len * u(0.8, 1.6)
        parts.append(sphere((0, R * hr * 0.55, zn - nose_len - cl * 0.3), 1.0, (R * 0.6, R * hr * 0.7, cl / 2), 16))
    # wings
    yw = {"low": -0.55, "mid": 0.0, "high": 0.6}[wing_y] * R * hr
    hs = span / 2
    t = max(0.02, rc * 0.1)
    sweep = sweep_k * hs
    dihedral = hs * (u(-0.02, 0.05) if wing_y == "high" else u(0.0, 0.12))
    tc = rc * taper
    parts += _panel_pair(wz, yw, rc, tc, hs, sweep, dihedral, t)
    if kind == "airliner" and rng.random() < 0.5:  # winglets
        wh = hs * u(0.06, 0.12)
        for s in (-1, 1):
            parts.append(hull([(s * x, yw + dihedral + dy, wz - sweep + dz) for x in (hs - 0.03, hs) for dy in (-t * 0.3, t * 0.3)
                               for dz in (-tc / 2, tc / 2)]
                              + [(s * hs, yw + dihedral + wh, wz - sweep - tc * 0.5 + dz) for dz in (-tc * 0.3, tc * 0.3)]))
    if kind == "jet" and rng.random() < 0.4:  # canards
        parts += _panel_pair(zn - nose_len - rc * 0.3, 0.0, rc * 0.3, rc * 0.1, hs * 0.4, rc * 0.2, 0.0, t * 0.7)
    # engines
    def wing_at(frac):
        """(z of the chord centre, y of the mid-surface, local chord) at |x| = frac * hs."""
        return wz - sweep * frac, yw + dihedral * frac, rc + (tc - rc) * frac

    if engines in ("wing2", "wing4"):
        nr, nl = R * u(0.4, 0.7), L * u(0.09, 0.16)
        fracs = [u(0.28, 0.4)] if engines == "wing2" else [u(0.22, 0.3), u(0.48, 0.6)]
        for frac in fracs:
            zc, yc, ch = wing_at(frac)
            for s in (-1, 1):
                x = s * frac * hs
                if prop_engines:  # nacelle on the wing with a two-blade propeller in front
                    z0, z1 = zc - ch * 0.5, zc + ch * 0.5 + nl * 0.6
                    parts.append(cylinder((x, yc, z0), (x, yc, z1), nr, nr * 0.8, 16))
                    parts.append(rotated(box((nr * 0.4, nr * 5, 0.015), (x, yc, z1 - 0.002)), (0, 0, u(0, 180)), (x, yc, z1)))
                else:
                    ny = yc - t / 2 - nr * 1.1
                    parts.append(cylinder((x, ny, zc + ch * 0.5 - nl * 0.75), (x, ny, zc + ch * 0.5 + nl * 0.25), nr * 0.85, nr, 16))
                    parts.append(box((nr * 0.3, nr * 1.2 + t, ch * 0.4), (x, (ny + yc) / 2, zc + ch * 0.15)))
    elif engines == "rear2":
        nr, nl = R * u(0.45, 0.65), L * u(0.1, 0.15)
        zc = zt + tail_len * 1.05
        for s in (-1, 1):
            parts.append(cylinder((s * (R + nr * 1.3), R * 0.3, zc - nl / 2), (s * (R + nr * 1.3), R * 0.3, zc + nl / 2), nr * 0.85, nr, 16))
            parts.append(box((R + nr * 1.3, nr * 0.4, nl * 0.5), (s * (R + nr * 1.3) / 2, R * 0.3, zc)))
    elif engines == "intakes":
        il = L * u(0.2, 0.35)
        for s in (-1, 1):
            parts.append(hull([(s * x, y, z) for x in (R * 0.5, R * 1.35) for y in (-R * hr * 0.5, R * hr * 0.3)
                               for z in (zn - nose_len - il, zn - nose_len - 0.02)]))
    elif engines == "nose":
        sl = R * u(0.5, 1.0)
        parts.append(cylinder((0, 0, zn - 0.02), (0, 0, zn + sl), R * tip_r, R * 0.06, 16))
        nb, pr = int(rng.integers(2, 5)), R * u(2.0, 3.5)
        a0 = u(0, 90)
        for k in range(nb):
            parts.append(box((pr * 0.18, pr * 1.1, 0.012), (0, pr * 0.45, zn + sl * 0.25)).rotate((0, 0, a0 + 360.0 * k / nb)))
    if biplane:  # an upper wing on cabane and interplane struts
        yu, stag, hsu = R * hr + rc * u(0.5, 0.9), rc * u(0.0, 0.4), hs * u(0.9, 1.05)
        parts.append(hull([(x, yu + dy, wz + stag + dz) for x in (-hsu, hsu) for dy in (-t * 0.3, t * 0.3) for dz in (-tc / 2, tc / 2)]
                          + [(0.0, yu + dy, wz + stag + dz) for dy in (-t / 2, t / 2) for dz in (-rc / 2, rc / 2)]))
        for s in (-1, 1):
            parts.append(bar((s * R * 0.4, R * hr * 0.5, wz + stag * 0.5), (s * R * 0.6, yu, wz + stag), 0.01))
            zc, yc, _ = wing_at(0.65)
            parts.append(bar((s * 0.65 * hs, yc, zc), (s * 0.65 * hs, yu, wz + stag), 0.012))
    if kind == "prop" and rng.random() < 0.65:
        if rng.random() < 0.4:  # floats (seaplane)
            fr, fl, xf, yf = R * u(0.35, 0.5), L * u(0.45, 0.65), R * u(1.5, 2.5), -R * hr - R * u(1.0, 1.8)
            for s in (-1, 1):
                parts.append(sphere((s * xf, yf, wz + rc * 0.3), 1.0, (fr, fr, fl / 2), 16))
                for dz in (-rc * 0.3, rc * 0.6):
                    parts.append(bar((s * R * 0.3, -R * hr * 0.5, wz + dz), (s * xf, yf, wz + dz), 0.01))
        else:  # fixed landing gear
            wr = R * u(0.35, 0.5)
            gy = -R * hr - R * u(0.8, 1.4)
            for s in (-1, 1):
                parts.append(cylinder((s * R * 0.3, -R * hr * 0.5, wz + rc * 0.4), (s * R * 1.6, gy, wz + rc * 0.5), R * 0.1, segments=8))
                parts.append(cylinder((s * R * 1.45, gy, wz + rc * 0.5), (s * R * 1.85, gy, wz + rc * 0.5), wr, segments=16))
    # tail
    ty = R * hr * tail_up  # fuselage centre line at the tail end
    fb = min(tail_len * u(0.55, 0.95), L * 0.2)  # fin base length
    fh = R * hr + L * u(0.07, 0.24)
    fsweep = fb * u(0.3, 1.0)
    ft = max(0.018, t * 0.8)

    top = fb * u(0.35, 0.6)  # fin tip chord

    def fin(x, cant):
        pts = [(x + dx, ty, z) for dx in (-ft / 2, ft / 2) for z in (zt + 0.01, zt + fb)]
        pts += [(x + cant + dx * 0.6, ty + fh, z) for dx in (-ft / 2, ft / 2) for z in (zt + 0.01 + fsweep - fb * 0.3, zt + fsweep - fb * 0.3 + top)]
        return hull(pts), (zt + fsweep - fb * 0.3 + top / 2, ty + fh)

    hsp = hs * u(0.25, 0.45) if kind != "glider" else hs * u(0.12, 0.2)
    hc = fb * u(0.5, 0.8)
    if tail == "twin":
        for s in (-1, 1):
            parts.append(fin(s * R * 0.45, s * fh * u(0.1, 0.35))[0])
        parts += _panel_pair(zt + hc / 2 + 0.01, ty, hc, hc * 0.45, hsp, hc * 0.4, 0.0, ft)
    else:
        f, (fz, fy) = fin(0.0, 0.0)
        parts.append(f)
        if tail == "T":
            parts += _panel_pair(fz, fy - ft * 0.8, fb * 0.45, fb * 0.3, hsp * 0.8, fb * 0.15, 0.0, ft)
        elif tail == "conv":
            parts += _panel_pair(zt + hc / 2 + 0.01, ty, hc, hc * 0.5, hsp, hc * u(0.1, 0.6), hsp * u(0.0, 0.1), ft)
    return union(parts)


def _bench(rng):
    """Park, garden or gym bench: slab or slatted seat on legs, slab sides, trestles or blocks; optional back and arms."""
    u = rng.uniform
    W, H, th = u(0.9, 2.4), u(0.32, 0.55), u(0.03, 0.09)
    D = min(u(0.28, 0.65), W * 0.4)
    seat = _pick(rng, ("slab", "slats"), [0.55, 0.45])
    base = _pick(rng, ("legs", "sides", "trestle", "blocks"), [0.4, 0.25, 0.2, 0.15])
    back = _pick(rng, ("none", "solid", "slats"), [0.4, 0.3, 0.3])
    inset = u(0.03, 0.2) * W
    xe = W / 2 - inset  # the supports' x
    parts = []
    y_under = H - th  # underside of the seat, or of the bearers under slats
    if seat == "slab":
        parts.append(box((W, th, D), (0, H - th / 2, 0)))
    else:
        n = int(rng.integers(3, 7))
        gap = D * u(0.02, 0.06)
        bw = (D - gap * (n - 1)) / n
        for k in range(n):
            parts.append(box((W, th, bw), (0, H - th / 2, -D / 2 + bw / 2 + k * (bw + gap))))
    support_x = [-xe, xe]
    if base == "legs":
        lr = u(0.02, 0.05)
        if W > 1.6 and rng.random() < 0.6:
            support_x.append(0.0)
        zl = D / 2 - u(0.04, 0.15) * D
        stretch = rng.random() < 0.5
        yt = y_under - (0.035 if seat == "slats" else 0.0) + 0.01
        parts += _legs([(x, s2 * zl) for x in support_x for s2 in (-1, 1)], yt, 0.0, lr,
                       splay=0.0 if stretch else u(0, 0.06), square=rng.random() < 0.5)
        if stretch:
            ys = u(0.08, 0.3) * H
            for x in support_x:
                parts.append(box((0.04, 0.04, 2 * zl), (x, ys, 0)))
            parts.append(box((2 * xe, 0.04, 0.04), (0, ys, 0)))
    elif base == "sides":
        st = u(0.04, 0.1)
        dd = D * u(0.7, 1.0)
        for x in support_x:
            side = box((st, H - th + 0.01, dd), (x, (H - th + 0.01) / 2, 0))
            if rng.random() < 0.5:  # arched cut-out between two feet
                side = difference(side, [box((st * 2, (H - th) * 0.5, dd * 0.6), (x, 0, 0))])
            parts.append(side)
    elif base == "trestle":
        for x in support_x:
            for s2 in (-1, 1):
                parts.append(bar((x, H - th + 0.005, s2 * D * 0.15), (x, 0.02, s2 * D * 0.48), 0.025))
            parts.append(box((0.05, 0.04, D), (x, 0.02, 0)))
            parts.append(box((0.05, H - th, 0.05), (x, (H - th) / 2, 0)))
        parts.append(box((2 * xe, 0.04, 0.04), (0, (H - th) * 0.4, 0)))
    else:  # blocks
        bw_ = u(0.12, 0.35) * W
        support_x = [s * (W / 2 - max(inset, bw_ / 2)) for s in (-1, 1)]
        for x in support_x:
            parts.append(box((bw_, H - th + 0.01, D * u(0.6, 0.95)), (x, (H - th + 0.01) / 2, 0)))
    if seat == "slats":  # bearers under the slats, over the supports
        for x in support_x:
            parts.append(box((0.06, 0.05, D), (x, H - th - 0.015, 0)))
    px = W / 2 - min(inset, 0.12 * W)
    if back != "none":
        bh, tilt, gap0 = u(0.2, 0.55), u(0.0, 0.15), u(0.0, 0.12)
        bz = -D / 2 + 0.03
        for s in (-1, 1):  # posts
            parts.append(bar((s * px, H - th, bz), (s * px, H + bh, bz - tilt), 0.025))
        if back == "solid":
            y0 = H + gap0
            parts.append(hull([(x, y, z + dz) for x in (-W / 2, W / 2) for dz in (0.0, 0.035)
                               for (y, z) in ((y0, bz - tilt * gap0 / bh - 0.035), (H + bh, bz - tilt - 0.035))]))
        else:
            n = int(rng.integers(2, 5))
            for k in range(n):
                f = (gap0 + (bh - gap0) * (k + 0.5) / n) / bh
                hb = (bh - gap0) / n * 0.6
                parts.append(hull([(x, H + f * bh + dy, bz - tilt * f - 0.03 + dz) for x in (-W / 2, W / 2)
                                   for dy in (-hb / 2, hb / 2) for dz in (0.0, 0.03)]))
        if rng.random() < 0.45:  # arms
            ah = u(0.15, 0.28)
            for s in (-1, 1):
                parts.append(box((0.05, 0.035, D * 0.9), (s * px, H + ah, -0.02 * D)))
                parts.append(bar((s * px, H - th, D * 0.38), (s * px, H + ah, D * 0.38), 0.02))
    return union(parts)


def _cabinet(rng):
    """Dresser, sideboard, wardrobe, open cabinet or hutch: drawers, doors, both or open shelves; plinth, legs or
    feet; optionally a shallower upper cabinet (open shelves or doors) standing on the back of the top."""
    u = rng.uniform
    W, H, D = u(0.4, 1.8), u(0.35, 2.0), u(0.3, 0.7)
    hutch = rng.random() < 0.2
    if hutch:
        W, H_total, D = max(W, 0.7), max(H, 1.3), max(D, 0.4)
        H = H_total * u(0.38, 0.55)
    base = _pick(rng, ("plinth", "legs", "feet", "none"), [0.35, 0.3, 0.15, 0.2])
    front = _pick(rng, ("drawers", "doors", "mixed", "open"), [0.3, 0.3, 0.25, 0.15])
    bh = {"plinth": u(0.03, 0.1), "legs": u(0.08, 0.3), "feet": u(0.03, 0.07), "none": 0.0}[base] * min(1.0, H + 0.3)
    body_h = H - bh
    parts = []
    body = box((W, body_h, D), (0, bh + body_h / 2, 0))
    gap = 0.015
    cells = []  # (x, y, w, h, kind)

    def grid(y0, y1, rows, cols, kind):
        cw, ch = (W - gap * (cols + 1)) / cols, (y1 - y0 - gap * (rows + 1)) / rows
        for i in range(rows):
            for j in range(cols):
                cells.append((-W / 2 + gap + cw / 2 + j * (cw + gap), y0 + gap + ch / 2 + i * (ch + gap), cw, ch, kind, j, cols))

    y0, y1 = bh, H
    if front == "drawers":
        grid(y0, y1, int(rng.integers(2, 7)), int(rng.integers(1, 4)), "drawer")
    elif front == "doors":
        rows = 2 if body_h > 1.2 and rng.random() < 0.5 else 1
        grid(y0, y1, rows, int(rng.integers(1, 4 if W > 0.9 else 3)), "door")
    elif front == "mixed":
        split = y0 + body_h * u(0.45, 0.75)
        grid(y0, split, 1, int(rng.integers(1, 3)), "door")
        grid(split, y1, int(rng.integers(1, 4)), int(rng.integers(1, 4)), "drawer")
    else:
        rows, cols = int(rng.integers(1, 5)), int(rng.integers(1, 4))
        lower = rng.random() < 0.5
        if lower:
            split = y0 + body_h * u(0.2, 0.4)
            grid(y0, split, 1, cols, "drawer")
            y0 = split
        cw, ch = (W - gap * 2 * (cols + 1)) / cols, (y1 - y0 - gap * 2 * (rows + 1)) / rows
        cuts = [box((cw, ch, D), (-W / 2 + 2 * gap + cw / 2 + j * (cw + 2 * gap), y0 + 2 * gap + ch / 2 + i * (ch + 2 * gap), D * 0.1))
                for i in range(rows) for j in range(cols)]
        body = difference(body, cuts)
    parts.append(body)
    handle = _pick(rng, ("bar", "knob", "none"), [0.5, 0.35, 0.15])
    for (cx, cy, cw, ch, kind, j, cols) in cells:
        parts.append(box((cw, ch, 0.02), (cx, cy, D / 2 + 0.005)))
        if handle == "none":
            continue
        if kind == "door":
            side = 0.0 if cols == 1 else (1.0 if j % 2 == 0 else -1.0)
            hx = cx + side * cw * 0.38 if cols > 1 else cx + cw * 0.38
            if handle == "bar":
                parts.append(box((0.02, min(ch * 0.3, 0.3), 0.03), (hx, cy, D / 2 + 0.025)))
            else:
                parts.append(cylinder((hx, cy, D / 2), (hx, cy, D / 2 + 0.04), 0.015, segments=10))
        else:
            if handle == "bar":
                parts.append(box((cw * u(0.2, 0.5), min(0.025, ch * 0.3), 0.03), (cx, cy, D / 2 + 0.025)))
            else:
                for hx in ((cx,) if cw < 0.5 else (cx - cw * 0.25, cx + cw * 0.25)):
                    parts.append(cylinder((hx, cy, D / 2), (hx, cy, D / 2 + 0.04), 0.015, segments=10))
    if rng.random() < 0.6 or hutch:  # top overhang
        oh = u(0.0, 0.05)
        parts.append(box((W + 2 * oh, u(0.02, 0.05), D + oh), (0, H, oh / 2)))
    if hutch:
        hw, hd = W * u(0.85, 1.0), D * u(0.3, 0.6)
        hh = H_total - H
        upper = box((hw, hh + 0.01, hd), (0, H + hh / 2, -D / 2 + hd / 2))
        rows = int(rng.integers(1, 4))
        cols = int(rng.integers(1, 4))
        cw, ch = (hw - 0.03 * (cols + 1)) / cols, (hh - 0.03 * (rows + 1)) / rows
        fz = -D / 2 + hd
        cells_h = [(-hw / 2 + 0.03 + cw / 2 + j * (cw + 0.03), H + 0.03 + ch / 2 + i * (ch + 0.03)) for i in range(rows) for j in range(cols)]
        if rng.random() < 0.6:  # open shelves
            upper = difference(upper, [box((cw, ch, hd), (x, y, fz - hd * 0.4)) for x, y in cells_h])
            parts.append(upper)
        else:  # doors
            parts.append(upper)
            for x, y in cells_h:
                parts.append(box((cw, ch, 0.02), (x, y, fz + 0.005)))
    if base == "plinth":
        parts.append(box((W * u(0.85, 0.97), bh + 0.01, D * 0.9), (0, (bh + 0.01) / 2, 0)))
    elif base == "legs":
        lr = u(0.02, 0.04)
        parts += _legs(_corners(W / 2 - lr * 1.5, D / 2 - lr * 1.5), bh + 0.01, 0.0, lr, splay=u(0, 0.05),
                       square=rng.random() < 0.5, taper=u(0.5, 1.0))
    elif base == "feet":
        fr = u(0.03, 0.05)
        for x, z in _corners(W / 2 - fr, D / 2 - fr):
            parts.append(box((2 * fr, bh + 0.01, 2 * fr), (x, (bh + 0.01) / 2, z)))
    return union(parts)


def _car(rng):
    """Sedan, hatchback, SUV, coupe, convertible, micro car, off-roader, van or pickup: lower body with sloped
    bonnet, greenhouse at a style-dependent place (or just a windscreen), four wheels, optional spoiler, roof
    rails, spare wheel or pickup bed."""
    u = rng.uniform
    style = _pick(rng, ("sedan", "hatch", "suv", "coupe", "convertible", "micro", "offroad", "van", "pickup"),
                  [0.14, 0.12, 0.12, 0.1, 0.08, 0.08, 0.1, 0.13, 0.13])
    L = u(1.2, 1.6) if style == "micro" else u(1.6, 2.6)
    W = L * ({"micro": u(0.5, 0.62), "offroad": u(0.44, 0.55)}.get(style, u(0.34, 0.5)))
    bh = L * {"suv": u(0.16, 0.25), "van": u(0.15, 0.24), "pickup": u(0.16, 0.24), "coupe": u(0.09, 0.14),
              "convertible": u(0.1, 0.15), "micro": u(0.17, 0.24), "offroad": u(0.17, 0.25)}.get(style, u(0.11, 0.18))
    clear = L * (u(0.1, 0.15) if style == "offroad" else u(0.07, 0.11) if style in ("suv", "pickup") else u(0.03, 0.07))
    wr = L * (u(0.12, 0.15) if style == "offroad" else u(0.08, 0.12) * (1.2 if style in ("suv", "pickup") else 1.0))
    wr = min(wr, clear + bh * 0.6)
    y0, top = clear, clear + bh
    # greenhouse: (rear base, rear roof, front roof, front base) z positions as fractions of L, roof height
    if style == "sedan":
        zr0, zr1, zf1, zf0, ch = -0.38, -0.18, 0.12, 0.25, u(0.1, 0.17)
    elif style == "hatch":
        zr0, zr1, zf1, zf0, ch = -0.47, -0.43, 0.1, 0.25, u(0.11, 0.18)
    elif style in ("suv", "offroad"):
        zr0, zr1, zf1, zf0, ch = -0.48, -0.46, 0.16, 0.27, u(0.12, 0.19)
    elif style in ("coupe", "convertible"):
        zr0, zr1, zf1, zf0, ch = -0.3, -0.12, 0.0, 0.18, u(0.08, 0.13)
    elif style == "micro":
        zr0, zr1, zf1, zf0, ch = -0.48, -0.46, 0.22, 0.36, u(0.17, 0.25)
    elif style == "van":
        zr0, zr1, zf1, zf0, ch = -0.49, -0.48, 0.3, 0.43, u(0.16, 0.27)
    else:  # pickup: cab only
        zr0, zr1, zf1, zf0, ch = -0.05, -0.03, 0.12, 0.24, u(0.13, 0.19)
    shift = u(-0.08, 0.08) if style in ("sedan", "coupe", "convertible", "pickup") else u(-0.01, 0.03)
    zr0, zr1, zf1, zf0 = (min(0.49, max(-0.49, (f + shift))) * L for f in (zr0, zr1, zf1, zf0))
    ch *= L
    # lower body: side profile with a sloped bonnet and boot, narrower at the top
    hood_drop = bh * u(0.0, 0.3)
    fch, rch = L * u(0.02, 0.08), L * u(0.02, 0.06)
    pts = []
    for x in (-W / 2, W / 2):
        for (y, z) in ((y0, -L / 2 + rch), (y0, L / 2 - fch), (y0 + bh * u(0.3, 0.5), L / 2), (top - hood_drop, L / 2 - fch * 0.5),
                       (y0 + bh * 0.4, -L / 2), (top, -L / 2 + rch * 0.5), (top, zf0)):
            pts.append((x if y < top - hood_drop - 1e-9 else x * 0.94, y, z))
    parts = [hull(pts)]
    gw = W * u(0.75, 0.92)
    rw = gw * u(0.8, 0.95)
    if style == "convertible":  # top down: a windscreen and two seat backs
        parts.append(hull([(sx * w / 2, y, z + dz) for sx in (-1, 1) for dz in (0.0, 0.02)
                           for (w, y, z) in ((gw, top - 0.01, zf0), (rw, top + ch * 0.7, zf0 - ch * 0.5))]))
        for s in (-1, 1):
            parts.append(box((W * 0.3, ch * 0.7, 0.08), (s * W * 0.22, top + ch * 0.35 - 0.01, (zr0 + zf0) / 2 - 0.05 * L)))
    else:
        parts.append(hull([(sx * gw / 2, top - 0.01, z) for sx in (-1, 1) for z in (zr0, zf0)]
                          + [(sx * rw / 2, top + ch, z) for sx in (-1, 1) for z in (zr1, zf1)]))
    if style == "offroad" and rng.random() < 0.7:  # spare wheel on the tailgate
        parts.append(cylinder((0, y0 + bh * 0.55, -L / 2 - wr * 0.5), (0, y0 + bh * 0.55, -L / 2 + rch + 0.02), wr * 0.9, segments=SEGMENTS))
    if style == "pickup":  # bed walls behind the cab
        wt, wh = 0.03, bh * u(0.25, 0.45)
        zb0, zb1 = -L / 2 + rch * 0.5, zr0 + 0.01
        for s in (-1, 1):
            parts.append(box((wt, wh + 0.01, zb1 - zb0), (s * (W / 2 - wt / 2), top + wh / 2 - 0.005, (zb0 + zb1) / 2)))
        parts.append(box((W, wh + 0.01, wt), (0, top + wh / 2 - 0.005, zb0 + wt / 2)))
    if style in ("sedan", "coupe") and rng.random() < 0.3:  # rear spoiler on two posts
        zs = -L / 2 + rch + 0.05
        for s in (-1, 1):
            parts.append(box((0.03, 0.07, 0.03), (s * W * 0.3, top + 0.03, zs)))
        parts.append(box((W * 0.85, 0.02, 0.1), (0, top + 0.07, zs - 0.01)))
    if style in ("suv", "van", "hatch", "offroad") and rng.random() < 0.35:  # roof rails
        for s in (-1, 1):
            parts.append(box((0.025, 0.03, (zf1 - zr1) * 0.85), (s * rw * 0.4, top + ch + 0.012, (zf1 + zr1) / 2)))
    # wheels
    wb = L * (u(0.26, 0.33) if style == "micro" else u(0.28, 0.36))
    zfw, zrw = wb + L * u(-0.03, 0.03), -wb + L * u(-0.03, 0.05)
    ww = W * u(0.12, 0.2)
    for z in (zfw, zrw):
        for s in (-1, 1):
            parts.append(cylinder((s * (W / 2 - ww * 0.6), wr, z), (s * (W / 2 + ww * 0.4), wr, z), wr, segments=SEGMENTS))
    return union(parts)


def _chair(rng):
    """Side, arm, office, stool-like or lounge chair: four or three legs, swivel, sled, cantilever or pedestal base;
    solid, slatted, ladder, round or gap back; optional arms and stretchers."""
    u = rng.uniform
    S = u(0.38, 0.7)  # seat width
    D = S * u(0.8, 1.25)
    H = u(0.33, 0.55)
    th = u(0.03, 0.1)
    base = _pick(rng, ("legs4", "legs3", "swivel", "sled", "cantilever", "pedestal"), [0.42, 0.06, 0.16, 0.12, 0.1, 0.14])
    r_ = rng.random()
    round_seat = (base in ("legs3", "pedestal") and r_ < 0.7) or (base in ("legs4", "swivel") and r_ < 0.15)
    back = _pick(rng, ("solid", "slats", "ladder", "round", "gap"), [0.35, 0.2, 0.15, 0.12, 0.18])
    back_h = u(0.2, 0.75)
    tilt = u(0.0, 0.2) * back_h
    arms = rng.random() < 0.35 and not round_seat
    parts = []
    if round_seat:
        parts.append(cylinder((0, H - th, 0), (0, H, 0), S / 2, segments=24))
    else:
        parts.append(box((S, th, D), (0, H - th / 2, 0)))
    hd = S / 2 if round_seat else D / 2  # half depth actually covered by the seat
    # base
    if base in ("legs4", "legs3"):
        lr = u(0.015, 0.04)
        if base == "legs4" and not round_seat:
            pts = [(sx * (S / 2 - lr * 1.5), sz * (hd - lr * 1.5)) for sx, sz in ((-1, -1), (-1, 1), (1, 1), (1, -1))]  # around
        else:
            n = 4 if base == "legs4" else 3
            a0 = np.pi / 2 if n == 3 else np.pi / 4
            pts = [(S * 0.4 * np.cos(a0 + 2 * np.pi * k / n), S * 0.4 * np.sin(a0 + 2 * np.pi * k / n)) for k in range(n)]
        splay, yt = u(0, 0.07), H - th + 0.01
        parts += _legs(pts, yt, 0.0, lr, splay=splay, square=rng.random() < 0.5, taper=u(0.6, 1.0))
        if rng.random() < 0.35:  # stretchers, a ring of bars between the legs
            ys = H * u(0.2, 0.45)
            lp = [_leg_at(x, z, splay, 1.0 - ys / yt) for x, z in pts]
            for k in range(len(lp)):
                (x0, z0), (x1, z1) = lp[k], lp[(k + 1) % len(lp)]
                parts.append(bar((x0, ys, z0), (x1, ys, z1), lr * 0.7))
    elif base == "swivel":
        col = u(0.025, 0.05)
        parts.append(cylinder((0, 0.04, 0), (0, H - th + 0.01, 0), col, segments=16))
        n, sr = int(rng.choice([4, 5, 5])), u(0.22, 0.35)
        for k in range(n):
            a = 2 * np.pi * k / n
            e = (sr * np.cos(a), 0.03, sr * np.sin(a))
            parts.append(bar((0, 0.06, 0), e, 0.02))
            parts.append(sphere((e[0], 0.03, e[2]), 0.03, segments=10))
        if rng.random() < 0.7:
            parts.append(box((S * 0.5, 0.04, D * 0.5), (0, H - th - 0.015, 0)))
    elif base == "sled":
        fr = u(0.012, 0.022)
        z0, z1 = -hd * u(0.7, 0.95), hd * u(0.7, 0.95)
        for s in (-1, 1):
            x = s * (S / 2 - fr * 2)
            xb = x * u(1.0, 1.15)
            parts.append(cylinder((x, H - th + 0.005, z1), (xb, fr, z1 + 0.03), fr, segments=10))
            parts.append(cylinder((x, H - th + 0.005, z0), (xb, fr, z0 - 0.03), fr, segments=10))
            parts.append(cylinder((xb, fr, z0 - 0.03 - fr), (xb, fr, z1 + 0.03 + fr), fr, segments=10))
            parts.append(sphere((xb, fr, z1 + 0.03), fr, segments=10))
            parts.append(sphere((xb, fr, z0 - 0.03), fr, segments=10))
    elif base == "cantilever":
        fr = u(0.012, 0.02)
        zf = hd * u(0.6, 0.95)
        for s in (-1, 1):
            x = s * (S / 2 - fr * 2)
            pts = [(x, H - th + 0.005, -hd * 0.3), (x, H - th + 0.005, zf), (x, fr, zf + u(-0.05, 0.05)), (x, fr, -hd * u(0.6, 1.0))]
            for p, q in zip(pts[:-1], pts[1:]):
                parts.append(cylinder(p, q, fr, segments=10))
            for p in pts[1:-1]:
                parts.append(sphere(p, fr, segments=10))
    else:  # pedestal (tulip)
        parts.append(cylinder((0, 0.02, 0), (0, H - th + 0.01, 0), u(0.03, 0.07), u(0.05, 0.15), 20))
        parts.append(cylinder((0, 0, 0), (0, u(0.02, 0.05), 0), S * u(0.3, 0.5), segments=24))
    # back
    bz = -hd * 0.8 if round_seat else -hd + 0.03
    bw = S * 0.55 if round_seat else (S * u(0.7, 1.0) if back != "round" else S)

    def slab(x0, x1, f0, f1, t=0.03):
        return hull([(x, H + back_h * f, bz - tilt * f + dz) for x in (x0, x1) for f in (f0, f1) for dz in (-t / 2, t / 2)])

    if back == "solid":
        parts.append(slab(-bw / 2, bw / 2, -th / back_h, 1.0, u(0.025, 0.07)))
    elif back == "round":
        parts.append(slab(-0.02, 0.02, -th / back_h, 0.4))
        parts.append(sphere((0, H + back_h * 0.65, bz - tilt * 0.65), 1.0, (bw * 0.5, back_h * 0.4, 0.03), 20))
    else:
        pr = 0.02
        for s in (-1, 1):  # posts
            parts.append(slab(s * bw / 2 - pr, s * bw / 2 + pr, -th / back_h, 1.0, 0.035))
        if back == "slats":
            n = int(rng.integers(2, 7))
            for k in range(n):
                x = -bw / 2 + bw * (k + 1) / (n + 1)
                parts.append(slab(x - 0.012, x + 0.012, -th / back_h, 0.95, 0.02))
            parts.append(slab(-bw / 2, bw / 2, 0.85, 1.0))
        elif back == "ladder":
            n = int(rng.integers(2, 5))
            for k in range(n):
                f = 0.35 + 0.65 * (k + 1) / n
                parts.append(slab(-bw / 2, bw / 2, f - 0.08, f))
        else:  # gap: a panel on the upper part of the posts
            parts.append(slab(-bw / 2, bw / 2, u(0.3, 0.55), 1.0))
    if arms:
        ah = u(0.15, 0.28)
        style = _pick(rng, ("post", "panel"), [0.75, 0.25])
        for s in (-1, 1):
            x = s * (S / 2 - 0.02)
            if style == "panel":
                parts.append(box((0.05, ah + th, hd * 1.8), (x, H - th + (ah + th) / 2, -0.02)))
            else:
                z0, z1 = bz - tilt * ah / back_h, hd * u(0.8, 1.0)
                parts.append(box((0.045, 0.035, z1 - z0 + 0.02), (x, H + ah, (z0 + z1) / 2)))
                parts.append(cylinder((x, H - th / 2, hd - 0.06), (x, H + ah, hd - 0.06), 0.018, segments=10))
                parts.append(cylinder((x, H - th / 2, bz + 0.02), (x, H + ah, bz + 0.02 - tilt * ah / back_h), 0.018, segments=10))
    return union(parts)


def _display(rng):
    """Monitor or TV: a panel (4:3 to 21:9, optionally tilted, optional CRT back) on a neck and base, feet,
    a slanted arm, an L arm or a pedestal."""
    u = rng.uniform
    crt = rng.random() < 0.15
    W = u(0.6, 1.5)
    Hs = W * (u(0.7, 0.8) if crt else u(0.4, 0.78))
    T = u(0.06, 0.1) if crt else u(0.015, 0.07)
    stand = _pick(rng, ("neck", "feet", "slant", "arm", "pedestal"), [0.35, 0.2, 0.15, 0.15, 0.15])
    neck_h = u(0.05, 0.35) if stand != "feet" else u(0.02, 0.12)
    chin = Hs * u(0.0, 0.12)
    y0 = neck_h + Hs / 2
    tilt = -u(0.0, 14.0) if stand not in ("feet", "pedestal") else 0.0
    bez = Hs * u(0.02, 0.08)
    screen = [box((W, Hs, T), (0, y0, 0)),
              box((W - 2 * bez, Hs - 2 * bez - chin, 0.012), (0, y0 + chin / 2, T / 2))]
    if crt:
        dd = W * u(0.35, 0.6)
        screen.append(hull([(x, y, -T / 2 + 0.01) for x in (-W * 0.45, W * 0.45) for y in (y0 - Hs * 0.45, y0 + Hs * 0.45)]
                           + [(x, y, -T / 2 - dd) for x in (-W * 0.22, W * 0.22) for y in (y0 - Hs * 0.25, y0 + Hs * 0.2)]))
    elif rng.random() < 0.5:  # back housing
        screen.append(hull([(x, y, -T / 2 + 0.01) for x in (-W * 0.4, W * 0.4) for y in (y0 - Hs * 0.4, y0 + Hs * 0.35)]
                           + [(x, y, -T / 2 - u(0.02, 0.06)) for x in (-W * 0.25, W * 0.25) for y in (y0 - Hs * 0.25, y0 + Hs * 0.2)]))
    parts = [rotated(union(screen), (tilt, 0, 0), (0, y0, -T / 2))] if tilt else list(screen)
    nw = u(0.05, 0.18)
    if stand == "neck":
        nd = 0.05
        parts.append(box((nw, y0 + 0.02, nd), (0, (y0 + 0.02) / 2, -T / 2 - nd / 2 + 0.01)))
        if rng.random() < 0.5:
            parts.append(cylinder((0, 0, -T / 2), (0, 0.025, -T / 2), u(0.12, 0.3), segments=24))
        else:
            parts.append(box((u(0.25, 0.6), 0.025, u(0.15, 0.3)), (0, 0.0125, -T / 2)))
    elif stand == "feet":
        fx = W * u(0.25, 0.45)
        fd = u(0.15, 0.3)
        for s in (-1, 1):
            parts.append(hull([(s * fx + dx, y, z) for dx in (-0.02, 0.02) for (y, z) in
                               ((neck_h + Hs * 0.12, -T / 4), (neck_h + Hs * 0.12, T / 4), (0.0, -fd / 2), (0.0, fd / 2), (0.015, -fd / 2), (0.015, fd / 2))]))
    elif stand == "slant":
        bd = u(0.15, 0.3)
        h = nw / 2  # a slanted post with horizontal ends, its top just inside the screen's back
        parts.append(hull(_square_prism((0, 0.02, -T / 2 - bd * 0.8), (0, y0, -T / 2 - h + 0.01), h)))
        parts.append(box((u(0.25, 0.5), 0.025, bd), (0, 0.0125, -T / 2 - bd * 0.4)))
    elif stand == "arm":
        bd = u(0.15, 0.25)
        zp = -T / 2 - u(0.08, 0.2)
        parts.append(box((nw, y0 + 0.05, 0.04), (0, (y0 + 0.05) / 2, zp)))
        parts.append(box((nw * 0.7, 0.04, -T / 2 - zp + 0.02), (0, y0, (zp - T / 2) / 2 + 0.01)))
        parts.append(cylinder((0, 0, zp), (0, 0.025, zp), u(0.1, 0.2), segments=24) if rng.random() < 0.5
                     else box((u(0.2, 0.4), 0.025, bd), (0, 0.0125, zp)))
    else:  # pedestal
        pw, pd = W * u(0.2, 0.6), u(0.12, 0.3)
        parts.append(box((pw * 0.6, neck_h + Hs * 0.15, 0.04), (0, (neck_h + Hs * 0.15) / 2, -T / 2)))
        parts.append(box((pw, u(0.03, 0.08), pd), (0, 0.02, -T / 2)))
    return union(parts)


def _lamp_shade(top, r_bot, r_top, h, kind):
    """A solid shade around the vertical axis through ``top``, spanning heights [y, y + h] (wide end down)."""
    x, y, z = (float(c) for c in top)
    if kind == "drum":
        return cylinder((x, y, z), (x, y + h, z), r_bot, r_bot * 0.95, 24)
    if kind == "cone":
        return cylinder((x, y, z), (x, y + h, z), r_bot, r_top, 24)
    if kind == "square":
        return hull([(x + sx * r, yy, z + sz * r) for sx in (-1, 1) for sz in (-1, 1) for (yy, r) in ((y, r_bot * 0.9), (y + h, r_top * 0.9))])
    if kind == "globe":
        r = max(h / 2, r_bot * 0.6)
        return sphere((x, y + h - r, z), r, segments=20)
    k = np.linspace(0.0, 1.0, 7)
    if kind == "dome":
        prof = [(r_bot * np.cos(a * np.pi / 2), h * np.sin(a * np.pi / 2)) for a in k]
    else:  # bell: a concave flare
        prof = [(r_top + (r_bot - r_top) * (1 - a) ** 2, h * a) for a in k]
    return lathe([(0.0, 0.0)] + prof + [(0.0, h)], (x, y, z), 20)


def _lamp(rng):
    """Floor, table, desk (articulated arm) or arc lamp on a disk, square, tripod, vase or column base, with a
    drum, cone, square, dome, bell or globe shade."""
    u = rng.uniform
    kind = _pick(rng, ("floor", "table", "desk", "arc"), [0.3, 0.32, 0.2, 0.18])
    if kind in ("floor", "table"):
        shade = _pick(rng, ("drum", "cone", "square", "dome", "bell", "globe"), [0.22, 0.28, 0.14, 0.12, 0.12, 0.12])
    else:
        shade = _pick(rng, ("cone", "dome", "bell", "globe"), [0.35, 0.3, 0.2, 0.15] if kind == "arc" else [0.5, 0.3, 0.2, 0.0])
    pr = u(0.012, 0.03)  # pole radius
    parts = []
    if kind == "floor":
        pole_h = u(0.9, 1.7)
        bkind = _pick(rng, ("disk", "square", "tripod"), [0.5, 0.2, 0.3])
    elif kind == "table":
        pole_h = u(0.25, 0.6)
        bkind = _pick(rng, ("vase", "disk", "square", "column"), [0.4, 0.25, 0.15, 0.2])
    else:
        pole_h = u(0.15, 0.3) if kind == "desk" else u(1.0, 1.6)
        bkind = _pick(rng, ("disk", "square"), [0.6, 0.4])
    br = u(0.1, 0.22)
    if bkind == "disk":
        base_top = u(0.02, 0.06)
        parts.append(cylinder((0, 0, 0), (0, base_top, 0), br, br * u(0.7, 1.0), 24))
    elif bkind == "square":
        base_top = u(0.02, 0.06)
        parts.append(box((2 * br, base_top, 2 * br * u(0.7, 1.0)), (0, base_top / 2, 0)))
    elif bkind == "tripod":
        base_top = pole_h * u(0.2, 0.45)
        for k in range(3):
            a = np.pi / 2 + 2 * np.pi * k / 3
            parts.append(cylinder((br * 1.5 * np.cos(a), 0, br * 1.5 * np.sin(a)), (0, base_top + 0.02, 0), pr, segments=10))
    elif bkind == "vase":
        base_top, vr = pole_h * u(0.5, 0.9), u(0.08, 0.18)
        neck = vr * u(0.2, 0.5)
        prof = [(0.0, 0.0), (vr * u(0.5, 0.8), 0.0)]
        prof += [(neck + (vr - neck) * np.sin(np.pi * (0.15 + 0.7 * a)), base_top * (0.08 + 0.8 * a)) for a in np.linspace(0, 1, 6)]
        parts.append(lathe(prof + [(neck, base_top), (0.0, base_top)], (0, 0, 0), 20))
    else:  # column
        cr = u(0.04, 0.1)
        base_top = pole_h * u(0.5, 0.9)
        parts.append(cylinder((0, 0, 0), (0, 0.03, 0), cr * 1.8, segments=20))
        parts.append(cylinder((0, 0.02, 0), (0, base_top, 0), cr, cr * u(0.6, 1.2), 20))
    top = np.array([0.0, max(pole_h, base_top + 0.1), 0.0])
    parts.append(cylinder((0, base_top - 0.01, 0), top, pr, segments=12))
    sh = u(0.15, 0.35)
    rb, rt = u(0.12, 0.3), u(0.05, 0.2)
    if kind in ("floor", "table"):
        if kind == "table":
            sh, rb, rt = sh * 0.8, rb * 0.9, rt * 0.9
        y_s = max(top[1] - sh * u(0.2, 0.6), min(base_top + 0.05, top[1] - 0.03))  # the shade above the base
        parts.append(_lamp_shade((0, y_s, 0), rb, rt, sh, shade))
        parts.append(cylinder((0, y_s - 0.02, 0), (0, y_s + 0.02, 0), max(pr * 1.5, 0.025), segments=12))
        return union(parts)
    # desk / arc: an arm from the pole top; the shade hangs at its end
    if kind == "desk":
        a1, l1 = np.radians(u(-30, 25)), u(0.3, 0.6)
        a2, l2 = np.radians(u(40, 100)), u(0.25, 0.55)
        j1 = top + l1 * np.array([0, np.cos(a1), np.sin(a1)])
        pts = [top, j1, j1 + l2 * np.array([0, np.cos(a2), np.sin(a2)])]
    else:  # a quarter-ellipse arc up and forward, going on over the top
        reach, rise, amax = u(0.35, 0.8), u(0.15, 0.45), u(0.5, 0.75) * np.pi
        pts = [top + np.array([0, rise * np.sin(a), reach * (1 - np.cos(a))]) for a in np.linspace(0, amax, 6)]
    for p, q in zip(pts[:-1], pts[1:]):
        parts.append(cylinder(p, q, pr, segments=10))
        parts.append(sphere(q, pr * 1.6, segments=10))
    parts.append(sphere(pts[0], pr * 1.6, segments=10))
    end = pts[-1]
    hang = u(0.0, 0.2) if kind == "arc" else 0.0
    if hang > 0:
        parts.append(cylinder(end, end - np.array([0, hang, 0]), pr * 0.5, segments=8))
    sh2, rb2 = sh * 0.8, rb * (0.8 if kind == "desk" else 1.0)
    parts.append(_lamp_shade(end - np.array([0, hang + sh2 * 0.85, 0]), rb2, min(rt, rb2) * 0.5, sh2, shade))
    return union(parts)


def _loudspeaker(rng):
    """Bookshelf speaker, floor tower, subwoofer cube, cylinder, sound bar, sloped studio monitor, trapezoidal PA
    speaker with a horn or egg-shaped speaker; one to five drivers, optional stand (post or tripod), port,
    plinth or feet."""
    u = rng.uniform
    kind = _pick(rng, ("bookshelf", "tower", "sub", "cylinder", "bar", "slant", "pa", "egg"),
                 [0.17, 0.17, 0.11, 0.11, 0.1, 0.12, 0.12, 0.1])
    parts = []
    y_base = 0.0
    if kind in ("bookshelf", "pa", "egg") and rng.random() < 0.4:  # on a stand
        y_base = u(0.35, 0.7) if kind != "pa" else u(0.6, 1.2)
        if kind == "pa" or rng.random() < 0.3:  # tripod and pole
            for k in range(3):
                a = np.pi / 2 + 2 * np.pi * k / 3
                parts.append(cylinder((0.3 * np.cos(a), 0, 0.3 * np.sin(a)), (0, y_base * 0.4, 0), 0.012, segments=8))
            parts.append(cylinder((0, y_base * 0.4 - 0.02, 0), (0, y_base + 0.12, 0), 0.018, segments=10))
        else:
            parts.append(box((u(0.25, 0.45), 0.03, u(0.25, 0.4)), (0, 0.015, 0)))
            parts.append(box((0.06, y_base + 0.05, 0.06), (0, (y_base + 0.05) / 2, 0)))
    if kind == "bookshelf":
        W, H, D = u(0.18, 0.45), u(0.3, 0.6), u(0.2, 0.45)
    elif kind == "tower":
        W, H, D = u(0.15, 0.45), u(0.7, 1.35), u(0.2, 0.55)
    elif kind == "pa":
        W, H, D = u(0.3, 0.55), u(0.45, 0.8), u(0.3, 0.5)
    elif kind == "egg":
        W = u(0.2, 0.4)
        H, D = W * u(1.1, 1.7), W * u(0.9, 1.2)
    elif kind == "sub":
        W = u(0.3, 0.6)
        H, D = W * u(0.85, 1.15), W * u(0.85, 1.15)
    elif kind == "cylinder":
        W = u(0.15, 0.4)
        H, D = u(0.25, 1.0), W
    elif kind == "bar":
        W, H, D = u(0.8, 1.6), u(0.07, 0.16), u(0.08, 0.2)
    else:
        W, H, D = u(0.2, 0.4), u(0.3, 0.55), u(0.25, 0.45)
    yb = y_base
    if kind == "cylinder":
        parts.append(cylinder((0, yb, 0), (0, yb + H, 0), W / 2, W / 2 * u(0.8, 1.0), 24))
        if rng.random() < 0.5:
            parts.append(cylinder((0, yb + H * 0.95, 0), (0, yb + H + 0.02, 0), W / 2 * 0.8, segments=24))
        for k in range(int(rng.integers(0, 3))):
            y = yb + H * (0.2 + 0.6 * k)
            parts.append(cylinder((0, y, 0), (0, y + 0.02, 0), W / 2 + 0.01, segments=24))
        return union(parts)
    front_z = D / 2
    rr = 0.0  # rounding radius of the cabinet's edges
    setback = H * u(0.1, 0.3) if kind == "slant" else 0.0  # the sloped baffle's top lies this far back
    if kind == "slant":
        back_frac = u(0.5, 0.8)
        parts.append(side_extrude([(-D / 2, yb), (D / 2, yb), (D / 2 - setback, yb + H), (-D / 2, yb + H * back_frac)], W))
    elif kind == "pa":  # narrower at the back
        wb, hb = W * u(0.45, 0.75), H * u(0.75, 1.0)
        parts.append(hull([(sx * w / 2, yb + H / 2 + sy * h / 2, z) for sx in (-1, 1) for sy in (-1, 1)
                           for (w, h, z) in ((W, H, D / 2), (wb, hb, -D / 2))]))
    elif kind == "egg":
        parts.append(sphere((0, yb + H / 2, 0), 1.0, (W / 2, H / 2, D / 2), 24))
        if y_base == 0.0:
            parts.append(cylinder((0, -0.01, 0), (0, H * 0.12, 0), W * 0.3, W * 0.2, 16))
    elif rng.random() < 0.5:
        rr = min(W, H, D) * u(0.05, 0.2)
        parts.append(rounded_box((W, H, D), (0, yb + H / 2, 0), rr))
    else:
        parts.append(box((W, H, D), (0, yb + H / 2, 0)))
    # drivers
    if kind == "pa":  # a woofer below a horn
        centres = [(0.0, yb + H * 0.33, min(W, H) * u(0.3, 0.4))]
        hw, hh = W * u(0.4, 0.7), H * u(0.15, 0.25)
        hy = yb + H * 0.78
        parts.append(hull([(sx * w / 2, hy + sy * h / 2, z) for sx in (-1, 1) for sy in (-1, 1)
                           for (w, h, z) in ((hw, hh, D / 2 + 0.02), (hw * 0.2, hh * 0.3, D / 2 - 0.1))]))
    elif kind == "egg":
        centres = [(0.0, yb + H * 0.5, W * u(0.25, 0.35))]
    elif kind == "bar":
        n = int(rng.integers(2, 7))
        centres = [(-W / 2 + W * (k + 0.5) / n, yb + H / 2, H * 0.35) for k in range(n)]
    elif kind == "sub":
        centres = [(0.0, yb + H / 2, W * u(0.3, 0.42))]
    else:
        n = int(rng.integers(2, 6)) if kind == "tower" else int(rng.integers(1, 4))
        top_y = yb + H - min(W * 0.3, H * 0.2)
        bot_y = yb + H * (0.35 if kind == "tower" else 0.3)
        ys = [top_y] if n == 1 else list(np.linspace(top_y, bot_y, n))
        rmax = W * 0.4 if n == 1 else 0.45 * (top_y - bot_y) / (n - 1)
        centres = [(0.0, y, min(rmax, W * (0.18 if k == 0 and n > 1 else u(0.28, 0.4)))) for k, y in enumerate(ys)]
    cuts = []
    tilt = -np.degrees(np.arctan2(setback, H))
    for (x, y, r) in centres:
        z = front_z - setback * (y - yb) / H
        driver = [cylinder((x, y, z - 0.02), (x, y, z + 0.015), r * 1.12, segments=20),
                  cylinder((x, y, z + 0.01), (x, y, z + 0.04), r * 0.7, r * 0.2, 16)]
        parts += [rotated(d, (tilt, 0, 0), (x, y, z)) for d in driver] if setback else driver
    if kind in ("bookshelf", "tower", "sub") and rng.random() < 0.4:  # bass-reflex port
        pr_ = min(W, H) * 0.07
        cuts.append(cylinder((0, yb + H * 0.12, D / 2 - 0.15), (0, yb + H * 0.12, D / 2 + 0.1), pr_, segments=16))
    if kind in ("tower", "sub") and rng.random() < 0.5:
        if rng.random() < 0.5:  # plinth
            parts.append(box((W + u(0.04, 0.12), 0.03, D + u(0.04, 0.12)), (0, 0.015, 0)))
        else:  # spiked feet
            for x, z in _corners(W / 2 - 0.03 - rr, D / 2 - 0.03 - rr):
                parts.append(cylinder((x, -0.05, z), (x, 0.01, z), 0.005, 0.025, 10))
    s = union(parts)
    return difference(s, cuts) if cuts else s


def _rifle(rng):
    """Hunting, assault or sniper rifle: stock (classic, thumbhole, skeleton or tube), receiver, barrel, optional
    scope or iron sights, box, curved, drum or no magazine, handguard, bipod, muzzle brake, carry handle."""
    u = rng.uniform
    L = u(1.4, 2.8)  # along Z, muzzle at +Z
    body_l = L * u(0.2, 0.32)
    body_h = L * u(0.04, 0.07)
    stock_l = L * u(0.2, 0.32)
    z_s = -L / 2 + stock_l  # stock / receiver joint
    z_b = z_s + body_l  # receiver front
    br = L * u(0.006, 0.012)
    bw = 0.05
    parts = [box((bw, body_h, body_l), (0, 0, (z_s + z_b) / 2))]
    parts.append(cylinder((0, body_h * 0.2, z_b - 0.05), (0, body_h * 0.2, L / 2), br, segments=12))
    stock = _pick(rng, ("classic", "thumbhole", "skeleton", "tube"), [0.4, 0.15, 0.2, 0.25])
    drop = u(0.0, 0.25) * body_h * 3
    butt_h = body_h * u(1.2, 2.2)
    zb0 = -L / 2
    if stock in ("classic", "thumbhole"):
        s = side_extrude([(z_s + 0.02, body_h / 2), (z_s + 0.02, -body_h / 2), (zb0, -drop - butt_h), (zb0, -drop),
                          (zb0 + stock_l * 0.3, -drop * 0.8)], bw * 0.9)
        if stock == "thumbhole":
            s = difference(s, [side_extrude([(z_s - stock_l * 0.15, -body_h * 0.3), (z_s - stock_l * 0.45, -drop * 0.5 - butt_h * 0.3),
                                             (z_s - stock_l * 0.45, -drop * 0.4)], bw * 2)])
        parts.append(s)
    elif stock == "skeleton":
        fr = body_h * 0.15
        parts.append(bar((0, body_h * 0.3, z_s + 0.02), (0, -drop + 0.0, zb0 + 0.02), fr))
        parts.append(bar((0, -body_h * 0.45, z_s + 0.02), (0, -drop - butt_h + fr, zb0 + 0.02), fr))
        parts.append(box((bw * 0.9, butt_h + fr * 2, 0.04), (0, -drop - butt_h / 2, zb0 + 0.02)))
    else:  # tube stock with a butt pad
        parts.append(cylinder((0, body_h * 0.1, z_s + 0.02), (0, body_h * 0.1 - drop * 0.3, zb0 + 0.03), body_h * 0.2, segments=12))
        parts.append(box((bw * 0.9, butt_h, 0.05), (0, body_h * 0.1 - drop * 0.3 - butt_h * 0.3, zb0 + 0.025)))
    # grip
    if stock != "classic" or rng.random() < 0.5:
        gz = z_s + body_l * u(0.1, 0.3)
        parts.append(hull([(x, y, z) for x in (-0.02, 0.02) for (y, z) in
                           ((-body_h * 0.4, gz), (-body_h * 0.4, gz + 0.06), (-body_h * 0.5 - 0.13, gz - 0.06), (-body_h * 0.5 - 0.13, gz - 0.01))]))
    # magazine
    mag = _pick(rng, ("none", "box", "curved", "drum"), [0.25, 0.35, 0.3, 0.1])
    mz = z_s + body_l * u(0.5, 0.75)
    ml = body_h * u(1.2, 3.0)
    if mag == "box":
        parts.append(box((0.035, ml, 0.07), (0, -body_h / 2 - ml / 2 + 0.02, mz)))
    elif mag == "curved":
        bend = ml * u(0.2, 0.5)
        parts.append(hull([(x, y, z) for x in (-0.018, 0.018) for (y, z) in
                           ((0.0, mz - 0.035), (0.0, mz + 0.035), (-body_h / 2 - ml * 0.5, mz + bend * 0.3 - 0.035), (-body_h / 2 - ml * 0.5, mz + bend * 0.3 + 0.035))]))
        parts.append(hull([(x, y, z) for x in (-0.018, 0.018) for (y, z) in
                           ((-body_h / 2 - ml * 0.5 + 0.02, mz + bend * 0.3 - 0.035), (-body_h / 2 - ml * 0.5 + 0.02, mz + bend * 0.3 + 0.035),
                            (-body_h / 2 - ml, mz + bend - 0.04), (-body_h / 2 - ml, mz + bend + 0.03))]))
    elif mag == "drum":
        dr = body_h * u(0.8, 1.3)
        parts.append(cylinder((-0.04, -body_h / 2 - dr * 0.8, mz), (0.04, -body_h / 2 - dr * 0.8, mz), dr, segments=20))
        parts.append(box((0.03, dr, 0.05), (0, -body_h / 2 - dr * 0.2, mz)))
    # handguard
    hg = _pick(rng, ("wood", "rail", "none"), [0.45, 0.3, 0.25])
    hl = (L / 2 - z_b) * u(0.3, 0.7)
    if hg == "wood":
        parts.append(box((bw * 0.8, body_h * 0.55, hl), (0, -body_h * 0.05, z_b + hl / 2 - 0.02)))
    elif hg == "rail":
        parts.append(box((bw * 0.9, body_h * 0.8, hl), (0, body_h * 0.15, z_b + hl / 2 - 0.02)))
    if rng.random() < 0.3:  # muzzle brake
        parts.append(cylinder((0, body_h * 0.2, L / 2 - 0.06), (0, body_h * 0.2, L / 2 + 0.01), br * 1.8, segments=12))
    if rng.random() < 0.25:  # bipod
        bz = z_b + hl * 0.8 if hg != "none" else z_b + (L / 2 - z_b) * 0.5
        leg = body_h * u(2.0, 3.5)
        for s in (-1, 1):
            parts.append(cylinder((0, body_h * 0.1, bz), (s * leg * 0.35, -leg, bz + leg * 0.3), 0.008, segments=8))
        parts.append(box((0.04, 0.04, 0.05), (0, body_h * 0.1, bz)))
    # optics
    optic = _pick(rng, ("none", "scope", "sights", "handle"), [0.25, 0.4, 0.2, 0.15])
    ty = body_h / 2
    if optic == "scope":
        sl, sr = body_l * u(0.6, 1.3), body_h * u(0.25, 0.45)
        zc = z_s + body_l * 0.5
        sy = ty + sr + body_h * u(0.2, 0.5)
        parts.append(cylinder((0, sy, zc - sl / 2), (0, sy, zc + sl / 2), sr, segments=16))
        if rng.random() < 0.6:  # objective bell
            parts.append(cylinder((0, sy, zc + sl / 2 - 0.01), (0, sy, zc + sl / 2 + sl * 0.2), sr, sr * u(1.3, 1.8), 16))
        for dz in (-sl * 0.25, sl * 0.25):
            parts.append(box((0.02, sy - ty + 0.01, 0.03), (0, (sy + ty) / 2 - 0.005, zc + dz)))
    elif optic == "sights":
        parts.append(box((0.015, body_h * 0.5, 0.02), (0, ty, z_s + body_l * 0.15)))
        parts.append(box((0.012, body_h * 0.6, 0.015), (0, body_h * 0.2 + body_h * 0.3, L / 2 - 0.08)))
    elif optic == "handle":
        hh = body_h * u(0.4, 0.8)
        for dz in (0.05, body_l - 0.08):
            parts.append(box((0.025, hh + 0.01, 0.03), (0, ty + hh / 2, z_s + dz)))
        parts.append(box((0.03, 0.03, body_l - 0.1), (0, ty + hh, z_s + body_l / 2 - 0.015)))
    return union(parts)


def _sofa(rng):
    """Loveseat to long sofa, optionally L-shaped (chaise), with both, one or no arms (box, rolled or slim),
    one to four seat cushions, optional back cushions, on legs or a plinth."""
    u = rng.uniform
    W, D = u(1.0, 2.8), u(0.6, 1.1)
    seat_h, back_h = u(0.28, 0.48), u(0.12, 0.5)
    arms = _pick(rng, ("both", "one", "none"), [0.65, 0.15, 0.2])
    arm_style = _pick(rng, ("box", "roll", "slim"))
    arm_w = u(0.05, 0.12) if arm_style == "slim" else u(0.1, 0.25)
    legs = rng.random() < 0.65
    base_y = u(0.03, 0.2) if legs else 0.0
    bt = u(0.12, 0.3)
    tilt = u(0.0, 0.15)
    chaise = rng.random() < 0.25
    r = u(0.015, 0.06)
    parts = [rounded_box((W, seat_h - base_y - 0.08, D), (0, base_y + (seat_h - base_y - 0.08) / 2, 0), r)]
    top = seat_h + back_h
    parts.append(hull([(x, y, z) for x in (-W / 2, W / 2) for (y, z) in
                       ((base_y + 0.02, -D / 2), (base_y + 0.02, -D / 2 + bt), (top, -D / 2 - tilt), (top, -D / 2 - tilt + bt * 0.8))]))
    sides = {"both": (-1, 1), "one": (int(rng.choice([-1, 1])),), "none": ()}[arms]
    ah = seat_h + u(0.05, 0.25)
    for s in sides:
        x = s * (W / 2 - arm_w / 2)
        if arm_style == "roll":
            parts.append(box((arm_w, ah - base_y - arm_w / 2, D), (x, base_y + (ah - base_y - arm_w / 2) / 2, 0)))
            parts.append(cylinder((x, ah - arm_w / 2, -D / 2), (x, ah - arm_w / 2, D / 2 + 0.02), arm_w * 0.6, segments=16))
        else:
            parts.append(rounded_box((arm_w, ah - base_y, D), (x, base_y + (ah - base_y) / 2, 0), min(r, arm_w * 0.3)))
    ext = 0.0
    if chaise:  # a chaise extending forward on one side
        cs = -1 if (arms == "one" and sides[0] == 1) else 1
        cw, ext = W * u(0.3, 0.5), D * u(0.5, 1.0)
        parts.append(rounded_box((cw, seat_h - base_y - 0.08, ext + 0.1), (cs * (W / 2 - cw / 2), base_y + (seat_h - base_y - 0.08) / 2, D / 2 + ext / 2 - 0.05), r))
    inner_l = -W / 2 + (arm_w if -1 in sides else 0.0)
    inner_r = W / 2 - (arm_w if 1 in sides else 0.0)
    inner = inner_r - inner_l
    n = int(rng.integers(1, 5)) if inner > 0.9 else int(rng.integers(1, 3))
    cw = inner / n
    ct = u(0.06, 0.14)
    for k in range(n):
        cx = inner_l + cw * (k + 0.5)
        parts.append(rounded_box((cw - 0.02, ct + 0.02, D - bt), (cx, seat_h - 0.08 + ct / 2, bt / 2), min(0.04, ct * 0.4), 8))
    if rng.random() < 0.5 and back_h > 0.2:  # back cushions
        nb = n if rng.random() < 0.7 else 1
        bw = inner / nb
        yc = seat_h + back_h * 0.42
        y0b, y1b, z0b, z1b = base_y + 0.02, top, -D / 2 + bt, -D / 2 - tilt + bt * 0.8  # the back's front face
        zf = z0b + (z1b - z0b) * (yc - y0b) / (y1b - y0b)
        for k in range(nb):
            cx = inner_l + bw * (k + 0.5)
            parts.append(rounded_box((bw - 0.02, back_h * 0.8, 0.12), (cx, yc, zf + 0.03), 0.04, 8))
    if legs:
        lr = u(0.015, 0.035)
        zl = D / 2 - 0.06
        pts = _corners(W / 2 - 0.08, zl)
        if chaise:
            pts += [(cs * (W / 2 - 0.08), D / 2 + ext - 0.08)]
        if W > 2.0:
            pts += [(0.0, zl), (0.0, -zl)]
        parts += _legs(pts, base_y + 0.02, 0.0, lr, splay=u(0, 0.04), square=rng.random() < 0.5, taper=u(0.5, 1.0))
    return union(parts)


def _table(rng):
    """Dining, coffee, bar or side table: rectangular, square, round or oval top on four, three or six legs,
    a pedestal (disk or 3-5 feet), trestle ends or panel sides; optional apron and lower shelf."""
    u = rng.uniform
    top = _pick(rng, ("rect", "square", "round", "oval"), [0.4, 0.15, 0.3, 0.15])
    H = u(0.38, 1.05)
    th = u(0.02, 0.08)
    if top == "rect":
        W = u(0.6, 2.2)
        D = W * u(0.35, 0.75)
    elif top == "square":
        W = D = u(0.5, 1.2)
    elif top == "round":
        W = D = u(0.45, 1.4)
    else:
        W = u(0.8, 2.0)
        D = W * u(0.5, 0.75)
    rounded = top in ("round", "oval")
    support = _pick(rng, ("legs", "pedestal", "trestle", "panels") if not rounded else ("legs", "legs3", "pedestal"),
                    [0.5, 0.15, 0.2, 0.15] if not rounded else [0.35, 0.2, 0.45])
    if support == "pedestal" and not rounded and W > 1.6:
        support = "pedestal2"
    parts = []
    if rounded:
        parts.append(cylinder((0, H - th, 0), (0, H, 0), 0.5, segments=32).scale((W, 1.0, D)))
    else:
        parts.append(box((W, th, D), (0, H - th / 2, 0)))
    yt = H - th + 0.01
    if support in ("legs", "legs3"):
        lr = u(0.015, 0.045)
        sq = rng.random() < 0.5
        splay = u(0.0, 0.08)
        if support == "legs3":
            pts = [(W * 0.33 * np.cos(a), D * 0.33 * np.sin(a)) for a in np.pi / 2 + 2 * np.pi * np.arange(3) / 3]
        elif rounded:
            pts = [(W * 0.33 * np.cos(a), D * 0.33 * np.sin(a)) for a in np.pi / 4 + np.pi / 2 * np.arange(4)]
        else:
            inset = u(0.03, 0.15)
            lx, lz = W / 2 - inset * min(W, 1.0), D / 2 - inset * min(D, 1.0)
            pts = _corners(lx, lz)
            if W > 1.7 and rng.random() < 0.6:
                pts += [(0.0, lz), (0.0, -lz)]
            if rng.random() < 0.45:  # apron
                ah = u(0.05, 0.12)
                parts.append(box((2 * lx + lr, ah, 0.025), (0, H - th - ah / 2 + 0.005, lz)))
                parts.append(box((2 * lx + lr, ah, 0.025), (0, H - th - ah / 2 + 0.005, -lz)))
                parts.append(box((0.025, ah, 2 * lz), (lx, H - th - ah / 2 + 0.005, 0)))
                parts.append(box((0.025, ah, 2 * lz), (-lx, H - th - ah / 2 + 0.005, 0)))
            if rng.random() < 0.3:  # lower shelf, the legs vertical
                splay = 0.0
                sy = H * u(0.12, 0.35)
                parts.append(box((2 * lx + 2 * lr, 0.025, 2 * lz + 2 * lr), (0, sy, 0)))
        parts += _legs(pts, yt, 0.0, lr, splay=splay, square=sq, taper=u(0.5, 1.0))
    elif support in ("pedestal", "pedestal2"):
        xs = [0.0] if support == "pedestal" else [-W * 0.3, W * 0.3]
        cr = u(0.025, 0.09)
        feet = _pick(rng, ("disk", "spokes"))
        nf = int(rng.integers(3, 6))
        fr = min(W, D) * u(0.25, 0.45)
        for x in xs:
            parts.append(cylinder((x, 0.02, 0), (x, yt, 0), cr * u(1.0, 2.0), cr, 16))
            if feet == "disk":
                parts.append(cylinder((x, 0, 0), (x, u(0.02, 0.06), 0), fr, fr * u(0.6, 1.0), 24))
            else:
                for k in range(nf):
                    a = 2 * np.pi * k / nf + (np.pi / 2 if support == "pedestal2" else 0.0)
                    parts.append(hull([(x + dx, y, dz) for (y, rr) in ((0.0, fr), (0.06, 0.0), (0.0, 0.0), (0.06, fr * 0.8))
                                       for dx, dz in ((rr * np.cos(a) + 0.02 * np.sin(a), rr * np.sin(a) - 0.02 * np.cos(a)),
                                                      (rr * np.cos(a) - 0.02 * np.sin(a), rr * np.sin(a) + 0.02 * np.cos(a)))]))
        if support == "pedestal2":
            parts.append(box((W * 0.6, 0.05, 0.05), (0, H * u(0.1, 0.3), 0)))
    elif support == "trestle":
        xe = W / 2 - u(0.08, 0.25) * W / 2
        for s in (-1, 1):
            parts.append(box((0.06, yt - 0.06, 0.08), (s * xe, (yt + 0.06) / 2 - 0.01, 0)))
            parts.append(box((0.08, 0.06, D * u(0.6, 0.95)), (s * xe, 0.03, 0)))
            parts.append(box((0.06, 0.04, D * u(0.5, 0.9)), (s * xe, yt - 0.02, 0)))
        parts.append(box((2 * xe, 0.06, 0.04), (0, H * u(0.15, 0.4), 0)))
    else:  # panel sides
        pt = u(0.03, 0.08)
        xe = W / 2 - u(0.0, 0.1) * W
        for s in (-1, 1):
            parts.append(box((pt, yt, D * u(0.7, 1.0)), (s * (xe - pt / 2), yt / 2, 0)))
        if rng.random() < 0.5:
            parts.append(box((2 * xe, H * u(0.2, 0.5), 0.02), (0, H * 0.6, -D * 0.3)))
    return union(parts)


def _telephone(rng):
    """Smartphone, keypad mobile, open flip phone, desk phone with a handset, rotary phone or cordless phone on a dock."""
    u = rng.uniform
    kind = _pick(rng, ("smart", "keypad", "flip", "desk", "rotary", "cordless"), [0.25, 0.15, 0.12, 0.22, 0.12, 0.14])
    if kind in ("smart", "keypad"):
        W, H, T = u(0.3, 0.55), u(0.65, 1.0), u(0.03, 0.1)
        if kind == "keypad":
            W, T = W * 0.8, T * 1.3
        parts = [rounded_box((W, H, T), (0, H / 2, 0), u(0.01, min(W, H, T) * 0.49))]
        sf = u(0.6, 0.92) if kind == "smart" else u(0.3, 0.45)
        parts.append(box((W * u(0.8, 0.92), H * sf, 0.012), (0, H * (1 - sf / 2 - (1 - sf) * 0.4 if kind == "smart" else 0.75), T / 2)))
        if kind == "keypad":
            rows, cols = int(rng.integers(3, 6)), 3
            for i in range(rows):
                for j in range(cols):
                    parts.append(box((W * 0.2, H * 0.04, 0.02), ((j - 1) * W * 0.27, H * (0.08 + 0.45 * (i + 0.5) / rows), T / 2)))
        if rng.random() < 0.5:  # camera bump
            cw = W * u(0.25, 0.5)
            parts.append(rounded_box((cw, cw * u(0.5, 1.0), 0.03), (-W / 2 + cw / 2 + 0.04, H - cw / 2 - 0.04, -T / 2), 0.01, 8))
        if kind == "keypad" and rng.random() < 0.5:  # antenna
            parts.append(cylinder((W * 0.3, H - 0.05, 0), (W * 0.3, H + u(0.08, 0.2), 0), 0.018, segments=10))
        return union(parts)
    if kind == "flip":
        W, H, T = u(0.3, 0.45), u(0.4, 0.55), u(0.04, 0.07)
        ang = u(140, 175)
        parts = [rounded_box((W, H, T), (0, H / 2, 0), 0.02, 8)]
        for i in range(4):
            for j in range(3):
                parts.append(box((W * 0.2, H * 0.05, 0.02), ((j - 1) * W * 0.27, H * (0.15 + 0.15 * i), T / 2)))
        lh = H * u(0.8, 1.0)
        lid = union([rounded_box((W, lh, T * 0.8), (0, lh / 2 - 0.02, 0), 0.02, 8),
                     box((W * 0.85, lh * 0.65, 0.01), (0, lh * 0.55, T * 0.4))])
        lid = rotated(lid, (180 - ang, 0, 0), (0, 0, 0)).translate((0, H, 0))
        parts += [lid, cylinder((-W / 2, H, 0), (W / 2, H, 0), T * 0.55, segments=12)]
        return union(parts)
    # desk, rotary, cordless: a base on the desk
    W, D = u(0.4, 0.8), u(0.35, 0.75)
    hb, hf = u(0.1, 0.28), u(0.04, 0.12)
    if kind == "rotary":
        hb, hf = hb * 1.2, hb
    parts = [hull([(x, y, z) for x in (-W / 2, W / 2) for (y, z) in ((0, -D / 2), (0, D / 2), (hb, -D / 2), (hf, D / 2))])]

    def slope_y(z):
        return hf + (hb - hf) * (D / 2 - z) / D

    if kind == "cordless":  # an upright handset standing in the dock
        hw, hh = W * u(0.35, 0.5), u(0.5, 0.9)
        parts.append(rounded_box((hw, hh, 0.08), (0, slope_y(-D * 0.2) + hh / 2 - 0.06, -D * 0.2), 0.03, 8))
        for i in range(4):
            for j in range(3):
                parts.append(box((hw * 0.22, 0.03, 0.02), ((j - 1) * hw * 0.28, slope_y(-D * 0.2) + hh * (0.2 + 0.12 * i), -D * 0.2 + 0.045)))
        return union(parts)
    side = kind == "desk" and rng.random() < 0.45  # office phone: the handset lengthwise on the left
    cup = u(0.1, 0.16)
    if side:
        hl = D * u(0.85, 1.1)
        hx = -W / 2 + cup * 0.6
        hy = max(slope_y(-D / 2), slope_y(D / 2)) + 0.03
        parts.append(hull([(hx + dx, hy + dy, z) for z in (-hl * 0.35, hl * 0.35) for dy in (-0.025, 0.025) for dx in (-0.035, 0.035)]))
        for s in (-1, 1):
            parts.append(rounded_box((cup, cup, hl * 0.22), (hx, hy - cup * 0.3, s * hl * 0.4), 0.03, 8))
    else:  # a handset lying across the top: two cups joined by a bar
        hl = W * u(0.9, 1.3)
        hz = -D / 2 + u(0.1, 0.2) * D
        hy = slope_y(hz) + 0.04
        parts.append(hull([(x, hy + dy, hz + dz) for x in (-hl * 0.35, hl * 0.35) for dy in (-0.025, 0.025) for dz in (-0.035, 0.035)]))
        for s in (-1, 1):
            parts.append(rounded_box((hl * 0.22, cup, cup), (s * hl * 0.4, hy - cup * 0.3, hz), 0.03, 8))
    if kind == "rotary":
        zc = D * 0.15
        n = np.array([0.0, D, hb - hf])
        n /= np.linalg.norm(n)
        c = np.array([0.0, slope_y(zc), zc])
        parts.append(cylinder(c - 0.02 * n, c + 0.03 * n, min(W, D) * u(0.25, 0.35), segments=24))
    else:
        rows = int(rng.integers(3, 5))
        kx = W * 0.15 if side else 0.0
        for i in range(rows):
            z = D / 2 - 0.1 - (D * 0.5) * i / rows
            for j in range(3):
                parts.append(box((0.07, 0.03, 0.05), (kx + (j - 1) * 0.1, slope_y(z), z)))
        if rng.random() < 0.5:  # a little display
            parts.append(box((W * 0.4, 0.03, 0.08), (W * 0.15, slope_y(-D * 0.05), -D * 0.05)))
    return union(parts)


def _watercraft(rng):
    """Motorboat, sailboat, ship, canoe, catamaran or barge: hull by stations (V, round or flat bottom, fine or
    blunt bow, transom or pointed stern), cabins, superstructure tiers, funnels, masts with sails, outboard."""
    u = rng.uniform
    kind = _pick(rng, ("motor", "sail", "ship", "canoe", "catamaran", "barge"), [0.22, 0.2, 0.2, 0.13, 0.1, 0.15])
    L = u(1.4, 2.6)
    ratio = {"motor": u(2.6, 4.0), "sail": u(2.8, 4.2), "ship": u(4.5, 8.0), "canoe": u(5.5, 9.0), "catamaran": u(2.0, 2.8),
             "barge": u(2.5, 4.5)}[kind]
    B = L / ratio
    Dh = B * ({"canoe": u(0.3, 0.45), "ship": u(0.45, 0.75), "barge": u(0.3, 0.5)}.get(kind, u(0.4, 0.65)))

    sheer = Dh * u(0.0, 0.25)  # the bow higher than the stern
    flat = kind == "barge"
    bottoms = [0.8 if flat else u(0.05, 0.35) for _ in range(4)]  # bottom / deck half-beam per station
    transom = u(0.6, 0.95)
    bow_fine = {"ship": u(0.6, 1.0), "barge": u(0.0, 0.4)}.get(kind, 0.9 if kind in ("canoe", "catamaran") else u(0.5, 1.0))
    pointed = kind == "canoe"

    def hull_solid(L, B, Dh, x0=0.0):
        """Convex hull through four stations (deck and bottom outlines) plus the stem (and a pointed stern)."""
        pts = []
        for (f, w), bot in zip(((0.0, 0.05 if pointed else transom), (0.25, 1.0), (0.55, 0.95), (0.8, 0.4 + 0.4 * (1 - bow_fine))), bottoms):
            z = -L / 2 + f * L
            yb = 0.0 if f > 0.0 else Dh * 0.15
            for s in (-1, 1):
                pts += [(x0 + s * w * B / 2, Dh + sheer * f, z), (x0 + s * max(bot * w * B / 2, 0.005), yb, z)]
        pts += [(x0, Dh + sheer + 0.02, L / 2), (x0, Dh * (0.2 if flat else 0.35), L / 2 - 0.01)]
        if pointed:
            pts += [(x0, Dh + 0.02, -L / 2 - 0.02), (x0, Dh * 0.35, -L / 2 - 0.01)]
        return hull(pts)

    parts = []
    if kind == "catamaran":
        sep = B * u(0.35, 0.45)
        hb = B * u(0.25, 0.35)
        for s in (-1, 1):
            parts.append(hull_solid(L, hb, Dh, s * sep))
        parts.append(box((2 * sep, Dh * 0.3, L * u(0.45, 0.7)), (0, Dh * 0.95, -L * 0.05)))
    elif kind == "canoe":
        parts.append(hull_solid(L, B, Dh))
        inner = hull_solid(L * 0.9, B * 0.8, Dh)
        parts = [difference(parts[0], [inner.translate((0, Dh * 0.25, 0))])]
        for z in (-L * 0.2, 0.0, L * 0.2)[: int(rng.integers(1, 4))]:  # thwarts
            parts.append(box((B * 0.9, 0.02, 0.04), (0, Dh * 0.85, z)))
        return union(parts)
    else:
        parts.append(hull_solid(L, B, Dh))
    # superstructure
    top = Dh
    if kind in ("motor", "sail", "catamaran"):
        if rng.random() < (0.8 if kind != "sail" else 0.6):
            cl, ch = L * u(0.15, 0.4), Dh * u(0.35, 0.9)
            cz = min(L * (u(-0.1, 0.2) if kind == "motor" else u(-0.25, 0.05)), L * 0.3 - cl / 2)
            cb = B * (u(0.5, 0.8) if kind != "catamaran" else u(0.5, 0.75))
            parts.append(hull([(x, top - 0.02, z) for x in (-cb / 2, cb / 2) for z in (cz - cl / 2, cz + cl / 2)]
                              + [(x, top + ch, z) for x in (-cb * 0.42, cb * 0.42) for z in (cz - cl / 2, cz + cl * u(0.0, 0.4))]))
            if kind == "motor" and rng.random() < 0.5:  # flybridge
                parts.append(box((cb * 0.7, ch * 0.5, cl * 0.5), (0, top + ch * 1.2, cz - cl * 0.15)))
        if kind == "motor" and rng.random() < 0.5:  # outboard motor
            parts.append(box((B * 0.15, Dh * 1.4, B * 0.18), (0, Dh * 0.6, -L / 2 - B * 0.05)))
    elif kind in ("ship", "barge"):
        tiers = int(rng.integers(1, 4)) if kind == "ship" else int(rng.integers(0, 3))
        if tiers:
            cz = L * u(-0.35, 0.2)
            cl, cb = L * u(0.15, 0.35), B * u(0.5, 0.85)
            y = top - 0.02
            for _ in range(tiers):
                th_ = Dh * u(0.3, 0.6)
                parts.append(box((cb, th_ + 0.02, cl), (0, y + th_ / 2 + 0.01, cz)))
                y += th_
                cl *= u(0.5, 0.85)
                cb *= u(0.7, 0.95)
            if kind == "ship":
                for k in range(int(rng.integers(0, 4))):  # funnels
                    fz = cz - L * 0.06 * (k + 1) + L * 0.03
                    parts.append(cylinder((0, top - 0.02, fz), (0, y + Dh * u(0.4, 1.0), fz - 0.02), B * u(0.08, 0.15), segments=16))
                if rng.random() < 0.6:  # mast
                    parts.append(cylinder((0, y - 0.02, cz + cl * 0.3), (0, y + Dh * u(0.8, 1.5), cz + cl * 0.3), 0.012, segments=8))
        if kind == "barge" and rng.random() < 0.6:  # cargo
            for k in range(int(rng.integers(1, 4))):
                ch = Dh * u(0.3, 0.9)
                parts.append(box((B * 0.7, ch, L * 0.15), (0, Dh + ch / 2 - 0.02, L * (0.25 - 0.18 * k))))
    if kind in ("sail", "catamaran") and (kind == "sail" or rng.random() < 0.5):
        masts = 2 if kind == "sail" and rng.random() < 0.25 else 1
        for m in range(masts):
            mh = L * u(0.45, 0.8) * (0.7 if m else 1.0)
            mz = L * (u(0.0, 0.15) if m == 0 else u(-0.3, -0.2))
            y0 = Dh * (1.1 if kind == "catamaran" else 1.0)
            parts.append(cylinder((0, y0 - 0.05, mz), (0, y0 + mh, mz), 0.015, segments=10))
            boom = L * u(0.2, 0.4)
            parts.append(hull([(dx, y, z) for dx in (-0.006, 0.006) for (y, z) in
                               ((y0 + 0.1, mz - 0.01), (y0 + mh * 0.95, mz - 0.01), (y0 + 0.1, mz - boom))]))
            if m == 0 and rng.random() < 0.7:  # jib
                bz = L * 0.45
                parts.append(hull([(dx, y, z) for dx in (-0.006, 0.006) for (y, z) in
                                   ((y0 + mh * 0.85, mz + 0.01), (y0 + 0.08, mz + 0.01), (Dh + 0.06, bz))]))
        if kind == "sail" and rng.random() < 0.6:  # keel fin
            parts.append(hull([(dx, y, z) for dx in (-0.02, 0.02) for (y, z) in
                               ((0.05, L * 0.1), (0.05, -L * 0.15), (-Dh * u(0.8, 1.5), -L * 0.02), (-Dh * u(0.8, 1.5), -L * 0.12))]))
    return union(parts)


_GENERATORS: dict[str, Callable] = {
    "airplane": _airplane,
    "bench": _bench,
    "cabinet": _cabinet,
    "car": _car,
    "chair": _chair,
    "display": _display,
    "lamp": _lamp,
    "loudspeaker": _loudspeaker,
    "rifle": _rifle,
    "sofa": _sofa,
    "table": _table,
    "telephone": _telephone,
    "watercraft": _watercraft,
}


def make_shape(category: str, index: int) -> Mesh:
    """One procedural shape, deterministic in (category, index).

    Args:
        category: one of :data:`CATEGORIES`.
        index: shape number >= 0 (any int; each gives different parameters and variants).

    Returns:
        A closed, watertight, outward-oriented :class:`engine.mesh.Mesh` (V vertices, F faces,
        MIN_FACES <= F <= MAX_FACES), +Y up, front +Z, normalised into [-0.5, 0.5]^3.
    """
    if category not in _GENERATORS:
        raise ValueError(f"unknown category {category!r}; expected one of {', '.join(CATEGORIES)}")
    if not isinstance(index, (int, np.integer)) or index < 0:
        raise ValueError(f"shape index must be an int >= 0, got {index!r}")
    solid = _GENERATORS[category](_rng(category, int(index)))
    return _to_mesh(solid)


def shape_id(category: str, index: int) -> str:
    """The shape id used on disk for a procedural shape: ``"<category>_<index:05d>"``."""
    return f"{category}_{int(index):05d}"
