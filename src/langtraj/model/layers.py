"""Building blocks: relative-pose attention (the query-centric mechanism), MLPs, step embeddings.

Every token carries a pose (x, y, heading) in the scene frame. Attention from token i to token j adds
an embedding of j's pose seen from i (distance, bearing, heading difference) to j's key and value,
so what a token learns depends only on relative geometry, never on where the scene frame lies.

See docs/model.md.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import torch
from torch import Tensor, nn
from torch.utils.checkpoint import checkpoint


def mlp(in_dim: int, hidden: int, out_dim: int, layers: int = 2) -> nn.Sequential:
    """Linear-ReLU stack with a LayerNorm after each hidden layer."""
    mods: list[nn.Module] = []
    dim = in_dim
    for _ in range(layers - 1):
        mods += [nn.Linear(dim, hidden), nn.LayerNorm(hidden), nn.ReLU()]
        dim = hidden
    mods.append(nn.Linear(dim, out_dim))
    return nn.Sequential(*mods)


def recomputing(enabled: bool, module: nn.Module) -> bool:
    """Whether `module` should recompute its blocks in backward (gradient checkpointing): asked for
    (`ModelConfig.gradient_checkpointing`), training, and building a graph; never in sampling."""
    return enabled and module.training and torch.is_grad_enabled()


def run_block(recompute: bool, function: Callable[..., Tensor], *args: Any) -> Tensor:
    """`function(*args)`; with `recompute`, its activations are dropped after the forward pass and recomputed
    in backward (`torch.utils.checkpoint`, non-reentrant, dropout replayed), which trades a second forward
    pass for the memory of every block but one (docs/model.md, 'Training memory'). Same result either way."""
    if not recompute:
        return function(*args)
    return checkpoint(function, *args, use_reentrant=False)


def gather_keys(values: Tensor, index: Tensor) -> Tensor:
    """values [B, Nk, ...] gathered per query: [B, Nq, K, ...] with row (b, i, j) = values[b, index[b, i, j]]
    (index [B, Nq, K], long)."""
    rows = torch.arange(values.shape[0], device=values.device)[:, None, None]
    return values[rows, index]


def relative_pose_features(query_pose: Tensor, key_pose: Tensor) -> Tensor:
    """[..., Nq, Nk, 5]: log(1 + distance), sin and cos of the bearing of j from i in i's frame, and sin
    and cos of the heading difference; query poses are [..., Nq, 3] (x, y, heading), key poses [..., Nk, 3]
    shared by every query or [..., Nq, Nk, 3] per query (a query's neighbours, `gather_keys`)."""
    keys = key_pose if key_pose.dim() == query_pose.dim() + 1 else key_pose[..., None, :, :]
    dx = keys[..., 0] - query_pose[..., :, None, 0]
    dy = keys[..., 1] - query_pose[..., :, None, 1]
    heading = query_pose[..., :, None, 2]
    cos_h, sin_h = torch.cos(heading), torch.sin(heading)
    forward, left = cos_h * dx + sin_h * dy, -sin_h * dx + cos_h * dy  # j seen from i's frame
    distance = torch.sqrt(dx**2 + dy**2 + 1e-6)
    bearing = torch.atan2(left, forward)  # 0 for coincident tokens, whatever the frame
    dheading = keys[..., 2] - heading
    return torch.stack(
        [torch.log1p(distance), torch.sin(bearing), torch.cos(bearing), torch.sin(dheading), torch.cos(dheading)],
        dim=-1,
    )


@dataclass
class PoseTerms:
    """Relative-pose embeddings r_ij of one attention, laid out for the two products they enter: `keys`
    [B0, Nq, heads, head_dim, K] (against the queries) and `values` [B0, Nq, heads, K, head_dim]. With
    `tokens`, the key and value tokens are folded in (k_j + r_ij, v_j + r_ij): keys fixed for a scene,
    such as the encoded scene tokens every denoising step attends to."""

    keys: Tensor
    values: Tensor
    tokens: bool = False

    @property
    def width(self) -> int:
        """K: the keys of each query."""
        return self.keys.shape[-1]


class RelPoseAttention(nn.Module):
    """Multi-head attention whose keys and values carry the key token's pose relative to the query's."""

    def __init__(self, dim: int, heads: int, dropout: float = 0.0):
        super().__init__()
        if dim % heads:
            raise ValueError(f"hidden size {dim} is not divisible by {heads} heads")
        self.heads, self.head_dim = heads, dim // heads
        self.q = nn.Linear(dim, dim)
        self.k = nn.Linear(dim, dim)
        self.v = nn.Linear(dim, dim)
        self.rel = mlp(5, dim, dim)
        self.out = nn.Linear(dim, dim)
        self.drop = nn.Dropout(dropout)

    def relative(
        self, query_pose: Tensor, key_pose: Tensor, index: Tensor | None = None, key: Tensor | None = None
    ) -> PoseTerms:
        """The pose terms of queries at `query_pose` [B0, Nq, 3] against keys at `key_pose` [B0, Nk, 3] (all
        of them, or each query's `index` [B0, Nq, K]), reusable while poses stay put. With `key` [B0, Nk, D],
        the key tokens are folded in (`PoseTerms.tokens`)."""
        if index is not None:
            key_pose = gather_keys(key_pose, index)
        rel = self.rel(relative_pose_features(query_pose, key_pose))  # [B0, Nq, K, D]
        b0, nq, width, _ = rel.shape
        h, hd = self.heads, self.head_dim
        rel = rel.view(b0, nq, width, h, hd)
        as_keys, as_values = rel.permute(0, 1, 3, 4, 2), rel.permute(0, 1, 3, 2, 4)  # views, laid out below
        if key is None:
            return PoseTerms(as_keys.contiguous(), as_values.contiguous())
        # The key tokens are gathered per query straight into each layout, and the sum of a laid-out operand and a
        # view comes out laid out: one pass per tensor (`contiguous` is then free; it lays out the dense case).
        k = self.k(key).view(b0, -1, h, hd)
        v = self.v(key).view(b0, -1, h, hd)
        keys = (_per_query(k, index, nq, 4) + as_keys).contiguous()
        return PoseTerms(keys, (_per_query(v, index, nq, 3) + as_values).contiguous(), True)

    def forward(
        self,
        query: Tensor,
        query_pose: Tensor,
        key: Tensor | None,
        key_pose: Tensor | None,
        mask: Tensor,
        rel: PoseTerms | None = None,
        index: Tensor | None = None,
    ) -> Tensor:
        """query [B, Nq, D], key [B, Nk, D], poses [B, N, 3], mask bool [B, Nq, Nk] (True: attend); `rel`
        from `relative` when already computed (with the key tokens folded in, `key` is not read). Rows
        with nothing to attend to return zeros.

        Local attention: with `index` [B0 or B, Nq, K] (long, distinct keys per query), query i attends to
        keys index[i] only; `mask` is then [B, Nq, K]. The plain query-key products are computed densely
        (one matrix product) and gathered; the pose terms, the costly part, only for the K keys
        (docs/model.md, 'Local attention').

        `rel` (and `index`) may hold B0 rows where B is a multiple of B0 and row r of the batch has the poses
        of row r % B0 (samples of the same scenes, sample-major): the pose terms are then computed once per
        scene instead of once per sample. q . (k_j + r_ij) and sum_j w_ij (v_j + r_ij) are split into their
        plain-attention and pose parts so that the pose embeddings are never copied per sample.
        """
        b, nq, d = query.shape
        terms = self.relative(query_pose, key_pose, index) if rel is None else rel
        b0, width = terms.keys.shape[0], terms.width
        if b % b0:
            raise ValueError(f"{b} query rows are not a multiple of the {b0} rows of the pose embeddings")
        g, h, hd = b // b0, self.heads, self.head_dim
        # Everything per query is laid out pose-major, [B0, Nq, h, g, K]: the pose terms' layout, so that the
        # costly products against them are batched matrix products without a copy of their operands or results.
        q = self.q(query).view(g, b0, nq, h, hd)
        logits = torch.matmul(q.permute(1, 2, 3, 0, 4), terms.keys)  # [B0, Nq, h, g, K]
        if not terms.tokens:
            k = self.k(key).view(g, b0, -1, h, hd)
            plain = torch.matmul(q.transpose(2, 3), k.permute(0, 1, 3, 4, 2))  # [g, B0, h, Nq, Nk], dense
            if index is not None:
                columns = _per_sample(index, g, b0)[:, :, None].expand(g, b0, h, nq, width)
                plain = torch.gather(plain, -1, columns)
            logits = logits + plain.permute(1, 3, 2, 0, 4)
        # Masked keys get the dtype's lowest value, whose weight underflows to exactly 0 as -inf's would; a row
        # with no key left comes out uniform instead of NaN and is zeroed at the output. The logits are fresh
        # (a product or a sum), so they are masked and scaled in place: no copy of the largest tensor here.
        keep = _per_sample(mask, g, b0).permute(1, 2, 0, 3)[:, :, None]  # [B0, Nq, 1, g, K]
        logits = logits.masked_fill_(~keep, torch.finfo(logits.dtype).min).div_(math.sqrt(hd))
        weights = self.drop(torch.softmax(logits, dim=-1))
        out = torch.matmul(weights, terms.values)  # [B0, Nq, h, g, hd]
        out = out.permute(3, 0, 1, 2, 4)  # [g, B0, Nq, h, hd]
        if not terms.tokens:
            v = self.v(key).view(g, b0, -1, h, hd)
            by_sample = weights.permute(3, 0, 2, 1, 4)  # [g, B0, h, Nq, K]
            dense = (
                by_sample
                if index is None
                else by_sample.new_zeros(g, b0, h, nq, v.shape[2]).scatter_add_(-1, columns, by_sample)
            )
            out = out + torch.matmul(dense, v.transpose(2, 3)).transpose(2, 3)
        any_key = _per_sample(mask, g, b0).any(-1)[..., None, None]  # [g, B0, Nq, 1, 1]
        return self.out((out * any_key).reshape(b, nq, d))


def _per_query(tokens: Tensor, index: Tensor | None, queries: int, key_axis: int) -> Tensor:
    """Key tokens [B0, Nk, h, hd] for each query, with its K keys (its `index` [B0, Nq, K], or all Nk) on axis
    `key_axis`: 4 gives [B0, Nq, h, hd, K] (`PoseTerms.keys`), 3 gives [B0, Nq, h, K, hd] (`PoseTerms.values`).
    Gathered tokens come out contiguous; without `index` the result is a broadcast view."""
    per_head = tokens.permute(0, 2, 3, 1) if key_axis == 4 else tokens.permute(0, 2, 1, 3)  # [B0, h, ., .]
    if index is None:
        return per_head[:, None].expand(-1, queries, -1, -1, -1)
    b0, h, hd = tokens.shape[0], tokens.shape[2], tokens.shape[3]
    shape = (b0, queries, h, hd, index.shape[-1]) if key_axis == 4 else (b0, queries, h, index.shape[-1], hd)
    rows = index[:, :, None, None, :] if key_axis == 4 else index[:, :, None, :, None]
    return torch.gather(per_head[:, None].expand(*shape[:2], *per_head.shape[1:]), key_axis, rows.expand(shape))


def _per_sample(rows: Tensor, samples: int, scenes: int) -> Tensor:
    """`rows` [B0 or B, ...] (one row per scene, or per sample and scene, sample-major) as [samples, B0, ...]."""
    if rows.shape[0] == scenes:
        return rows[None].expand(samples, *rows.shape)
    return rows.reshape(samples, scenes, *rows.shape[1:])


class AttentionBlock(nn.Module):
    """Pre-norm residual block: relative-pose attention, then a feed-forward layer."""

    def __init__(self, dim: int, heads: int, dropout: float = 0.0):
        super().__init__()
        self.norm_q = nn.LayerNorm(dim)
        self.norm_k = nn.LayerNorm(dim)
        self.attn = RelPoseAttention(dim, heads, dropout)
        self.norm_ff = nn.LayerNorm(dim)
        self.ff = nn.Sequential(nn.Linear(dim, 4 * dim), nn.GELU(), nn.Dropout(dropout), nn.Linear(4 * dim, dim))

    def fixed_context(
        self, pose: Tensor, context: Tensor, context_pose: Tensor, index: Tensor | None = None
    ) -> PoseTerms:
        """Pose terms with the context tokens folded in, for a context that stays put across calls (the
        scene tokens of every denoising step): `forward` then reads neither `context` nor its pose."""
        return self.attn.relative(pose, context_pose, index, key=self.norm_k(context))

    def forward(
        self,
        x: Tensor,
        pose: Tensor,
        context: Tensor | None,
        context_pose: Tensor | None,
        mask: Tensor,
        rel: PoseTerms | None = None,
        index: Tensor | None = None,
    ) -> Tensor:
        """`context` and its pose may be None when `rel` holds them folded in (`fixed_context`)."""
        keys = None if rel is not None and rel.tokens else self.norm_k(context)  # folded: not read again
        x = x + self.attn(self.norm_q(x), pose, keys, context_pose, mask, rel, index)
        return x + self.ff(self.norm_ff(x))


def step_embedding(k: Tensor, dim: int) -> Tensor:
    """Sinusoidal embedding [..., dim] of diffusion step indices `k`."""
    half = dim // 2
    freqs = torch.exp(-math.log(10000.0) * torch.arange(half, device=k.device, dtype=torch.float32) / half)
    angles = k.float()[..., None] * freqs
    return torch.cat([torch.sin(angles), torch.cos(angles)], dim=-1)
