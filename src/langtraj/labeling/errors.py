"""The labeling tool's refusals beyond bad input (`langtraj.errors.InputError`); the web app maps each to
its HTTP status (docs/labeling.md, 'Web API')."""

from __future__ import annotations

from langtraj.errors import LangTrajError


class Conflict(LangTrajError):
    """The request is well formed but the task's state forbids it (lock lost, already submitted): 409."""


class Forbidden(LangTrajError):
    """The request touches another annotator's slot or labels, or needs another role: 403."""


class NotFound(LangTrajError):
    """No such task, slot or annotation: 404."""
