"""The experiments of docs/experiments.md, each printing its table: open-loop minADE and the text gain,
closed-loop realism, controllability and safety, instruction following, the oracle-prompt check, and the
demo. Each composes the library packages below it (sim, training, interdrive, metrics, synth, viz) and
none of them imports it. See docs/experiments.md and docs/design.md, 'Package layout'.
"""

from langtraj.experiments import closed_loop, failures, instruction, open_loop, realism  # noqa: F401  (register them)
from langtraj.experiments.base import EXPERIMENTS, Experiment, experiment_settings

__all__ = ["EXPERIMENTS", "Experiment", "experiment_settings"]
