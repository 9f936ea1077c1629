"""Typed user errors: the CLI turns each into one line on stderr and exit status 2."""

from __future__ import annotations


class UserError(Exception):
    """Bad input from the user (file, stage, argument): reported in one line, exit status 2."""


class StageError(UserError):
    """The stage cannot be opened or lacks what a render needs (camera, valid geometry)."""


class InvalidGeometryError(StageError):
    """A prim has non-finite points or out-of-range face indices; names the prim."""

    def __init__(self, prim_path: str, problem: str) -> None:
        super().__init__(f"invalid geometry on {prim_path}: {problem} "
                         f"(use --skip-invalid to drop the prim with a warning)")
        self.prim_path = prim_path


class SettingsError(UserError):
    """A setting is out of range or does not apply to the chosen method."""
