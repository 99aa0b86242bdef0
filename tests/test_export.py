"""Mesh export round trips (+ the Khronos glTF validator) and post-processing."""

from __future__ import annotations

import base64
import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import trimesh

from engine.errors import ExportError
from engine.export import export_mesh, supported_suffixes
from engine.icosphere import icosphere
from engine.mesh import Mesh, vertex_normals
from engine.postprocess import (
    candidate_pairs,
    candidate_pairs_bruteforce,
    mesh_stats,
    self_intersections,
    smooth,
    subdivide,
    triangles_intersect,
)

ROOT = Path(__file__).resolve().parents[1]
POS_ATOL = 1e-6
"""Positions written as float32 (GLB/glTF/PLY/STL) or with 9 decimals (OBJ) come back within this."""
MEASURE_RTOL = 1e-5
"""Area / volume of a reloaded mesh against the original (float32 storage)."""


def _bumpy(level: int = 2, seed: int = 0) -> Mesh:
    """A deformed icosphere (so vertex order and positions are not trivially recoverable)."""
    m = icosphere(level)
    rng = np.random.default_rng(seed)
    v = m.vertices * (1.0 + 0.1 * rng.standard_normal((m.num_vertices, 1))).astype(np.float32)
    return m.with_vertices(v * np.array([1.0, 0.7, 1.2], np.float32) + np.array([0.1, -0.2, 0.3], np.float32))


def _load(path: Path) -> trimesh.Trimesh:
    return trimesh.load(path, process=False, force="mesh")


def _reference(mesh: Mesh) -> trimesh.Trimesh:
    return trimesh.Trimesh(mesh.vertices.astype(np.float64), mesh.faces, process=False)


@pytest.mark.parametrize("suffix", [".obj", ".glb", ".gltf", ".ply", ".stl"])
def test_round_trip_keeps_geometry(tmp_path, suffix):
    mesh = _bumpy()
    path = export_mesh(mesh, tmp_path / f"m{suffix}")
    assert path == tmp_path / f"m{suffix}"
    got = _load(path)
    ref = _reference(mesh)
    assert len(got.faces) == mesh.num_faces
    if suffix == ".stl":  # STL stores three corners per face: compare the corners in face order
        np.testing.assert_allclose(got.vertices[got.faces], mesh.vertices[mesh.faces], atol=POS_ATOL)
    else:  # vertex count, order and positions kept
        assert len(got.vertices) == mesh.num_vertices
        np.testing.assert_allclose(got.vertices, mesh.vertices, atol=POS_ATOL)
        np.testing.assert_array_equal(got.faces, mesh.faces)
    assert got.area == pytest.approx(ref.area, rel=MEASURE_RTOL)
    assert got.volume == pytest.approx(ref.volume, rel=MEASURE_RTOL)
    assert list(tmp_path.iterdir()) == [path]  # one file, no leftovers (.bin, temp files)


def test_obj_carries_area_weighted_vertex_normals(tmp_path):
    mesh = _bumpy()
    text = export_mesh(mesh, tmp_path / "m.obj").read_text()
    vn = np.array([[float(x) for x in line.split()[1:]] for line in text.splitlines() if line.startswith("vn ")])
    assert vn.shape == (mesh.num_vertices, 3)
    np.testing.assert_allclose(vn, vertex_normals(mesh.vertices, mesh.faces), atol=1e-6)
    no_normals = export_mesh(mesh, tmp_path / "plain.obj", include_normals=False).read_text()
    assert "vn " not in no_normals


def test_gltf_is_self_contained_and_exports_do_not_interfere(tmp_path):
    a, b = _bumpy(seed=1), _bumpy(1, seed=2)
    export_mesh(a, tmp_path / "a.gltf")
    export_mesh(b, tmp_path / "b.gltf")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.gltf", "b.gltf"]
    doc = json.loads((tmp_path / "a.gltf").read_text())
    assert all(buf["uri"].startswith("data:") for buf in doc["buffers"])
    np.testing.assert_allclose(_load(tmp_path / "a.gltf").vertices, a.vertices, atol=POS_ATOL)
    np.testing.assert_allclose(_load(tmp_path / "b.gltf").vertices, b.vertices, atol=POS_ATOL)
    raw = base64.b64decode(doc["buffers"][0]["uri"].split(",", 1)[1])
    assert len(raw) == doc["buffers"][0]["byteLength"]


def test_format_override_and_bad_paths(tmp_path):
    mesh = icosphere(1)
    p = export_mesh(mesh, tmp_path / "mesh.dat", fmt="ply")
    assert len(_load_as(p, "ply").vertices) == mesh.num_vertices
    with pytest.raises(ExportError, match=r"unknown file suffix '\.xyz'; supported: \.obj, \.glb, \.gltf, \.ply, \.stl"):
        export_mesh(mesh, tmp_path / "m.xyz")
    with pytest.raises(ExportError, match="noext: the file name has no suffix to choose the format by"):
        export_mesh(mesh, tmp_path / "noext")
    (tmp_path / "afile").write_text("x")
    with pytest.raises(ExportError, match="cannot write .*afile is a file, not a folder"):
        export_mesh(mesh, tmp_path / "afile" / "m.obj")
    with pytest.raises(ExportError, match="no faces"):
        export_mesh(Mesh(np.zeros((3, 3)), np.zeros((0, 3), np.int64)), tmp_path / "e.obj")
    assert supported_suffixes() == (".obj", ".glb", ".gltf", ".ply", ".stl")


def _load_as(path: Path, file_type: str) -> trimesh.Trimesh:
    with open(path, "rb") as fh:
        return trimesh.load(fh, file_type=file_type, process=False, force="mesh")


def test_failed_export_leaves_the_old_file(tmp_path, monkeypatch):
    import engine.export as ex

    target = export_mesh(icosphere(1), tmp_path / "keep.obj")
    before = target.read_bytes()

    def boom(mesh, include_normals):
        raise RuntimeError("writer failed")

    monkeypatch.setitem(ex.WRITERS, ".obj", boom)
    with pytest.raises(RuntimeError):
        export_mesh(icosphere(2), target)
    assert target.read_bytes() == before and list(tmp_path.iterdir()) == [target]


# -------------------------------------------------------------------------- Khronos glTF validator

_VALIDATE_JS = """
const fs = require('fs');
const validator = require('gltf-validator');
const path = process.argv[2];
validator.validateBytes(new Uint8Array(fs.readFileSync(path)), {uri: path})
  .then((report) => { console.log(JSON.stringify(report)); })
  .catch((error) => { console.error('validation failed: ' + error); process.exit(3); });
"""


@pytest.fixture(scope="session")
def gltf_validator() -> Path:
    """Install the Khronos validator (npm gltf-validator) into <repo>/.cache/npm; skip without node/npm."""
    node, npm = shutil.which("node"), shutil.which("npm")
    if not node or not npm:
        pytest.skip("node/npm not found: the Khronos glTF validator cannot run")
    prefix = ROOT / ".cache" / "npm"
    if not (prefix / "node_modules" / "gltf-validator").is_dir():
        try:
            r = subprocess.run([npm, "install", "--prefix", str(prefix), "gltf-validator", "--no-audit", "--no-fund"],
                               capture_output=True, text=True, timeout=300)
        except subprocess.TimeoutExpired:
            pytest.skip("npm install gltf-validator timed out")
        if r.returncode != 0:
            pytest.skip(f"npm install gltf-validator failed: {r.stderr.strip().splitlines()[-1:]}")
    script = prefix / "validate_gltf.js"
    script.write_text(_VALIDATE_JS)
    return script


@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
def test_khronos_validator_reports_no_errors(tmp_path, gltf_validator, suffix):
    path = export_mesh(_bumpy(), tmp_path / f"m{suffix}")
    r = subprocess.run(["node", str(gltf_validator), str(path)], capture_output=True, text=True, timeout=120,
                       cwd=gltf_validator.parent)
    assert r.returncode == 0, r.stderr
    report = json.loads(r.stdout)
    issues = report["issues"]
    assert issues["numErrors"] == 0, issues["messages"][:5]
    assert issues["numWarnings"] == 0 and issues["numInfos"] == 0, issues["messages"][:5]  # targets set, etc.
    assert report["info"]["totalVertexCount"] == 162 and report["info"]["totalTriangleCount"] == 320


# -------------------------------------------------------------------------- post-processing


def test_laplacian_step_matches_hand_computation():
    """Tetrahedron: every vertex neighbours the other three, so one step moves v to v + lam (mean(others) - v)."""
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], np.float64)
    f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    mesh = Mesh(v, f)
    lam = 0.5
    expected = v + lam * ((v.sum(axis=0) - v) / 3.0 - v)
    np.testing.assert_allclose(smooth(mesh, "laplacian", 1, lam=lam).vertices, expected, atol=1e-6)
    mu = -0.53
    step2 = expected + mu * ((expected.sum(axis=0) - expected) / 3.0 - expected)
    np.testing.assert_allclose(smooth(mesh, "taubin", 1, lam=lam, mu=mu).vertices, step2, atol=1e-6)


def test_taubin_removes_noise_with_less_shrinkage_than_laplacian():
    m = icosphere(3)
    rng = np.random.default_rng(0)
    noisy = m.with_vertices(m.vertices * (1 + 0.05 * rng.standard_normal((m.num_vertices, 1))).astype(np.float32))
    r = lambda mesh: np.linalg.norm(mesh.vertices.astype(np.float64), axis=1)  # noqa: E731
    taubin, lap = smooth(noisy, "taubin", 20), smooth(noisy, "laplacian", 20)
    assert r(taubin).std() < 0.5 * r(noisy).std()
    assert abs(r(taubin).mean() - 0.5) < 0.01 < abs(r(lap).mean() - 0.5)
    assert smooth(noisy, "taubin", 0) is noisy


def test_smooth_keeps_isolated_vertices_and_rejects_bad_arguments():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [5, 5, 5]], np.float32)
    mesh = Mesh(v, [[0, 1, 2]])
    out = smooth(mesh, "laplacian", 3)
    np.testing.assert_array_equal(out.vertices[3], v[3])
    assert np.all(np.isfinite(out.vertices))
    for kwargs in ({"method": "median"}, {"iterations": -1}, {"lam": 0.0}, {"lam": np.nan}, {"mu": 0.2}):
        with pytest.raises(ValueError):
            smooth(mesh, **kwargs)


def test_midpoint_subdivision_counts_and_exact_geometry():
    m = _bumpy(1)
    s = subdivide(m, 2, "midpoint")
    E = 30 * 4  # level-1 icosphere: 120 edges
    assert s.num_faces == m.num_faces * 16 and s.num_vertices == m.num_vertices + E + (E * 2 + m.num_faces * 3)
    np.testing.assert_array_equal(s.vertices[: m.num_vertices], m.vertices)  # old vertices first, unchanged
    ref = _reference(m)
    assert _reference(s).area == pytest.approx(ref.area, rel=1e-5)  # flat split: same surface
    assert _reference(s).volume == pytest.approx(ref.volume, rel=1e-5)
    assert mesh_stats(s)["watertight"] and mesh_stats(s)["winding_consistent"]


def test_loop_subdivision_matches_trimesh_reference():
    m = _bumpy(2, seed=3)
    s = subdivide(m, 1, "loop")
    rv, rf = trimesh.remesh.subdivide_loop(m.vertices.astype(np.float64), m.faces, iterations=1)
    assert s.num_vertices == len(rv) and s.num_faces == len(rf)
    ours = s.vertices[np.lexsort(s.vertices.T)]
    theirs = rv[np.lexsort(rv.T)]
    np.testing.assert_allclose(ours, theirs, atol=1e-6)
    np.testing.assert_allclose(_reference(s).area, trimesh.Trimesh(rv, rf, process=False).area, rtol=1e-5)


def test_loop_subdivision_with_boundary_stays_finite():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.5]], np.float32)
    mesh = Mesh(v, [[0, 1, 2], [1, 3, 2]])
    s = subdivide(mesh, 2, "loop")
    assert s.num_faces == 32 and np.all(np.isfinite(s.vertices))
    one = subdivide(mesh, 1, "loop")
    # every vertex is on the boundary: v0's boundary neighbours are v1 and v2 (3/4, 1/8, 1/8 rule)
    np.testing.assert_allclose(one.vertices[0], 0.75 * v[0] + 0.125 * (v[1] + v[2]), atol=1e-7)
    # edge 1-2 is interior: 3/8 of its ends + 1/8 of the opposite vertices 0 and 3; boundary edge 0-1: midpoint
    mids = one.vertices[4:]
    assert np.any(np.all(np.abs(mids - (0.375 * (v[1] + v[2]) + 0.125 * (v[0] + v[3]))) < 1e-7, axis=1))
    assert np.any(np.all(np.abs(mids - 0.5 * (v[0] + v[1])) < 1e-7, axis=1))
    with pytest.raises(ValueError, match="over the limit"):
        subdivide(icosphere(3), 9)


def test_self_intersections_known_cases():
    assert self_intersections(icosphere(3)) == 0
    # two triangles crossing like links of a chain: exactly one intersecting pair
    v = np.array([[0, 0, 0], [2, 0, 0], [0, 2, 0], [0.5, 0.5, -1], [0.5, 0.5, 1], [3, 3, 0.1]], np.float64)
    assert self_intersections(Mesh(v, [[0, 1, 2], [3, 4, 5]])) == 1
    # moved apart: none
    far = v.copy()
    far[3:] += 10.0
    assert self_intersections(Mesh(far, [[0, 1, 2], [3, 4, 5]])) == 0
    # sharing a vertex does not count (adjacent), even when they fold through each other
    shared = np.array([[0, 0, 0], [2, 0, 0], [0, 2, 0], [1, 1, -1], [1, 1, 1]], np.float64)
    assert self_intersections(Mesh(shared, [[0, 1, 2], [0, 3, 4]])) == 0
    # touching at a point (no crossing) is not counted
    touch = np.array([[0, 0, 0], [2, 0, 0], [0, 2, 0], [0.5, 0.5, 0], [0.5, 0.5, 1], [1.5, 1.5, 1]], np.float64)
    assert self_intersections(Mesh(touch, [[0, 1, 2], [3, 4, 5]])) == 0


def test_self_intersections_with_degenerate_faces_stay_finite():
    """A zero-area (collinear) face whose edge pierces a triangle counts once; no NaN, no crash."""
    v = np.array([[0, 0, 0], [2, 0, 0], [0, 2, 0], [0.5, 0.5, -1], [0.5, 0.5, 0], [0.5, 0.5, 1]], np.float64)
    assert self_intersections(Mesh(v, [[0, 1, 2], [3, 4, 5]])) == 1
    point = np.array([[0, 0, 0], [2, 0, 0], [0, 2, 0], [0.5, 0.5, 1], [0.5, 0.5, 1], [0.5, 0.5, 1]], np.float64)
    assert self_intersections(Mesh(point, [[0, 1, 2], [3, 4, 5]])) == 0
    st = mesh_stats(Mesh(v, [[0, 1, 2], [3, 4, 5]]))
    assert np.isfinite(st["area"]) and st["watertight"] is False


@pytest.mark.parametrize("scale", [1e-6, 1.0, 1e6])
def test_self_intersections_of_overlapping_spheres_match_brute_force(scale):
    a = icosphere(1)
    v = np.concatenate([a.vertices, a.vertices + np.array([0.3, 0.05, 0.02], np.float32)]) * scale
    mesh = Mesh(v, np.concatenate([a.faces, a.faces + a.num_vertices]))
    brute = candidate_pairs_bruteforce(mesh)
    fast = candidate_pairs(mesh)
    np.testing.assert_array_equal(fast, brute[np.lexsort((brute[:, 1], brute[:, 0]))])
    tri = mesh.vertices.astype(np.float64)[mesh.faces]
    loop_count = sum(bool(triangles_intersect(tri[[i]], tri[[j]])[0]) for i, j in brute)  # slow pairwise reference
    count = self_intersections(mesh)
    assert count == loop_count and count > 0


def test_candidate_pairs_match_brute_force_on_a_crumpled_mesh():
    # random vertex jitter on a fine sphere: boxes of every size and many overlaps, no pair listed twice
    rng = np.random.default_rng(3)
    m = icosphere(3)
    mesh = Mesh(m.vertices + rng.normal(0.0, 0.08, m.vertices.shape).astype(np.float32), m.faces)
    brute = candidate_pairs_bruteforce(mesh)
    np.testing.assert_array_equal(candidate_pairs(mesh), brute[np.lexsort((brute[:, 1], brute[:, 0]))])


@pytest.mark.parametrize("eps", [0.0, 0.05])
def test_triangles_intersect_early_out_agrees_with_the_edge_test(eps):
    # the plane-side early out and the straddle filter must not change an answer: against the definition (an
    # edge of one crosses the other) evaluated on every pair, on random pairs of which a good share cross, and
    # with a tolerance that decides some of them; edge-on pairs (a corner in the other's plane) included
    from engine.postprocess import _segment_crosses_triangle

    rng = np.random.default_rng(0)
    t1 = rng.normal(size=(4000, 3, 3))
    t2 = t1[:, [1, 2, 0]] * 0.5 + rng.normal(scale=0.6, size=(4000, 3, 3))
    t2[:500, 0] = t1[:500, 0] + 0.3 * (t1[:500, 1] - t1[:500, 0]) + 0.2 * (t1[:500, 2] - t1[:500, 0])  # in t1's plane
    ref = np.zeros(4000, bool)
    for s, t in ((t1, t2), (t2, t1)):
        for i, j in ((0, 1), (1, 2), (2, 0)):
            ref |= _segment_crosses_triangle(s[:, i], s[:, j], t[:, 0], t[:, 1], t[:, 2], eps)
    got = triangles_intersect(t1, t2, eps)
    assert 0.1 < ref.mean() < 0.9
    np.testing.assert_array_equal(got, ref)


def test_mesh_stats_on_closed_and_open_meshes():
    m = icosphere(2)
    st = mesh_stats(m)
    ref = _reference(m)
    assert st["watertight"] and st["winding_consistent"] and st["self_intersections"] == 0
    assert st["area"] == pytest.approx(ref.area, rel=1e-9) and st["volume"] == pytest.approx(ref.volume, rel=1e-9)
    open_mesh = Mesh(m.vertices, m.faces[1:])
    assert not mesh_stats(open_mesh)["watertight"] and mesh_stats(open_mesh)["volume"] is None
    flipped = Mesh(m.vertices, np.concatenate([m.faces[:1, ::-1], m.faces[1:]]))
    assert not mesh_stats(flipped)["winding_consistent"]


def test_atomic_writes_get_ordinary_permissions(tmp_path):
    import os
    import stat

    from engine.fileio import atomic_write_bytes

    old = os.umask(0o022)
    os.umask(old)
    new = tmp_path / "new.bin"
    atomic_write_bytes(new, b"x")
    assert stat.S_IMODE(new.stat().st_mode) == 0o666 & ~old  # as open() would, not mkstemp's 0o600
    kept = tmp_path / "kept.bin"
    kept.write_bytes(b"old")
    kept.chmod(0o640)
    atomic_write_bytes(kept, b"new")
    assert stat.S_IMODE(kept.stat().st_mode) == 0o640 and kept.read_bytes() == b"new"


def test_staged_writes_are_all_or_nothing(tmp_path):
    from engine.fileio import StagedWrites

    keep = tmp_path / "keep.obj"
    keep.write_text("old")
    (tmp_path / "afile").write_text("x")
    with pytest.raises(OSError) as exc:
        with StagedWrites() as staged:
            staged.add(keep, "new")
            staged.add(tmp_path / "deep" / "er" / "n.png", b"png")
            staged.add(tmp_path / "afile" / "r.json", "{}")  # a parent that is a file
    assert exc.value.filename == str(tmp_path / "afile" / "r.json") and "afile is a file" in exc.value.strerror
    assert keep.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile", "keep.obj"]  # no temporaries, no new folders
    with StagedWrites() as staged:
        staged.add(keep, "new")
        staged.add(tmp_path / "deep" / "n.png", b"png")
    assert keep.read_text() == "new" and (tmp_path / "deep" / "n.png").read_bytes() == b"png"


def test_atomic_write_errors_name_the_target_not_a_temporary_file(tmp_path):
    from engine.fileio import atomic_write_text, remove_stale_temporaries

    (tmp_path / "afile").write_text("x")
    with pytest.raises(NotADirectoryError) as exc:
        atomic_write_text(tmp_path / "afile" / "sub" / "e.json", "{}")
    assert exc.value.filename == str(tmp_path / "afile" / "sub" / "e.json") and ".tmp" not in str(exc.value)
    (tmp_path / ".e.json.abc123.tmp").write_text("half")
    (tmp_path / ".other.tmp").write_text("not ours")
    assert [p.name for p in remove_stale_temporaries(tmp_path, "e.json")] == [".e.json.abc123.tmp"]
    assert (tmp_path / ".other.tmp").exists()
