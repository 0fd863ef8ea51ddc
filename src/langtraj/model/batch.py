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
