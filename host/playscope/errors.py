"""One error type for bad input, so the CLI can print it as a single line naming file and row."""

from __future__ import annotations

import os


class InputError(ValueError):
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
