"""WOSAC scenario metrics: likelihoods of the logged features under the rollouts' distributions.

Follows the Waymo Open Sim Agents Challenge (Montali et al., 2023; the paper's appendix 'WOSAC
Challenge Metrics'): time-series features are scored per evaluated agent with a histogram pooled over
rollouts and steps, averaged over the log's valid steps and exponentiated; collision, offroad and
red-light indicators are aggregated over time per agent and scored with a Bernoulli estimate. Buckets
are weight-normalised averages; the meta-metric is the weighted sum.

A map without road edges (nuScenes through ScenarioNet) is measured against edges derived from its lanes
(`scenario.drivable`); one with neither has no road-edge distance or offroad indication: those likelihoods and
the offroad rate are NaN, and the buckets and the meta-metric are taken over the remaining features with their
weights rescaled to the same total. Such figures are not comparable with the challenge's (the official code
refuses these scenes).

See docs/metrics.md.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np

from langtraj.errors import InputError
from langtraj.metrics.config import BUCKETS, FEATURES, WosacConfig, wosac_config
from langtraj.metrics.features import Features, SceneMap, compute_features, log_tracks, rollout_tracks
from langtraj.metrics.kinematics import kinematic_validity
from langtraj.rollouts.container import Rollouts
from langtraj.rollouts.validation import check_rollouts
from langtraj.scenario.model import Scenario

_TIMESERIES = {
    "linear_speed": "speed",
    "linear_acceleration": "acceleration",
    "angular_speed": "speed",
    "angular_acceleration": "acceleration",
    "distance_to_nearest_object": "step",
    "time_to_collision": "vehicle",
    "distance_to_road_edge": "step",
}
"""Time-series features and the validity mask each is averaged over."""


@dataclass(frozen=True)
class ScenarioMetrics:
    """Every WOSAC figure for one scenario (the official `SimAgentMetrics` fields plus buckets)."""

    scenario_id: str
    config: str
    metametric: float
    kinematic_metrics: float
    interactive_metrics: float
    map_based_metrics: float
    linear_speed_likelihood: float
    linear_acceleration_likelihood: float
    angular_speed_likelihood: float
    angular_acceleration_likelihood: float
    distance_to_nearest_object_likelihood: float
    collision_indication_likelihood: float
    time_to_collision_likelihood: float
    distance_to_road_edge_likelihood: float
    offroad_indication_likelihood: float
    traffic_light_violation_likelihood: float
    average_displacement_error: float
    min_average_displacement_error: float
    simulated_collision_rate: float
    simulated_offroad_rate: float
    simulated_traffic_light_violation_rate: float
    log_following_agents: int = 0  # agents whose rollouts replay the logged future: not a valid simulation

    def to_dict(self) -> dict[str, float | str]:
        return asdict(self)


def _mean_where(values: np.ndarray, mask: np.ndarray) -> float:
    count = mask.sum()
    return float(np.where(mask, values, 0.0).sum() / count) if count else float("nan")


def _weighted(config: WosacConfig, names, likelihood: dict[str, float]) -> float:
    """Weight-normalised mean of the finite likelihoods among `names` (NaN when none has weight)."""
    pairs = [(config.weight(n), likelihood[n]) for n in names if not np.isnan(likelihood[n])]
    total = sum(w for w, _ in pairs)
    return sum(w * v for w, v in pairs) / total if total > 0 else float("nan")


def score_features(
    config: WosacConfig, scenario_id: str, log: Features, sim: Features, log_valid: np.ndarray, is_vehicle: np.ndarray
) -> ScenarioMetrics:
    """Metrics from the log's features (N = 1) and the rollouts' (N = R); `log_valid` [E, 80]."""
    speed_valid, accel_valid = kinematic_validity(log_valid)
    masks = {
        "step": log_valid,
        "speed": speed_valid,
        "acceleration": accel_valid,
        "vehicle": log_valid & is_vehicle[:, None],
    }
    likelihood: dict[str, float] = {}
    for name, mask_name in _TIMESERIES.items():
        sim_values = getattr(sim, name)  # [R, E, T]
        num_rollouts, num_obj, num_steps = sim_values.shape
        pooled = sim_values.transpose(1, 0, 2).reshape(num_obj, num_rollouts * num_steps)
        estimator = config.features[name].estimator
        log_prob = estimator.log_prob(getattr(log, name)[0], pooled)
        likelihood[name] = float(np.exp(_mean_where(log_prob, masks[mask_name])))

    indicators = {
        "collision_indication": (log.collision, sim.collision, log_valid),
        "offroad_indication": (log.offroad, sim.offroad, log_valid),
        "traffic_light_violation": (log.traffic_light_violation, sim.traffic_light_violation, masks["vehicle"]),
    }
    sim_any: dict[str, np.ndarray] = {}
    for name, (log_flag, sim_flag, mask) in indicators.items():
        log_any = (log_flag[0] & mask).any(-1)  # [E]
        sim_any[name] = (sim_flag & mask[None]).any(-1)  # [R, E]
        estimator = config.features[name].estimator
        log_prob = estimator.log_prob(log_any[:, None], sim_any[name].T)[:, 0]
        likelihood[name] = float(np.exp(log_prob.mean()))

    offroad_rate = float(sim_any["offroad_indication"].mean())
    if np.isnan(sim.distance_to_road_edge).all():  # no road edges measured (neither edges nor lanes)
        likelihood["distance_to_road_edge"] = likelihood["offroad_indication"] = float("nan")
        offroad_rate = float("nan")
    buckets = {bucket: _weighted(config, names, likelihood) for bucket, names in BUCKETS.items()}
    metametric = _weighted(config, FEATURES, likelihood) * sum(config.weight(n) for n in FEATURES)
    ade = sim.average_displacement_error
    red_light_rate = (sim.traffic_light_violation & log_valid[None]).any(-1)
    return ScenarioMetrics(
        scenario_id=scenario_id,
        config=config.name,
        metametric=metametric,
        kinematic_metrics=buckets["kinematic"],
        interactive_metrics=buckets["interactive"],
        map_based_metrics=buckets["map_based"],
        **{f"{name}_likelihood": likelihood[name] for name in FEATURES},
        average_displacement_error=float(ade.mean()),
        min_average_displacement_error=float(ade.mean(axis=1).min()),
        simulated_collision_rate=float(sim_any["collision_indication"].mean()),
        simulated_offroad_rate=offroad_rate,
        simulated_traffic_light_violation_rate=float(red_light_rate.mean()),
    )


def evaluate_scenario(
    scenario: Scenario, rollouts: Rollouts, config: str | WosacConfig = "2025", *, scene_map: SceneMap | None = None
) -> ScenarioMetrics:
    """WOSAC metrics of `rollouts` for `scenario` (which must hold the 80 logged future steps).

    Raises InputError when the rollouts do not fit the scenario (agent set, steps, NaN or inf).
    """
    config = wosac_config(config)
    future = scenario.num_steps - scenario.current_index - 1
    if future < rollouts.num_steps:
        raise InputError(
            f"scenario {scenario.scenario_id} logs {future} future steps; scoring needs {rollouts.num_steps}",
            where="scenario",
        )
    agents = check_rollouts(scenario, rollouts)
    scene_map = scene_map or SceneMap.from_scenario(scenario)
    log = log_tracks(scenario)
    sim = rollout_tracks(scenario, rollouts, agents)
    log_features = compute_features(log, scene_map)
    sim_features = compute_features(sim, scene_map, log=log)
    log_valid = log.valid[0][log.evaluated][:, log.future]
    scores = score_features(
        config, scenario.scenario_id, log_features, sim_features, log_valid, log.is_vehicle[log.evaluated]
    )
    return replace(scores, log_following_agents=len(rollouts.log_following_ids))
