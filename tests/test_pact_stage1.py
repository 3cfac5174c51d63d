"""PAct stage 1 (generator/pact): configs, VAE, image encoder, part-aware flow, sampler."""

from __future__ import annotations

import dataclasses
import json

import pytest
import torch
from safetensors.torch import save_file

from generator.pact import (
    FlowTrainConfig,
    SamplerConfig,
    build,
    build_stage1,
    flow_loss,
    generate_parts,
    load_checkpoint,
    load_config,
    sample,
    save_checkpoint,
    vae_loss,
)
from generator.pact.model import model_configs
from generator.pact.model.flow import guided_velocity, noisy, sample_t
from generator.pact.model.image_encoder import (
    ViTConfig,
    WeightsLayoutError,
    dinov2_key_to_local,
    load_dinov2_weights,
)
from generator.pact.model.part_flow import PartFlowConfig
from generator.pact.model.ss_vae import SSVAEConfig, SSVAETrainConfig, occupancy_iou
from generator.pact.model.stage1 import ConfigMismatchError, Stage1Config, config_from_dict

torch.set_num_threads(1)  # tiny ops: a second thread only adds barrier waits on a shared CPU

TINY_FLOW = PartFlowConfig(
    max_parts=3,
    latent_channels=2,
    latent_resolution=4,
    patch_size=2,
    part_embed_dim=8,
    width=32,
    depth=2,
    heads=2,
    cond_dim=16,
    cond_grid=2,
    cond_prefix_tokens=1,
)
TINY_VIT = ViTConfig(image_size=32, patch_size=16, width=16, depth=1, heads=2)
TINY_VAE = SSVAEConfig(
    resolution=16, latent_channels=2, channels=(8, 16), num_res_blocks=1, stem_stride=2
)


def tiny_stage1() -> Stage1Config:
    return Stage1Config(vae=TINY_VAE, image_encoder=TINY_VIT, flow=TINY_FLOW).check()


def n_params(m: torch.nn.Module) -> int:
    return sum(p.numel() for p in m.parameters())


def randomize_modulation(model: torch.nn.Module, std: float = 0.2, seed: int = 0) -> None:
    """adaLN-Zero starts every block as the identity; give gates and the output layer values."""
    g = torch.Generator().manual_seed(seed)
    with torch.no_grad():
        for name, p in model.named_parameters():
            if "adaLN" in name or "out_proj" in name or "mask_proj" in name:
                p.copy_(torch.randn(p.shape, generator=g) * std)


def tiny_inputs(B: int = 2, seed: int = 0):
    g = torch.Generator().manual_seed(seed)
    c = TINY_FLOW
    r = c.latent_resolution
    x = torch.randn(B, c.max_parts, c.latent_channels, r, r, r, generator=g)
    cond = torch.randn(B, c.cond_tokens, c.cond_dim, generator=g)
    mask = torch.randint(0, c.max_parts + 1, (B, 8, 8), generator=g)
    return x, cond, mask


# --- configs and model classes -----------------------------------------------------------


def test_small_and_full_configs_build_with_expected_sizes():
    small = build_stage1(load_config("small"))
    assert 1e6 < n_params(small["flow"]) < 20e6
    assert n_params(small["image_encoder"]) < 10e6

    full_cfg = load_config("full")
    assert full_cfg.flow.width == 1024 and full_cfg.flow.depth == 24 and full_cfg.flow.heads == 16
    assert full_cfg.flow.max_parts >= 16 and full_cfg.vae.resolution == 64
    assert full_cfg.vae.latent_resolution == 16 and full_cfg.vae.latent_channels == 8
    with torch.device("meta"):
        full = build_stage1(full_cfg)
    assert all(p.is_meta for p in full["flow"].parameters())
    assert 400e6 < n_params(full["flow"]) < 700e6
    assert 300e6 < n_params(full["image_encoder"]) < 310e6  # DINOv2 ViT-L/14: 304M
    assert full_cfg.image_encoder.num_tokens == 1 + 4 + 37 * 37


def test_config_json_round_trip_and_mismatch_is_reported(tmp_path):
    cfg = load_config("small")
    path = tmp_path / "c.json"
    path.write_text(json.dumps(cfg.to_dict()))
    assert load_config(path) == cfg
    bad = cfg.to_dict()
    bad["flow"]["latent_channels"] = 4
    with pytest.raises(ConfigMismatchError):
        config_from_dict(bad)
    with pytest.raises(ValueError, match="unknown"):
        model_configs.config_from_dict(PartFlowConfig, {"widht": 3})
    with pytest.raises(model_configs.UnknownModelError):
        build("nope")
    assert set(model_configs.names()) >= {"ss_vae", "vit", "part_flow"}


# --- part-aware flow transformer ----------------------------------------------------


def test_within_part_attention_does_not_leak_and_global_does():
    model = build("part_flow", TINY_FLOW).eval()
    randomize_modulation(model)
    glob, local = model.blocks[0], model.blocks[1]
    assert not glob.within_part and local.within_part  # even global, odd within-part
    g = torch.Generator().manual_seed(1)
    B, K, L, D = 2, TINY_FLOW.max_parts, TINY_FLOW.tokens_per_part, TINY_FLOW.width
    h = torch.randn(B, K, L, D, generator=g)
    c = torch.randn(B, D, generator=g)
    ctx = torch.randn(B, TINY_FLOW.cond_tokens, TINY_FLOW.cond_dim, generator=g)
    h2 = h.clone()
    h2[:, 1] += torch.randn(B, L, D, generator=g)  # change part 1 only
    with torch.no_grad():
        a, b = local(h, c, ctx), local(h2, c, ctx)
        assert torch.allclose(a[:, [0, 2]], b[:, [0, 2]], atol=1e-6)
        assert not torch.allclose(a[:, 1], b[:, 1], atol=1e-3)
        a, b = glob(h, c, ctx), glob(h2, c, ctx)
        assert not torch.allclose(a[:, 0], b[:, 0], atol=1e-4)
        assert not torch.allclose(a[:, 2], b[:, 2], atol=1e-4)


def test_output_shapes_and_null_condition_ignores_image_and_mask():
    model = build("part_flow", TINY_FLOW).eval()
    randomize_modulation(model)
    x, cond, mask = tiny_inputs()
    t = torch.tensor([0.3, 0.8])
    with torch.no_grad():
        out = model(x, t, cond, mask)
        assert out.velocity.shape == x.shape
        assert out.exists_logits.shape == (2, TINY_FLOW.max_parts)
        assert out.features.shape == (2, TINY_FLOW.max_parts, TINY_FLOW.tokens_per_part, 32)
        drop = torch.ones(2, dtype=torch.bool)
        u1 = model(x, t, cond, mask, cond_drop=drop).velocity
        u2 = model(x, t, torch.randn_like(cond), None, cond_drop=drop).velocity
        u3 = model(x, t, None, None).velocity
        assert torch.allclose(u1, u2, atol=1e-6) and torch.allclose(u1, u3, atol=1e-6)
        assert not torch.allclose(u1, out.velocity, atol=1e-4)
        # the mask matters when kept
        m2 = model(x, t, cond, torch.zeros_like(mask)).velocity
        assert not torch.allclose(m2, out.velocity, atol=1e-5)


def test_mask_embedding_uses_the_part_identity_rows():
    model = build("part_flow", TINY_FLOW)
    T, g = TINY_FLOW.max_parts, TINY_FLOW.cond_grid
    E = model.part_embed
    full = torch.full((1, 8, 8), 2)  # id 2 = slot 1 everywhere
    emb = model.mask_embedding(full, None, 1)  # (1, g*g, d_p)
    assert emb.shape == (1, g * g, TINY_FLOW.part_embed_dim)
    assert torch.allclose(emb, E[1].expand_as(emb))
    bg = model.mask_embedding(torch.zeros(1, 8, 8, dtype=torch.long), None, 1)
    assert torch.allclose(bg, model.mask_extra[0].expand_as(bg))
    # left half id 1 (base, slot 0), right half id 3 (slot 2): the top-left patch is E[0]
    half = torch.ones(1, 8, 8, dtype=torch.long)
    half[..., 4:] = 3
    emb = model.mask_embedding(half, None, 1).view(g, g, -1)
    assert torch.allclose(emb[0, 0], E[0]) and torch.allclose(emb[0, g - 1], E[2])
    # the gradient of the mask path lands in E's rows, the same parameter the tokens use
    model.mask_embedding(full, None, 1).sum().backward()
    assert E.grad[1].abs().sum() > 0 and E.grad[[0, 2]].abs().sum() == 0
    with pytest.raises(ValueError, match="mask ids"):
        model.mask_embedding(torch.full((1, 8, 8), T + 1), None, 1)


def test_cfg_scale_one_equals_conditional_prediction():
    model = build("part_flow", TINY_FLOW).eval()
    randomize_modulation(model)
    x, cond, mask = tiny_inputs()
    t = torch.tensor([0.5, 0.9])
    with torch.no_grad():
        v_cond = model(x, t, cond, mask).velocity
        v_one = guided_velocity(model, x, t, cond, mask, scale=1.0).velocity
        v_seven = guided_velocity(model, x, t, cond, mask, scale=7.0).velocity
        v_zero = guided_velocity(model, x, t, cond, mask, scale=0.0).velocity
    assert torch.allclose(v_one, v_cond, atol=1e-5)
    assert torch.allclose(v_zero, model(x, t, None, None).velocity, atol=1e-5)
    assert not torch.allclose(v_seven, v_cond, atol=1e-3)


def test_sampling_is_deterministic_for_a_seed_and_reports_features():
    model = build("part_flow", TINY_FLOW).eval()
    randomize_modulation(model)
    _, cond, mask = tiny_inputs()
    steps = []
    cfg = SamplerConfig(steps=5, cfg_scale=3.0)

    def hook(i: int, t: float, feats: torch.Tensor) -> None:
        steps.append((i, t, feats.shape))

    a, ea = sample(model, cond, mask, cfg, torch.Generator().manual_seed(7), callback=hook)
    b, eb = sample(model, cond, mask, cfg, torch.Generator().manual_seed(7))
    c, _ = sample(model, cond, mask, cfg, torch.Generator().manual_seed(8))
    assert torch.equal(a, b) and torch.equal(ea, eb)
    assert not torch.allclose(a, c)
    assert a.shape == (2, 3, 2, 4, 4, 4) and ea.shape == (2, 3)
    assert [s[0] for s in steps] == list(range(5)) and steps[0][1] == 1.0
    assert steps[0][2] == (2, 3, TINY_FLOW.tokens_per_part, TINY_FLOW.width)


def test_guidance_interval_guides_only_the_steps_inside_it():
    """Outside cfg_interval a step is the conditional prediction alone: an interval no
    step falls in samples exactly as cfg_scale 1 everywhere; [0.5, 1] runs the 2B batch
    only on the steps with t >= 0.5 and gives a sample unlike either."""
    model = build("part_flow", TINY_FLOW).eval()
    randomize_modulation(model)
    _, cond, mask = tiny_inputs()
    batches = []
    model.register_forward_hook(lambda mod, args, out: batches.append(args[0].shape[0]))

    def draw(**kw):
        return sample(model, cond, mask, SamplerConfig(steps=4, **kw),
                      torch.Generator().manual_seed(7))[0]  # fmt: skip

    never = draw(cfg_scale=5.0, cfg_interval=(2.0, 3.0))
    plain = draw(cfg_scale=1.0)
    batches.clear()
    half = draw(cfg_scale=5.0, cfg_interval=(0.5, 1.0))
    assert batches == [4, 4, 4, 2]  # t = 1, 0.75, 0.5 guided (2B), t = 0.25 not (B = 2)
    full = draw(cfg_scale=5.0)
    assert torch.allclose(never, plain, atol=1e-5)
    assert not torch.allclose(half, full, atol=1e-4) and not torch.allclose(half, plain, atol=1e-4)


def test_flow_interpolation_and_time_sampling():
    x0, eps = torch.randn(4, 3, 2), torch.randn(4, 3, 2)
    assert torch.allclose(noisy(x0, eps, torch.zeros(4)), x0)
    assert torch.allclose(noisy(x0, eps, torch.ones(4)), eps)
    t = sample_t(20000, 1.0, 1.0, torch.Generator().manual_seed(0))
    logit = torch.log(t / (1 - t))
    assert abs(logit.mean().item() - 1.0) < 0.05 and abs(logit.std().item() - 1.0) < 0.05


def test_flow_model_overfits_a_tiny_batch():
    torch.manual_seed(0)
    model = build("part_flow", TINY_FLOW).train()
    x0, cond, mask = tiny_inputs()
    exists = torch.tensor([[True, True, False], [True, False, False]])
    cfg = FlowTrainConfig(p_uncond=0.0, p_mask_drop=0.0, exists_weight=1.0)
    opt = torch.optim.Adam(model.parameters(), lr=3e-3)
    first = None
    for _ in range(300):
        # same seed every step: the same t, noise and drops, i.e. a fixed tiny batch
        loss, metrics = flow_loss(
            model, x0, cond, mask, exists, cfg, torch.Generator().manual_seed(3)
        )
        first = first or metrics
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert first["mse"] > 1.0
    assert metrics["mse"] < 0.02 * first["mse"]
    assert metrics["exists_bce"] < 0.05


def test_x0_prediction_returns_the_velocity_it_implies():
    """predict="x0": the output layer's x0_hat becomes v = (x_t - x0_hat) / t. With the
    zero-initialised output layer x0_hat = 0, so v = x_t / t by hand; the t floor holds."""
    torch.manual_seed(0)
    model = build("part_flow", dataclasses.replace(TINY_FLOW, predict="x0")).eval()
    x, cond, mask = tiny_inputs()
    t = torch.tensor([0.5, 0.01])
    v = model(x, t, cond, mask).velocity
    assert torch.allclose(v[0], x[0] / 0.5, atol=1e-6)
    assert torch.allclose(v[1], x[1] / TINY_FLOW.x0_t_min, atol=1e-4)
    # a live output layer moves x0_hat away from 0
    randomize_modulation(model)
    a = model(x, torch.tensor([0.3, 0.3]), cond, mask)
    assert not torch.allclose(a.velocity, x / 0.3)
    with pytest.raises(ValueError, match="predict"):
        build("part_flow", dataclasses.replace(TINY_FLOW, predict="eps"))


def test_x0_prediction_overfits_a_tiny_batch():
    torch.manual_seed(0)
    model = build("part_flow", dataclasses.replace(TINY_FLOW, predict="x0")).train()
    x0, cond, mask = tiny_inputs()
    exists = torch.tensor([[True, True, False], [True, False, False]])
    cfg = FlowTrainConfig(p_uncond=0.0, p_mask_drop=0.0)
    opt = torch.optim.Adam(model.parameters(), lr=3e-3)
    losses = []
    for _ in range(200):
        loss, metrics = flow_loss(
            model, x0, cond, mask, exists, cfg, torch.Generator().manual_seed(3)
        )
        losses.append(metrics["mse"])
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert losses[-1] < 0.05 * losses[0]


# --- checkpoints --------------------------------------------------------------------


def test_checkpoint_round_trip_samples_identically(tmp_path):
    model = build("part_flow", TINY_FLOW).eval()
    randomize_modulation(model)
    _, cond, mask = tiny_inputs()
    cfg = SamplerConfig(steps=4)
    before, _ = sample(model, cond, mask, cfg, torch.Generator().manual_seed(5))
    save_checkpoint(model, tmp_path / "flow")
    assert sorted(p.name for p in (tmp_path / "flow").iterdir()) == [
        "config.json",
        "model.safetensors",
    ]
    loaded = load_checkpoint(tmp_path / "flow").eval()
    assert loaded.cfg == model.cfg
    after, _ = sample(loaded, cond, mask, cfg, torch.Generator().manual_seed(5))
    assert torch.equal(before, after)
    vit = build("vit", TINY_VIT).eval()
    save_checkpoint(vit, tmp_path / "vit")
    img = torch.rand(1, 3, 32, 32)
    assert torch.equal(vit(img), load_checkpoint(tmp_path / "vit").eval()(img))


# --- sparse-structure VAE -----------------------------------------------------------


def _shapes(R: int) -> torch.Tensor:
    c = (torch.arange(R) + 0.5) / R - 0.5
    x, y, z = torch.meshgrid(c, c, c, indexing="ij")
    sphere = (x**2 + y**2 + z**2) < 0.3**2
    box = (x.abs() < 0.35) & (y.abs() < 0.2) & (z.abs() < 0.1)
    slab = (z > 0.2) & (z < 0.4) & (x.abs() < 0.4)
    ring = ((x**2 + y**2).sqrt() - 0.25).abs() < 0.08
    ring &= z.abs() < 0.1
    empty = torch.zeros_like(sphere)  # unused part slots are all-empty grids
    return torch.stack([sphere, box, slab, ring, empty]).float()  # (5, R, R, R)


def test_vae_shapes_and_overfits_a_few_grids():
    torch.manual_seed(0)
    vae = build("ss_vae", TINY_VAE)
    occ = _shapes(16)
    z, mean, logvar = vae.encode(occ[:, None])
    assert z.shape == mean.shape == logvar.shape == (5, 2, 4, 4, 4)
    assert vae.decode(z).shape == (5, 1, 16, 16, 16)
    parts = occ[:4].view(2, 2, 16, 16, 16)  # (B, K, R, R, R)
    assert vae.encode_parts(parts).shape == (2, 2, 2, 4, 4, 4)
    assert vae.decode_parts(vae.encode_parts(parts)).shape == (2, 2, 16, 16, 16)
    assert vae.empty_latent().shape == (2, 4, 4, 4)
    # parts are encoded independently: a part's latent does not depend on its neighbours
    other = parts.clone()
    other[:, 1] = 0
    assert torch.allclose(vae.encode_parts(parts)[:, 0], vae.encode_parts(other)[:, 0], atol=1e-5)

    opt = torch.optim.Adam(vae.parameters(), lr=3e-3)
    cfg = SSVAETrainConfig(kl_weight=1e-4)
    g = torch.Generator().manual_seed(0)
    for _ in range(300):
        loss, metrics = vae_loss(vae.train(), occ, cfg, g)
        opt.zero_grad()
        loss.backward()
        opt.step()
    vae.eval()
    with torch.no_grad():
        iou = occupancy_iou(vae.decode_parts(vae.encode_parts(occ[None]))[0], occ)
        empty = vae.decode(vae.empty_latent()[None])
    assert iou > 0.9, metrics
    assert (empty > 0).float().mean() < 0.05


# --- image encoder and DINOv2 weights -----------------------------------------------


def _official_dinov2_state_dict(cfg: ViTConfig, grid: int, chunked: bool = False) -> dict:
    """Random tensors under the official DINOv2 (facebookresearch/dinov2) key names."""
    g = torch.Generator().manual_seed(0)
    D, P = cfg.width, cfg.patch_size

    def r(*shape):
        return torch.randn(*shape, generator=g)

    sd = {
        "cls_token": r(1, 1, D),
        "pos_embed": r(1, 1 + grid * grid, D),
        "register_tokens": r(1, cfg.num_register_tokens, D),
        "mask_token": r(1, D),
        "patch_embed.proj.weight": r(D, 3, P, P),
        "patch_embed.proj.bias": r(D),
        "norm.weight": r(D),
        "norm.bias": r(D),
    }
    for i in range(cfg.depth):
        b = f"blocks.0.{i}." if chunked else f"blocks.{i}."
        H = int(D * cfg.mlp_ratio)
        for k, shape in {
            "norm1.weight": (D,), "norm1.bias": (D,),
            "attn.qkv.weight": (3 * D, D), "attn.qkv.bias": (3 * D,),
            "attn.proj.weight": (D, D), "attn.proj.bias": (D,),
            "ls1.gamma": (D,), "norm2.weight": (D,), "norm2.bias": (D,),
            "mlp.fc1.weight": (H, D), "mlp.fc1.bias": (H,),
            "mlp.fc2.weight": (D, H), "mlp.fc2.bias": (D,), "ls2.gamma": (D,),
        }.items():  # fmt: skip
            sd[b + k] = r(*shape)
    return sd


def test_dinov2_local_weights_load_into_the_vit(tmp_path):
    cfg = ViTConfig(
        image_size=28, patch_size=14, width=32, depth=2, heads=2,
        num_register_tokens=4, layerscale_init=1e-5, output="prenorm_layernorm",
    )  # fmt: skip
    sd = _official_dinov2_state_dict(cfg, grid=2)
    save_file(sd, str(tmp_path / "dinov2.safetensors"))
    torch.save({"model": _official_dinov2_state_dict(cfg, 3, chunked=True)}, tmp_path / "d.pth")

    vit = build("vit", dataclasses.replace(cfg, weights=str(tmp_path / "dinov2.safetensors")))
    assert torch.equal(vit.blocks[1].attn.qkv.weight, sd["blocks.1.attn.qkv.weight"])
    assert torch.equal(vit.blocks[1].attn.out.bias, sd["blocks.1.attn.proj.bias"])
    assert torch.equal(vit.blocks[0].ls2, sd["blocks.0.ls2.gamma"])
    assert torch.equal(vit.patch_embed.weight, sd["patch_embed.proj.weight"])
    assert torch.equal(vit.ln_f.weight, sd["norm.weight"])
    assert torch.equal(vit.register_tokens, sd["register_tokens"])
    assert torch.equal(vit.pos_embed, sd["pos_embed"])
    tokens = vit(torch.rand(2, 3, 28, 28))
    assert tokens.shape == (2, 1 + 4 + 4, 32)

    # chunked-blocks layout from a .pth, pos_embed resized from a 3x3 to a 2x2 grid
    vit2 = build("vit", cfg)
    load_dinov2_weights(vit2, tmp_path / "d.pth")
    assert vit2.pos_embed.shape == (1, 5, 32)

    with pytest.raises(WeightsLayoutError):
        load_dinov2_weights(build("vit", dataclasses.replace(cfg, depth=3)), tmp_path / "d.pth")
    with pytest.raises(FileNotFoundError):
        load_dinov2_weights(vit2, tmp_path / "missing.pth")


def test_dinov2_vitl14_key_mapping_covers_the_full_size_encoder():
    full = load_config("full").image_encoder
    with torch.device("meta"):
        vit = build("vit", full)
    official = ["cls_token", "pos_embed", "register_tokens", "mask_token", "norm.weight",
                "norm.bias", "patch_embed.proj.weight", "patch_embed.proj.bias"]  # fmt: skip
    for i in range(24):
        for k in ["norm1", "norm2", "attn.qkv", "attn.proj", "mlp.fc1", "mlp.fc2"]:
            official += [f"blocks.{i}.{k}.weight", f"blocks.{i}.{k}.bias"]
        official += [f"blocks.{i}.ls1.gamma", f"blocks.{i}.ls2.gamma"]
    mapped = {dinov2_key_to_local(k) for k in official} - {None}
    assert mapped == set(vit.state_dict())
    assert vit.pos_embed.shape == (1, 1 + 37 * 37, 1024)


# --- end to end ---------------------------------------------------------------------


def test_generate_parts_end_to_end_shapes():
    models = {k: m.eval() for k, m in build_stage1(tiny_stage1()).items()}
    occ, exists = generate_parts(
        models,
        torch.rand(1, 3, 32, 32),
        torch.randint(0, 4, (1, 32, 32)),
        SamplerConfig(steps=2),
        torch.Generator().manual_seed(0),
    )
    assert occ.shape == (1, 3, 16, 16, 16) and occ.dtype == torch.bool
    assert exists.shape == (1, 3)
    assert not occ[~exists].any()


def test_tidy_parts_hand_computed_case():
    import numpy as np

    from generator.pact.model.stage1 import tidy_parts

    occ = np.zeros((4, 8, 8, 8), bool)
    occ[0, :6, :6, :6] = True  # base: 216 voxels
    occ[1, 4:8, 0:3, 0:3] = True  # a door: 36 voxels, 18 of them inside the base
    occ[2, 0, 7, 7] = True  # a one-voxel speck
    occ[3, 0:2, 0:2, 6:8] = True  # a part the mask does not show
    occ[1, 7, 5:8, 5:8] = True  # a stray 9-voxel chunk of the door, apart from it
    occ[0, 7, 7, 0:2] = True  # a stray 2-voxel chunk of the base: a speck
    exists = np.array([True, False, True, True])  # the head dropped the door
    out, ex = tidy_parts(occ, exists, mask_ids=np.array([0, 1, 2, 3]))
    assert ex.tolist() == [True, True, False, False]  # the mask's part list wins
    # the door keeps its voxels and only its largest piece; the base loses the speck
    assert out.reshape(4, -1).sum(1).tolist() == [216 - 18, 36, 0, 0]
    assert not (out[0] & out[1]).any()
    # without a mask the existence flags decide
    out, ex = tidy_parts(occ, exists)
    assert ex.tolist() == [True, False, False, True]
    assert out[3].sum() == 8 and out[0].sum() == 216


def test_conditioning_init_options():
    """By default the mask projection starts at zero (the image tokens are unchanged) and
    E starts at 0.02 scale; ``zero_init_mask_proj=False`` with ``part_embed_std=1`` makes
    the mask change the image tokens from the first step, at the image tokens' scale."""
    from dataclasses import replace

    torch.manual_seed(0)
    cond = torch.randn(1, TINY_FLOW.cond_tokens, TINY_FLOW.cond_dim)
    mask = torch.ones(1, 8, 8, dtype=torch.long)
    mask[..., 4:] = 2
    default = build("part_flow", TINY_FLOW)
    assert torch.equal(default.context(cond, mask, None, None, 1), cond)
    assert float(default.part_embed.std()) < 0.05
    live = build("part_flow", replace(TINY_FLOW, part_embed_std=1.0, zero_init_mask_proj=False))
    added = live.context(cond, mask, None, None, 1) - cond
    assert 0.5 < float(live.part_embed.std()) < 1.5
    assert float(added[:, TINY_FLOW.cond_prefix_tokens :].pow(2).mean().sqrt()) > 0.1
    assert torch.equal(added[:, : TINY_FLOW.cond_prefix_tokens], torch.zeros_like(added[:, :1]))


def _box_shell(lo, hi, R=16):
    import numpy as np

    solid = np.zeros((R, R, R), bool)
    solid[lo[0] : hi[0], lo[1] : hi[1], lo[2] : hi[2]] = True
    inner = np.zeros_like(solid)
    inner[lo[0] + 1 : hi[0] - 1, lo[1] + 1 : hi[1] - 1, lo[2] + 1 : hi[2] - 1] = True
    return solid & ~inner


def test_close_surface_fills_wall_holes_and_keeps_a_kneehole_open():
    import numpy as np

    from generator.pact.model.stage1 import close_surface

    # a cabinet: a box shell (x 2..12, y 2..14, z 0..12) with a drawer front in it
    occ = np.zeros((3, 16, 16, 16), bool)
    occ[0] = _box_shell((2, 2, 0), (12, 14, 12))
    occ[1, 11, 4:10, 6:10] = True  # the drawer's front panel, in the front wall (x = 11)
    occ[0] &= ~occ[1]
    occ[0, 5:8, 2, 4:7] = False  # a 3 x 3 hole in the side wall (y = 2)
    occ[1, 11, 6:8, 7:9] = False  # a 2 x 2 hole in the drawer's front
    out = close_surface(occ)
    assert out[0, 5:8, 2, 4:7].all()  # the wall's hole is the base's again
    assert out[1, 11, 6:8, 7:9].all() and not out[0, 11, 6:8, 7:9].any()  # the drawer's
    assert not (out[0] & out[1]).any()
    assert out.sum() == occ.sum() + 9 + 4  # nothing else added: the inside stays hollow
    # a desk: a top (z 10..11) on two pedestals (y 1..4 and y 11..14), the kneehole
    # between them open at the front, the back and the floor
    desk = np.zeros((2, 16, 16, 16), bool)
    desk[0, 2:12, 1:15, 10:12] = True
    desk[0, 2:12, 1:5, 0:10] = True
    desk[0, 2:12, 11:15, 0:10] = True
    closed = close_surface(desk)
    assert not closed[:, :, 5:11, 0:10].any()  # nothing closes the kneehole
    assert (closed == desk).all()
    assert (close_surface(np.zeros((2, 8, 8, 8), bool)) == 0).all()
