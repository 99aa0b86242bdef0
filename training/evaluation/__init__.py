"""Evaluation and reports: how good a trained run or an exported model folder is.

Modules:
    metrics  -- voxel IoU, Chamfer-L1, normal consistency, silhouette IoU (numpy + scipy, no torch)
    evaluate -- ``sketchmesh eval``: the paper's Table 1 on the test split, with baselines
    models_eval -- ``sketchmesh eval --models DIR``: exported ONNX models on any dataset (e.g. your own
                meshes), per-mesh voxel IoU beside the retrieval and template-sphere floors
    tradeoff -- ``sketchmesh bench tradeoff``: accuracy against latency of exported ONNX variants
    gallery  -- ``sketchmesh gallery``: a picture of sketches, normals and meshes
    variety  -- how varied a shape library is: held-out shapes' nearest-train voxel IoU (nearest_train_iou)

Import the submodules directly; importing this package loads nothing heavy.
"""
