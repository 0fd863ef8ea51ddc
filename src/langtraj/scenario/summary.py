"""One JSON-compatible summary per scenario (what `langtraj inspect` prints). See docs/data.md."""

from __future__ import annotations

from typing import Any

from langtraj.scenario.model import Scenario


def scenario_summary(scenario: Scenario) -> dict[str, Any]:
    """Counts and identities of a scenario; prediction and interest lists are given as track ids."""
    agents = scenario.agents
    return {
        "scenario_id": scenario.scenario_id,
        "source_format": scenario.source_format,
        "num_agents": scenario.num_agents,
        "num_map_features": len(scenario.road_map),
        "num_steps": scenario.num_steps,
        "current_index": scenario.current_index,
        "duration_s": round(float(scenario.timestamps[-1] - scenario.timestamps[0]), 3) if scenario.num_steps else 0.0,
        "sdc_id": scenario.sdc_id,
        "objects_of_interest": agents.ids[agents.objects_of_interest].tolist(),
        "tracks_to_predict": agents.ids[agents.tracks_to_predict].tolist(),
        "agent_type_counts": agents.type_counts(),
        "map_feature_counts": scenario.road_map.type_counts(),
        "num_traffic_light_lanes": scenario.traffic_lights.num_lanes,
        "num_events": len(scenario.events),
    }
