"""The behaviours a prompt can ask, one module each: their words, parameters, targets, steering and judges, behind one
interface and registry (`BehaviourKind`, `KINDS`, `kind`; docs/design.md, 'Behaviours').

`base` the interface, `Parameter` and the declarative steering terms (`Steer`); `scripts` manoeuvres executed
exactly (`Script`); `recipes` steering several
behaviours share; one module per behaviour (`turn`: left, right and straight; `lane_change`: left and right; `stop`,
`speed_change`: up and down; `pull_over`, `go_first`, `yield_`, `follow`, `cut_in`, `overtake_cut_in`, `brake_hard`,
`tailgate`, `run_red_light`, `pull_out`), imported by `builtin`. A new behaviour is one module with one registered
class (`@register`), imported before a prompt is read.
"""

from langtraj.interdrive.behaviours.base import (
    KINDS,
    BehaviourKind,
    Parameter,
    Steer,
    kind,
    register,
)
from langtraj.interdrive.behaviours.scripts import Script, ScriptState, unicycle_step

__all__ = ["KINDS", "BehaviourKind", "Parameter", "Script", "ScriptState", "Steer", "kind", "register", "unicycle_step"]
