"""Stage-1 input augmentation (generator/pact/training/augment.py): what each transform changes
and what it leaves alone, on hand-made images and masks."""

from __future__ import annotations

import torch

from generator.pact.training.augment import (
    AugmentConfig,
    augment_inputs,
    drop_rgb,
    photometric,
    ragged_mask,
    recolor_parts,
)


def _scene(B: int = 2, S: int = 32) -> tuple[torch.Tensor, torch.Tensor]:
    """A grey background, a base (id 1) filling rows 4..27 and a drawer (id 2) in its
    lower half, each a flat colour."""
    image = torch.full((B, 3, S, S), 0.5)
    mask = torch.zeros(B, S, S, dtype=torch.int64)
    mask[:, 4:28, 4:28] = 1
    mask[:, 16:28, 8:24] = 2
    image[:, :, 4:28, 4:28] = torch.tensor([0.8, 0.2, 0.1]).view(1, 3, 1, 1)
    image[:, :, 16:28, 8:24] = torch.tensor([0.1, 0.3, 0.9]).view(1, 3, 1, 1)
    return image, mask


def _gen(seed: int = 0) -> torch.Generator:
    return torch.Generator().manual_seed(seed)


def test_inactive_config_returns_the_inputs():
    image, mask = _scene()
    out, m = augment_inputs(image, mask, AugmentConfig(), _gen())
    assert out is image and m is mask


def test_recolor_gives_each_part_one_tint_and_spares_unpicked_samples():
    image, mask = _scene()
    pick = torch.tensor([True, False])
    out = recolor_parts(image, mask, pick, _gen(), max_id=9)
    assert torch.equal(out[1], image[1])
    for part in (1, 2):  # a flat part stays flat (one tint per part) but changes colour
        px = out[0].permute(1, 2, 0)[mask[0] == part]
        assert torch.allclose(px, px[0].expand_as(px))
        assert not torch.allclose(px[0], image[0].permute(1, 2, 0)[mask[0] == part][0])
    assert out.min() >= 0 and out.max() <= 1


def test_photometric_saturation_zero_gives_grey():
    image, _ = _scene(B=1)
    # draw until the saturation factor (third uniform) is small: then channels nearly agree
    for seed in range(200):
        g = _gen(seed)
        u = torch.rand(1, 3, generator=_gen(seed))
        if u[0, 2] < 0.02:
            out = photometric(image, torch.tensor([True]), g)
            spread = (out.max(1).values - out.min(1).values).max()
            assert spread < 0.05
            return
    raise AssertionError("no seed drew a small saturation")


def test_rgb_dropout_flattens_the_object_and_keeps_the_background():
    image, mask = _scene()
    out = drop_rgb(image, mask, torch.tensor([True, True]), _gen())
    fg = out[0].permute(1, 2, 0)[mask[0] != 0]
    assert torch.allclose(fg, fg[0].expand_as(fg))
    assert torch.equal(out[:, :, mask[0] == 0], image[:, :, mask[0] == 0])


def test_ragged_mask_only_moves_edges_by_at_most_three_pixels():
    _, mask = _scene(B=4)
    noisy = ragged_mask(mask, torch.tensor([True, True, True, False]), _gen(3))
    assert torch.equal(noisy[3], mask[3])
    changed = noisy[:3] != mask[:3]
    assert changed.any()
    # every changed pixel lies within 3 px (Chebyshev) of a pixel of the id it took
    for b, y, x in changed.nonzero().tolist():
        lid = noisy[b, y, x]
        win = mask[b, max(y - 3, 0) : y + 4, max(x - 3, 0) : x + 4]
        assert (win == lid).any()
    # the inside of a part, 4 px or more from any edge, never changes
    assert torch.equal(noisy[:3, 8:13, 8:24], mask[:3, 8:13, 8:24])
    assert set(noisy.unique().tolist()) <= set(mask.unique().tolist())


def test_augment_is_deterministic_per_generator_seed():
    image, mask = _scene()
    cfg = AugmentConfig(recolor=0.5, photometric=0.5, rgb_dropout=0.5, mask_noise=0.5)
    a = augment_inputs(image, mask, cfg, _gen(7))
    b = augment_inputs(image, mask, cfg, _gen(7))
    c = augment_inputs(image, mask, cfg, _gen(8))
    assert torch.equal(a[0], b[0]) and torch.equal(a[1], b[1])
    assert not (torch.equal(a[0], c[0]) and torch.equal(a[1], c[1]))
