"""InterDrive: single-agent heuristic labels, interaction labels and prompts for any Scenario.

See docs/interdrive.md.
"""
