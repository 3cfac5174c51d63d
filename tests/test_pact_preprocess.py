"""Foreground crop before the image encoder, the silhouette U-Net, the auxiliary
part-id loss, and a foreground-cropping stage 1 trained and run end to end."""

from __future__ import annotations

import copy
import json

import numpy as np
import pytest
import torch
from test_pact_train import FAST, TINY, write_tiny_dataset

from generator.pact.inference.stage1_generator import Stage1Generator
from generator.pact.model.checkpoint import load_checkpoint, save_checkpoint
from generator.pact.model.foreground import ForegroundConfig, ForegroundNet, iou
from generator.pact.model.image_encoder import ImageEncoder, ViTConfig
from generator.pact.model.preprocess import (
    ForegroundMissingError,
    crop_boxes,
    encoder_inputs,
    foreground_crop,
    square_inputs,
    square_silhouette,
)
from generator.pact.training.train_foreground import train_foreground
from generator.pact.training.train_stage1 import aux_seg_loss, export_weights, train_stage1

torch.set_num_threads(1)


def _scene() -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """An 8x8 image of distinct pixel values, a 2x4 object at rows 2-3, cols 2-5."""
    image = torch.arange(3 * 64, dtype=torch.float32).view(1, 3, 8, 8) / (3 * 64)
    mask = torch.zeros(1, 8, 8, dtype=torch.long)
    mask[0, 2:4, 2:4] = 1
    mask[0, 2:4, 4:6] = 2
    return image, mask > 0, mask


def test_crop_is_the_foreground_square_hand_computed():
    image, fg, mask = _scene()
    out, m = foreground_crop(image, fg, mask, size=4, margin=0.0)
    # the box's longer side is 4 px (cols 2-5); the square is centred on the box: rows
    # 1-4, cols 2-5; at size 4 every output pixel centre is an input pixel centre
    expected = image[:, :, 1:5, 2:6].clone()
    keep = fg[:, 1:5, 2:6]
    expected = torch.where(keep[:, None], expected, torch.ones_like(expected))
    torch.testing.assert_close(out, expected, atol=1e-5, rtol=0)
    assert torch.equal(m, mask[:, 1:5, 2:6])
    assert out[0, :, 0].eq(1).all() and out[0, :, 3].eq(1).all()  # rows 1 and 4: white


def test_crop_past_the_edge_is_background_and_margin_grows_the_box():
    image = torch.zeros(1, 3, 8, 8)
    fg = torch.zeros(1, 8, 8, dtype=torch.bool)
    fg[0, 0:2, 0:2] = True  # in the corner: the square crop reaches outside the image
    mask = fg.long() * 3
    out, m = foreground_crop(image, fg, mask, size=8, margin=0.5)
    # box 2 px, margin 0.5 of it on each side: a 4 px square from -1 to 3 (pixel edges)
    # sampled at 8, output pixel i samples input x = -1 + (i + 0.5) / 2 (pixel edges):
    # pixel 0 (x = -0.75) only padding, pixels 3-4 (x = 0.75, 1.25) only the object,
    # pixel 1 (x = -0.25) a quarter object: 1 - 0.25 (bilinear), pixel 7 whitened
    assert out[0, :, 0].eq(1).all() and out[0, :, :, 0].eq(1).all()
    assert out[0, :, 3:5, 3:5].eq(0).all()  # the black object
    torch.testing.assert_close(out[0, :, 3, 1], torch.full((3,), 0.75))
    assert out[0, :, 7].eq(1).all()
    assert m[0, :2].eq(0).all() and m[0, 2:6, 2:6].eq(3).all() and m[0, 6:].eq(0).all()
    cx, cy, half = crop_boxes(fg, 0.5)[0].tolist()
    assert (cx, cy, half) == pytest.approx((-0.75, -0.75, 2.0))


def test_no_foreground_is_only_resized_and_jitter_is_seeded():
    image, fg, mask = _scene()
    out, _ = foreground_crop(image, torch.zeros_like(fg), None, size=8)
    torch.testing.assert_close(out, image)
    a = foreground_crop(image, fg, None, 8, jitter=0.1, generator=torch.Generator().manual_seed(1))
    b = foreground_crop(image, fg, None, 8, jitter=0.1, generator=torch.Generator().manual_seed(1))
    c = foreground_crop(image, fg, None, 8)
    assert torch.equal(a[0], b[0]) and not torch.equal(a[0], c[0])


def test_square_inputs_pad_with_edge_colours_and_background_ids():
    image = np.zeros((4, 2, 3), np.uint8)
    image[:, 0] = 200  # left column
    image[:, 1] = 100  # right column
    mask = np.ones((4, 2), np.int64)
    mask[0, 0] = 12  # past max_parts: the base's id
    img, m, sq_image, sq_mask = square_inputs(image, mask, 4, max_parts=8)
    assert sq_image.shape == (4, 4, 3)
    assert (sq_image[:, 0] == 200).all() and (sq_image[:, 3] == 100).all()  # edge colours
    assert sq_mask[:, 0].tolist() == [0, 0, 0, 0] and sq_mask[0, 1] == 1
    assert img.shape == (1, 3, 4, 4) and m.shape == (1, 4, 4)
    with pytest.raises(ValueError, match="does not match"):
        square_inputs(image, mask[:2], 4)


def test_encoder_inputs_need_a_mask_or_a_foreground_net():
    enc = ImageEncoder(ViTConfig(image_size=16, patch_size=8, width=8, depth=1, heads=2))
    image, fg, mask = _scene()
    same, _ = encoder_inputs(enc, image, None)  # a plain encoder takes the image as it is
    assert same is image
    enc.cfg.foreground_crop = True
    with pytest.raises(ForegroundMissingError, match="part mask"):
        encoder_inputs(enc, image, None)
    cropped, m = encoder_inputs(enc, image, mask)
    assert cropped.shape == (1, 3, 16, 16) and set(m.unique().tolist()) == {0, 1, 2}
    net = ForegroundNet(ForegroundConfig(image_size=8, channels=(4, 8)))
    with torch.no_grad():  # logits = +10 inside the object, -10 outside
        net.forward = lambda x: torch.where(fg, 10.0, -10.0).float()
    by_net, _ = encoder_inputs(enc, image, None, net)
    torch.testing.assert_close(by_net, cropped)
    by_alpha, _ = encoder_inputs(enc, image, None, None, silhouette=fg)  # a photo's alpha
    torch.testing.assert_close(by_alpha, cropped)
    wrong = torch.zeros_like(fg)
    wrong[0, 0, 0] = True  # the mask wins over the silhouette
    torch.testing.assert_close(encoder_inputs(enc, image, mask, None, wrong)[0], cropped)


def test_square_silhouette_pads_and_resizes_like_the_image():
    alpha = np.zeros((4, 2), np.uint8)
    alpha[1:3, :] = 255
    sil = square_silhouette(alpha, 8)  # 4x2 -> padded 4x4 (one column each side) -> 8x8
    assert sil.shape == (1, 8, 8) and sil.dtype == torch.bool
    assert sil[0, 2:6, 2:6].all() and sil.sum() == 16


def test_foreground_predict_keeps_the_largest_component():
    net = ForegroundNet(ForegroundConfig(image_size=8, channels=(4, 8)))
    logits = torch.full((1, 8, 8), -5.0)
    logits[0, 0:2, 0:2] = 5.0  # 4 px speck
    logits[0, 4:8, 3:8] = 5.0  # 20 px object
    net.forward = lambda x: logits
    fg = net.predict(torch.zeros(1, 3, 8, 8))
    assert fg.sum() == 20 and fg[0, 4:8, 3:8].all()
    assert iou(fg, fg) == 1.0 and iou(fg, ~fg) == 0.0


def test_aux_seg_loss_hand_computed():
    cfg = ViTConfig(image_size=16, patch_size=8, width=8, depth=1, heads=2, aux_seg_classes=3)
    enc = ImageEncoder(cfg)
    with torch.no_grad():  # uniform logits: the loss is log(3) whatever the histogram
        enc.seg_head.weight.zero_()
        enc.seg_head.bias.zero_()
    mask = torch.zeros(1, 16, 16, dtype=torch.long)
    mask[0, :8, :8] = 1
    mask[0, :4, 8:] = 2
    mask[0, 8:, 8:] = 7  # past the head's classes: background
    with torch.no_grad():
        tokens = enc(torch.rand(1, 3, 16, 16))
    with torch.no_grad():
        assert float(aux_seg_loss(enc, tokens, mask)) == pytest.approx(np.log(3), rel=1e-5)
    with torch.no_grad():  # class 1 favoured by 2 nats everywhere: hand-computed entropy
        enc.seg_head.bias.copy_(torch.tensor([0.0, 2.0, 0.0]))
    lp = torch.log_softmax(torch.tensor([0.0, 2.0, 0.0]), 0)
    # patches: (0,0) all class 1; (0,1) half class 2, half 0; (1,0) and (1,1) class 0
    want = (-lp[1] - 0.5 * (lp[2] + lp[0]) - lp[0] - lp[0]) / 4
    with torch.no_grad():
        assert float(aux_seg_loss(enc, tokens, mask)) == pytest.approx(float(want), rel=1e-5)


def test_foreground_net_trains_and_round_trips(tmp_path):
    data = write_tiny_dataset(tmp_path / "data")
    cfg = ForegroundConfig(image_size=32, channels=(4, 8))
    metrics = train_foreground(
        data, tmp_path / "fg", steps=3, batch_size=2, cfg=cfg, val_fraction=0.3
    )
    assert 0.0 <= metrics["val_iou"] <= 1.0 and metrics["val_images"] > 0
    net = load_checkpoint(tmp_path / "fg" / "foreground")
    assert isinstance(net, ForegroundNet) and net.cfg.image_size == 32
    assert json.loads((tmp_path / "fg" / "foreground_val.json").read_text()) == metrics


def test_foreground_cropping_stage1_trains_and_generates(tmp_path):
    data = write_tiny_dataset(tmp_path / "data")
    tiny = copy.deepcopy(TINY)
    tiny["image_encoder"].update(foreground_crop=True, aux_seg_classes=4)
    tiny["flow_train"].update(crop_jitter=0.05, aux_seg_weight=0.5)
    cfg = tmp_path / "crop.json"
    cfg.write_text(json.dumps(tiny))
    run = tmp_path / "run"
    train_stage1(data, run, str(cfg), "vae", steps=2, **FAST)
    train_stage1(data, run, str(cfg), "flow", steps=2, **FAST)
    log = (run / "flow" / "log.csv").read_text()
    assert "aux_seg" in log
    assert set(export_weights(run, tmp_path / "w")) == {"ss_vae", "stage1"}
    gen = Stage1Generator.load(tmp_path / "w")
    assert gen.models["image_encoder"].cfg.foreground_crop
    rng = np.random.default_rng(0)
    image = rng.integers(0, 255, (32, 32, 3), dtype=np.uint8)
    mask = np.zeros((32, 32), np.uint8)
    mask[8:24, 10:22] = 1
    mask[10:16, 12:20] = 2
    gen.generate(image, mask).validate()
    with pytest.raises(ForegroundMissingError):
        gen.generate(image, None)
    alpha = np.where(mask > 0, 255, 0).astype(np.uint8)  # a photo's alpha channel
    gen.generate(image, None, {"alpha": alpha}).validate()
    net = ForegroundNet(ForegroundConfig(image_size=32, channels=(4, 8)))
    save_checkpoint(net, run / "foreground")
    assert "foreground" in export_weights(run, tmp_path / "w")  # float16 on disk
    gen = Stage1Generator.load(tmp_path / "w")
    assert "foreground" in gen.models
    gen.generate(image, None).validate()  # the silhouette comes from the U-Net
