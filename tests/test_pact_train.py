"""PAct stage-1 training: data, exact resume, logs, data-parallel sync, export, generator."""

from __future__ import annotations

import csv
import json
import os
import socket
from pathlib import Path

import numpy as np
import pytest
import torch
import torch.multiprocessing as mp

from generator.data.shards import pack_occupancy, write_manifest
from generator.pact.inference.stage1_generator import (
    Stage1Generator,
    estimate_joint,
    occupancy_mesh,
)
from generator.pact.model.stage1 import (
    LatentStats,
    build_stage1,
    config_from_dict,
    load_stage1,
    save_stage1,
)
from generator.pact.training.stage1_data import Stage1Dataset, in_val_split
from generator.pact.training.train_stage1 import export_weights, train_stage1

torch.set_num_threads(1)

R, S_IMG, V, MAX_SLOTS = 16, 32, 2, 4
TINY = {
    "vae": {"resolution": R, "latent_channels": 2, "channels": [8, 16], "stem_stride": 2},
    "image_encoder": {"image_size": 32, "patch_size": 16, "width": 16, "depth": 1, "heads": 2},
    "flow": {
        "max_parts": 3,
        "latent_channels": 2,
        "latent_resolution": 4,
        "patch_size": 2,
        "part_embed_dim": 8,
        "width": 32,
        "depth": 2,
        "heads": 2,
        "cond_dim": 16,
        "cond_grid": 2,
        "cond_prefix_tokens": 1,
    },
    "vae_train": {"batch_size": 4, "bf16": False},
    "flow_train": {"batch_size": 2, "bf16": False},
    "sampler": {"steps": 2, "cfg_scale": 2.0},
}
FAST = dict(warmup=1, log_every=1, eval_every=4, ckpt_every=2, val_fraction=0.3)


def write_tiny_dataset(root: Path, n: int = 6) -> Path:
    """n objects (part counts 1..4, so the 4-part ones exceed max_parts=3), boxes."""
    rng = np.random.default_rng(0)
    counts = [1 + i % MAX_SLOTS for i in range(n)]
    occ = np.zeros((n, MAX_SLOTS, R**3 // 8), np.uint8)
    masks = np.zeros((n, V, S_IMG, S_IMG), np.uint8)
    for i, c in enumerate(counts):
        for k in range(c):
            g = np.zeros((R, R, R), bool)
            lo = rng.integers(0, R // 2, 3)
            g[lo[0] : lo[0] + 6, lo[1] : lo[1] + 5, lo[2] : lo[2] + 4] = True
            occ[i, k] = pack_occupancy(g)
            masks[i, :, 4 * k : 4 * k + 4, 4:20] = k + 1
    ids = [f"box_s{i:07d}" for i in range(n)]
    arrays = {
        "object_ids": np.array(ids),
        "part_count": np.array(counts, np.int16),
        "images": rng.integers(0, 255, (n, V, S_IMG, S_IMG, 3), dtype=np.uint8),
        "masks": masks,
        "occupancy": occ,
    }
    root.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(root / "shard_00000.npz", **arrays)
    manifest = {
        "schema": "pact.dataset",
        "version": 1,
        "resolution": R,
        "image_size": S_IMG,
        "views": V,
        "max_parts": MAX_SLOTS,
        "n": n,
        "shards": [{"file": "shard_00000.npz", "objects": ids, "failed": []}],
    }
    write_manifest(root, manifest)
    return root


@pytest.fixture(scope="module")
def tiny(tmp_path_factory) -> tuple[Path, Path]:
    root = tmp_path_factory.mktemp("pact_train")
    data = write_tiny_dataset(root / "data")
    cfg = root / "tiny.json"
    cfg.write_text(json.dumps(TINY))
    return data, cfg


@pytest.fixture(scope="module")
def trained_vae(tiny, tmp_path_factory) -> Path:
    data, cfg = tiny
    out = tmp_path_factory.mktemp("vae_run")
    train_stage1(data, out, str(cfg), "vae", steps=3, **FAST)
    return out


def _weights(models: dict[str, torch.nn.Module]) -> dict[str, torch.Tensor]:
    return {f"{r}.{k}": v.clone() for r, m in models.items() for k, v in m.state_dict().items()}


def _assert_same(a: dict[str, torch.Tensor], b: dict[str, torch.Tensor]) -> None:
    assert a.keys() == b.keys()
    for k in a:
        assert torch.equal(a[k], b[k]), k


# --- data -------------------------------------------------------------------------------


def test_dataset_items_and_skips(tiny):
    data, _ = tiny
    ds = Stage1Dataset(data, max_parts=3, split="all")
    assert ds.num_objects == 5 and ds.skipped == ["box_s0000003"]  # 4 parts > 3 slots
    assert len(ds) == 5 * V
    item = ds[3]  # object 1 (2 parts), view 1
    assert item["image"].shape == (3, S_IMG, S_IMG) and item["image"].dtype == torch.float32
    assert 0.0 <= float(item["image"].min()) and float(item["image"].max()) <= 1.0
    assert item["mask"].shape == (S_IMG, S_IMG) and item["mask"].dtype == torch.int64
    assert int(item["mask"].max()) == 2
    assert item["occupancy"].shape == (3, R, R, R) and item["occupancy"].dtype == torch.bool
    assert item["exists"].tolist() == [True, True, False]
    assert not item["occupancy"][2].any() and item["occupancy"][1].any()
    batch = ds.batch([0, 3, 5])
    assert batch["image"].shape == (3, 3, S_IMG, S_IMG) and batch["object"].tolist() == [0, 1, 2]
    resized = Stage1Dataset(data, max_parts=3, split="all", image_size=16)
    assert resized[0]["image"].shape == (3, 16, 16) and resized[0]["mask"].shape == (16, 16)


def test_split_is_a_stable_partition(tiny):
    data, _ = tiny
    tr = Stage1Dataset(data, 3, "train", val_fraction=0.3)
    va = Stage1Dataset(data, 3, "val", val_fraction=0.3)
    assert set(tr.object_ids).isdisjoint(va.object_ids)
    assert len(tr.object_ids) + len(va.object_ids) == 5
    assert all(in_val_split(o, 0.3) for o in va.object_ids)


# --- training ---------------------------------------------------------------------------


def test_vae_resume_is_bit_exact_and_logs(tiny, tmp_path):
    data, cfg = tiny
    full = train_stage1(data, tmp_path / "a", str(cfg), "vae", steps=4, **FAST)
    train_stage1(data, tmp_path / "b", str(cfg), "vae", steps=4, stop_after=2, **FAST)
    resumed = train_stage1(data, tmp_path / "b", str(cfg), "vae", steps=4, **FAST)
    _assert_same(_weights(full.models), _weights(resumed.models))

    rows = list(csv.DictReader((tmp_path / "b/vae/log.csv").open()))
    steps = [int(r["step"]) for r in rows if r.get("vae/loss")]
    assert steps == [1, 2, 3, 4]  # no duplicated rows after the resume
    assert any(r.get("vae_val/iou") for r in rows)
    assert list((tmp_path / "b/vae/tb").glob("events.out.tfevents.*"))
    assert (tmp_path / "b/vae/checkpoint/ss_vae/model.safetensors").is_file()
    assert not (tmp_path / "b/vae/checkpoint.tmp").exists()


def test_flow_resume_is_bit_exact(tiny, trained_vae, tmp_path):
    """With the input augmentation on: its draws are keyed by step as well."""
    data, cfg = tiny
    vae_dir = str(trained_vae / "vae/checkpoint/ss_vae")
    aug = dict(aug_recolor=0.5, aug_photometric=0.5, aug_rgb_dropout=0.5, aug_mask_noise=0.5)
    kw = dict(FAST, vae_dir=vae_dir, **aug)
    full = train_stage1(data, tmp_path / "a", str(cfg), "flow", steps=4, **kw)
    train_stage1(data, tmp_path / "b", str(cfg), "flow", steps=4, stop_after=2, **kw)
    resumed = train_stage1(data, tmp_path / "b", str(cfg), "flow", steps=4, **kw)
    _assert_same(_weights(full.models), _weights(resumed.models))
    rows = list(csv.DictReader((tmp_path / "b/flow/log.csv").open()))
    assert [int(r["step"]) for r in rows if r.get("flow/loss")] == [1, 2, 3, 4]
    assert any(r.get("flow_val/mse") for r in rows)


def test_flow_snapshots_keep_the_weights_of_their_step(tiny, trained_vae, tmp_path):
    """--snapshot-every: the weights at every K-th step, beside the rolling checkpoint."""
    data, cfg = tiny
    kw = dict(FAST, vae_dir=str(trained_vae / "vae/checkpoint/ss_vae"), snapshot_every=3)
    three = train_stage1(data, tmp_path / "a", str(cfg), "flow", steps=4, stop_after=3, **kw)
    four = train_stage1(data, tmp_path / "b", str(cfg), "flow", steps=4, **kw)
    snaps = sorted(p.name for p in (tmp_path / "b/flow/snapshots").iterdir())
    assert snaps == ["step_000003", "step_000004"]  # every 3rd step and the last
    models, _, _ = load_stage1(tmp_path / "b/flow/snapshots/step_000004/stage1")
    _assert_same(_weights(models), _weights(four.models))
    at3, _, _ = load_stage1(tmp_path / "b/flow/snapshots/step_000003/stage1")
    _assert_same(_weights(at3), _weights(three.models))  # the same schedule stopped at 3
    meta = json.loads((tmp_path / "b/flow/snapshots/step_000003/stage1/config.json").read_text())
    assert meta["extra"]["step"] == 3
    assert meta["extra"]["samples_seen"] == 3 * TINY["flow_train"]["batch_size"]


def test_flow_init_from_starts_at_the_given_weights_and_statistics(tiny, trained_vae, tmp_path):
    data, cfg = tiny
    vae_dir = str(trained_vae / "vae/checkpoint/ss_vae")
    torch.manual_seed(123)  # not the trainer's seed 0: different initial weights
    init_models = build_stage1(config_from_dict(TINY))
    init_models.pop("vae")
    stats = LatentStats((0.5, -0.25), (2.0, 0.5))
    save_stage1(init_models, config_from_dict(TINY), tmp_path / "init", stats)
    kw = dict(FAST, vae_dir=vae_dir, lr=1e-9)  # one step that barely moves the weights
    run = train_stage1(
        data, tmp_path / "a", str(cfg), "flow", steps=1, init_from=str(tmp_path / "init"), **kw
    )
    scratch = train_stage1(data, tmp_path / "b", str(cfg), "flow", steps=1, **kw)
    init, got, fresh = _weights(init_models), _weights(run.models), _weights(scratch.models)
    for k in init:
        torch.testing.assert_close(got[k], init[k], atol=1e-6, rtol=0)
    assert any((fresh[k] - init[k]).abs().max() > 1e-3 for k in init)  # seed 0 differs
    _, _, saved_stats = load_stage1(tmp_path / "a/flow/checkpoint/stage1")
    assert saved_stats == stats  # the latents are normalized as the weights were trained
    other = config_from_dict({**TINY, "flow": {**TINY["flow"], "width": 64}})
    torch.manual_seed(0)
    wide = build_stage1(other)
    wide.pop("vae")
    save_stage1(wide, other, tmp_path / "wide", stats)
    with pytest.raises(ValueError, match="flow config differs"):
        train_stage1(
            data, tmp_path / "c", str(cfg), "flow", steps=1, init_from=str(tmp_path / "wide"), **kw
        )


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _ddp_worker(rank: int, world: int, port: int, data: str, cfg: str, out: str, vae: str):
    os.environ.update(
        MASTER_ADDR="127.0.0.1", MASTER_PORT=str(port), RANK=str(rank), WORLD_SIZE=str(world)
    )
    torch.set_num_threads(1)
    run = train_stage1(data, out, cfg, "flow", steps=3, vae_dir=vae, **FAST)
    torch.save(_weights(run.models), Path(out) / f"rank{rank}.pt")
    torch.distributed.destroy_process_group()


@pytest.mark.slow
def test_ddp_two_gloo_ranks_stay_in_sync(tiny, trained_vae, tmp_path):
    data, cfg = tiny
    vae_dir = str(trained_vae / "vae/checkpoint/ss_vae")
    args = (2, _free_port(), str(data), str(cfg), str(tmp_path), vae_dir)
    mp.spawn(_ddp_worker, args=args, nprocs=2, join=True)
    w0 = torch.load(tmp_path / "rank0.pt")
    w1 = torch.load(tmp_path / "rank1.pt")
    _assert_same(w0, w1)
    torch.manual_seed(0)  # the trainer's seed: the initial weights
    init = _weights(build_stage1(config_from_dict(TINY)))
    assert any(not torch.equal(w0[k], init[k]) for k in w0)  # it did train
    assert (tmp_path / "flow/log.csv").is_file()  # rank 0 wrote


# --- export and the generator -----------------------------------------------------------


def test_stage1_checkpoint_float16_roundtrip(tmp_path):
    cfg = config_from_dict(TINY)
    torch.manual_seed(0)
    models = build_stage1(cfg)
    stats = LatentStats((0.1, -0.2), (1.5, 0.5))
    save_stage1(models, cfg, tmp_path / "s1", stats, dtype=torch.float16)
    loaded, cfg2, stats2 = load_stage1(tmp_path / "s1")
    assert cfg2 == cfg and stats2 == stats
    for role in ("image_encoder", "flow"):
        for k, v in models[role].state_dict().items():
            w = loaded[role].state_dict()[k]
            assert w.dtype == v.dtype
            torch.testing.assert_close(w, v.half().float())
    z = torch.randn(1, 3, 2, 4, 4, 4)
    torch.testing.assert_close(stats.denormalize(stats.normalize(z)), z)


def test_export_and_generate_valid_object(tiny, trained_vae, tmp_path):
    data, cfg = tiny
    vae_dir = str(trained_vae / "vae/checkpoint/ss_vae")
    train_stage1(data, trained_vae, str(cfg), "flow", steps=2, vae_dir=vae_dir, **FAST)
    paths = export_weights(trained_vae, tmp_path / "w")
    assert set(paths) == {"ss_vae", "stage1"}
    gen = Stage1Generator.load(tmp_path / "w")
    rng = np.random.default_rng(0)
    image = rng.integers(0, 255, (48, 40, 3), dtype=np.uint8)  # non-square on purpose
    mask = np.zeros((48, 40), np.uint8)
    mask[10:30, 5:35] = 1
    mask[12:20, 8:30] = 2
    mask[0:2, 0:2] = 9  # more parts than slots: treated as background
    for m in (mask, None):
        obj = gen.generate(image, m, {"category": "cabinet"})
        obj.validate()
        assert obj.scale is None and obj.parts[0].name == "base"
        assert gen.timings["stage1"] > 0
        lo, hi = obj.bounds()
        assert (lo >= -0.55).all() and (hi <= 0.55).all()
    # with a mask, 8 samples per image are drawn and one kept: one row of occupancies and
    # features per image, the same for the same seed
    assert gen.candidates == 8
    feats: list[torch.Tensor] = []
    occ, exists = gen.predict_parts_batch(
        [image, image], [mask, mask], lambda i, t, f: feats.append(f)
    )
    assert occ.shape[0] == exists.shape[0] == 2
    assert len(feats) == gen.sampler.steps and all(f.shape[0] == 2 for f in feats)
    again, _ = gen.predict_parts_batch([image, image], [mask, mask])
    assert np.array_equal(again, occ)


def test_occupancy_mesh_matches_the_grid():
    g = np.zeros((16, 16, 16), bool)
    g[2:10, 4:8, 0:16] = True
    mesh = occupancy_mesh(g)
    assert mesh.volume > 0 and mesh.is_watertight
    lo, hi = mesh.bounds
    np.testing.assert_allclose(lo, [-0.5 + 2 / 16, -0.5 + 4 / 16, -0.5], atol=0.04)
    np.testing.assert_allclose(hi, [-0.5 + 10 / 16, -0.5 + 8 / 16, 0.5], atol=0.04)
    assert occupancy_mesh(np.zeros((8, 8, 8), bool)) is None


@pytest.mark.parametrize(
    "box, semantic, kind",
    [
        ([[0.40, -0.38, -0.4], [0.44, 0.00, 0.4]], "door", "revolute"),  # tall left panel
        ([[0.40, 0.00, -0.4], [0.44, 0.38, 0.4]], "door", "revolute"),  # tall right panel
        ([[0.40, -0.38, -0.4], [0.44, 0.38, 0.0]], "door", "revolute"),  # wide: drop-down
        ([[-0.40, -0.40, 0.5], [0.40, 0.40, 0.53]], "lid", "revolute"),
        ([[0.00, -0.30, 0.1], [0.42, 0.30, 0.3]], "drawer", "prismatic"),
    ],
)
def test_estimated_joints_open_outward(box, semantic, kind):
    base = np.array([[-0.4, -0.4, -0.5], [0.4, 0.4, 0.5]])
    box = np.array(box)
    sem, joint = estimate_joint(box, base)
    assert (sem, joint.type) == (semantic, kind)
    c = np.r_[box.mean(0), 1.0]
    moved = joint.transform(0.5 * joint.upper) @ c
    if semantic == "lid":
        assert moved[2] > c[2] + 0.05  # lifts
    else:
        assert moved[0] > c[0] + 0.05  # comes out of the front (+x)
    if kind == "prismatic":
        assert joint.upper == pytest.approx(0.8 * (box[1, 0] - box[0, 0]))
