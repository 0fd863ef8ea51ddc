"""Building blocks: relative-pose attention (the query-centric mechanism), MLPs, step embeddings.

Every token carries a pose (x, y, heading) in the scene frame. Attention from token i to token j adds
an embedding of j's pose seen from i (distance, bearing, heading difference) to j's key and value,
so what a token learns depends only on relative geometry, never on where the scene frame lies.

See docs/model.md.
"""

from __future__ import annotations

import math

import torch
from torch import Tensor, nn


def mlp(in_dim: int, hidden: int, out_dim: int, layers: int = 2) -> nn.Sequential:
    """Linear-ReLU stack with a LayerNorm after each hidden layer."""
    mods: list[nn.Module] = []
    dim = in_dim
    for _ in range(layers - 1):
        mods += [nn.Linear(dim, hidden), nn.LayerNorm(hidden), nn.ReLU()]
        dim = hidden
    mods.append(nn.Linear(dim, out_dim))
    return nn.Sequential(*mods)


def relative_pose_features(query_pose: Tensor, key_pose: Tensor) -> Tensor:
    """[..., Nq, Nk, 5]: log(1 + distance), sin and cos of the bearing of j from i in i's frame, and sin
    and cos of the heading difference; poses are [..., N, 3] (x, y, heading)."""
    dx = key_pose[..., None, :, 0] - query_pose[..., :, None, 0]
    dy = key_pose[..., None, :, 1] - query_pose[..., :, None, 1]
    heading = query_pose[..., :, None, 2]
    cos_h, sin_h = torch.cos(heading), torch.sin(heading)
    forward, left = cos_h * dx + sin_h * dy, -sin_h * dx + cos_h * dy  # j seen from i's frame
    distance = torch.sqrt(dx**2 + dy**2 + 1e-6)
    bearing = torch.atan2(left, forward)  # 0 for coincident tokens, whatever the frame
    dheading = key_pose[..., None, :, 2] - heading
    return torch.stack(
        [torch.log1p(distance), torch.sin(bearing), torch.cos(bearing), torch.sin(dheading), torch.cos(dheading)],
        dim=-1,
    )


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

    def relative(self, query_pose: Tensor, key_pose: Tensor) -> Tensor:
        """The pose embeddings [B, Nq, Nk, D] added to keys and values (reusable while poses stay put)."""
        return self.rel(relative_pose_features(query_pose, key_pose))

    def forward(
        self, query: Tensor, query_pose: Tensor, key: Tensor, key_pose: Tensor, mask: Tensor, rel: Tensor | None = None
    ) -> Tensor:
        """query [B, Nq, D], key [B, Nk, D], poses [B, N, 3], mask bool [B, Nq, Nk] (True: attend); `rel`
        from `relative` when already computed. Rows with nothing to attend to return zeros.

        `rel` may hold B0 rows where B is a multiple of B0 and row r of the batch has the poses of row
        r % B0 (samples of the same scenes, sample-major): the pose terms are then computed once per scene
        instead of once per sample. q . (k_j + r_ij) and sum_j w_ij (v_j + r_ij) are split into their
        plain-attention and pose parts so that the pose embeddings are never copied per sample.
        """
        b, nq, d = query.shape
        nk = key.shape[1]
        rel = self.relative(query_pose, key_pose) if rel is None else rel  # [B0, Nq, Nk, D]
        b0 = rel.shape[0]
        if b % b0:
            raise ValueError(f"{b} query rows are not a multiple of the {b0} rows of the pose embeddings")
        g, h, hd = b // b0, self.heads, self.head_dim
        rel = rel.view(b0, nq, nk, h, hd)
        q = self.q(query).view(b, nq, h, hd)
        k = self.k(key).view(b, nk, h, hd)
        v = self.v(key).view(b, nk, h, hd)
        logits = torch.einsum("bqhd,bkhd->bhqk", q, k)
        logits = logits + torch.einsum("gbqhd,bqkhd->gbhqk", q.view(g, b0, nq, h, hd), rel).reshape(b, h, nq, nk)
        logits = logits.masked_fill(~mask[:, None], float("-inf")) / math.sqrt(hd)
        any_key = mask.any(-1)[:, None, :, None]  # [B, 1, Nq, 1]
        weights = self.drop(torch.softmax(logits.masked_fill(~any_key, 0.0), dim=-1) * any_key)
        out = torch.einsum("bhqk,bkhd->bqhd", weights, v)
        out = out + torch.einsum("gbhqk,bqkhd->gbqhd", weights.view(g, b0, h, nq, nk), rel).reshape(b, nq, h, hd)
        return self.out(out.reshape(b, nq, d))


class AttentionBlock(nn.Module):
    """Pre-norm residual block: relative-pose attention, then a feed-forward layer."""

    def __init__(self, dim: int, heads: int, dropout: float = 0.0):
        super().__init__()
        self.norm_q = nn.LayerNorm(dim)
        self.norm_k = nn.LayerNorm(dim)
        self.attn = RelPoseAttention(dim, heads, dropout)
        self.norm_ff = nn.LayerNorm(dim)
        self.ff = nn.Sequential(nn.Linear(dim, 4 * dim), nn.GELU(), nn.Dropout(dropout), nn.Linear(4 * dim, dim))

    def forward(
        self, x: Tensor, pose: Tensor, context: Tensor, context_pose: Tensor, mask: Tensor, rel: Tensor | None = None
    ) -> Tensor:
        x = x + self.attn(self.norm_q(x), pose, self.norm_k(context), context_pose, mask, rel)
        return x + self.ff(self.norm_ff(x))


def step_embedding(k: Tensor, dim: int) -> Tensor:
    """Sinusoidal embedding [..., dim] of diffusion step indices `k`."""
    half = dim // 2
    freqs = torch.exp(-math.log(10000.0) * torch.arange(half, device=k.device, dtype=torch.float32) / half)
    angles = k.float()[..., None] * freqs
    return torch.cat([torch.sin(angles), torch.cos(angles)], dim=-1)
