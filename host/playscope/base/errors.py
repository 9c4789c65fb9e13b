"""Error types of playscope: bad input prints as one line naming file and row (the CLI)."""

from __future__ import annotations

import os


class PlayscopeError(Exception):
    """Base of every error playscope raises on purpose (the CLI prints it as one line)."""


class InputError(PlayscopeError, ValueError):
    """Bad input from outside (a session file, a table, a video).

    str(err) is one line: ``"<file>:<row>: <message>"`` (row omitted when unknown).
    ``row`` counts lines of the file from 1, so the header of a CSV is row 1.
    """

    def __init__(self, file: str | os.PathLike | None, message: str, row: int | None = None):
        self.file = None if file is None else os.fspath(file)
        self.row = row
        self.message = message
        where = self.file or "<input>"
        if row is not None:
            where = f"{where}:{row}"
        super().__init__(f"{where}: {message}")
