"""Evaluation and reports: how good a trained run or an exported model folder is.

Modules:
    metrics  -- voxel IoU, Chamfer-L1, normal consistency, silhouette IoU (numpy + scipy, no torch)
    evaluate -- ``sketchmesh eval``: the paper's Table 1 on the test split, with baselines
    tradeoff -- ``sketchmesh bench tradeoff``: accuracy against latency of exported ONNX variants
    gallery  -- ``sketchmesh gallery``: a picture of sketches, normals and meshes

Import the submodules directly; importing this package loads nothing heavy.
"""
