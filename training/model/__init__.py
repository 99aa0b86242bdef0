"""The model: the paper's two networks and the mesh predictor's losses (torch).

Modules:
    networks -- NormalGenerator (pix2pix U-Net), PatchDiscriminator, MeshPredictor and the
                generator's losses (paper sections 3.2, 3.3, 4.1)
    losses   -- the mesh predictor's losses, paper Eq. 2-6, as pure functions plus MeshLoss

Import the submodules directly; importing this package loads nothing heavy.
"""
