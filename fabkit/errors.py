"""Typed failures shared by every stage.

The CLI maps `InputError` (and its `OutputError`, a file that cannot be written) to exit code 2 (one line naming the file and the problem) and
`ToleranceError` to exit code 1 (the run finished but missed a tolerance or a check).
"""
from __future__ import annotations


class FabkitError(Exception):
    """Base class of all fabkit errors."""


class InputError(FabkitError):
    """Bad input: a file or argument fabkit cannot use.

    `source` names the file (or argument) and `message` the problem; str() gives one line.
    """

    def __init__(self, message: str, source: str | None = None):
        self.source = source
        self.message = message
        super().__init__(f"{source}: {message}" if source else message)

    def with_source(self, source: str) -> "InputError":
        """Return the same error attributed to `source` (used when a validator did not know the file)."""
        if self.source:
            return self
        return type(self)(self.message, source=source)


class OutputError(InputError):
    """An output that cannot be written (read-only folder, name too long, full disk, a clash with
    an input or another output). `source` names the output path; the CLI exits 2."""


class MeshError(InputError):
    """A mesh that violates the mesh contract (names the face / vertex / edge)."""


class ToleranceError(FabkitError):
    """A computation ran but its result misses the requested tolerance."""
