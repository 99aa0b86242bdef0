"""ONNX model loading and validation against :mod:`engine.contract`.

Nothing is loaded at import time. :func:`load_generator`, :func:`load_predictor` and :func:`load_router` create an
onnxruntime session (CPU, ``intra_op_num_threads`` = physical cores or ``SKETCHMESH_THREADS``,
one inter-op thread, spinning off) and check, once, the input/output names, ranks and static dimensions and the
required metadata. Every problem is an :class:`engine.errors.ModelError` naming the file and
what was wrong.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass, field
from pathlib import Path

from engine import contract as C
from engine.cliutil import int_from_env
from engine.errors import ModelError
from engine.icosphere import TEMPLATE_RADIUS, level_for_vertex_count

MAX_DEFAULT_THREADS = 8
"""Cap on the default intra-op thread count (more threads than this rarely pays at batch 1)."""

HOW_TO_GET_MODELS = (
    "pass --models DIR with a folder holding generator.onnx and mesh_predictor.onnx, "
    "or train them with `sketchmesh train` and `sketchmesh export`"
)


def physical_cores() -> int:
    """Estimate the physical cores available to this process (hyper-threads counted once).

    Uses the CPU affinity mask and, on Linux, the sysfs topology (package, core) of each allowed
    CPU; falls back to the logical count. Always >= 1.
    """
    try:
        allowed = sorted(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)
    cores = set()
    for cpu in allowed:
        base = Path(f"/sys/devices/system/cpu/cpu{cpu}/topology")
        try:
            cores.add((base.joinpath("physical_package_id").read_text().strip(), base.joinpath("core_id").read_text().strip()))
        except OSError:
            return max(1, len(allowed))
    return max(1, len(cores))


THREADS_ENV = "SKETCHMESH_THREADS"
"""Environment variable that sets :func:`default_threads` (a whole number of threads, 1 to MAX_THREADS_ENV)."""
MAX_THREADS_ENV = 256


def default_threads() -> int:
    """intra-op threads used when the caller gives none: physical cores, capped at MAX_DEFAULT_THREADS,
    unless ``SKETCHMESH_THREADS`` names a count (the app and every command that takes no ``--threads``).

    Raises:
        SketchmeshError: ``SKETCHMESH_THREADS`` is set but not a whole number from 1 to MAX_THREADS_ENV.
    """
    chosen = int_from_env(THREADS_ENV, 1, MAX_THREADS_ENV, " (threads)")
    return chosen if chosen is not None else max(1, min(physical_cores(), MAX_DEFAULT_THREADS))


def resolve_models_dir(models_dir: str | os.PathLike | None) -> Path:
    """The model folder to use: ``models_dir`` if given (it replaces the bundled one), else assets.MODELS_DIR."""
    if models_dir is None:
        try:
            from assets import MODELS_DIR
        except ModuleNotFoundError as exc:  # an editable install made before assets/ became a package
            if exc.name != "assets":
                raise
            return Path(__file__).resolve().parents[1] / "assets" / "models"
        return Path(MODELS_DIR)
    return Path(models_dir).expanduser()


def model_paths(models_dir: Path) -> tuple[Path, Path]:
    """(generator path, predictor path) in a folder, checking that the folder and files exist.

    Raises:
        ModelError: the folder or a file is missing, with what to do about it.
    """
    if not models_dir.exists():
        raise ModelError(f"model folder {models_dir} does not exist; {HOW_TO_GET_MODELS}")
    if not models_dir.is_dir():
        raise ModelError(f"model folder {models_dir} is not a folder; {HOW_TO_GET_MODELS}")
    paths = models_dir / C.GENERATOR_FILE, models_dir / C.PREDICTOR_FILE
    missing = [p.name for p in paths if not p.is_file()]
    if missing:
        raise ModelError(f"no {' or '.join(missing)} in {models_dir}; {HOW_TO_GET_MODELS}")
    return paths


@dataclass
class LoadedModel:
    """An onnxruntime session that passed validation.

    Attributes:
        path: the .onnx file.
        role: ``"generator"``, ``"mesh_predictor"`` or ``"router"``.
        session: the onnxruntime.InferenceSession.
        metadata: the model's metadata_props.
        input_name: the single input's name.
        output_names: output names in the contract's order.
        template_level: icosphere level (predictor only, else None).
        template_radius: template radius (predictor only, else None).
        categories: the router's output order (router only, else None).
        routes: specialist file name -> its categories (router only, else None).
        route_threshold: summed probability above which a drawing goes to a specialist (router only).
        route_mirror: whether, with mirror averaging on, the drawing is routed on the mean of its and its flip's
            probabilities (router only; False when the metadata has no ``route_mirror``).
    """

    path: Path
    role: str
    session: object
    metadata: dict[str, str]
    input_name: str
    output_names: list[str]
    template_level: int | None = None
    template_radius: float | None = None
    categories: list[str] | None = None
    routes: dict[str, list[str]] | None = None
    route_threshold: float | None = None
    route_mirror: bool = False
    input_shapes: dict[str, list] = field(default_factory=dict)
    output_shapes: dict[str, list] = field(default_factory=dict)

    @property
    def batch_dynamic(self) -> bool:
        """Whether the input's batch dimension is dynamic (a model may fix it at 1: then it runs one row at a time)."""
        dims = self.input_shapes.get(self.input_name)
        return bool(dims) and not isinstance(dims[0], int)

    def info(self) -> dict:
        """JSON-ready description: path, role, metadata, shapes, template, file size."""
        return {
            "path": str(self.path),
            "role": self.role,
            "metadata": dict(self.metadata),
            "inputs": {k: [d if isinstance(d, int) else str(d) for d in v] for k, v in self.input_shapes.items()},
            "outputs": {k: [d if isinstance(d, int) else str(d) for d in v] for k, v in self.output_shapes.items()},
            "template_level": self.template_level,
            "template_radius": self.template_radius,
            **({"categories": list(self.categories), "routes": {k: list(v) for k, v in self.routes.items()},
                "route_threshold": self.route_threshold, "route_mirror": self.route_mirror}
               if self.role == C.ROLE_ROUTER else {}),
            "file_bytes": self.path.stat().st_size if self.path.exists() else None,
        }


def _session_options(threads: int):
    import onnxruntime as ort

    so = ort.SessionOptions()
    so.intra_op_num_threads = int(threads)
    so.inter_op_num_threads = 1
    so.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    so.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
    so.add_session_config_entry("session.intra_op.allow_spinning", "0")
    so.add_session_config_entry("session.inter_op.allow_spinning", "0")
    so.log_severity_level = 3  # errors only: warnings would break the CLI's one-line messages
    return so


def _open_session(path: Path, threads: int):
    import onnxruntime as ort

    if not path.is_file():
        raise ModelError(f"{path}: no such model file; {HOW_TO_GET_MODELS}")
    try:
        ort.set_default_logger_severity(3)
        return ort.InferenceSession(str(path), sess_options=_session_options(threads), providers=["CPUExecutionProvider"])
    except Exception as exc:  # onnxruntime raises several private exception types
        detail = " ".join(str(exc).split())
        if "Protobuf parsing failed" in detail or "INVALID_PROTOBUF" in detail:
            detail = "not a valid ONNX file (protobuf parsing failed)"
        raise ModelError(f"{path}: cannot load model: {detail[:300]}") from None


def _dims(shape) -> list:
    return [d if isinstance(d, int) else (d or "?") for d in shape]


def _check_static(path: Path, what: str, got: list, want: list) -> None:
    """``want`` holds ints (must match when ``got`` is static) or None (any). Rank must match."""
    if len(got) != len(want):
        raise ModelError(f"{path}: {what} must have rank {len(want)} {tuple(d if d is not None else 'N' for d in want)}, got shape {got}")
    for k, (g, w) in enumerate(zip(got, want)):
        if w is not None and isinstance(g, int) and g != w:
            raise ModelError(
                f"{path}: {what} dimension {k} must be {w} (expected {tuple(d if d is not None else 'N' for d in want)}), got shape {got}"
            )
        if k == 0 and isinstance(g, int) and g != 1:
            raise ModelError(f"{path}: {what} batch dimension must be dynamic or 1, got shape {got}")


def _check_metadata(path: Path, meta: dict[str, str], role: str) -> None:
    missing = [k for k in C.REQUIRED_METADATA if k not in meta]
    if missing:
        raise ModelError(f"{path}: model metadata lacks {', '.join(missing)} (not exported by `sketchmesh export`?)")
    if meta[C.META_ROLE] != role:
        raise ModelError(f"{path}: model role is {meta[C.META_ROLE]!r}, expected {role!r} (files swapped?)")
    if meta[C.META_FORMAT] != C.FORMAT_VERSION:
        raise ModelError(f"{path}: model format {meta[C.META_FORMAT]!r} is not this engine's format {C.FORMAT_VERSION!r}; re-export it")
    if meta[C.META_CONVENTIONS] != C.CONVENTIONS_ID:
        raise ModelError(
            f"{path}: model conventions {meta[C.META_CONVENTIONS]!r} differ from the engine's {C.CONVENTIONS_ID!r}; re-export it"
        )


def _io(session, path: Path) -> tuple[dict[str, list], dict[str, list]]:
    """Input and output shapes by name; every tensor must be float32 (the contract's NCHW float32)."""
    for kind, args in (("input", session.get_inputs()), ("output", session.get_outputs())):
        for a in args:
            if a.type != "tensor(float)":
                raise ModelError(f"{path}: {kind} {a.name!r} must be float32 (tensor(float)), got {a.type}")
    ins = {i.name: _dims(i.shape) for i in session.get_inputs()}
    outs = {o.name: _dims(o.shape) for o in session.get_outputs()}
    return ins, outs


def _check_names(path: Path, kind: str, got: dict, want: list[str]) -> None:
    if sorted(got) != sorted(want):
        raise ModelError(f"{path}: model {kind}s must be {want}, got {list(got)}")


def load_generator(path: str | os.PathLike, threads: int | None = None) -> LoadedModel:
    """Load and validate ``generator.onnx``: ``sketch`` (N, 1, 256, 256) -> ``normals`` (N, 3, 256, 256).

    Raises:
        ModelError: missing/corrupt file, wrong names, ranks, static dims or metadata.
    """
    path = Path(path)
    sess = _open_session(path, threads or default_threads())
    meta = dict(sess.get_modelmeta().custom_metadata_map)
    _check_metadata(path, meta, C.ROLE_GENERATOR)
    ins, outs = _io(sess, path)
    _check_names(path, "input", ins, [C.GENERATOR_INPUT])
    _check_names(path, "output", outs, [C.GENERATOR_OUTPUT])
    s = C.SKETCH_SIZE
    _check_static(path, f"input {C.GENERATOR_INPUT!r}", ins[C.GENERATOR_INPUT], [None, 1, s, s])
    _check_static(path, f"output {C.GENERATOR_OUTPUT!r}", outs[C.GENERATOR_OUTPUT], [None, 3, s, s])
    return LoadedModel(path, C.ROLE_GENERATOR, sess, meta, C.GENERATOR_INPUT, [C.GENERATOR_OUTPUT], input_shapes=ins, output_shapes=outs)


def file_sha256(path: Path) -> str:
    """Hex SHA-256 of a file's bytes (a generator's identity for the int8 file made from it)."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def load_runtime_generator(models_dir: Path, threads: int | None = None) -> LoadedModel:
    """The generator the engine runs from a folder: ``generator_int8.onnx`` when the folder has one (checked to be
    made from the folder's ``generator.onnx``: its ``source_sha256``), else ``generator.onnx``.

    Raises:
        ModelError: a missing folder or file, a model that fails validation, or an int8 file made from another
        generator (stale: remake or delete it).
    """
    gen, _ = model_paths(models_dir)
    fast = models_dir / C.GENERATOR_INT8_FILE
    if not fast.is_file():
        return load_generator(gen, threads)
    model = load_generator(fast, threads)
    want, have = model.metadata.get(C.META_SOURCE_SHA256, ""), file_sha256(gen)
    if want != have:
        raise ModelError(f"{fast} was not made from {gen} (its {C.META_SOURCE_SHA256} is {want[:12] or 'missing'}, "
                         f"the file's {have[:12]}): remake it with `sketchmesh quantize-generator {models_dir} --data "
                         "DATASET` or delete it to run the float generator")
    return model


def load_predictor(path: str | os.PathLike, threads: int | None = None) -> LoadedModel:
    """Load and validate ``mesh_predictor.onnx``: ``normals`` (N, 3, 64, 64) -> ``local_offset``
    (N, V, 3), ``global_offset`` (N, 3), with V the vertex count of the ``template_level`` icosphere.

    Raises:
        ModelError: missing/corrupt file, wrong names, ranks, static dims or metadata, or a V that
        does not match ``template_level``.
    """
    path = Path(path)
    sess = _open_session(path, threads or default_threads())
    meta = dict(sess.get_modelmeta().custom_metadata_map)
    _check_metadata(path, meta, C.ROLE_PREDICTOR)
    if C.META_TEMPLATE_LEVEL not in meta:
        raise ModelError(f"{path}: mesh predictor metadata lacks {C.META_TEMPLATE_LEVEL!r}")
    try:
        level = int(meta[C.META_TEMPLATE_LEVEL])
        radius = float(meta.get(C.META_TEMPLATE_RADIUS, repr(TEMPLATE_RADIUS)))
    except ValueError:
        raise ModelError(
            f"{path}: bad template metadata (level {meta.get(C.META_TEMPLATE_LEVEL)!r}, radius {meta.get(C.META_TEMPLATE_RADIUS)!r})"
        ) from None
    if not 0 <= level <= 6 or not (radius > 0 and radius < float("inf")):
        raise ModelError(f"{path}: template level must be 0..6 and radius finite > 0, got {level} and {radius}")
    ins, outs = _io(sess, path)
    _check_names(path, "input", ins, [C.PREDICTOR_INPUT])
    _check_names(path, "output", outs, [C.PREDICTOR_OUTPUT_LOCAL, C.PREDICTOR_OUTPUT_GLOBAL])
    s = C.PREDICTOR_INPUT_SIZE
    V = 10 * 4**level + 2
    _check_static(path, f"input {C.PREDICTOR_INPUT!r}", ins[C.PREDICTOR_INPUT], [None, 3, s, s])
    _check_static(path, f"output {C.PREDICTOR_OUTPUT_LOCAL!r}", outs[C.PREDICTOR_OUTPUT_LOCAL], [None, None, 3])
    _check_static(path, f"output {C.PREDICTOR_OUTPUT_GLOBAL!r}", outs[C.PREDICTOR_OUTPUT_GLOBAL], [None, 3])
    v_dim = outs[C.PREDICTOR_OUTPUT_LOCAL][1]
    if isinstance(v_dim, int):
        try:
            out_level = level_for_vertex_count(v_dim)
        except ValueError as exc:
            raise ModelError(f"{path}: {exc}") from None
        if out_level != level:
            raise ModelError(
                f"{path}: metadata template_level {level} ({V} vertices) does not match the output's {v_dim} vertices (level {out_level})"
            )
    return LoadedModel(
        path, C.ROLE_PREDICTOR, sess, meta, C.PREDICTOR_INPUT, [C.PREDICTOR_OUTPUT_LOCAL, C.PREDICTOR_OUTPUT_GLOBAL],
        template_level=level, template_radius=radius, input_shapes=ins, output_shapes=outs,
    )


def router_path(models_dir: Path) -> Path | None:
    """``router.onnx`` in a model folder, or None when the folder routes nothing."""
    p = Path(models_dir) / C.ROUTER_FILE
    return p if p.is_file() else None


def _json_meta(path: Path, meta: dict[str, str], key: str):
    if key not in meta:
        raise ModelError(f"{path}: router metadata lacks {key!r}")
    try:
        return json.loads(meta[key])
    except ValueError:
        raise ModelError(f"{path}: router metadata {key!r} is not JSON: {meta[key][:80]!r}") from None


def is_specialist_file_name(name) -> bool:
    """Whether a router may send drawings to ``name``: a bare ``.onnx`` file name in the model folder, not one of the
    folder's own networks (generator, general predictor, router)."""
    return (isinstance(name, str) and Path(name).name == name and name.endswith(".onnx")
            and name not in (C.GENERATOR_FILE, C.PREDICTOR_FILE, C.ROUTER_FILE))


def load_router(path: str | os.PathLike, threads: int | None = None) -> LoadedModel:
    """Load and validate ``router.onnx``: ``normals`` (N, 3, 64, 64) -> ``probabilities`` (N, K), with its
    ``categories``, ``routes``, ``route_threshold`` and optional ``route_mirror`` metadata (:mod:`engine.contract`). Every specialist
    file it names must be in the same folder (it is loaded only when a drawing is routed to it).

    Raises:
        ModelError: missing/corrupt file, wrong names, ranks or metadata, or a specialist file that is missing.
    """
    path = Path(path)
    sess = _open_session(path, threads or default_threads())
    meta = dict(sess.get_modelmeta().custom_metadata_map)
    _check_metadata(path, meta, C.ROLE_ROUTER)
    cats = _json_meta(path, meta, C.META_CATEGORIES)
    if (not isinstance(cats, list) or len(cats) < 2 or not all(isinstance(c, str) and c for c in cats)
            or len(set(cats)) != len(cats)):
        raise ModelError(f"{path}: router categories must be a list of two or more distinct names, got {cats!r}")
    routes = _json_meta(path, meta, C.META_ROUTES)
    if not isinstance(routes, dict) or not routes:
        raise ModelError(f"{path}: router routes must name at least one specialist file, got {routes!r}")
    seen: set = set()
    for name, group in routes.items():
        if not is_specialist_file_name(name):
            raise ModelError(f"{path}: router route {name!r} must be another .onnx file name in the same folder")
        if (not isinstance(group, list) or not group or not all(isinstance(c, str) and c in cats for c in group)
                or len(set(group)) != len(group) or seen & set(group)):
            raise ModelError(f"{path}: route {name!r} must list categories of the router's, each in one route; "
                             f"got {group!r}")
        seen |= set(group)
        if not (path.parent / name).is_file():
            raise ModelError(f"{path}: the router sends drawings to {name}, which is not in {path.parent}")
    try:
        threshold = float(meta.get(C.META_ROUTE_THRESHOLD, ""))
    except ValueError:
        threshold = float("nan")
    if not 0.0 < threshold < 1.0:
        raise ModelError(f"{path}: router metadata {C.META_ROUTE_THRESHOLD!r} must be a number in (0, 1), "
                         f"got {meta.get(C.META_ROUTE_THRESHOLD)!r}")
    mirror = meta.get(C.META_ROUTE_MIRROR, "false").strip()
    if mirror not in ("true", "false"):
        raise ModelError(f"{path}: router metadata {C.META_ROUTE_MIRROR!r} must be true or false, got {mirror[:80]!r}")
    ins, outs = _io(sess, path)
    _check_names(path, "input", ins, [C.ROUTER_INPUT])
    _check_names(path, "output", outs, [C.ROUTER_OUTPUT])
    s = C.PREDICTOR_INPUT_SIZE
    _check_static(path, f"input {C.ROUTER_INPUT!r}", ins[C.ROUTER_INPUT], [None, 3, s, s])
    _check_static(path, f"output {C.ROUTER_OUTPUT!r}", outs[C.ROUTER_OUTPUT], [None, len(cats)])
    return LoadedModel(path, C.ROLE_ROUTER, sess, meta, C.ROUTER_INPUT, [C.ROUTER_OUTPUT], categories=list(cats),
                       routes={k: list(v) for k, v in routes.items()}, route_threshold=threshold,
                       route_mirror=mirror == "true",
                       input_shapes=ins, output_shapes=outs)
