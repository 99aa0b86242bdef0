"""The ONNX boundary between ``training`` (which exports) and ``engine`` (which runs).

Both sides import these names; the exporter writes the metadata, the engine checks it
on load. Image conventions are in :mod:`engine.camera`.

Generator (``generator.onnx``)
    input  ``sketch``  (N, 1, 256, 256) float32 in [0, 1], 1 = ink (a framed sketch).
    output ``normals`` (N, 3, 256, 256) float32 in [0, 1], the encoded normal image
           ((n + 1) / 2, background 0).

Mesh predictor (``mesh_predictor.onnx``)
    input  ``normals`` (N, 3, 64, 64) float32 in [0, 1] (the generator output, area-downsampled).
    outputs ``local_offset`` (N, V, 3) and ``global_offset`` (N, 3) float32; the mesh in the
           view frame is ``template_vertices + local_offset + global_offset[:, None]``.

Router (``router.onnx``, optional)
    input  ``normals`` (N, 3, 64, 64) as the mesh predictor's; output ``probabilities`` (N, K) float32,
           a softmax over the ``categories`` of its metadata (a JSON list of K names). Its metadata
           ``routes`` (a JSON object: specialist file name -> list of categories) names other mesh
           predictors in the same folder, and ``route_threshold`` (a float in (0, 1)): a drawing goes to
           the specialist whose categories' summed probability is largest and above the threshold, every
           other drawing to ``mesh_predictor.onnx``. Optional ``route_mirror`` (JSON ``true`` or ``false``,
           absent = false): with the engine's mirror averaging on, the router reads the drawing and its
           left-right flip and routes on their mean probabilities (else on the plain drawing's alone).
           A folder without ``router.onnx`` routes nothing.

Metadata (``metadata_props`` of each model, all strings)
    ``sketchmesh_format`` (= FORMAT_VERSION), ``sketchmesh_role`` ("generator" or
    "mesh_predictor"), ``code_version``, ``config`` (JSON of the resolved training config),
    ``conventions`` (= CONVENTIONS_ID); the mesh predictor also carries
    ``template_level`` (e.g. "3") and ``template_radius``; the generator carries
    ``base_channels`` and ``generator_arch`` ("resize" or "pix2pix"; absent from exports that
    predate the option, which are "pix2pix"). ``quantization`` ("none", "int8-dynamic", "fp16-weights", "int8-weights" or
    "int8-static") is optional.
    The engine only reads the required keys and the predictor's template: the others describe the
    model (the graph itself is what runs) and may be absent.
"""

from __future__ import annotations

FORMAT_VERSION = "1"
CONVENTIONS_ID = "sketchmesh-conventions-1"

GENERATOR_FILE = "generator.onnx"
PREDICTOR_FILE = "mesh_predictor.onnx"
ROUTER_FILE = "router.onnx"
GENERATOR_INT8_FILE = "generator_int8.onnx"
"""Optional, beside ``generator.onnx``: the same generator with its convolutions in int8 and their inputs quantised
with ranges calibrated on training sketches (:func:`engine.bench.static_int8_generator`). When a folder has it, the
engine runs it in place of ``generator.onnx`` (which stays what training imports); its ``source_sha256`` must be the
float file's, so a stale file is an error, never a silent mismatch."""

SKETCH_SIZE = 256
PREDICTOR_INPUT_SIZE = 64

GENERATOR_INPUT = "sketch"
GENERATOR_OUTPUT = "normals"
PREDICTOR_INPUT = "normals"
PREDICTOR_OUTPUT_LOCAL = "local_offset"
PREDICTOR_OUTPUT_GLOBAL = "global_offset"
ROUTER_INPUT = "normals"
ROUTER_OUTPUT = "probabilities"

ROLE_GENERATOR = "generator"
ROLE_PREDICTOR = "mesh_predictor"
ROLE_ROUTER = "router"

META_FORMAT = "sketchmesh_format"
META_ROLE = "sketchmesh_role"
META_CODE_VERSION = "code_version"
META_CONFIG = "config"
META_CONVENTIONS = "conventions"
META_TEMPLATE_LEVEL = "template_level"
META_TEMPLATE_RADIUS = "template_radius"
META_BASE_CHANNELS = "base_channels"
META_GENERATOR_ARCH = "generator_arch"
META_QUANTIZATION = "quantization"
META_CATEGORIES = "categories"
META_ROUTES = "routes"
META_ROUTE_THRESHOLD = "route_threshold"
META_ROUTE_MIRROR = "route_mirror"
META_SOURCE_SHA256 = "source_sha256"
PRECISION_VARIANTS = ("fp32", "int8-predictor", "int8", "int8w")
"""How a model folder can be run: as exported, with the predictor dynamically quantised to int8,
with both networks quantised, or with every network's large weights stored in int8 and computed in
float32 (``sketchmesh bench engine`` / ``bench tradeoff``)."""
MIRROR_SUFFIX = "+mirror"
MIRRORED_VARIANTS = (*PRECISION_VARIANTS, *(v + MIRROR_SUFFIX for v in PRECISION_VARIANTS))
"""Every variant name the benches take: a precision, optionally with the engine's mirror averaging on."""

REQUIRED_METADATA = (META_FORMAT, META_ROLE, META_CODE_VERSION, META_CONVENTIONS)

# ---- sketch raster style, shared by the data generator and the engine's preprocessing ----
SKETCH_STROKE_WIDTH_PX = 2.0
"""Normalised stroke width (pixels at 256x256) of the generator's input. The data generator
draws clean line drawings at this width; the engine thins a user's strokes to one pixel and
redraws them at this width, so both look alike to the generator."""

SKETCH_INK_THRESHOLD = 0.5
"""Ink coverage (after polarity normalisation, 1 = ink) above which a pixel counts as a stroke."""
