"""Errors LangTraj raises for bad input; the CLI prints them as one line and exits non-zero."""

from __future__ import annotations

from pathlib import Path


def one_line(error: BaseException) -> str:
    """`Type: first line of the message` (the type alone for an empty message): how a report names an error."""
    lines = str(error).strip().splitlines()
    return f"{type(error).__name__}: {lines[0]}" if lines else type(error).__name__


class LangTrajError(Exception):
    """Base class of every error the CLI reports as one clear line instead of a traceback."""


class InputError(LangTrajError):
    """Bad input data: names the file and, where known, the record and field that are wrong."""

    def __init__(self, message: str, *, path: str | Path | None = None, where: str | None = None):
        self.path = None if path is None else str(path)
        self.where = where
        self.detail = message
        parts = [p for p in (self.path, where, message) if p]
        super().__init__(": ".join(parts))

    def located(self, *, path: str | Path | None = None, where: str | None = None) -> InputError:
        """The same error with a file and/or location prepended (keeps existing ones)."""
        joined_where = ", ".join(w for w in (where, self.where) if w) or None
        return InputError(self.detail, path=self.path or path, where=joined_where)


class ScenarioValidationError(InputError):
    """A Scenario whose arrays break the data contract (shapes, dtypes, NaN positions, bad indices)."""

    def located(self, *, path: str | Path | None = None, where: str | None = None) -> ScenarioValidationError:
        joined_where = ", ".join(w for w in (where, self.where) if w) or None
        return ScenarioValidationError(self.detail, path=self.path or path, where=joined_where)


class DataWarning(UserWarning):
    """Input data LangTraj repaired as it read it (a box wider than long, ...): names the file and what was done."""
