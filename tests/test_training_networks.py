"""Networks, generator losses, Sobel sampling, camera batching, config: against hand-computed values."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from engine.camera import Camera, frame_camera, look_at, relative_camera  # noqa: E402
from engine.icosphere import icosphere  # noqa: E402
from training.loop.config import TrainConfig  # noqa: E402
from training.model.networks import (  # noqa: E402
    CompactMeshPredictor,
    MeshPredictor,
    NormalGenerator,
    PatchDiscriminator,
    adversarial_loss,
    basis_times,
    build_predictor,
    combinatorial_laplacian,
    downsample_normals,
    framed_ndc,
    global_l1_loss,
    laplacian_basis,
    local_l1_loss,
    sample_bilinear,
    sample_channels,
    sample_edge_pixels,
    smoothing_operator,
    sobel_magnitude,
    view_frame_cameras,
)

torch.set_num_threads(2)


def n_params(m: torch.nn.Module) -> int:
    return sum(p.numel() for p in m.parameters())


# ---------------------------------------------------------------------------- generator


def test_generator_parameter_count_matches_hand_count():
    # base 4: encoder channels 4, 8, 16, 32, 32, 32, 32, 32; 4x4 kernels (16 weights per in/out pair);
    # biases only on the first and innermost encoder convs and on the output conv (InstanceNorm elsewhere).
    down = (16 * 1 * 4 + 4) + 16 * 4 * 8 + 16 * 8 * 16 + 16 * 16 * 32 + 3 * 16 * 32 * 32 + (16 * 32 * 32 + 32)
    up = 16 * 32 * 32 + 3 * (16 * 64 * 32) + 16 * 64 * 16 + 16 * 32 * 8 + 16 * 16 * 4 + (16 * 8 * 3 + 3)
    assert down + up == 212967
    assert n_params(NormalGenerator(4, arch="pix2pix")) == 212967  # the bundled models' layers, unchanged
    # resize: the same encoder (reflect padding has no parameters); decoder 3x3 convs (9 weights per pair),
    # except the innermost, a 1x1 conv with a bias (it sees the 1x1 code broadcast to 2x2, no InstanceNorm)
    up_resize = (32 * 32 + 32) + 3 * (9 * 64 * 32) + 9 * 64 * 16 + 9 * 32 * 8 + 9 * 16 * 4 + (9 * 8 * 3 + 3)
    assert down == 76388 and up_resize == 68667
    assert n_params(NormalGenerator(4, arch="resize")) == down + up_resize == 145055
    assert n_params(NormalGenerator(4)) == 145055  # resize is the default


@pytest.mark.parametrize("arch", ["resize", "pix2pix"])
def test_generator_output_shape_and_range(arch):
    g = NormalGenerator(4, arch=arch).eval()
    assert g.arch == arch and g.base_channels == 4
    x = (torch.rand(2, 1, 256, 256) > 0.95).float()
    with torch.no_grad():
        y = g(x)
    assert y.shape == (2, 3, 256, 256)
    assert torch.isfinite(y).all() and y.min() >= 0 and y.max() <= 1
    assert (y.amax(dim=(2, 3)) - y.amin(dim=(2, 3))).min() > 1e-3  # a real sketch: the output varies


@pytest.mark.parametrize("arch", ["resize", "pix2pix"])
def test_generator_eval_output_does_not_depend_on_the_batch(arch):
    """InstanceNorm: a sketch gives the same normals alone (batch 1, the engine) as inside a batch."""
    g = NormalGenerator(4, arch=arch).eval()
    x = torch.rand(3, 1, 256, 256)
    with torch.no_grad():
        together = g(x)
        alone = g(x[1:2])
    assert torch.allclose(together[1:2], alone, atol=1e-5)


@pytest.mark.parametrize("seed", [0, 1])
def test_resize_generator_maps_a_constant_sketch_to_a_constant_image_and_pix2pix_does_not(seed):
    """No positional artefacts: with reflect padding and resize-convolutions every layer maps a spatially
    constant map to a constant one, so a blank (or uniformly grey) sketch gives one colour everywhere.
    The pix2pix layers (zero padding, stride-2 transposed convs) draw a border and a checkerboard."""
    x = torch.cat([torch.zeros(1, 1, 256, 256), torch.full((1, 1, 256, 256), 0.3)])
    torch.manual_seed(seed)
    resize = NormalGenerator(4, arch="resize").eval()
    torch.manual_seed(seed)
    pix2pix = NormalGenerator(4, arch="pix2pix").eval()
    with torch.no_grad():
        y_r, y_p = resize(x), pix2pix(x)
    spread_r = y_r.amax(dim=(2, 3)) - y_r.amin(dim=(2, 3))  # (2 inputs, 3 channels)
    assert spread_r.max() < 1e-5, spread_r
    spread_p = y_p.amax(dim=(2, 3)) - y_p.amin(dim=(2, 3))
    assert spread_p.min() > 1e-3, spread_p  # the check can fail: the old layers are positional
    interior = y_p[:, :, 100:156, 100:156]
    # the right border column differs from the interior, and neighbouring interior pixels differ (checkerboard)
    assert (y_p[:, :, 100:156, -1] - interior[:, :, :, 0]).abs().amax() > 1e-3
    assert (interior[:, :, :, 1:] - interior[:, :, :, :-1]).abs().amax() > 1e-3


def test_generator_rejects_an_unknown_arch():
    with pytest.raises(ValueError, match="arch"):
        NormalGenerator(4, arch="unet")


def test_generator_rejects_bad_input_with_the_shape_it_got():
    g = NormalGenerator(4)
    with pytest.raises(ValueError, match=r"\(2, 3, 256, 256\)"):
        g(torch.zeros(2, 3, 256, 256))
    with pytest.raises(ValueError, match="divisible"):
        g(torch.zeros(1, 1, 200, 200))


# ---------------------------------------------------------------------------- discriminator


def test_patch_discriminator_shape_and_parameter_count():
    d = PatchDiscriminator(4)
    expected = (16 * 4 * 4 + 4) + 16 * 4 * 8 + 16 * 8 * 16 + 16 * 16 * 32 + (16 * 32 * 1 + 1)
    assert n_params(d) == expected == 11525
    out = d(torch.rand(2, 1, 256, 256), torch.rand(2, 3, 256, 256))
    assert out.shape == (2, 1, 30, 30)  # 70x70 receptive fields on a 256 image
    with pytest.raises(ValueError, match="normals"):
        d(torch.rand(2, 1, 256, 256), torch.rand(2, 3, 128, 128))


# ---------------------------------------------------------------------------- mesh predictor


def test_predictor_parameter_count_and_shapes():
    p = MeshPredictor(template_level=2, base_channels=4, hidden=16, latent=8)
    convs = (25 * 3 * 4 + 4) + (25 * 4 * 8 + 8) + (25 * 8 * 16 + 16)
    bns = 2 * (4 + 8 + 16)
    fcs = (16 * 8 * 8 * 16 + 16) + (16 * 16 + 16) + (16 * 8 + 8) + (8 * 16 + 16) + (16 * 32 + 32)
    heads = (32 * 162 * 3 + 162 * 3) + (32 * 3 + 3)
    assert n_params(p) == convs + bns + fcs + heads == 38017
    local, glob = p(torch.rand(2, 3, 64, 64))
    assert local.shape == (2, 162, 3) and glob.shape == (2, 3)
    v = p.vertices(local, glob)
    expected = torch.from_numpy(np.array(icosphere(2).vertices))[None] + local + glob[:, None]
    assert torch.allclose(v, expected)


def test_predictor_starts_near_the_template_and_offsets_stay_bounded():
    p = MeshPredictor(template_level=2, base_channels=4, hidden=16, latent=8)
    p.train()
    local, glob = p(torch.rand(4, 3, 64, 64))
    assert local.abs().max() < 0.05 and glob.abs().max() < 0.05
    with torch.no_grad():  # extreme weights: tanh bounds the offsets, nothing overflows
        for head in (p.local_head, p.global_head):
            head.weight.fill_(1e6)
        local, glob = p(torch.rand(4, 3, 64, 64))
    assert torch.isfinite(local).all() and torch.isfinite(glob).all()
    assert local.abs().max() <= p.local_scale + 1e-6 and glob.abs().max() <= p.global_scale + 1e-6


def test_smoothing_operator_is_a_convex_averaging():
    from training.model.networks import smoothing_operator

    mesh = icosphere(2)
    assert np.array_equal(smoothing_operator(mesh.faces, mesh.num_vertices, 0.0), np.eye(162, dtype=np.float32))
    m = smoothing_operator(mesh.faces, mesh.num_vertices, 16.0).astype(np.float64)
    np.testing.assert_allclose(m.sum(axis=1), 1.0, atol=1e-5)  # L 1 = 0: constants pass unchanged
    np.testing.assert_allclose(m, m.T, atol=1e-6)
    assert m.min() >= -1e-7  # M-matrix inverse: non-negative
    # applying it to the smooth operator's own definition: (I + lam L) m = I
    adj = np.zeros((162, 162))
    f = np.asarray(mesh.faces)
    for a, b in ((0, 1), (1, 2), (2, 0)):
        adj[f[:, a], f[:, b]] = adj[f[:, b], f[:, a]] = 1
    lap = np.diag(adj.sum(1)) - adj
    np.testing.assert_allclose((np.eye(162) + 16.0 * lap) @ m, np.eye(162), atol=1e-4)
    # a one-vertex spike is spread over its neighbourhood: the peak drops, the mean is kept
    spike = np.zeros(162)
    spike[5] = 1.0
    out = m @ spike
    assert out[5] < 0.5 and abs(out.sum() - 1.0) < 1e-5 and np.count_nonzero(out > 1e-3) > 7


def test_predictor_smoothing_keeps_offsets_bounded_and_rejects_bad_values():
    p = MeshPredictor(template_level=2, base_channels=4, hidden=16, latent=8, smoothing=16.0)
    plain = MeshPredictor(template_level=2, base_channels=4, hidden=16, latent=8, smoothing=0.0)
    plain.load_state_dict(p.state_dict())
    x = torch.rand(2, 3, 64, 64)
    p.eval()
    plain.eval()
    with torch.no_grad():
        local_s, glob_s = p(x)
        local_p, glob_p = plain(x)
    torch.testing.assert_close(glob_s, glob_p)
    torch.testing.assert_close(local_s, p.offset_smoother @ local_p)
    with torch.no_grad():
        p.local_head.weight.fill_(1e6)
        local, _ = p(x)
    assert torch.isfinite(local).all() and local.abs().max() <= p.local_scale + 1e-5
    for bad in (-1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="smoothing"):
            MeshPredictor(template_level=2, base_channels=4, hidden=16, latent=8, smoothing=bad)


def test_predictor_clamp_bound_is_linear_inside_and_bounded_outside():
    tanh = MeshPredictor(template_level=2, base_channels=4, hidden=16, latent=8, smoothing=0.0)
    clamp = MeshPredictor(template_level=2, base_channels=4, hidden=16, latent=8, smoothing=0.0, local_bound="clamp")
    clamp.load_state_dict(tanh.state_dict())
    x = torch.rand(2, 3, 64, 64)
    tanh.eval()
    clamp.eval()
    with torch.no_grad():
        raw = tanh.local_head(tanh.decoder(tanh.encoder(x)) * tanh.head_gain).view(2, -1, 3)
        torch.testing.assert_close(clamp(x)[0], clamp.local_scale * raw)  # identity inside the bound
        for m in (tanh, clamp):
            m.local_head.bias.fill_(1e6)
        local_t, local_c = tanh(x)[0], clamp(x)[0]
    assert torch.allclose(local_t, torch.full_like(local_t, tanh.local_scale))
    assert torch.allclose(local_c, torch.full_like(local_c, 2.0 * clamp.local_scale))
    # inside the bound the gradient is the identity's, where tanh's has vanished
    clamp.train()
    with torch.no_grad():
        clamp.local_head.bias.fill_(1.5)
    local, _ = clamp(x)
    local.sum().backward()
    assert clamp.local_head.bias.grad.abs().min() > 0
    with pytest.raises(ValueError, match="local_bound"):
        MeshPredictor(template_level=2, base_channels=4, hidden=16, latent=8, local_bound="sigmoid")


def test_predictor_clamp_after_bounds_the_smoothed_offsets_not_the_raw_ones():
    """clamp-after: offsets are exactly S @ (scale * raw) inside the bound (the smoother's full range
    is reachable) and never beyond +-2 * scale, even for huge raw outputs."""
    p = MeshPredictor(template_level=2, base_channels=4, hidden=16, latent=8, smoothing=16.0, local_bound="clamp-after")
    p.eval()
    x = torch.rand(2, 3, 64, 64)
    with torch.no_grad():
        raw = p.local_head(p.decoder(p.encoder(x)) * p.head_gain).view(2, -1, 3)
        want = p.offset_smoother @ (p.local_scale * raw)
        torch.testing.assert_close(p(x)[0], want)
        # a uniform raw output of 1.9 is a pure translation mode (rows of S sum to 1): kept whole,
        # where the bound-before-smoothing variants cap every mode of the raw output at the bound
        p.local_head.weight.zero_()
        p.local_head.bias.fill_(1.9)
        torch.testing.assert_close(p(x)[0], torch.full((2, p.num_vertices, 3), 1.9 * p.local_scale), rtol=1e-5, atol=1e-5)
        p.local_head.bias.fill_(1e6)
        local = p(x)[0]
    assert torch.isfinite(local).all() and local.abs().max() <= 2.0 * p.local_scale + 1e-6


# ---------------------------------------------------------------------------- generator losses


def test_sobel_magnitude_of_a_unit_step_is_four_beside_the_step():
    img = torch.zeros(1, 1, 8, 8)
    img[..., 4:] = 1.0
    mag = sobel_magnitude(img)[0]
    expected = torch.zeros(8, 8)
    expected[:, 3:5] = 4.0  # (1 + 2 + 1) * (1 - 0) on both sides of the step
    assert torch.allclose(mag, expected, atol=1e-5)
    three = sobel_magnitude(img.expand(1, 3, 8, 8))[0]  # channels add in quadrature
    assert torch.allclose(three, expected * np.sqrt(3.0), atol=1e-5)


def test_sample_edge_pixels_picks_only_edge_pixels_deterministically():
    img = torch.zeros(2, 3, 32, 32)
    img[:, :, 8:24, 8:24] = 0.7  # a square: edges on its border rows/columns
    mag = sobel_magnitude(img)
    edges = set(torch.nonzero(mag[0].reshape(-1) >= 1.0).flatten().tolist())
    assert 0 < len(edges) < 32 * 32 // 4
    g1 = torch.Generator().manual_seed(3)
    idx = sample_edge_pixels(img, 40, 1.0, g1)
    assert idx.shape == (2, 40)
    for row in idx:
        assert set(row.tolist()) <= edges and len(set(row.tolist())) == 40  # no repeats
    again = sample_edge_pixels(img, 40, 1.0, torch.Generator().manual_seed(3))
    other = sample_edge_pixels(img, 40, 1.0, torch.Generator().manual_seed(4))
    assert torch.equal(idx, again) and not torch.equal(idx, other)


def test_sample_edge_pixels_fills_with_the_strongest_when_edges_are_few():
    img = torch.zeros(1, 1, 16, 16)
    img[..., 5, 5] = 1.0  # one bright pixel: Sobel 2 beside it (horizontally/vertically), less diagonally
    mag = sobel_magnitude(img)[0].reshape(-1)
    idx = sample_edge_pixels(img, 20, 1.9, torch.Generator().manual_seed(0))[0]
    strong = set(torch.nonzero(mag >= 1.9).flatten().tolist())
    assert strong <= set(idx.tolist())  # every candidate is taken
    rest = [i for i in idx.tolist() if i not in strong]
    weakest_taken = mag[rest].min()
    not_taken = torch.ones_like(mag, dtype=torch.bool)
    not_taken[idx] = False
    assert weakest_taken >= mag[not_taken].max() - 1e-6  # fillers are the next strongest
    empty = sample_edge_pixels(torch.zeros(1, 3, 16, 16), 5, 0.5)  # no edges at all: still a valid tensor
    assert empty.shape == (1, 5)


def test_local_l1_matches_a_loop_and_global_l1_matches_numpy():
    gen = torch.Generator().manual_seed(0)
    pred, target = torch.rand(2, 3, 8, 8, generator=gen), torch.rand(2, 3, 8, 8, generator=gen)
    idx = torch.tensor([[0, 9, 63], [5, 5, 17]])
    total = 0.0
    for n in range(2):
        for i in idx[n].tolist():
            r, c = divmod(i, 8)
            total += float((pred[n, :, r, c] - target[n, :, r, c]).abs().sum())
    assert local_l1_loss(pred, target, idx).item() == pytest.approx(total / (2 * 3 * 3), rel=1e-6)
    assert global_l1_loss(pred, target).item() == pytest.approx(np.abs(pred.numpy() - target.numpy()).mean(), rel=1e-6)


def test_adversarial_loss_hand_values():
    zeros = torch.zeros(2, 1, 30, 30)
    assert adversarial_loss(zeros, True).item() == pytest.approx(np.log(2.0))
    assert adversarial_loss(zeros, False).item() == pytest.approx(np.log(2.0))
    big = torch.full((1, 1, 2, 2), 50.0)  # saturated logits: finite, about 0 and 50
    assert adversarial_loss(big, True).item() == pytest.approx(0.0, abs=1e-6)
    assert adversarial_loss(big, False).item() == pytest.approx(50.0, rel=1e-6)


def test_downsample_is_4x4_area_average():
    x = torch.rand(2, 3, 256, 256, dtype=torch.float64)
    ref = x.numpy().reshape(2, 3, 64, 4, 64, 4).mean(axis=(3, 5))
    assert np.allclose(downsample_normals(x).numpy(), ref, atol=1e-12)


# ---------------------------------------------------------------------------- cameras


def test_view_frame_cameras_match_engine_relative_camera():
    rng = np.random.default_rng(0)
    pts = rng.uniform(-0.5, 0.5, (50, 3))
    cams_in, cams_other = [], []
    for _ in range(3):
        cams_in.append(frame_camera(look_at(rng.uniform(0, 360), 30.0), pts))
        cams_other.append([frame_camera(look_at(rng.uniform(0, 360), rng.uniform(-20, 40)), pts) for _ in range(2)])
    t_in = torch.tensor(np.stack([c.to_array() for c in cams_in]))
    t_other = torch.tensor(np.stack([[c.to_array() for c in row] for row in cams_other]))
    out = view_frame_cameras(t_in, t_other)
    assert out.shape == (3, 3, 16)
    for b in range(3):
        expected = [relative_camera(cams_in[b], cams_in[b])] + [relative_camera(cams_in[b], c) for c in cams_other[b]]
        for k, cam in enumerate(expected):
            assert np.allclose(out[b, k].numpy(), cam.to_array(), atol=1e-12)
        assert np.allclose(out[b, 0, :9].numpy(), np.eye(3).ravel(), atol=1e-12)  # the input view: identity
        Camera.from_array(out[b, 1].numpy())  # a valid camera (rotation check)
    with pytest.raises(ValueError, match="other_cameras"):
        view_frame_cameras(t_in, t_other[:2])


# ---------------------------------------------------------------------------- config


def test_config_json_round_trip_and_validation():
    cfg = TrainConfig(mode="joint", data_dir="d", out_dir="o", betas=(0.5, 0.9), categories=("chair",),
                      debug_nan_iters=(3,))
    back = TrainConfig.from_json(cfg.to_json())
    assert back == cfg and isinstance(back.betas, tuple)
    assert (cfg.lambda_n, cfg.lambda_s, cfg.lambda_e, cfg.lambda_m) == (0.002, 0.9, 0.9, 0.01)
    # the paper's RMSProp rates for the cGAN; the predictor's Adam rate is a measured departure (config docstring)
    assert (cfg.lr_g, cfg.lr_d, cfg.lr_mesh) == (5e-5, 5e-5, 2e-3)
    # batch 0 resolves per mode, and the resolved value is what the config (and a checkpoint) keeps
    assert (TrainConfig(mode="mesh").batch, TrainConfig(mode="normals").batch, cfg.batch) == (32, 4, 4)
    assert TrainConfig.from_json(TrainConfig(mode="mesh").to_json()).batch == 32
    with pytest.raises(ValueError, match="mode"):
        TrainConfig(mode="bogus")
    with pytest.raises(ValueError, match="batch"):
        TrainConfig(batch=-1)
    with pytest.raises(ValueError, match="lambda_s"):
        TrainConfig(lambda_s=float("nan"))
    with pytest.raises(ValueError, match="unknown"):
        TrainConfig.from_dict({"nope": 1})


def test_config_generator_arch_default_validation_and_old_configs():
    from training.cli.train import INIT_FIELDS
    from training.loop.config import GENERATOR_ARCHS as CONFIG_ARCHS
    from training.loop.trainer import MODEL_SHAPE_FIELDS, build_models
    from training.model.networks import GENERATOR_ARCHS

    assert CONFIG_ARCHS == GENERATOR_ARCHS  # the torch-free config's copy matches the networks'
    assert TrainConfig().generator_arch == "resize"
    for arch in ("resize", "pix2pix"):
        cfg = TrainConfig(generator_arch=arch)
        assert TrainConfig.from_json(cfg.to_json()).generator_arch == arch  # a saved value is kept
    with pytest.raises(ValueError, match="generator_arch must be 'resize' or 'pix2pix', got 'unet'"):
        TrainConfig(generator_arch="unet")
    # a config saved before the option (no key) is an old run: trained with the pix2pix layers
    old = TrainConfig(mode="normals", base_channels=4).to_dict()
    del old["generator_arch"]
    loaded = TrainConfig.from_dict(old)
    assert loaded.generator_arch == "pix2pix"
    assert TrainConfig.from_json(TrainConfig().to_json().replace('"generator_arch": "resize",', "")).generator_arch == "pix2pix"
    # ... and its generator is rebuilt with those layers, so the old weights load strictly
    gen = build_models(loaded)["generator"]
    assert gen.arch == "pix2pix" and gen.base_channels == 4
    gen.load_state_dict(NormalGenerator(4, arch="pix2pix").state_dict())
    assert build_models(TrainConfig(mode="joint", base_channels=4))["generator"].arch == "resize"
    # a run cannot resume, nor hand its generator over, across archs
    assert "generator_arch" in MODEL_SHAPE_FIELDS and "generator_arch" in INIT_FIELDS["generator"]


def test_laplacian_basis_full_is_the_large_steps_smoother_in_the_eigenbasis():
    """With M = V the basis is (I + lam L)^-1 sqrt(V) Phi, Phi orthonormal: so B c for c = Phi^T u / sqrt(V)
    gives back S u (the smoother of MeshPredictor); truncating keeps the smoothest columns."""
    t = icosphere(2)
    v = t.num_vertices
    full = laplacian_basis(t.faces, v, v, 16.0)
    raw = laplacian_basis(t.faces, v, v, 0.0) / np.sqrt(v)  # Phi
    np.testing.assert_allclose(raw.T @ raw, np.eye(v), atol=1e-4)
    u = np.random.default_rng(0).normal(size=(v, 3))
    np.testing.assert_allclose(full @ (raw.T @ u) / np.sqrt(v), smoothing_operator(t.faces, v, 16.0) @ u, atol=1e-4)
    # the first mode is the constant (a unit coefficient moves every vertex by 1); the next three are
    # (to within the icosphere's irregularity) the coordinate functions x, y, z: > 99.9 % of each
    # unit column lies in their span
    np.testing.assert_allclose(full[:, 0], 1.0, atol=1e-5)
    residual = np.linalg.lstsq(np.c_[t.vertices, np.ones(v)], raw[:, 1:4], rcond=None)[1]
    assert residual.max() < 1e-3
    np.testing.assert_array_equal(laplacian_basis(t.faces, v, 10, 16.0), full[:, :10])
    for bad in (0, v + 1):
        with pytest.raises(ValueError, match="modes"):
            laplacian_basis(t.faces, v, bad, 16.0)


def test_compact_predictor_basis_travels_with_its_weights():
    """The eigenbasis is not portable (the icosphere's repeated eigenvalues leave LAPACK free to return any
    basis of their eigenspaces; another machine or BLAS thread count returns another), so it is saved in
    the state dict and a loaded predictor gives the outputs it was trained to give, whatever basis this
    machine computes. A state dict without it (checkpoints written before) keeps the computed one."""
    t = icosphere(2)
    v = t.num_vertices
    trained = CompactMeshPredictor(template_level=2, base_channels=4, hidden=16, latent=8)
    trained.eval()
    # another machine's basis: the same spans, rotated inside the 3-dimensional eigenspace of modes 1-3
    # (the coordinate functions; their eigenvalue is repeated, to rounding, by the icosphere's symmetry)
    q, _ = np.linalg.qr(np.random.default_rng(1).normal(size=(3, 3)))
    rotated = trained.basis.numpy().copy()
    rotated[:, 1:4] = rotated[:, 1:4] @ q.astype(np.float32)
    with torch.no_grad():
        trained.basis.copy_(torch.from_numpy(rotated))
    state = trained.state_dict()
    assert "basis" in state
    x = torch.rand(2, 3, 64, 64)
    here = CompactMeshPredictor(template_level=2, base_channels=4, hidden=16, latent=8)
    here.eval()
    assert not torch.allclose(here.basis, trained.basis)
    here.load_state_dict(state)
    with torch.no_grad():
        for a, b in zip(here(x), trained(x)):
            torch.testing.assert_close(a, b)
    old = {k: w for k, w in state.items() if k != "basis"}
    fresh = CompactMeshPredictor(template_level=2, base_channels=4, hidden=16, latent=8)
    computed = fresh.basis.clone()
    fresh.load_state_dict(old)  # strict: no missing-key error
    torch.testing.assert_close(fresh.basis, computed)
    with pytest.raises(RuntimeError, match="basis"):
        fresh.load_state_dict({**old, "basis": torch.zeros(v, 5)})


def test_compact_predictor_offsets_are_the_basis_times_the_head_and_stay_bounded():
    p = CompactMeshPredictor(template_level=2, base_channels=4, hidden=16, latent=8, modes=20)
    p.eval()
    x = torch.rand(2, 3, 64, 64)
    with torch.no_grad():
        coeff = p.local_head(p.decoder(p.encoder(x)) * p.head_gain).view(2, 20, 3)
        local, glob = p(x)
        torch.testing.assert_close(local, p.local_scale * p.basis @ coeff)
        assert local.shape == (2, 162, 3) and glob.shape == (2, 3)
        p.local_head.bias.fill_(1e6)
        local, _ = p(x)
    assert torch.isfinite(local).all() and local.abs().max() <= 2.0 * p.local_scale + 1e-6
    assert n_params(CompactMeshPredictor()) < 0.15 * n_params(MeshPredictor())
    with pytest.raises(ValueError, match="modes"):
        CompactMeshPredictor(template_level=2, modes=163)
    with pytest.raises(ValueError, match="arch"):
        build_predictor("unet")
    cfg_bad = dict(predictor_arch="big")
    with pytest.raises(ValueError, match="predictor_arch"):
        TrainConfig(**cfg_bad)


@torch.no_grad()
def _trained_looking(net: torch.nn.Module) -> None:
    """Non-zero heads and biases, BatchNorm statistics off their defaults: what a trained predictor looks like."""
    for m in net.modules():
        if isinstance(m, torch.nn.Linear):
            m.weight.normal_(0, 0.3)
            m.bias.normal_(0, 0.1)
        if isinstance(m, torch.nn.BatchNorm2d):
            m.running_mean.normal_(0, 0.1)
            m.running_var.uniform_(0.5, 2.0)


def test_widened_compact_predictor_computes_the_same_function_and_every_new_weight_learns():
    torch.manual_seed(0)
    small = CompactMeshPredictor(2, base_channels=8, hidden=32, latent=16)
    _trained_looking(small)
    big = CompactMeshPredictor(2, base_channels=8, hidden=48, latent=24)
    assert big.load_widened(small.state_dict()) == (16, 32)
    x = torch.rand(3, 3, 64, 64)
    for mode in ("eval", "train"):  # running statistics and batch statistics alike
        getattr(small, mode)(), getattr(big, mode)()
        (ls, gs), (lb, gb) = small(x), big(x)
        torch.testing.assert_close(lb, ls, rtol=1e-5, atol=1e-6)
        torch.testing.assert_close(gb, gs, rtol=1e-5, atol=1e-6)
    fc = big.encoder[len(big.encoder) - 2]
    opt = torch.optim.SGD(big.parameters(), lr=0.1)
    for step in range(2):
        opt.zero_grad()
        local, glob = big(x)
        (local.square().sum() + glob.sum()).backward()
        # the zero blocks get a gradient at once; the new code units' inputs once those blocks moved
        assert big.decoder[0].weight.grad[:32, 16:].abs().sum() > 0  # new code units -> old hidden units
        assert big.local_head.weight.grad[:, 32:].abs().sum() > 0  # new hidden units -> offsets
        assert (fc.weight.grad[16:].abs().sum() > 0) == (step == 1)
        opt.step()
    with pytest.raises(ValueError, match="at least the old"):
        CompactMeshPredictor(2, base_channels=8, hidden=16, latent=16).load_widened(small.state_dict())
    with pytest.raises(ValueError, match="encoder.0.weight"):
        CompactMeshPredictor(2, base_channels=16, hidden=48, latent=24).load_widened(small.state_dict())
    with pytest.raises(ValueError, match="not a compact predictor"):
        big.load_widened({"x": torch.zeros(1)})


def test_deepened_compact_predictor_starts_as_the_same_function_and_its_blocks_learn():
    """Residual encoder blocks start as the identity: a trained predictor loaded into a deeper one computes the same
    offsets, in eval and train mode; every block's zero convolution gets a gradient at the first step."""
    torch.manual_seed(1)
    shallow = CompactMeshPredictor(2, base_channels=8, hidden=32, latent=16)
    with torch.no_grad():
        for m in shallow.modules():
            if isinstance(m, torch.nn.Linear):
                m.weight.normal_(0, 0.3)
            if isinstance(m, torch.nn.BatchNorm2d):
                m.running_mean.normal_(0, 0.1)
                m.running_var.uniform_(0.5, 2.0)
    deep = CompactMeshPredictor(2, base_channels=8, hidden=32, latent=16, blocks=2)
    assert deep.load_grown(shallow.state_dict()) is None
    wide_deep = CompactMeshPredictor(2, base_channels=8, hidden=48, latent=24, blocks=1)
    assert wide_deep.load_grown(shallow.state_dict()) == (16, 32)  # deepened and widened at once
    x = torch.rand(3, 3, 64, 64)
    for mode in ("eval", "train"):
        for net in (shallow, deep, wide_deep):
            getattr(net, mode)()
        ref = shallow(x)
        for net in (deep, wide_deep):
            for got, want in zip(net(x), ref):
                torch.testing.assert_close(got, want, rtol=1e-5, atol=1e-6)
    assert sum(p.numel() for p in deep.blocks.parameters()) == 2 * sum(
        2 * 9 * c * c + 3 * c + 1 for c in (8, 16, 32, 64))  # two 3x3 convs (one with bias), a BatchNorm, the gate
    # the gates get a gradient at the first step, the blocks' convolutions once their gate has moved
    opt = torch.optim.Adam(deep.parameters(), lr=1e-3)
    for step in range(2):
        opt.zero_grad()
        local, glob = deep(x)
        (local.square().sum() + glob.sum()).backward()
        for stage in deep.blocks:
            for block in stage:
                assert block.gain.grad.abs() > 0
                assert (block.body[3].weight.grad.abs().sum() > 0) == (step == 1)
        opt.step()
    # Adam moves a gate by at most about lr per step: after two steps each is within 2 lr of 0 (and has moved)
    for stage in deep.blocks:
        for block in stage:
            assert 0 < abs(float(block.gain.detach())) <= 2e-3 * (1 + 1e-6)
    with pytest.raises(ValueError, match="encoder blocks this predictor lacks"):
        shallow.load_grown(deep.state_dict())
    with pytest.raises(ValueError, match=r"blocks must be in \[0, 4\]"):
        CompactMeshPredictor(2, blocks=5)
    with pytest.raises(ValueError, match="compact-predictor option"):
        build_predictor("softras", blocks=1)
    with pytest.raises(ValueError, match="predictor_blocks needs predictor_arch compact"):
        TrainConfig(predictor_arch="softras", predictor_blocks=1)


def test_resmoothed_compact_predictor_computes_the_same_function_in_the_new_damping():
    """A predictor trained with basis damping 16 loaded at damping 4: the same offsets; each basis column keeps its
    direction and takes the gain sqrt(V) / (1 + 4 mu) of its Laplacian eigenvalue (eigvalsh, independently); a head
    coefficient's gradient scales by the gain ratio, so the rough modes move further per step."""
    torch.manual_seed(3)
    old = CompactMeshPredictor(2, base_channels=8, hidden=32, latent=16, smoothing=16.0)
    _trained_looking(old)
    new = CompactMeshPredictor(2, base_channels=8, hidden=32, latent=16, smoothing=4.0)
    new.load_state_dict(new.resmoothed_state(old.state_dict(), 16.0))
    x = torch.rand(3, 3, 64, 64)
    for mode in ("eval", "train"):
        old.train(mode == "train"), new.train(mode == "train")
        for got, want in zip(new(x), old(x)):
            torch.testing.assert_close(got, want, rtol=1e-5, atol=1e-6)
    faces = old.template_faces.numpy()
    v = old.num_vertices
    mu = np.clip(np.linalg.eigvalsh(combinatorial_laplacian(faces, v)), 0.0, None)
    b_old, b_new = old.basis.double().numpy(), new.basis.double().numpy()
    np.testing.assert_allclose(np.linalg.norm(b_new, axis=0), np.sqrt(v) / (1.0 + 4.0 * mu), rtol=1e-4, atol=1e-6)
    cos = (b_old * b_new).sum(0) / (np.linalg.norm(b_old, axis=0) * np.linalg.norm(b_new, axis=0))
    np.testing.assert_allclose(cos, 1.0, atol=1e-6)
    ratio = (1.0 + 16.0 * mu) / (1.0 + 4.0 * mu)
    grads = []
    for net in (old, new):
        net.eval().zero_grad()
        local, _ = net(x)
        (local * torch.linspace(-1, 1, local.numel()).view_as(local)).sum().backward()
        grads.append(net.local_head.bias.grad.double().view(-1, 3).numpy())
    np.testing.assert_allclose(grads[1], grads[0] * ratio[:, None], rtol=1e-3, atol=1e-7)
    assert ratio[-1] > 3.5 and abs(ratio[0] - 1.0) < 1e-9  # the roughest mode's steps grow about 4x, the constant one's not
    with pytest.raises(ValueError, match="finite and >= 0"):
        new.resmoothed_state(old.state_dict(), -1.0)
    with pytest.raises(ValueError, match="basis is"):
        CompactMeshPredictor(2, base_channels=8, hidden=32, latent=16, modes=10).resmoothed_state(old.state_dict(), 16.0)
    broken = dict(old.state_dict(), basis=torch.rand_like(old.basis))
    with pytest.raises(ValueError, match="not Laplacian eigenvectors"):
        new.resmoothed_state(broken, 16.0)


def test_framed_ndc_is_the_engines_framing_of_the_input_view():
    """framed_ndc of view-frame points equals engine.camera.project through frame_camera (the dataset's framing of a
    view), for cameras at several elevations and azimuths; it ignores the focal length and stays finite for points
    at or behind the camera and for a mesh collapsed to one point."""
    from engine.camera import DEFAULT_DISTANCE, Camera, project

    rng = np.random.default_rng(0)
    pts = rng.normal(size=(200, 3)) * [0.4, 0.2, 0.3]
    for elev, azim in ((0.0, 0.0), (30.0, 45.0), (45.0, 200.0)):
        cam = look_at(azim, elev)
        assert np.allclose(cam.t, [0.0, 0.0, -DEFAULT_DISTANCE])
        want, _ = project(pts, frame_camera(Camera(cam.R, cam.t, 7.0), pts))
        view = torch.from_numpy(pts @ cam.R.T)[None]  # p_view = R p_world
        np.testing.assert_allclose(framed_ndc(view)[0].numpy(), want, atol=1e-9)
    odd = torch.tensor([[[0.0, 0.0, DEFAULT_DISTANCE + 1.0], [0.1, 0.2, 0.0], [0.0, 0.0, DEFAULT_DISTANCE]]])
    assert torch.isfinite(framed_ndc(odd)).all()
    assert torch.isfinite(framed_ndc(torch.zeros(1, 5, 3))).all()
    with pytest.raises(ValueError, match=r"\(N, V, 3\)"):
        framed_ndc(torch.zeros(5, 3))


def test_aligned_branch_reads_the_image_the_right_way_up(monkeypatch):
    """Row 0 of an image is its top: the branch's features at a vertex above the centre (v > 0) come from the upper
    rows, at a vertex to the right (u > 0) from the right columns (an image lit only there tells them apart)."""
    import training.model.networks as networks

    monkeypatch.setattr(networks, "ALIGNED_STAGES", 1)
    net = CompactMeshPredictor(2, base_channels=8, hidden=32, latent=16, aligned=4)
    img = torch.zeros(1, 1, 32, 32)
    img[:, :, :16, 16:] = 1.0  # the upper right quadrant
    net.aligned_mlp = torch.nn.Sequential(torch.nn.Linear(4, 1), torch.nn.ReLU(), torch.nn.Linear(1, 3, bias=False))
    with torch.no_grad():  # the sampled value, weighted 1; the position, 0; out along x
        net.aligned_mlp[0].weight.copy_(torch.tensor([[1.0, 0.0, 0.0, 0.0]]))
        net.aligned_mlp[0].bias.zero_()
        net.aligned_mlp[2].weight.copy_(torch.tensor([[1.0 / net.local_scale], [0.0], [0.0]]))
        pts = torch.tensor([[[0.3, 0.3, 0.0], [-0.3, 0.3, 0.0], [0.3, -0.3, 0.0], [-0.3, -0.3, 0.0]]]).repeat(1, 5, 1)
        for small in (False, True):  # 20 vertices against 1,024 pixels: sampled first; against 16: projected first
            got = net._aligned_offsets(pts, [img[:, :, ::8, ::8] if small else img])
            torch.testing.assert_close(got[..., 0], torch.tensor([[1.0, 0.0, 0.0, 0.0]]).repeat(1, 5))
            torch.testing.assert_close(got[..., 1:], torch.zeros(1, 20, 2))


@pytest.mark.parametrize("size", [(32, 32), (8, 5), (1, 6), (1, 1)])
def test_sample_bilinear_is_grid_sample_with_border_padding(size):
    """sample_bilinear equals F.grid_sample (bilinear, border, align_corners=False) in value and in its gradient
    with respect to the maps, at points inside, on the border and outside the image, for square, oblong,
    one-row and one-pixel maps."""
    torch.manual_seed(3)
    h, w = size
    maps = torch.randn(2, 5, h, w, dtype=torch.float64, requires_grad=True)
    grid = torch.rand(2, 40, 2, dtype=torch.float64) * 3.0 - 1.5
    grid[:, :4] = torch.tensor([[-1.0, -1.0], [1.0, 1.0], [1.0, -1.0], [0.0, 0.0]], dtype=torch.float64)
    want = torch.nn.functional.grid_sample(maps, grid.unsqueeze(2), mode="bilinear", padding_mode="border",
                                           align_corners=False).squeeze(-1).transpose(1, 2)
    got = sample_bilinear(maps, grid)
    torch.testing.assert_close(got, want, rtol=1e-12, atol=1e-12)
    weights = torch.randn_like(want)
    (g_want,) = torch.autograd.grad((want * weights).sum(), maps)
    (g_got,) = torch.autograd.grad((got * weights).sum(), maps)
    torch.testing.assert_close(g_got, g_want, rtol=1e-12, atol=1e-12)


def _trace(fn, args):
    """torch.jit.trace (deprecated in favour of torch.export, but what sets torch.jit.is_tracing, as the ONNX
    exporter the project uses does) without its deprecation warning and its warnings about shapes read as Python
    numbers (the export traces the same code at fixed shapes)."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        warnings.simplefilter("ignore", torch.jit.TracerWarning)
        return torch.jit.trace(fn, args)


def test_sample_channels_is_sample_bilinear_and_the_trace_keeps_the_gathers():
    """What the predictor samples with in torch: F.grid_sample, channel-major, equal to sample_bilinear's gathers in
    value and in the gradient of the maps (none reaches the grid); traced for ONNX, the aligned branch holds the
    gathers and no grid sampler, and gives the same offsets."""
    torch.manual_seed(4)
    maps = torch.randn(3, 6, 9, 7, dtype=torch.float64, requires_grad=True)
    grid = (torch.rand(3, 50, 2, dtype=torch.float64) * 2.6 - 1.3).requires_grad_()
    got, want = sample_channels(maps, grid), sample_bilinear(maps, grid).transpose(1, 2)
    torch.testing.assert_close(got, want, rtol=1e-12, atol=1e-12)
    weights = torch.randn_like(want)
    g_got = torch.autograd.grad((got * weights).sum(), maps)[0]
    g_want = torch.autograd.grad((want * weights).sum(), maps)[0]
    torch.testing.assert_close(g_got, g_want, rtol=1e-12, atol=1e-12)
    assert got.requires_grad  # the gradient reaches the maps ...
    assert torch.autograd.grad(sample_channels(maps, grid).sum(), grid, allow_unused=True)[0] is None  # ... not the grid
    net = CompactMeshPredictor(2, base_channels=8, hidden=32, latent=16, aligned=12).double().eval()
    net.requires_grad_(False)  # a traced closure holds the weights as constants
    net.aligned_mlp[2].weight.normal_()
    verts = torch.randn(2, net.basis.shape[0], 3, dtype=torch.float64) * 0.4
    branch_maps = [torch.randn(2, 8, 32, 32, dtype=torch.float64), torch.randn(2, 16, 8, 8, dtype=torch.float64),
                   torch.randn(2, 32, 4, 4, dtype=torch.float64)]
    traced = _trace(lambda v, a, b, c: net._aligned_offsets(v, [a, b, c]), (verts, *branch_maps))
    kinds = {n.kind() for n in traced.graph.nodes()}
    assert "aten::grid_sampler" not in kinds and "aten::index" in kinds
    torch.testing.assert_close(traced(verts, *branch_maps), net._aligned_offsets(verts, branch_maps),
                               rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("n", [1, 4])
def test_basis_times_is_the_broadcast_matmul(n):
    """The basis product the predictor computes as one (V, M) x (M, 3N) product equals torch.matmul's broadcast
    (V, M) @ (N, M, 3) in value and in both gradients; traced, it stays the broadcast matmul."""
    torch.manual_seed(n)
    basis = torch.randn(10, 7, dtype=torch.float64, requires_grad=True)
    coeff = torch.randn(n, 7, 3, dtype=torch.float64, requires_grad=True)
    got, want = basis_times(basis, coeff), torch.matmul(basis, coeff)
    assert got.shape == (n, 10, 3)
    torch.testing.assert_close(got, want, rtol=1e-12, atol=1e-12)
    weights = torch.randn_like(want)
    for a, b in zip(torch.autograd.grad((got * weights).sum(), (basis, coeff)),
                    torch.autograd.grad((want * weights).sum(), (basis, coeff))):
        torch.testing.assert_close(a, b, rtol=1e-12, atol=1e-12)
    traced = _trace(basis_times, (basis.detach(), coeff.detach()))
    assert "aten::matmul" in {node.kind() for node in traced.graph.nodes()}


def test_predictor_trains_the_same_function_as_its_onnx_graph_form(monkeypatch):
    """The larger predictor with its aligned branch, in torch (grid_sample, channels-last encoder, one basis
    product) and in the form it is traced to for ONNX (gathers, contiguous images, broadcast matmul): the same
    offsets and the same parameter gradients in float64, in training mode (BatchNorm on the batch)."""
    import training.model.networks as networks

    torch.manual_seed(8)
    net = CompactMeshPredictor(2, base_channels=8, hidden=32, latent=16, aligned=12).double().train()
    _trained_looking(net)
    with torch.no_grad():
        net.aligned_mlp[2].weight.normal_(std=0.5)
    x = torch.rand(4, 3, 64, 64, dtype=torch.float64)
    weights = torch.randn(4, net.basis.shape[0], 3, dtype=torch.float64)
    results = []
    for traced in (False, True):
        monkeypatch.setattr(networks, "_traced", lambda traced=traced: traced)
        net.zero_grad()
        local, glob = net(x)
        ((local + glob[:, None]) * weights).sum().backward()
        results.append((local.detach(), glob.detach(), {k: p.grad.clone() for k, p in net.named_parameters()}))
    (l0, g0, grads0), (l1, g1, grads1) = results
    torch.testing.assert_close(l0, l1, rtol=1e-10, atol=1e-12)
    torch.testing.assert_close(g0, g1, rtol=1e-10, atol=1e-12)
    assert grads0.keys() == grads1.keys()
    for k in grads0:
        torch.testing.assert_close(grads0[k], grads1[k], rtol=1e-8, atol=1e-10, msg=k)
    assert float(l0.abs().max()) > 0 and float(grads0["aligned_mlp.0.weight"].abs().sum()) > 0


def test_aligned_branch_is_its_perceptron_on_the_concatenated_samples():
    """The branch's first layer, summed block by block with small maps projected before they are sampled (the
    cheaper order), equals the perceptron applied to the concatenation [maps sampled at the vertex; the vertex],
    computed here directly, for maps both larger and smaller than the vertex count."""
    F = torch.nn.functional
    torch.manual_seed(11)
    net = CompactMeshPredictor(2, base_channels=8, hidden=32, latent=16, aligned=12).double()
    with torch.no_grad():
        net.aligned_mlp[2].weight.normal_()
    verts = torch.randn(2, net.basis.shape[0], 3, dtype=torch.float64) * 0.4
    maps = [torch.randn(2, 8, 32, 32, dtype=torch.float64), torch.randn(2, 16, 8, 8, dtype=torch.float64),
            torch.randn(2, 32, 4, 4, dtype=torch.float64)]
    assert maps[0].shape[-1] ** 2 > verts.shape[1] > maps[1].shape[-1] ** 2  # both orders are exercised
    uv = framed_ndc(verts)
    grid = torch.stack([uv[..., 0], -uv[..., 1]], dim=-1).unsqueeze(2)
    sampled = [F.grid_sample(m, grid, mode="bilinear", padding_mode="border", align_corners=False).squeeze(-1)
               for m in maps]
    features = torch.cat([*sampled, verts.transpose(1, 2)], dim=1).transpose(1, 2)
    want = net.local_scale * net.aligned_mlp(features)
    torch.testing.assert_close(net._aligned_offsets(verts, maps), want, rtol=1e-10, atol=1e-12)


def test_aligned_branch_starts_as_the_same_function_learns_and_exports(tmp_path):
    """A trained predictor loaded into one with the aligned branch computes the same offsets (the branch's last
    layer starts at zero); that layer gets a gradient at the first step, the first layer from the second; ONNX
    Runtime runs the branch (GridSample) like torch; a branch cannot be dropped by loading."""
    import onnxruntime as ort

    import engine.contract as C
    from training.export.to_onnx import PARITY_TOLERANCE, export_models, parity_inputs

    torch.manual_seed(5)
    plain = CompactMeshPredictor(2, base_channels=8, hidden=32, latent=16)
    _trained_looking(plain)
    net = CompactMeshPredictor(2, base_channels=8, hidden=32, latent=16, aligned=16)
    assert net.load_grown(plain.state_dict()) is None
    x = torch.rand(3, 3, 64, 64)
    plain.eval(), net.eval()
    for got, want in zip(net(x), plain(x)):
        torch.testing.assert_close(got, want, rtol=1e-6, atol=1e-7)
    opt = torch.optim.Adam(net.parameters(), lr=1e-2)
    for step in range(2):
        opt.zero_grad()
        local, glob = net(x)
        (local * torch.linspace(-1, 1, local.numel()).view_as(local)).sum().backward()
        assert net.aligned_mlp[2].weight.grad.abs().sum() > 0
        assert (net.aligned_mlp[0].weight.grad.abs().sum() > 0) == (step == 1)
        opt.step()
    net.eval()
    sketches, normals64, _ = parity_inputs(TrainConfig(data_dir=str(tmp_path / "no_data")))
    (report,) = export_models(None, net, tmp_path, config_json=TrainConfig(predictor_aligned=16).to_json(),
                              code_version="t", sketches=sketches, normals64=normals64)
    assert report.max_abs_error <= PARITY_TOLERANCE
    sess = ort.InferenceSession(str(tmp_path / C.PREDICTOR_FILE), providers=["CPUExecutionProvider"])
    ops = {n.op_type for n in __import__("onnx").load(str(tmp_path / C.PREDICTOR_FILE)).graph.node}
    assert "Gather" in ops and "GridSample" not in ops  # sample_bilinear's gathers, not ORT's slow GridSample
    outs = sess.run(None, {C.PREDICTOR_INPUT: x.numpy()})
    with torch.no_grad():
        ref = net(x)
    assert max(float(np.abs(o - r.numpy()).max()) for o, r in zip(outs, ref)) < PARITY_TOLERANCE
    with pytest.raises(ValueError, match="aligned branch this predictor lacks"):
        CompactMeshPredictor(2, base_channels=8, hidden=32, latent=16).load_grown(net.state_dict())
    with pytest.raises(ValueError, match="aligned must be >= 0"):
        CompactMeshPredictor(2, aligned=-1)
    with pytest.raises(ValueError, match="compact-predictor options"):
        build_predictor("softras", aligned=8)
    with pytest.raises(ValueError, match="predictor_aligned needs predictor_arch compact"):
        TrainConfig(predictor_arch="softras", predictor_aligned=8)
