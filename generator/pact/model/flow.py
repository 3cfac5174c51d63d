"""Rectified flow in the part-latent space (TRELLIS convention).

x_t = (1 - t) x_0 + t * eps, t = 0 is data and t = 1 is noise, the network predicts the
velocity v = eps - x_0. Training times are logit-normal, t = sigmoid(N(mean, std)) with
mean 1.0, std 1.0 as in TRELLIS's flow trainer (biased towards noise). Sampling is Euler
from t = 1 to t = 0 with classifier-free guidance v = v_u + s (v_c - v_u), where the
unconditional branch zeroes the image tokens and uses the "no mask" row. Guidance may be
limited to an interval of t (``SamplerConfig.cfg_interval``, TRELLIS's guidance-interval
sampler): outside it the step is the conditional prediction alone, one forward pass of B
instead of 2B.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import torch
import torch.nn.functional as F

from generator.pact.model.part_flow import FlowOutput, PartFlowTransformer


@dataclass
class FlowTrainConfig:
    t_mean: float = 1.0  # logit-normal time sampling (TRELLIS)
    t_std: float = 1.0
    p_uncond: float = 0.1  # image (and mask) replaced by the null condition
    p_mask_drop: float = 0.3  # only the mask replaced by "no mask"
    exists_weight: float = 0.1  # BCE on the per-slot exists logit
    # training inputs of a foreground-cropping encoder: crop centre and margin jitter
    crop_jitter: float = 0.0
    # weight of the encoder's auxiliary per-patch part-id loss (needs aux_seg_classes)
    aux_seg_weight: float = 0.0
    lr: float = 1e-4
    batch_size: int = 8
    bf16: bool = True


@dataclass
class SamplerConfig:
    steps: int = 25
    cfg_scale: float = 7.0
    rescale_t: float = 1.0  # TRELLIS's t' = s t / (1 + (s - 1) t); 1.0 = uniform steps
    # guidance only at steps whose t lies in [lo, hi]; the others take v_c (one pass)
    cfg_interval: tuple[float, float] = (0.0, 1.0)


def guided_at(t: float, interval: tuple[float, float]) -> bool:
    """Whether the sampler step at time ``t`` uses classifier-free guidance."""
    lo, hi = interval
    return lo <= t <= hi


# called once per Euler step with (step index, t, last-block features (B, K, L, D))
FeatureCallback = Callable[[int, float, torch.Tensor], None]


def randn(shape: tuple[int, ...], generator: torch.Generator | None, device) -> torch.Tensor:
    gen_device = generator.device if generator is not None else device
    return torch.randn(shape, generator=generator, device=gen_device).to(device)


def rand(n: int, generator: torch.Generator | None, device) -> torch.Tensor:
    gen_device = generator.device if generator is not None else device
    return torch.rand(n, generator=generator, device=gen_device).to(device)


def sample_t(
    batch: int,
    mean: float = 1.0,
    std: float = 1.0,
    generator: torch.Generator | None = None,
    device: torch.device | str = "cpu",
) -> torch.Tensor:
    """Logit-normal times, (B,) in (0, 1)."""
    return torch.sigmoid(randn((batch,), generator, device) * std + mean)


def noisy(x0: torch.Tensor, eps: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
    """x_t = (1 - t) x_0 + t eps with t (B,) broadcast over the rest of x0's dims."""
    tt = t.view(-1, *([1] * (x0.dim() - 1)))
    return (1.0 - tt) * x0 + tt * eps


def flow_loss(
    model: PartFlowTransformer,
    x0: torch.Tensor,
    cond: torch.Tensor,
    mask: torch.Tensor | None,
    exists: torch.Tensor,
    cfg: FlowTrainConfig | None = None,
    generator: torch.Generator | None = None,
) -> tuple[torch.Tensor, dict[str, float]]:
    """One flow-matching loss on a batch.

    x0: (B, K, C, r, r, r) part latents (empty slots hold the empty-grid latent);
    cond: (B, N_img, D_img) image tokens; mask: (B, H, W) part ids or None;
    exists: (B, K) bool, slot used. Returns (scalar loss, metrics); the caller owns
    autocast, backward and the optimiser.
    """
    cfg = cfg or FlowTrainConfig()
    B, device = x0.shape[0], x0.device
    x0 = x0.float()
    t = sample_t(B, cfg.t_mean, cfg.t_std, generator, device)  # (B,)
    eps = randn(tuple(x0.shape), generator, device)
    cond_drop = rand(B, generator, device) < cfg.p_uncond
    mask_drop = rand(B, generator, device) < cfg.p_mask_drop
    out = model(noisy(x0, eps, t), t, cond, mask, cond_drop=cond_drop, mask_drop=mask_drop)
    mse = (out.velocity.float() - (eps - x0)).pow(2).mean()
    bce = F.binary_cross_entropy_with_logits(out.exists_logits.float(), exists.float())
    loss = mse + cfg.exists_weight * bce
    metrics = {"loss": loss.item(), "mse": mse.item(), "exists_bce": bce.item()}
    return loss, metrics


def guided_velocity(
    model: PartFlowTransformer,
    x: torch.Tensor,
    t: torch.Tensor,
    cond: torch.Tensor | None,
    mask: torch.Tensor | None,
    scale: float,
) -> FlowOutput:
    """CFG velocity v_u + s (v_c - v_u); exists logits and features are the conditional
    branch's. Both branches run as one batch of 2B. With cond=None, the plain prediction."""
    if cond is None:
        return model(x, t, None, None)
    B = x.shape[0]
    drop = torch.cat([torch.zeros(B, dtype=torch.bool), torch.ones(B, dtype=torch.bool)])
    out = model(
        torch.cat([x, x]),
        torch.cat([t, t]),
        torch.cat([cond, cond]),
        None if mask is None else torch.cat([mask, mask]),
        cond_drop=drop.to(x.device),
    )
    v_c, v_u = out.velocity.float().chunk(2)
    return FlowOutput(v_u + scale * (v_c - v_u), out.exists_logits[:B], out.features[:B])


@torch.no_grad()
def sample(
    model: PartFlowTransformer,
    cond: torch.Tensor | None,
    mask: torch.Tensor | None = None,
    cfg: SamplerConfig | None = None,
    generator: torch.Generator | None = None,
    batch: int | None = None,
    callback: FeatureCallback | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Euler sampling from t = 1 to 0. Returns latents (B, T, C, r, r, r) and the exists
    logits (B, T) of the last step. Deterministic for a given ``generator`` seed.

    ``callback(step_index, t, features)`` receives the conditional branch's last-block
    token features (B, T, L, D) at every step (stage 2's articulation head averages them).
    """
    cfg = cfg or SamplerConfig()
    mcfg = model.cfg
    device = next(model.parameters()).device
    B = cond.shape[0] if cond is not None else (batch or 1)
    r = mcfg.latent_resolution
    x = randn((B, mcfg.max_parts, mcfg.latent_channels, r, r, r), generator, device)
    ts = torch.linspace(1.0, 0.0, cfg.steps + 1, dtype=torch.float64)
    ts = cfg.rescale_t * ts / (1.0 + (cfg.rescale_t - 1.0) * ts)
    exists = torch.zeros(B, mcfg.max_parts, device=device)
    for i in range(cfg.steps):
        t, t_next = float(ts[i]), float(ts[i + 1])
        tt = torch.full((B,), t, device=device)
        if cond is not None and not guided_at(t, cfg.cfg_interval):
            out = model(x, tt, cond, mask)  # the conditional branch alone
        else:
            out = guided_velocity(model, x, tt, cond, mask, cfg.cfg_scale)
        if callback is not None:
            callback(i, t, out.features)
        x = x + (t_next - t) * out.velocity.float()
        exists = out.exists_logits.float()
    return x, exists
