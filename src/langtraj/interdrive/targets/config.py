"""`CounterfactualConfig`: how far ahead the map is searched for what an agent may do, and the labelers' settings
the search reads (docs/interdrive.md, 'Targets and feasibility')."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from langtraj.interdrive.detector import DetectorConfig
from langtraj.interdrive.heuristics import HeuristicConfig


@dataclass(frozen=True)
class CounterfactualConfig:
    """How far ahead the map is searched, and the labelers' settings (their turn thresholds classify junction
    lanes; they also read the log to tell which alternatives it shows). Units: m, s, rad."""

    lookahead_m: float = 60.0
    """Least distance along the lane graph searched for the next junction and for neighbour lanes (m)."""
    lookahead_s: float = 8.0
    """Or as far as the agent's current speed carries it in this time, if farther (s): the simulated horizon."""
    neighbour_step_m: float = 5.0
    """Spacing of the stations along the lanes ahead where neighbour lanes are looked for (m)."""
    u_turn_angle: float = math.radians(150.0)
    """A junction branch turning by this much or more is a U-turn, which no behaviour asks for (rad)."""
    heuristics: HeuristicConfig = field(default_factory=HeuristicConfig)
    detector: DetectorConfig = field(default_factory=DetectorConfig)

    def __post_init__(self) -> None:
        for name in ("lookahead_m", "lookahead_s", "neighbour_step_m", "u_turn_angle"):
            if not getattr(self, name) > 0:
                raise ValueError(f"CounterfactualConfig.{name} must be > 0, got {getattr(self, name)!r}")

    def reach(self, speed: float) -> float:
        """How far along the lane graph the search goes for an agent at `speed` (m)."""
        return max(self.lookahead_m, speed * self.lookahead_s)
