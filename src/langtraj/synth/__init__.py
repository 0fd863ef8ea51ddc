"""SUMO scenario factory: randomized road networks and demand, simulated at 0.1 s, cut into windows
of the Scenario model with ground-truth behaviour events (docs/design.md, 'Package layout'; docs/data.md)."""
