"""The tensors a LangTraj model consumes: one scene per batch row, in that scene's frame.

The scene frame has its origin at the focal agent's current position (the SDC where there is one) and
its x axis along that agent's current heading, so every scene looks alike to the network. Agents and
map polylines are padded to fixed counts; every padded slot is False in its validity mask.
History and future are at the scenario rate (10 Hz): `H` history steps ending at the current one,
`F` future steps after it.

See docs/model.md.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import torch

AGENT_HISTORY_FEATURES = 7
"""Per history step: x, y, cos(heading), sin(heading), vx, vy (scene frame), and 1 where valid."""


@dataclass
class SceneBatch:
    """A batch of B scenes with up to A agents and M map polylines of P points each."""

    agent_history: torch.Tensor  # float [B, A, H, AGENT_HISTORY_FEATURES]
    history_valid: torch.Tensor  # bool [B, A, H]
    agent_type: torch.Tensor  # long [B, A], AgentType values, 0 for padding
    agent_size: torch.Tensor  # float [B, A, 2]: length, width (m)
    agent_valid: torch.Tensor  # bool [B, A]: a real agent, valid at the current step
    current_state: torch.Tensor  # float [B, A, 4]: x, y, heading, speed at the current step (scene frame)
    future: torch.Tensor  # float [B, A, F, 3]: x, y, heading (scene frame); training targets
    future_valid: torch.Tensor  # bool [B, A, F]
    map_points: torch.Tensor  # float [B, M, P, 2] (scene frame)
    map_valid: torch.Tensor  # bool [B, M, P]
    map_type: torch.Tensor  # long [B, M]: MapFeatureType values, 0 for padding
    text: list[list[str | None]]  # [B][A]: the agent's role-rephrased sentence, None without text
    interaction_labelled: torch.Tensor  # bool [B]: the scene has an interaction-label prompt
    origin: torch.Tensor  # float [B, 3]: scene frame in world coordinates (x, y, heading)
    agent_id: torch.Tensor  # long [B, A]: track ids, -1 for padding
    scenario_id: list[str]  # [B]
    target_actions: torch.Tensor | None = None  # float [B, A, N, 2]: fitted actions (physical), `model.targets`
    target_valid: torch.Tensor | None = None  # bool [B, A, N]: where `target_actions` are defined

    @property
    def batch_size(self) -> int:
        return self.agent_valid.shape[0]

    @property
    def num_agents(self) -> int:
        return self.agent_valid.shape[1]

    @property
    def has_text(self) -> torch.Tensor:
        """bool [B, A]: agents conditioned on a sentence."""
        return torch.tensor(
            [[t is not None for t in row] for row in self.text], dtype=torch.bool, device=self.agent_valid.device
        )

    def to(self, device: torch.device | str) -> SceneBatch:
        """The batch with every tensor on `device`."""
        moved = {
            f.name: getattr(self, f.name).to(device)
            for f in fields(self)
            if isinstance(getattr(self, f.name), torch.Tensor)
        }
        return replace(self, **moved)

    def advanced(self, executed: torch.Tensor) -> SceneBatch:
        """The batch S steps later, after every agent executed `executed` [B, A, S, 4] (x, y, heading, speed
        in the scene frame, at 10 Hz): those steps join the history (its last H steps kept, all valid for
        real agents), the last of them becomes the current state, and the future moves on by S steps
        (its last S steps invalid), so its stored target actions no longer apply (dropped). What closed-loop
        training feeds back to the model (docs/model.md)."""
        s = executed.shape[2]
        heading, speed = executed[..., 2], executed[..., 3]
        steps = torch.stack(
            [
                executed[..., 0],
                executed[..., 1],
                torch.cos(heading),
                torch.sin(heading),
                speed * torch.cos(heading),
                speed * torch.sin(heading),
                torch.ones_like(speed),
            ],
            dim=-1,
        )
        real = self.agent_valid[..., None]
        steps = steps * real[..., None]
        h = self.agent_history.shape[2]
        history = torch.cat([self.agent_history, steps.to(self.agent_history)], dim=2)[:, :, -h:]
        history_valid = torch.cat([self.history_valid, real.expand(-1, -1, s)], dim=2)[:, :, -h:]
        pad_future = self.future.new_zeros(*self.future.shape[:2], s, self.future.shape[3])
        pad_valid = self.future_valid.new_zeros(*self.future_valid.shape[:2], s)
        return replace(
            self,
            agent_history=history,
            history_valid=history_valid,
            current_state=torch.where(real, executed[:, :, -1], self.current_state),
            future=torch.cat([self.future[:, :, s:], pad_future], dim=2),
            future_valid=torch.cat([self.future_valid[:, :, s:], pad_valid], dim=2),
            target_actions=None,
            target_valid=None,
        )
