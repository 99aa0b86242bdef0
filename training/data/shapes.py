"""A procedural shape library: the 13 ShapeNet categories the paper reports.

Every category is a generator with continuous parameters (proportions, thicknesses, angles)
and discrete variants (chair with or without arms, round or square lamp shade, round or
rectangular table with one or four legs, sedan or van, ...). Parts are solid primitives
(boxes, cylinders, cones, spheres, convex hulls) joined with a **boolean union** in
manifold3d, so every shape is one closed, watertight, consistently oriented (outward,
counter-clockwise) triangle mesh with positive volume -- never a set of overlapping shells.

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


def _to_mesh(solid, min_faces: int = MIN_FACES) -> Mesh:
    n = solid.num_tri()
    while n and n < min_faces:
        solid = solid.refine(2)
        n = solid.num_tri()
    m = solid.to_mesh()
    v = np.asarray(m.vert_properties, dtype=np.float64)[:, :3]
    f = np.asarray(m.tri_verts, dtype=np.int64)
    if len(f) == 0:
        raise RuntimeError("procedural shape came out empty (a generator bug)")
    return Mesh(normalize_vertices(v).astype(np.float32), f)


def _legs4(x, z, y_top, y_bottom, r, splay=0.0, square=False):
    """Four legs at (+-x, +-z) from y_top down to y_bottom, splayed outwards by ``splay``."""
    parts = []
    for sx in (-1, 1):
        for sz in (-1, 1):
            top = (sx * x, y_top, sz * z)
            bot = (sx * (x + splay), y_bottom, sz * (z + splay))
            if square:
                parts.append(hull(_square_prism(top, bot, r)))
            else:
                parts.append(cylinder(bot, top, r))
    return parts


def _square_prism(p0, p1, half):
    """8 corner points of a square-section prism between p0 and p1 (axis mostly vertical)."""
    pts = []
    for p in (p0, p1):
        for dx in (-half, half):
            for dz in (-half, half):
                pts.append((p[0] + dx, p[1], p[2] + dz))
    return pts


# --------------------------------------------------------------------------- categories
def _airplane(rng):
    L = rng.uniform(1.6, 2.4)  # fuselage length (along Z, nose at +Z)
    R = rng.uniform(0.08, 0.14)
    span = rng.uniform(1.4, 2.4)
    sweep = rng.uniform(0.0, 0.5)
    chord = rng.uniform(0.25, 0.45)
    wing_y = rng.choice([-0.6, 0.0, 0.6]) * R
    engines = int(rng.choice([0, 2, 4]))
    t = 0.03
    fus = hull(
        [(0, 0, z) for z in (-L / 2, L / 2)]
        + [(R * np.cos(a), R * np.sin(a), zz) for a in np.linspace(0, 2 * np.pi, 12, endpoint=False) for zz in (-L / 2 + 0.35 * L, L / 2 - 0.15 * L)]
    )
    nose = sphere((0, 0, L / 2 - 0.15 * L), R, segments=16)
    parts = [fus, nose]
    wz = rng.uniform(-0.1, 0.15) * L
    for s in (-1, 1):
        root = [(0, wing_y - t / 2, wz + chord / 2), (0, wing_y + t / 2, wz + chord / 2), (0, wing_y - t / 2, wz - chord / 2), (0, wing_y + t / 2, wz - chord / 2)]
        tipc = chord * rng.uniform(0.3, 0.6) if s < 0 else None
        tipc = tipc or chord * 0.45
        tip_z = wz - sweep * span / 2
        tip = [(s * span / 2, wing_y - t / 3 + 0.05, tip_z + tipc / 2), (s * span / 2, wing_y + t / 3 + 0.05, tip_z + tipc / 2),
               (s * span / 2, wing_y - t / 3 + 0.05, tip_z - tipc / 2), (s * span / 2, wing_y + t / 3 + 0.05, tip_z - tipc / 2)]
        parts.append(hull(root + tip))
    # tail: vertical fin and horizontal stabilisers
    tz = -L / 2 + 0.05
    fin_h = rng.uniform(0.2, 0.4)
    parts.append(hull([(-t / 2, 0, tz), (t / 2, 0, tz), (-t / 2, 0, tz + 0.35), (t / 2, 0, tz + 0.35),
                       (-t / 3, fin_h, tz - 0.02), (t / 3, fin_h, tz - 0.02), (-t / 3, fin_h, tz + 0.12), (t / 3, fin_h, tz + 0.12)]))
    hs = rng.uniform(0.25, 0.45)
    parts.append(hull([(-hs, 0.02, tz), (hs, 0.02, tz), (-hs, 0.02 + t, tz), (hs, 0.02 + t, tz),
                       (-0.05, 0.02, tz + 0.25), (0.05, 0.02, tz + 0.25), (-0.05, 0.02 + t, tz + 0.25), (0.05, 0.02 + t, tz + 0.25)]))
    for k in range(engines // 2):
        ex = span * (0.18 + 0.14 * k)
        frac = ex / (span / 2)
        zc = wz - sweep * ex  # wing centre line at |x| = ex
        yw = wing_y + 0.05 * frac  # wing mid-surface there (dihedral)
        for s in (-1, 1):
            parts.append(cylinder((s * ex, yw - 0.1, zc - 0.15), (s * ex, yw - 0.1, zc + 0.15), 0.05, 0.06, 16))
            parts.append(box((0.02, 0.12, 0.1), (s * ex, yw - 0.04, zc)))  # pylon into the nacelle and the wing
    return union(parts)


def _bench(rng):
    W = rng.uniform(1.2, 2.0)
    D = rng.uniform(0.35, 0.55)
    H = rng.uniform(0.4, 0.5)
    th = rng.uniform(0.04, 0.08)
    variant = rng.integers(0, 2)  # 0: four legs, 1: two slab sides
    backrest = rng.random() < 0.6
    parts = [box((W, th, D), (0, H, 0))]
    if variant == 0:
        parts += _legs4(W / 2 - 0.08, D / 2 - 0.06, H, 0.0, rng.uniform(0.025, 0.045), square=rng.random() < 0.5)
    else:
        for s in (-1, 1):
            parts.append(box((0.06, H, D * 0.9), (s * (W / 2 - 0.1), H / 2, 0)))
    if backrest:
        bh = rng.uniform(0.3, 0.5)
        tilt = rng.uniform(0.0, 0.12)
        parts.append(hull([(x, y, z) for x in (-W / 2, W / 2) for (y, z) in
                           ((H, -D / 2 + 0.02), (H, -D / 2 + 0.06), (H + bh, -D / 2 - tilt), (H + bh, -D / 2 - tilt + 0.04))]))
    return union(parts)


def _cabinet(rng):
    W = rng.uniform(0.6, 1.4)
    H = rng.uniform(0.7, 1.6)
    D = rng.uniform(0.4, 0.6)
    plinth = rng.uniform(0.03, 0.1)
    rows = int(rng.integers(1, 5))
    cols = int(rng.choice([1, 2]))
    doors = rng.random() < 0.4
    parts = [box((W, H - plinth, D), (0, plinth + (H - plinth) / 2, 0)), box((W * 0.94, plinth + 0.01, D * 0.9), (0, plinth / 2, 0))]
    parts.append(box((W + 0.04, 0.03, D + 0.03), (0, H, 0.0)))  # top overhang
    gap = 0.02
    body_h = H - plinth
    if doors:
        rows = 1
    cell_w = (W - gap * (cols + 1)) / cols
    cell_h = (body_h - gap * (rows + 1)) / rows
    for i in range(rows):
        for j in range(cols):
            cx = -W / 2 + gap + cell_w / 2 + j * (cell_w + gap)
            cy = plinth + gap + cell_h / 2 + i * (cell_h + gap)
            parts.append(box((cell_w, cell_h, 0.02), (cx, cy, D / 2 + 0.005)))
            hx = cx + (cell_w * 0.35 * (1 if j == 0 else -1) if doors else 0.0)
            parts.append(box((0.02 if doors else cell_w * 0.3, cell_h * 0.3 if doors else 0.025, 0.03), (hx, cy, D / 2 + 0.025)))
    return union(parts)


def _car(rng):
    van = rng.random() < 0.35
    L = rng.uniform(1.8, 2.4)
    W = rng.uniform(0.8, 1.0)
    body_h = rng.uniform(0.3, 0.4)
    clearance = rng.uniform(0.12, 0.18)
    wr = rng.uniform(0.16, 0.2)
    r = 0.06
    y0 = clearance
    parts = [rounded_box((W, body_h, L), (0, y0 + body_h / 2, 0), r)]
    top = y0 + body_h
    if van:
        ch = rng.uniform(0.4, 0.55)
        front = L / 2 - rng.uniform(0.3, 0.45)
        pts = [(x, y, z) for x in (-W / 2 + 0.04, W / 2 - 0.04) for (y, z) in
               ((top - 0.01, -L / 2 + 0.03), (top + ch, -L / 2 + 0.05), (top + ch, front - 0.15), (top - 0.01, front + 0.1))]
    else:
        ch = rng.uniform(0.25, 0.35)
        rear, front = -L / 2 + rng.uniform(0.35, 0.55), L / 2 - rng.uniform(0.55, 0.75)
        pts = [(x, y, z) for x in (-W / 2 + 0.06, W / 2 - 0.06) for (y, z) in
               ((top - 0.01, rear - 0.15), (top + ch, rear + 0.1), (top + ch, front - 0.2), (top - 0.01, front + 0.15))]
    parts.append(hull(pts))
    wz = L / 2 - rng.uniform(0.3, 0.4)
    for z in (wz, -wz):
        for s in (-1, 1):
            parts.append(cylinder((s * (W / 2 - 0.08), wr, z), (s * (W / 2 + 0.03), wr, z), wr, segments=SEGMENTS))
    return union(parts)


def _chair(rng):
    S = rng.uniform(0.45, 0.6)  # seat width/depth
    D = S * rng.uniform(0.9, 1.15)
    H = rng.uniform(0.42, 0.5)
    th = rng.uniform(0.04, 0.08)
    back_h = rng.uniform(0.35, 0.6)
    arms = rng.random() < 0.4
    slats = rng.random() < 0.35
    round_legs = rng.random() < 0.5
    tilt = rng.uniform(0.0, 0.1)
    lr = rng.uniform(0.02, 0.035)
    parts = [box((S, th, D), (0, H, 0))]
    parts += _legs4(S / 2 - lr - 0.01, D / 2 - lr - 0.01, H, 0.0, lr, splay=rng.uniform(0, 0.04), square=not round_legs)
    bz = -D / 2 + 0.03
    if slats:
        n = int(rng.integers(3, 6))
        for s in (-1, 1):
            parts.append(hull(_square_prism((s * (S / 2 - 0.025), H, bz), (s * (S / 2 - 0.025), H + back_h, bz - tilt), 0.022)))
        for k in range(n):
            x = -S / 2 + 0.05 + (S - 0.1) * (k + 0.5) / n
            parts.append(hull([(x + dx, y, z + dz) for dx in (-0.012, 0.012) for dz in (-0.012, 0.012)
                               for (y, z) in ((H, bz), (H + back_h * 0.95, bz - tilt * 0.95))]))
        parts.append(hull([(x, y, z + dz) for x in (-S / 2, S / 2) for dz in (-0.02, 0.02)
                           for (y, z) in ((H + back_h * 0.85, bz - tilt * 0.85), (H + back_h, bz - tilt))]))
    else:
        parts.append(hull([(x, y, z + dz) for x in (-S / 2, S / 2) for dz in (-0.025, 0.025)
                           for (y, z) in ((H, bz), (H + back_h, bz - tilt))]))
    if arms:
        ah = rng.uniform(0.18, 0.26)
        for s in (-1, 1):
            x = s * (S / 2 - 0.02)
            parts.append(box((0.04, 0.035, D * 0.85), (x, H + ah, -0.02)))
            parts.append(cylinder((x, H, D / 2 - 0.06), (x, H + ah, D / 2 - 0.06), 0.018, segments=12))
    return union(parts)


def _display(rng):
    W = rng.uniform(0.9, 1.4)
    Hs = W * rng.uniform(0.5, 0.7)
    T = rng.uniform(0.03, 0.07)
    neck_h = rng.uniform(0.15, 0.35)
    base_round = rng.random() < 0.5
    crt = rng.random() < 0.2
    y0 = neck_h + Hs / 2
    parts = [box((W, Hs, T), (0, y0, 0))]
    parts.append(box((W * 0.94, Hs * 0.9, 0.02), (0, y0, T / 2)))  # raised bezel/screen panel
    if crt:
        parts.append(hull([(x, y, -T / 2) for x in (-W * 0.45, W * 0.45) for y in (y0 - Hs * 0.45, y0 + Hs * 0.45)]
                          + [(x, y, -T / 2 - W * 0.5) for x in (-W * 0.25, W * 0.25) for y in (y0 - Hs * 0.25, y0 + Hs * 0.25)]))
    parts.append(box((0.08, neck_h + 0.05, 0.06), (0, (neck_h + 0.05) / 2, -T / 2)))  # overlaps the screen
    if base_round:
        parts.append(cylinder((0, 0, -T / 2), (0, 0.03, -T / 2), rng.uniform(0.15, 0.25)))
    else:
        parts.append(box((rng.uniform(0.3, 0.5), 0.03, rng.uniform(0.2, 0.3)), (0, 0.015, -T / 2)))
    return union(parts)


def _lamp(rng):
    base_r = rng.uniform(0.15, 0.25)
    pole_h = rng.uniform(0.6, 1.4)
    round_shade = rng.random() < 0.6
    bent = rng.random() < 0.35
    shade_h = rng.uniform(0.2, 0.35)
    r_bot, r_top = rng.uniform(0.18, 0.3), rng.uniform(0.08, 0.18)
    parts = [cylinder((0, 0, 0), (0, 0.05, 0), base_r, segments=24)]
    parts.append(cylinder((0, 0.04, 0), (0, pole_h, 0), 0.018, segments=12))
    top = np.array([0.0, pole_h, 0.0])
    if bent:
        tip = top + np.array([0.0, rng.uniform(0.05, 0.2), rng.uniform(0.2, 0.35)])
        parts.append(cylinder(top, tip, 0.018, segments=12))
        parts.append(sphere(top, 0.03, segments=12))
        top = tip
    y_shade = top[1] - shade_h * 0.4
    if round_shade:
        parts.append(cylinder((top[0], y_shade, top[2]), (top[0], y_shade + shade_h, top[2]), r_bot, r_top, 24))
    else:
        parts.append(hull([(top[0] + sx * r, y, top[2] + sz * r) for sx in (-1, 1) for sz in (-1, 1)
                           for (y, r) in ((y_shade, r_bot * 0.9), (y_shade + shade_h, r_top * 0.9))]))
    parts.append(cylinder((top[0], y_shade - 0.03, top[2]), (top[0], y_shade + 0.02, top[2]), 0.03, segments=12))
    return union(parts)


def _loudspeaker(rng):
    tower = rng.random() < 0.5
    W = rng.uniform(0.25, 0.4)
    H = rng.uniform(0.8, 1.2) if tower else rng.uniform(0.35, 0.5)
    D = rng.uniform(0.25, 0.4)
    rounded = rng.random() < 0.5
    n = int(rng.integers(2, 4)) if tower else int(rng.integers(1, 3))
    body = rounded_box((W, H, D), (0, H / 2, 0), 0.03) if rounded else box((W, H, D), (0, H / 2, 0))
    parts = [body]
    for k in range(n):
        y = H - (k + 0.5) * H / n
        r = W * (0.22 if k == 0 else 0.38)
        parts.append(cylinder((0, y, D / 2 - 0.01), (0, y, D / 2 + 0.02), r * 1.1, segments=24))
        parts.append(cylinder((0, y, D / 2 + 0.02), (0, y, D / 2 + 0.05), r * 0.6, r * 0.2, segments=20))
    if tower and rng.random() < 0.5:
        parts.append(box((W + 0.08, 0.03, D + 0.08), (0, 0.015, 0)))
    return union(parts)


def _rifle(rng):
    L = rng.uniform(1.8, 2.6)  # along Z, muzzle at +Z
    barrel = rng.uniform(0.5, 0.9)
    br = rng.uniform(0.015, 0.025)
    body_l = rng.uniform(0.5, 0.7)
    body_h = rng.uniform(0.09, 0.14)
    scope = rng.random() < 0.5
    mag = rng.random() < 0.6
    z_body0 = -L / 2 + (L - barrel - body_l)
    zb1 = z_body0 + body_l
    parts = [box((0.05, body_h, body_l), (0, 0, (z_body0 + zb1) / 2))]
    parts.append(cylinder((0, body_h * 0.2, zb1 - 0.05), (0, body_h * 0.2, L / 2), br, segments=12))
    parts.append(hull([(x, y, z) for x in (-0.03, 0.03) for (y, z) in
                       ((body_h / 2, z_body0 + 0.02), (-body_h / 2, z_body0 + 0.02), (0.0, -L / 2), (-rng.uniform(0.15, 0.25), -L / 2))]))
    parts.append(box((0.04, 0.12, 0.05), (0, -body_h / 2 - 0.05, z_body0 + body_l * 0.3)))  # grip
    if mag:
        parts.append(box((0.035, rng.uniform(0.12, 0.2), 0.06), (0, -body_h / 2 - 0.06, z_body0 + body_l * 0.65)))
    if scope:
        sl = rng.uniform(0.25, 0.4)
        zc = z_body0 + body_l * 0.55
        parts.append(cylinder((0, body_h / 2 + 0.06, zc - sl / 2), (0, body_h / 2 + 0.06, zc + sl / 2), 0.03, segments=16))
        parts.append(box((0.02, 0.07, 0.03), (0, body_h / 2 + 0.02, zc)))
    return union(parts)


def _sofa(rng):
    W = rng.uniform(1.4, 2.2)
    D = rng.uniform(0.7, 0.95)
    seat_h = rng.uniform(0.35, 0.45)
    back_h = rng.uniform(0.3, 0.45)
    arms = rng.random() < 0.75
    cushions = int(rng.integers(1, 4))
    arm_w = rng.uniform(0.1, 0.2)
    r = 0.04
    base_y = 0.08
    parts = [rounded_box((W, seat_h - base_y, D), (0, base_y + (seat_h - base_y) / 2, 0), r)]
    bt = rng.uniform(0.15, 0.25)
    parts.append(rounded_box((W, seat_h + back_h, bt), (0, base_y + (seat_h + back_h - base_y) / 2, -D / 2 + bt / 2), r))
    inner = W - (2 * arm_w if arms else 0.0)
    if arms:
        ah = seat_h + rng.uniform(0.12, 0.22)
        for s in (-1, 1):
            parts.append(rounded_box((arm_w, ah - base_y, D), (s * (W / 2 - arm_w / 2), base_y + (ah - base_y) / 2, 0), r))
    cw = inner / cushions
    for k in range(cushions):
        cx = -inner / 2 + cw * (k + 0.5)
        parts.append(rounded_box((cw - 0.02, 0.1, D - bt - 0.02), (cx, seat_h + 0.03, bt / 2), 0.04))
    parts += _legs4(W / 2 - 0.08, D / 2 - 0.08, base_y + 0.01, 0.0, 0.025, square=True)
    return union(parts)


def _table(rng):
    round_top = rng.random() < 0.4
    single_leg = rng.random() < 0.4
    H = rng.uniform(0.65, 0.8)
    th = rng.uniform(0.03, 0.06)
    parts = []
    if round_top:
        R = rng.uniform(0.4, 0.6)
        parts.append(cylinder((0, H - th, 0), (0, H, 0), R, segments=32))
        lx = lz = R * 0.62
    else:
        W, D = rng.uniform(1.0, 1.8), rng.uniform(0.6, 0.9)
        parts.append(box((W, th, D), (0, H - th / 2, 0)))
        lx, lz = W / 2 - 0.07, D / 2 - 0.07
    if single_leg:
        parts.append(cylinder((0, 0.03, 0), (0, H - th + 0.01, 0), rng.uniform(0.03, 0.06), segments=16))
        if rng.random() < 0.5:
            parts.append(cylinder((0, 0, 0), (0, 0.04, 0), rng.uniform(0.2, 0.3), segments=24))
        else:
            for a in (0.0, 90.0, 180.0, 270.0):
                d = np.array([np.cos(np.radians(a)), 0, np.sin(np.radians(a))])
                parts.append(hull([p + o for p in (np.zeros(3) + [0, 0.02, 0], d * 0.3 + [0, 0.02, 0])
                                   for o in ([0, -0.02, -0.02], [0, 0.02, -0.02], [0, -0.02, 0.02], [0, 0.02, 0.02])]))
    else:
        parts += _legs4(lx, lz, H - th + 0.01, 0.0, rng.uniform(0.025, 0.045), square=rng.random() < 0.5)
        if not round_top and rng.random() < 0.5:  # apron
            parts.append(box((2 * lx, 0.08, 0.02), (0, H - th - 0.04, lz)))
            parts.append(box((2 * lx, 0.08, 0.02), (0, H - th - 0.04, -lz)))
    return union(parts)


def _telephone(rng):
    mobile = rng.random() < 0.6
    if mobile:
        W, H, T = rng.uniform(0.35, 0.5), rng.uniform(0.75, 1.0), rng.uniform(0.04, 0.08)
        parts = [rounded_box((W, H, T), (0, H / 2, 0), rng.uniform(0.02, 0.06))]
        parts.append(box((W * 0.86, H * 0.7, 0.01), (0, H * 0.55, T / 2)))  # screen
        if rng.random() < 0.5:  # keypad buttons
            for i in range(3):
                for j in range(3):
                    parts.append(box((W * 0.18, H * 0.035, 0.02), ((j - 1) * W * 0.26, H * (0.12 + 0.045 * i), T / 2)))
        if rng.random() < 0.5:
            parts.append(rounded_box((W * 0.35, H * 0.15, 0.02), (-W * 0.2, H * 0.85, -T / 2 - 0.005), 0.008))
        return union(parts)
    W, D = rng.uniform(0.5, 0.7), rng.uniform(0.5, 0.7)
    hb, hf = rng.uniform(0.18, 0.25), rng.uniform(0.06, 0.1)
    parts = [hull([(x, y, z) for x in (-W / 2, W / 2) for (y, z) in ((0, -D / 2), (0, D / 2), (hb, -D / 2), (hf, D / 2))])]
    hl = W * rng.uniform(1.0, 1.3)
    hy = hb + 0.05
    parts.append(hull([(x, hy + dy, -D / 2 + 0.12 + dz) for x in (-hl * 0.3, hl * 0.3) for dy in (-0.03, 0.03) for dz in (-0.04, 0.04)]))
    for s in (-1, 1):
        parts.append(rounded_box((hl * 0.25, 0.15, 0.14), (s * hl * 0.4, hy - 0.05, -D / 2 + 0.12), 0.03))
    for i in range(3):
        z = D / 2 - 0.12 - 0.1 * i
        y_surface = hf + (hb - hf) * (D / 2 - z) / D  # the slanted top at z
        for j in range(3):
            parts.append(box((0.07, 0.03, 0.06), ((j - 1) * 0.1, y_surface, z)))
    return union(parts)


def _watercraft(rng):
    L = rng.uniform(1.6, 2.4)  # bow at +Z
    B = rng.uniform(0.35, 0.6)
    Dh = rng.uniform(0.2, 0.35)
    sail = rng.random() < 0.4
    cabin = rng.random() < 0.7
    bow = L / 2
    stern = -L / 2
    deck = [(sx * B / 2 * w, Dh, z) for (z, w) in ((stern, 0.85), (stern + 0.3 * L, 1.0), (0.2 * L, 0.9), (bow - 0.1 * L, 0.45)) for sx in (-1, 1)]
    deck.append((0, Dh + 0.05, bow))
    keel = [(sx * B / 2 * w, 0.0, z) for (z, w) in ((stern + 0.05, 0.5), (0.1 * L, 0.3)) for sx in (-1, 1)]
    keel.append((0.0, 0.05, bow - 0.12 * L))
    parts = [hull(deck + keel)]
    if cabin:
        cl = L * rng.uniform(0.2, 0.35)
        ch = rng.uniform(0.12, 0.25)
        cz = rng.uniform(-0.2, 0.05) * L
        parts.append(rounded_box((B * 0.6, ch + 0.02, cl), (0, Dh + ch / 2, cz), 0.03))
        if rng.random() < 0.5:
            parts.append(box((B * 0.45, ch * 0.6, cl * 0.6), (0, Dh + ch + ch * 0.3, cz - cl * 0.1)))
    if sail:
        mh = rng.uniform(0.8, 1.3)
        mz = 0.1 * L
        parts.append(cylinder((0, Dh - 0.02, mz), (0, Dh + mh, mz), 0.02, segments=12))
        parts.append(hull([(dx, Dh + 0.12, mz - 0.01) for dx in (-0.008, 0.008)]
                          + [(dx, Dh + mh * 0.95, mz - 0.01) for dx in (-0.008, 0.008)]
                          + [(dx, Dh + 0.12, mz - rng.uniform(0.5, 0.8)) for dx in (-0.008, 0.008)]))
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
