"""PAct stage 2: SLAT VAE, structure-conditioned flow, articulation head (tiny configs)."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import torch

from generator.articulated import Primitive
from generator.pact.model.articulation import (
    ArticulationHead,
    ArticulationHeadConfig,
    ArticulationTargets,
    FeatureAggregator,
    pool_parts,
    project_origin_to_aabb,
)
from generator.pact.model.slat_vae import (
    SlatVAE,
    SlatVAEConfig,
    SlatVAETrainConfig,
    decode_part_mesh,
    shell_voxels,
    sparse_parts,
    vae_loss,
)
from generator.pact.model.stage2 import (
    Stage2SamplerConfig,
    Stage2TrainConfig,
    collate,
    sample_stage2,
    tokenize,
    training_step,
    untokenize,
)
from generator.pact.model.stage2_flow import Stage2FlowConfig, Stage2FlowTransformer, TokenBatch
from generator.pact.training.stage2_data import primitive_sdf, subsample_points


@pytest.fixture(autouse=True)
def _one_thread():
    # tiny models: on a shared 2-core machine, two OpenMP threads spin-wait for each other
    # (one SLAT VAE step: 0.02 s with 1 thread, 0.8 s with 2 under load)
    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)


TINY_FLOW = Stage2FlowConfig(
    max_parts=4, latent_channels=8, patch_size=4, resolution=32, width=32, depth=2, heads=2,
    cond_dim=16, max_tokens=128,
)  # fmt: skip


def _box_part(size=(0.3, 0.2, 0.25), centre=(0.0, 0.05, -0.1)):
    """A box part: occupancy (32^3), its token voxels, their SDF sub-samples (truncated)."""
    T = np.eye(4)
    T[:3, 3] = centre
    prim = Primitive("box", np.array(size), T)
    c = -0.5 + (np.arange(32) + 0.5) / 32
    grid = np.stack(np.meshgrid(c, c, c, indexing="ij"), -1).reshape(-1, 3)
    occ = (primitive_sdf(prim, grid) <= 0.5 * np.sqrt(3) / 32).reshape(32, 32, 32)
    coords = np.argwhere(shell_voxels(occ))
    sdf = primitive_sdf(prim, subsample_points(coords).reshape(-1, 3)) * 32
    return occ, coords, np.clip(sdf, -1, 1).reshape(len(coords), 64).astype(np.float32)


def _tiny_tokens(seed: int = 0):
    occ = np.zeros((4, 32, 32, 32), bool)
    occ[0, 4:20, 4:20, 4:12] = True
    occ[1, 20:28, 8:16, 8:16] = True
    from generator.pact.model.stage2 import voxels_from_occupancy

    coords, slot = voxels_from_occupancy(occ)
    z = np.random.default_rng(seed).normal(size=(len(coords), 8)).astype(np.float32)
    return tokenize(coords, slot, occ, TINY_FLOW, z), z


# --------------------------------------------------------------------------- head


def test_aggregator_matches_hand_computation():
    # 3 steps, S = 2: steps 1 and 2 are averaged; tokens 0, 1 belong to part 0, token 2 to part 1
    steps = [
        torch.tensor([[[9.0, 9.0], [9.0, 9.0], [9.0, 9.0]]]),
        torch.tensor([[[1.0, 2.0], [3.0, 0.0], [5.0, -1.0]]]),
        torch.tensor([[[3.0, 4.0], [1.0, 2.0], [7.0, 1.0]]]),
    ]
    agg = FeatureAggregator(total_steps=3, last=2)
    for i, f in enumerate(steps):
        agg(i, 1.0 - i / 3, f)
    assert agg.used == [1, 2]
    H = agg.mean()  # by hand: [[2, 3], [2, 1], [6, 0]]
    assert torch.allclose(H, torch.tensor([[[2.0, 3.0], [2.0, 1.0], [6.0, 0.0]]]))
    pooled, present = pool_parts(
        H, torch.tensor([[0, 0, 1]]), torch.ones(1, 3, dtype=torch.bool), max_parts=3
    )
    # part 0: mean [2, 2], max [2, 3]; part 1: mean = max = [6, 0]; part 2 absent
    assert torch.allclose(pooled[0, 0], torch.tensor([2.0, 2.0, 2.0, 3.0]))
    assert torch.allclose(pooled[0, 1], torch.tensor([6.0, 0.0, 6.0, 0.0]))
    assert present[0].tolist() == [True, True, False]


def test_changing_s_changes_the_steps_read():
    torch.manual_seed(0)
    flow = Stage2FlowTransformer(TINY_FLOW).eval()
    toks, _ = _tiny_tokens()
    batch = collate([toks], TINY_FLOW.max_tokens)
    cond = torch.randn(1, 5, 16)
    used = {}
    for S in (1, 3, 5):
        agg = FeatureAggregator(total_steps=5, last=S)
        sample_stage2(flow, batch, cond, Stage2SamplerConfig(steps=5, cfg_scale=2.0), None, agg)
        used[S] = agg.used
    assert used == {1: [4], 3: [2, 3, 4], 5: [0, 1, 2, 3, 4]}
    with pytest.raises(ValueError):
        FeatureAggregator(total_steps=5, last=6)


def test_joint_outputs_always_valid():
    torch.manual_seed(0)
    head = ArticulationHead(ArticulationHeadConfig(in_dim=16, hidden=32, layers=6))
    for scale in (0.0, 1.0, 100.0):
        out = head(torch.randn(64, 32) * scale)
        assert torch.allclose(out.axis.norm(dim=-1), torch.ones(64), atol=1e-5)
        assert (out.range[:, 0] < out.range[:, 1]).all()
        assert out.type_logits.shape == (64, 3) and out.semantic_logits.shape == (64, 4)
    assert sum(isinstance(m, torch.nn.Linear) for m in head.modules()) == 6


def test_origin_projection_onto_aabb_surface():
    lo, hi = np.zeros(3), np.array([1.0, 2.0, 1.0])
    # inside, nearest face is x = 0 (distance 0.2)
    assert np.allclose(project_origin_to_aabb([0.2, 1.0, 0.5], lo, hi), [0.0, 1.0, 0.5])
    # inside, nearest face is y = 2 (distance 0.1)
    assert np.allclose(project_origin_to_aabb([0.5, 1.9, 0.5], lo, hi), [0.5, 2.0, 0.5])
    # outside: the clamped point
    assert np.allclose(project_origin_to_aabb([2.0, 1.0, -1.0], lo, hi), [1.0, 1.0, 0.0])
    # on the surface: unchanged
    assert np.allclose(project_origin_to_aabb([1.0, 0.3, 0.4], lo, hi), [1.0, 0.3, 0.4])


# --------------------------------------------------------------------------- SLAT VAE


def test_slat_vae_shapes_and_overfit_one_part():
    torch.manual_seed(0)
    occ, coords, sdf = _box_part(size=(0.2, 0.15, 0.15))
    sp = sparse_parts(
        torch.from_numpy(coords), torch.zeros(len(coords), dtype=torch.long),
        torch.from_numpy(occ)[None],
    )  # fmt: skip
    assert sp.neighbours.shape == (len(coords), 27) and (sp.neighbours[:, 13] >= 0).all()
    vae = SlatVAE(SlatVAEConfig(embed=8, hidden=64))
    sdf_t = torch.from_numpy(sdf)
    rgb_t = torch.full((len(coords), 3), 0.2)
    mean, logvar = vae.encode(sdf_t, rgb_t, sp)
    assert mean.shape == logvar.shape == (len(coords), 8)
    s, c = vae.decode(mean, sp)
    assert s.shape == (len(coords), 64) and c.shape == (len(coords), 3)
    opt = torch.optim.Adam(vae.parameters(), lr=5e-3)
    tcfg = SlatVAETrainConfig(kl_weight=1e-5)
    for _ in range(150):
        loss, m = vae_loss(vae(sdf_t, rgb_t, sp), sdf_t, rgb_t, tcfg)
        opt.zero_grad()
        loss.backward()
        opt.step()
    out = vae(sdf_t, rgb_t, sp, sample=False)
    assert (out.sdf - sdf_t).abs().mean() < 0.05
    mesh = decode_part_mesh(
        coords, out.sdf.detach().numpy(), np.full((len(coords), 3), 90, np.uint8), occ
    )
    assert mesh is not None
    assert np.allclose(mesh.extents, [0.2, 0.15, 0.15], atol=0.03)


# --------------------------------------------------------------------------- flow


def test_tokenize_roundtrip_and_bound():
    toks, z = _tiny_tokens()
    assert len(toks.slot) <= TINY_FLOW.max_parts * TINY_FLOW.grid**3
    assert np.allclose(untokenize(toks.x, toks, 8), z)
    assert toks.active.sum() == len(z)


def test_part_embedding_added_to_every_token_of_its_part():
    torch.manual_seed(0)
    flow = Stage2FlowTransformer(TINY_FLOW).eval()
    _randomize(flow)
    toks, _ = _tiny_tokens()
    batch = collate([toks], TINY_FLOW.max_tokens)
    moved = batch._replace(slot=torch.where(batch.slot == 1, 3, batch.slot))
    diff = flow.embed_tokens(moved) - flow.embed_tokens(batch)  # (1, L, D)
    expect = (flow.part_embed[3] - flow.part_embed[1]).detach()
    is1 = batch.slot[0] == 1
    assert torch.allclose(diff[0, is1], expect.expand(int(is1.sum()), -1), atol=1e-6)
    assert torch.allclose(diff[0, ~is1], torch.zeros(1), atol=1e-6)
    cond, t = torch.randn(1, 5, 16), torch.tensor([0.5])
    with torch.no_grad():
        assert not torch.allclose(flow(moved, t, cond).velocity, flow(batch, t, cond).velocity)
        flow.part_embed[3] = flow.part_embed[1]  # same embedding row: same output
        assert torch.allclose(flow(moved, t, cond).velocity, flow(batch, t, cond).velocity)


def _randomize(flow: Stage2FlowTransformer) -> None:
    with torch.no_grad():  # adaLN-Zero and zero out_proj would make every output 0
        for p in flow.parameters():
            p.add_(torch.randn_like(p) * 0.05)


def _sampling_inputs() -> tuple[Stage2FlowTransformer, TokenBatch, torch.Tensor]:
    """A randomized tiny flow, one object's token batch and its image tokens."""
    torch.manual_seed(0)
    flow = Stage2FlowTransformer(TINY_FLOW).eval()
    _randomize(flow)
    toks, _ = _tiny_tokens()
    return flow, collate([toks], TINY_FLOW.max_tokens), torch.randn(1, 5, 16)


def test_cfg_scale_one_equals_conditional_and_sampling_is_deterministic():
    flow, batch, cond = _sampling_inputs()
    sampler = Stage2SamplerConfig(steps=4, cfg_scale=1.0)
    x = sample_stage2(flow, batch, cond, sampler, torch.Generator().manual_seed(3))
    # reference: plain conditional Euler from the same noise
    m = batch.active.repeat_interleave(8, -1).float()
    ref = torch.randn(batch.x.shape, generator=torch.Generator().manual_seed(3)) * m
    ts = torch.linspace(1.0, 0.0, 5, dtype=torch.float64)
    with torch.no_grad():
        for i in range(4):
            v = flow(batch.with_x(ref), torch.full((1,), float(ts[i])), cond).velocity
            ref = (ref + float(ts[i + 1] - ts[i]) * v) * m
    assert torch.allclose(x, ref, atol=1e-5)
    again = sample_stage2(flow, batch, cond, sampler, torch.Generator().manual_seed(3))
    other = sample_stage2(flow, batch, cond, sampler, torch.Generator().manual_seed(4))
    assert torch.equal(x, again) and not torch.allclose(x, other)
    guided = sample_stage2(flow, batch, cond, Stage2SamplerConfig(steps=4, cfg_scale=3.0),
                           torch.Generator().manual_seed(3))  # fmt: skip
    assert not torch.allclose(x, guided)


def test_stage2_guidance_interval_outside_is_the_conditional_step():
    flow, batch, cond = _sampling_inputs()

    def draw(**kw):
        return sample_stage2(flow, batch, cond, Stage2SamplerConfig(steps=4, **kw),
                             torch.Generator().manual_seed(3))  # fmt: skip

    never = draw(cfg_scale=3.0, cfg_interval=(2.0, 3.0))
    assert torch.allclose(never, draw(cfg_scale=1.0), atol=1e-5)
    half = draw(cfg_scale=3.0, cfg_interval=(0.5, 1.0))
    assert not torch.allclose(half, never, atol=1e-4)
    assert not torch.allclose(half, draw(cfg_scale=3.0), atol=1e-4)


def test_x0_prediction_velocity_by_hand():
    """predict="x0" with the zero-initialised output layer: x0_hat = 0, so the velocity is
    x_t / t on token voxels and 0 elsewhere."""
    from dataclasses import replace

    flow = Stage2FlowTransformer(replace(TINY_FLOW, predict="x0")).eval()
    toks, _ = _tiny_tokens()
    batch = collate([toks], TINY_FLOW.max_tokens)
    m = batch.active.repeat_interleave(8, -1).float()
    x = torch.randn(batch.x.shape, generator=torch.Generator().manual_seed(0)) * m
    with torch.no_grad():
        v = flow(batch.with_x(x), torch.full((1,), 0.25), torch.randn(1, 5, 16)).velocity
    assert torch.allclose(v, x / 0.25, atol=1e-5)
    assert float(v.abs().max()) > 0


def test_training_step_joint_loss_backpropagates():
    torch.manual_seed(0)
    from generator.pact.model.image_encoder import ImageEncoder, ViTConfig

    models = {
        "image_encoder": ImageEncoder(
            ViTConfig(image_size=32, patch_size=16, width=16, depth=1, heads=2)
        ),
        "flow": Stage2FlowTransformer(TINY_FLOW),
        "head": ArticulationHead(ArticulationHeadConfig(in_dim=32, hidden=32)),
    }
    toks, _ = _tiny_tokens()
    batch = collate([toks, _tiny_tokens(1)[0]], TINY_FLOW.max_tokens)
    K = TINY_FLOW.max_parts
    tgt = ArticulationTargets(
        torch.tensor([[0, 2, 0, 0], [0, 3, 0, 0]]), torch.tensor([[0, 1, 0, 0], [0, 2, 0, 0]]),
        torch.zeros(2, K, 3), torch.tensor([1.0, 0, 0]).expand(2, K, 3), torch.ones(2, K, 2),
    )  # fmt: skip
    loss, m = training_step(models, batch, torch.rand(2, 3, 32, 32), tgt, Stage2TrainConfig())
    loss.backward()
    assert np.isfinite(m["loss"]) and m["art"] > 0
    assert models["head"].out.weight.grad.abs().sum() > 0
    # out_proj starts at zero, so at init only L_art sends gradient into the token path
    assert models["flow"].input_proj.weight.grad.abs().sum() > 0


@pytest.fixture(scope="module")
def shipped_pact():
    from generator.pact.inference.generate import PActGenerator

    return PActGenerator.default(device="cpu")


@pytest.mark.slow
# one example with a drawer and a door (the other examples run in tests/test_cli.py)
@pytest.mark.parametrize("name", ["cabinet_t0000001"])
def test_shipped_model_generates_an_object_that_builds_and_validates(shipped_pact, name, tmp_path):
    """The shipped small PAct (both stages + head) on a bundled example image and mask:
    a valid ArticulatedObject with at most the mask's movable parts, valid joints (type,
    unit axis, lower < upper), per-stage timings, and (through the box layout,
    generator.box_layout) an asset that builds and passes every SAPIEN check without
    repairs, one of whose parts the scripted solver opens in SAPIEN. The cabinet has six
    movable parts, which stage 1 lays out badly."""
    import json
    from pathlib import Path

    from PIL import Image

    from asset_pipeline.assets.build import build_asset
    from asset_pipeline.validate import validate_asset
    from generator.bundle import save_bundle

    root = Path(__file__).resolve().parents[1] / "examples" / "images"
    image = np.asarray(Image.open(root / f"{name}.png").convert("RGB"))
    mask = np.asarray(Image.open(root / f"{name}.mask.png"))
    hints = json.loads((root / f"{name}.json").read_text())
    gen = shipped_pact
    obj = gen.generate(image, mask, hints)
    obj.validate(name)
    movable = [p for p in obj.parts if not p.is_base]
    assert 1 <= len(movable) <= len(set(np.unique(mask).tolist()) - {0, 1})
    for p in movable:
        j = p.joint
        assert j.type in ("revolute", "prismatic")
        assert np.isclose(np.linalg.norm(j.axis), 1.0, atol=1e-5)
        assert j.lower < j.upper
    assert {"stage1", "stage2", "decode", "articulation"} <= set(gen.timings)
    assert all(t >= 0 for t in gen.timings.values())

    d = save_bundle(obj, tmp_path / name)
    build_asset(d, height=hints.get("height"))
    report = validate_asset(d, preview=False, repair=False)
    assert report.ok, report.reasons

    # the task-level check: the scripted Panda grasps the layout's handle and opens a part
    from sim_envs import FolderSource
    from tasks.solver import solve_part

    (record,) = list(FolderSource(tmp_path))
    part = movable[0].name  # the microwave's door; the cabinet's drawer_1
    res, _ = solve_part(record, part, seed=0)
    assert res.success, (name, part, res)


def _joint(type_: str, semantic: str, origin, axis):  # noqa: ANN202
    from generator.pact.model.articulation import PartJoint

    return PartJoint(
        type_, semantic, np.array(origin, float), np.array(axis, float), 0.0, 1.2, np.ones(3) / 3
    )


def test_joint_type_from_the_stage1_head_where_the_heads_disagree(monkeypatch):
    """``stage2+types1``: a part keeps stage 2's joint where the stage-1 head reads the
    same joint type (its own origin and axis are not taken), takes the stage-1 head's
    joint where it reads another type, and keeps stage 2's where stage 1 has none. It is
    the default only with a stage-1 head and stage-1 features."""
    from types import SimpleNamespace

    from generator.pact.inference.generate import PActGenerator

    j2 = [
        None,
        _joint("revolute", "door", (0.2, -0.3, 0.0), (0, 0, 1)),
        _joint("prismatic", "drawer", (0.2, 0.0, 0.1), (1, 0, 0)),
        _joint("revolute", "door", (0.2, 0.3, 0.0), (0, 0, -1)),
    ]
    j1 = [
        None,
        _joint("prismatic", "drawer", (0.2, 0.0, -0.2), (1, 0, 0)),
        _joint("prismatic", "drawer", (0.0, 0.0, 0.0), (0, 1, 0)),
        None,
    ]
    real = PActGenerator.articulation

    def per_head(self, run, agg_steps=None, source=None):  # noqa: ANN001, ANN202
        return {"stage2": j2, "stage1": j1}.get(source) or real(self, run, agg_steps, source)

    monkeypatch.setattr(PActGenerator, "articulation", per_head)
    gen = object.__new__(PActGenerator)
    run = SimpleNamespace(features_1=[np.zeros(1)], features_2=[np.zeros(1)])
    out = real(gen, run, None, "stage2+types1")
    assert out[0] is None
    assert out[1] is j1[1]  # the heads disagree: the stage-1 head's drawer
    assert out[2] is j2[2]  # both read a drawer: stage 2's axis and origin
    assert out[3] is j2[3]  # no stage-1 joint
    gen.stage1_head = object()
    assert gen.articulation_source(run) == "stage2+types1"
    assert gen.articulation_source(SimpleNamespace(features_1=[], features_2=[1])) == "stage2"
    gen.stage1_head = None
    assert gen.articulation_source(run) == "stage2"
    assert gen.articulation_source(run, "stage1") == "stage1"


def test_category_prior_hinges_doors_as_the_category_does():
    """A user's category hint: a microwave's door hinged at its bottom edge turns to a
    side hinge (at the side nearest the prediction), an oven's side-hinged door to a
    bottom hinge, a microwave 'drawer' to a door; a cabinet's door, a lid and a part
    that is not a front panel keep what the head predicted."""
    from generator.pact.model.articulation import apply_category_prior

    lo, hi = np.array([0.3, -0.4, -0.3]), np.array([0.35, 0.2, 0.3])  # a front panel
    j = apply_category_prior(
        _joint("revolute", "door", (0.35, 0.1, -0.3), (0, 1, 0)), "microwave", lo, hi, 0.35
    )
    assert np.allclose(j.axis, (0, 0, 1)) and np.allclose(j.origin, (0.35, 0.2, 0.0))
    assert j.upper - j.lower >= np.pi / 2
    j = apply_category_prior(
        _joint("revolute", "door", (0.35, -0.4, 0.0), (0, 0, 1)), "oven", lo, hi, 0.35
    )
    assert np.allclose(j.axis, (0, 1, 0)) and np.allclose(j.origin, (0.35, -0.1, -0.3))
    j = apply_category_prior(
        _joint("prismatic", "drawer", (0.35, 0, 0), (1, 0, 0)), "microwave", lo, hi, 0.35
    )
    assert (j.type, j.semantic) == ("revolute", "door") and np.allclose(j.axis, (0, 0, 1))
    # left alone: no rule for cabinets; a drawer of an oven; a part away from the front
    for category, joint, front in (
        ("cabinet", _joint("revolute", "door", (0.35, 0.1, -0.3), (0, 1, 0)), 0.35),
        ("oven", _joint("prismatic", "drawer", (0.35, 0, 0), (1, 0, 0)), 0.35),
        ("microwave", _joint("revolute", "door", (0.35, 0.1, -0.3), (0, 1, 0)), 0.6),
    ):
        before = (joint.type, joint.semantic, joint.origin.copy(), joint.axis.copy())
        after = apply_category_prior(joint, category, lo, hi, front)
        assert (after.type, after.semantic) == before[:2]
        assert np.allclose(after.origin, before[2]) and np.allclose(after.axis, before[3])


def test_shape_prior_types_wide_side_hinged_front_parts_as_drawers():
    """Without a hint: a 'door' hinged about a vertical axis whose front is 3x as wide as
    tall becomes a drawer sliding along +x by 0.6 of the object's depth, or, 0.6 of the
    object tall, a door hinged at its bottom edge. A wide door
    hinged at its bottom edge (an oven's), a lid, a part back from the front, a square
    door, a drawer as wide as tall, and narrow drawers a quarter and nine tenths of the
    object tall (a chest's small one, a desk's pedestal drawer) keep what the head
    predicted."""
    from generator.pact.model.articulation import apply_shape_prior

    obj_lo, obj_hi = np.array([-0.4, -0.5, -0.5]), np.array([0.4, 0.5, 0.5])
    wide_lo, wide_hi = np.array([0.35, -0.3, 0.1]), np.array([0.4, 0.3, 0.3])  # 0.6 x 0.2
    j = apply_shape_prior(
        _joint("revolute", "door", (0.4, -0.3, 0.2), (0, 0, 1)), wide_lo, wide_hi, obj_lo, obj_hi
    )
    assert (j.type, j.semantic) == ("prismatic", "drawer")
    assert np.allclose(j.axis, (1, 0, 0)) and np.isclose(j.upper - j.lower, 0.6 * 0.8)
    # as wide for its height but 0.6 of the object tall: an oven's door, hinged at the bottom
    oven_lo, oven_hi = np.array([0.35, -0.65, -0.4]), np.array([0.4, 0.65, 0.2])  # 1.3 x 0.6
    wide_obj = (np.array([-0.4, -0.7, -0.5]), np.array([0.4, 0.7, 0.5]))
    j = apply_shape_prior(
        _joint("revolute", "door", (0.4, -0.65, 0), (0, 0, 1)), oven_lo, oven_hi, *wide_obj
    )
    assert (j.type, j.semantic) == ("revolute", "door")
    assert np.allclose(j.axis, (0, 1, 0)) and np.allclose(j.origin, (0.4, 0.0, -0.4))
    square_lo, square_hi = np.array([0.35, -0.3, -0.3]), np.array([0.4, 0.3, 0.3])
    box_lo, box_hi = np.array([0.0, 0.1, -0.5]), np.array([0.4, 0.4, -0.2])  # 0.3 x 0.3
    small_lo, small_hi = np.array([0.0, 0.1, 0.1]), np.array([0.4, 0.25, 0.35])  # 0.15 x 0.25
    file_lo, file_hi = np.array([0.0, 0.1, -0.5]), np.array([0.4, 0.5, 0.4])  # 0.4 x 0.9
    for joint, lo, hi in (
        (_joint("revolute", "door", (0.4, 0, 0.1), (0, 1, 0)), wide_lo, wide_hi),  # bottom hinge
        (_joint("revolute", "lid", (0.4, 0, 0.3), (0, 0, 1)), wide_lo, wide_hi),
        (_joint("revolute", "door", (0.2, -0.3, 0), (0, 0, 1)), wide_lo - 0.2, wide_hi - 0.2),
        (_joint("revolute", "door", (0.4, -0.3, 0), (0, 0, 1)), square_lo, square_hi),
        (_joint("prismatic", "drawer", (0.4, 0.25, -0.35), (1, 0, 0)), box_lo, box_hi),
        (_joint("prismatic", "drawer", (0.4, 0.2, 0.2), (1, 0, 0)), small_lo, small_hi),
        (_joint("prismatic", "drawer", (0.4, 0.3, 0.0), (1, 0, 0)), file_lo, file_hi),
    ):
        before = (joint.type, joint.semantic, joint.origin.copy(), joint.axis.copy())
        after = apply_shape_prior(joint, lo, hi, obj_lo, obj_hi)
        assert (after.type, after.semantic) == before[:2]
        assert np.allclose(after.origin, before[2]) and np.allclose(after.axis, before[3])


def test_shape_prior_makes_a_drawer_taller_than_wide_a_side_hinged_door():
    """A front part the heads call a drawer but whose front is twice as tall as wide and
    0.7 of the object tall (a cupboard's door the stage-1 sample drew as deep as a
    drawer) becomes a door hinged about a vertical axis at its edge nearer the object's
    side, a quarter turn."""
    from generator.pact.model.articulation import apply_shape_prior

    obj_lo, obj_hi = np.array([-0.4, -0.5, -0.5]), np.array([0.4, 0.5, 0.5])
    for lo, hi, hinge_y in (
        (np.array([-0.3, 0.1, -0.4]), np.array([0.4, 0.45, 0.3]), 0.45),  # right of middle
        (np.array([-0.3, -0.45, -0.4]), np.array([0.4, -0.1, 0.3]), -0.45),  # left
    ):
        j = apply_shape_prior(
            _joint("prismatic", "drawer", (0.4, 0, 0), (1, 0, 0)), lo, hi, obj_lo, obj_hi
        )
        assert (j.type, j.semantic) == ("revolute", "door")
        assert np.allclose(j.axis, (0, 0, 1)) and np.isclose(j.origin[1], hinge_y)
        assert np.isclose(j.origin[0], 0.4) and np.isclose(j.upper - j.lower, np.pi / 2)


def test_shape_prior_makes_a_full_width_front_part_of_a_tall_appliance_an_oven_door():
    """A wall oven 0.6 wide and 1.0 tall whose upper door (full width, 0.28 of the height)
    the heads call a drawer, or a side-hinged door (it is over twice as wide as tall, a
    drawer's shape): the door hinges at its bottom front edge. A nightstand's drawer in a
    frame (0.85 of the width, twice as wide as tall), called either, and an oven's
    storage drawer (0.2 of the height of an oven 1.25 as tall as wide), are drawers."""
    from generator.pact.model.articulation import apply_shape_prior

    oven = (np.array([-0.3, -0.3, -0.5]), np.array([0.3, 0.3, 0.5]))
    upper = (np.array([-0.2, -0.3, 0.12]), np.array([0.3, 0.3, 0.4]))
    framed = (np.array([-0.2, -0.255, 0.15]), np.array([0.3, 0.255, 0.4]))
    for called in (
        _joint("prismatic", "drawer", (0.3, 0, 0), (1, 0, 0)),
        _joint("revolute", "door", (0.3, -0.3, 0.25), (0, 0, 1)),
    ):
        j = apply_shape_prior(copy.deepcopy(called), *upper, *oven)
        assert (j.type, j.semantic) == ("revolute", "door")
        assert np.allclose(j.axis, (0, 1, 0)) and np.allclose(j.origin, (0.3, 0.0, 0.12))
        j = apply_shape_prior(copy.deepcopy(called), *framed, *oven)
        assert (j.type, j.semantic) == ("prismatic", "drawer")
    low = (np.array([-0.4, -0.4, -0.5]), np.array([0.4, 0.4, 0.5]))  # 0.8 wide, 1.0 tall
    storage = (np.array([-0.3, -0.4, -0.5]), np.array([0.4, 0.4, -0.3]))
    j = apply_shape_prior(_joint("prismatic", "drawer", (0.4, 0, 0), (1, 0, 0)), *storage, *low)
    assert j.type == "prismatic"


def test_door_panel_keeps_the_front_slab_closed_and_coloured():
    """The door made of a part drawn 0.5 deep is its front 0.1: a closed slab from x = 0.15
    to 0.25 with the part's full face, coloured as the part."""
    import trimesh

    from generator.pact.inference.generate import door_panel

    part = trimesh.creation.box((0.5, 0.3, 0.6))  # x from -0.25 to 0.25
    part.visual.vertex_colors = np.tile([200, 30, 30, 255], (len(part.vertices), 1))
    slab = door_panel(part, 0.1)
    assert np.allclose(slab.bounds, [[0.15, -0.15, -0.3], [0.25, 0.15, 0.3]])
    assert slab.is_watertight and np.isclose(slab.volume, 0.1 * 0.3 * 0.6)
    assert (np.asarray(slab.visual.vertex_colors)[:, :3] == (200, 30, 30)).all()
    assert door_panel(part, 0.6) is part  # nothing to cut: the part as it is


def test_lid_panel_keeps_the_top_slab_closed_and_coloured():
    """The lid made of a part drawn 0.6 tall is its top 0.05: a closed slab from z = 0.25
    to 0.3 over the part's whole depth and width (a door's cut would keep the front
    instead, a strip along the top of the front), coloured as the part."""
    import trimesh

    from generator.pact.inference.generate import lid_panel

    part = trimesh.creation.box((0.5, 0.3, 0.6))  # z from -0.3 to 0.3
    part.visual.vertex_colors = np.tile([30, 200, 30, 255], (len(part.vertices), 1))
    slab = lid_panel(part, 0.05)
    assert np.allclose(slab.bounds, [[-0.25, -0.15, 0.25], [0.25, 0.15, 0.3]])
    assert slab.is_watertight and np.isclose(slab.volume, 0.5 * 0.3 * 0.05)
    assert (np.asarray(slab.visual.vertex_colors)[:, :3] == (30, 200, 30)).all()
    assert lid_panel(part, 0.7) is part  # nothing to cut: the part as it is


def test_shape_prior_hinges_off_centre_doors_at_their_outer_edge():
    """The two doors of a pair (each a quarter of the width off the middle), whatever side
    the head hinged them at, hinge at their outer edges; a door in the middle keeps the
    head's side."""
    from generator.pact.model.articulation import apply_shape_prior

    obj_lo, obj_hi = np.array([-0.4, -0.5, -0.5]), np.array([0.4, 0.5, 0.5])
    left = (np.array([0.35, -0.48, -0.4]), np.array([0.4, -0.01, 0.4]))
    right = (np.array([0.35, 0.01, -0.4]), np.array([0.4, 0.48, 0.4]))
    j = apply_shape_prior(
        _joint("revolute", "door", (0.4, -0.01, 0), (0, 0, 1)), *left, obj_lo, obj_hi
    )
    assert j.type == "revolute" and np.allclose(j.origin, (0.4, -0.48, 0.0))
    j = apply_shape_prior(
        _joint("revolute", "door", (0.4, 0.01, 0), (0, 0, -1)), *right, obj_lo, obj_hi
    )
    assert j.type == "revolute" and np.allclose(j.origin, (0.4, 0.48, 0.0))
    middle = (np.array([0.35, -0.2, -0.4]), np.array([0.4, 0.25, 0.4]))
    j = apply_shape_prior(
        _joint("revolute", "door", (0.4, 0.25, 0), (0, 0, 1)), *middle, obj_lo, obj_hi
    )
    assert np.allclose(j.origin, (0.4, 0.25, 0.0))


def test_shape_prior_hinges_a_low_boxs_full_width_door_at_the_bottom():
    """An oven (1.2 tall for its width) whose full-width door, 1.25 as wide as tall, the
    head hinged at its side: the door hinges at its bottom edge. The same door on a fridge
    2.5 as tall as wide (a freezer door), or a round washer door as wide as tall, keeps
    its side hinge."""
    from generator.pact.model.articulation import apply_shape_prior

    oven = (np.array([-0.4, -0.4, -0.5]), np.array([0.4, 0.4, 0.46]))  # 0.8 wide, 0.96 tall
    door = (np.array([0.35, -0.4, -0.3]), np.array([0.4, 0.4, 0.34]))  # 0.8 x 0.64
    j = apply_shape_prior(_joint("revolute", "door", (0.4, -0.4, 0), (0, 0, 1)), *door, *oven)
    assert np.allclose(j.axis, (0, 1, 0)) and np.allclose(j.origin, (0.4, 0.0, -0.3))
    fridge = (np.array([-0.2, -0.2, -0.5]), np.array([0.2, 0.2, 0.5]))  # 0.4 wide, 1.0 tall
    freezer = (np.array([0.15, -0.2, 0.18]), np.array([0.2, 0.2, 0.5]))  # 0.4 x 0.32
    j = apply_shape_prior(
        _joint("revolute", "door", (0.2, -0.2, 0.3), (0, 0, 1)), *freezer, *fridge
    )
    assert np.allclose(j.axis, (0, 0, 1))
    washer = (np.array([0.35, -0.38, -0.3]), np.array([0.4, 0.38, 0.46]))  # 0.76 x 0.76
    j = apply_shape_prior(_joint("revolute", "door", (0.4, -0.38, 0), (0, 0, 1)), *washer, *oven)
    assert np.allclose(j.axis, (0, 0, 1))


def test_joint_from_shape_for_parts_no_head_read():
    """A part past the flow's slots: a front part 1.5x as wide as tall is a drawer; a
    panel half as wide as tall a door hinged at its side edge nearer the object's side
    (+y here), but a drawer when it is half the object deep; a part away from the front
    is fixed."""
    from generator.pact.model.articulation import joint_from_shape

    obj_lo, obj_hi = np.array([-0.4, -0.5, -0.5]), np.array([0.4, 0.5, 0.5])
    j = joint_from_shape(np.array([0.35, -0.3, 0.0]), np.array([0.4, 0.0, 0.2]), obj_lo, obj_hi)
    assert (j.type, j.semantic) == ("prismatic", "drawer") and np.allclose(j.axis, (1, 0, 0))
    j = joint_from_shape(np.array([0.35, 0.2, -0.3]), np.array([0.4, 0.5, 0.3]), obj_lo, obj_hi)
    assert (j.type, j.semantic) == ("revolute", "door")
    assert np.allclose(j.axis, (0, 0, 1)) and np.allclose(j.origin, (0.4, 0.5, 0.0))
    assert np.isclose(j.upper - j.lower, np.pi / 2)
    j = joint_from_shape(np.array([0.0, -0.3, 0.0]), np.array([0.2, 0.0, 0.2]), obj_lo, obj_hi)
    assert j.type == "fixed"
    # as narrow, but half the object deep: a box that cannot swing on a front hinge slides
    j = joint_from_shape(np.array([0.0, 0.2, -0.3]), np.array([0.4, 0.5, 0.3]), obj_lo, obj_hi)
    assert j.type == "prismatic"


def test_shape_prior_makes_a_tall_lid_on_the_front_a_front_part():
    """A 'lid' hinged at the back of the top is a lid while it is thin (a top-loading
    washer's, 0.06 of the height); 0.45 of a wall oven's height tall and full width, it is
    the oven's upper door, hinged at its bottom front edge; 0.3 of a nightstand's height
    and 2.5 times as wide as tall, its drawer."""
    from generator.pact.model.articulation import apply_shape_prior

    def lid():  # noqa: ANN202
        return _joint("revolute", "lid", (-0.3, 0, 0.5), (0, -1, 0))

    washer = (np.array([-0.3, -0.3, -0.5]), np.array([0.3, 0.3, 0.5]))
    top = (np.array([-0.25, -0.28, 0.44]), np.array([0.3, 0.28, 0.5]))
    j = apply_shape_prior(lid(), *top, *washer)
    assert (j.type, j.semantic) == ("revolute", "lid")
    assert np.allclose(j.axis, (0, -1, 0)) and np.allclose(j.origin, (-0.3, 0, 0.5))
    oven = washer  # 0.6 wide, 1.0 tall
    upper = (np.array([-0.25, -0.3, 0.05]), np.array([0.3, 0.3, 0.5]))
    j = apply_shape_prior(lid(), *upper, *oven)
    assert (j.type, j.semantic) == ("revolute", "door")
    assert np.allclose(j.axis, (0, 1, 0)) and np.allclose(j.origin, (0.3, 0.0, 0.05))
    nightstand = (np.array([-0.3, -0.4, -0.4]), np.array([0.3, 0.4, 0.4]))  # 0.8 x 0.8
    drawer = (np.array([-0.2, -0.3, 0.16]), np.array([0.3, 0.3, 0.4]))  # 0.6 x 0.24
    j = apply_shape_prior(lid(), *drawer, *nightstand)
    assert (j.type, j.semantic) == ("prismatic", "drawer")
    assert np.allclose(j.axis, (1, 0, 0))


def test_a_stacked_ovens_other_full_width_door_swings_down_too():
    """A stacked oven 1.7 as tall as wide: its upper door hinges at the bottom (the shape
    prior made it so); its lower door, full width and 1.2 as wide as tall, which the
    heads hinge at the side, hinges at its bottom edge too. A fridge's full-width door
    (taller than wide) and a narrower side door keep their side hinge, and with no
    bottom-hinged door on the object nothing changes."""
    from generator.pact.model.articulation import match_oven_doors

    oven = (np.array([-0.3, -0.3, -0.85]), np.array([0.3, 0.3, 0.85]))
    upper = (np.array([0.25, -0.3, 0.2]), np.array([0.3, 0.3, 0.6]))
    lower = (np.array([0.25, -0.3, -0.4]), np.array([0.3, 0.3, 0.1]))  # 0.6 x 0.5
    tall = (np.array([0.25, -0.3, -0.8]), np.array([0.3, 0.3, 0.1]))  # 0.6 x 0.9
    narrow = (np.array([0.25, -0.3, -0.4]), np.array([0.3, 0.2, 0.1]))  # 0.5 of the width

    def bottom():  # noqa: ANN202
        return _joint("revolute", "door", (0.3, 0, 0.2), (0, 1, 0))

    def side():  # noqa: ANN202
        return _joint("revolute", "door", (0.3, -0.3, 0), (0, 0, 1))

    j = match_oven_doors([bottom(), side()], [upper, lower], *oven)
    assert j[1].type == "revolute" and np.allclose(j[1].axis, (0, 1, 0))
    assert np.allclose(j[1].origin, (0.3, 0.0, -0.4))
    for other in (tall, narrow):
        j = match_oven_doors([bottom(), side()], [upper, other], *oven)
        assert np.allclose(j[1].axis, (0, 0, 1)) and np.allclose(j[1].origin, (0.3, -0.3, 0))
    j = match_oven_doors([side(), side()], [upper, lower], *oven)
    assert all(np.allclose(x.axis, (0, 0, 1)) for x in j)
