"""A child's output kept in a file, to read once it matters: a pipe that nobody reads while the child
runs fills under load (64 KiB), and then every process writing to it stops mid-run, the world and the
agents included. Pass a :class:`Spool` as ``stdout``/``stderr``; :meth:`Spool.text` reads it back."""
from __future__ import annotations

import tempfile


class Spool:
    def __init__(self) -> None:
        self.file = tempfile.TemporaryFile()

    def fileno(self) -> int:
        return self.file.fileno()

    def text(self) -> str:
        """Everything written so far."""
        self.file.flush()
        self.file.seek(0)
        return self.file.read().decode(errors="replace")
