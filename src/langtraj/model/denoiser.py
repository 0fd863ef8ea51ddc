"""The denoiser: noisy future actions of all agents to their clean estimate (x0), given the scene and
per-agent language conditions (paper 'LangTraj'; docs/design.md, 'The model').

Each block has (a) agent-agent attention over the noisy futures with relative pose, (b) cross-attention
to the scene tokens, (c) cross-attention to the agents' language embeddings E_L (each fused with its
agent's scene embedding; agents without text carry the learned null condition). An agent's own E_L is
also added to its input token, and together with the diffusion step it scales and shifts every
agent's token before each block (FiLM, zero-initialised as DiT's adaLN-Zero): the direct path for its
condition, which cross-attention alone learns too slowly to use.

See docs/model.md.
"""

from __future__ import annotations

from torch import Tensor, nn

from langtraj.model.config import ModelConfig
from langtraj.model.layers import AttentionBlock, PoseTerms, mlp, recomputing, run_block, step_embedding
from langtraj.model.scene_encoder import SceneContext

STEP_REFERENCE = 100
"""Steps of the schedule the step embedding is expressed in (the paper's pretraining K): step k of a
K-step cosine schedule has the noise level of step (k + 1) * 100 / K - 1 of the 100-step one."""


class Denoiser(nn.Module):
    """x_k [B, A, N, 2] and step k [B] -> x0 estimate [B, A, N, 2] (actions in network units)."""

    def __init__(self, config: ModelConfig):
        super().__init__()
        d = config.hidden_dim
        self.dim = d
        self.checkpointing = config.gradient_checkpointing
        self.action_in = mlp(config.num_actions * 2, d, d)
        self.step = mlp(d, d, d)
        # Steps are embedded as the step of a STEP_REFERENCE-step schedule with the same noise level, so a
        # model distilled to K = 5 starts from what its K = 100 teacher does at those levels.
        self.step_scale = STEP_REFERENCE / config.diffusion_steps
        self.blocks = nn.ModuleList(
            nn.ModuleList(AttentionBlock(d, config.num_heads, config.dropout) for _ in range(3))
            for _ in range(config.denoiser_blocks)
        )
        self.out = nn.Sequential(nn.LayerNorm(d), mlp(d, d, config.num_actions * 2))
        # Each agent's own E_L also enters its token directly; the last layer starts at zero, so a model
        # trained without text (stage 1) is unchanged until stage 2 learns to use the condition.
        self.condition_in = mlp(d, d, d)
        nn.init.zeros_(self.condition_in[-1].weight)
        nn.init.zeros_(self.condition_in[-1].bias)
        # A rolling model (`rolling_group`) also reads each action's own noise level; zero-initialised, so a model
        # fine-tuned from one without it starts where that one was (docs/model.md, 'Rolling plans').
        self.num_steps = config.diffusion_steps
        self.level_in = mlp(config.num_actions, d, d) if config.rolling_group else None
        if self.level_in is not None:
            nn.init.zeros_(self.level_in[-1].weight)
            nn.init.zeros_(self.level_in[-1].bias)
        self.modulation = nn.ModuleList(nn.Linear(d, 2 * d) for _ in range(config.denoiser_blocks))
        for layer in self.modulation:
            nn.init.zeros_(layer.weight)
            nn.init.zeros_(layer.bias)

    def pose_cache(self, scene: SceneContext) -> dict:
        """Relative-pose terms of every attention block, keyed (block, sub-block), with the scene tokens
        folded into those of the scene cross-attention. They depend on the current poses and the encoded
        scene only, so one computation serves every denoising step, and, computed on the scenes before
        they are repeated per sample, every sample (see `RelPoseAttention.forward`). Under local attention
        they cover each agent's neighbours only."""
        return {(i, j): self.pose_terms(i, j, scene) for i in range(len(self.blocks)) for j in range(3)}

    def pose_terms(self, i: int, j: int, scene: SceneContext) -> PoseTerms:
        """The relative-pose terms of sub-block j (0: agents, 1: scene tokens folded in, 2: text) of block i."""
        pose = scene.agent_pose
        agents, context = _indices(scene)
        block = self.blocks[i][j]
        if j == 1:
            return block.fixed_context(pose, scene.tokens, scene.pose, context)
        return block.attn.relative(pose, pose, agents)

    def forward(
        self, x_k: Tensor, k: Tensor, scene: SceneContext, language: Tensor, cache: dict | None = None
    ) -> Tensor:
        """`k` is each sample's step [B], or each action's [B, N] (a rolling plan's levels; the step embedding then
        reads their mean). `language` [B, A, D] is E_L for every agent (null condition where it has no text).
        `cache`, a dict kept across the denoising steps of one scene, holds the relative-pose embeddings
        (`pose_cache`), filled on first use when empty."""
        b, a, n, c = x_k.shape
        mean = k.float().mean(-1) if k.dim() == 2 else k.float()
        step = self.step(step_embedding((mean + 1.0) * self.step_scale - 1.0, self.dim))[:, None, :]
        if self.level_in is not None:
            levels = k if k.dim() == 2 else k[:, None].expand(b, n)
            step = step + self.level_in((levels.float() + 1.0) / self.num_steps)[:, None, :]
        condition = step + self.condition_in(language)  # [B, A, D]: each agent's step and own text
        h = self.action_in(x_k.reshape(b, a, n * c)) + scene.agent_tokens + condition
        film = nn.functional.silu(condition)
        mask = scene.agent_mask
        agents, context = _indices(scene)
        if scene.neighbours is None:
            pair = mask[:, :, None] & mask[:, None, :]
            scene_attn = mask[:, :, None] & scene.mask[:, None, :]
        else:
            pair = scene.neighbours.agents_valid & mask[:, :, None]
            scene_attn = scene.neighbours.context_valid & mask[:, :, None]
        # Under gradient checkpointing each sub-block computes its own pose terms, inside what it recomputes.
        recompute = cache is None and recomputing(self.checkpointing, self)
        if cache is None and not recompute:
            cache = self.pose_cache(scene)
        elif cache is not None and not cache:
            cache.update(self.pose_cache(scene))
        masks, indices = (pair, scene_attn, pair), (agents, context, agents)
        for i in range(len(self.blocks)):
            scale, shift = self.modulation[i](film).chunk(2, dim=-1)
            h = h * (1.0 + scale) + shift
            for j in range(3):  # agents attend to each other's tokens, to the scene (folded in), to the text
                key = (h, None, language)[j]
                if recompute:
                    h = run_block(True, self._fresh_sub_block, i, j, h, key, scene, masks[j], indices[j])
                else:
                    h = self._sub_block(i, j, h, key, scene, masks[j], cache[(i, j)], indices[j])
        return self.out(h).reshape(b, a, n, c) * mask[..., None, None]

    def _sub_block(
        self, i: int, j: int, h: Tensor, key: Tensor | None, scene: SceneContext, mask: Tensor, rel: PoseTerms, index
    ) -> Tensor:
        """Sub-block j of block i on tokens `h`; the scene tokens (j = 1) are folded into `rel`."""
        pose = scene.agent_pose
        return self.blocks[i][j](h, pose, key, None if key is None else pose, mask, rel, index)

    def _fresh_sub_block(
        self, i: int, j: int, h: Tensor, key: Tensor | None, scene: SceneContext, mask: Tensor, index
    ) -> Tensor:
        """`_sub_block` with its pose terms computed here, so that gradient checkpointing recomputes them too."""
        return self._sub_block(i, j, h, key, scene, mask, self.pose_terms(i, j, scene), index)


def _indices(scene: SceneContext) -> tuple[Tensor | None, Tensor | None]:
    """The agent and scene-token keys of each agent under local attention (None, None: dense)."""
    nb = scene.neighbours
    return (None, None) if nb is None else (nb.agents, nb.context)
