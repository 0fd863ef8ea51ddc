"""The shipped behaviours, imported in the order alternatives are listed (each registers itself on import)."""

import importlib

MODULES = (
    "turn", "lane_change", "stop", "speed_change", "pull_over", "go_first", "yield_", "follow", "cut_in",
    "overtake_cut_in", "brake_hard", "tailgate", "run_red_light", "pull_out",
)  # fmt: skip
"""The modules of `interdrive.behaviours` holding the shipped behaviours, in the order they register."""

for _module in MODULES:
    importlib.import_module(f"langtraj.interdrive.behaviours.{_module}")
