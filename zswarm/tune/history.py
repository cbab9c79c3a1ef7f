"""A tune's directory: what was asked (``tune.json``) and every candidate judged (``history.jsonl``).

Each candidate is one JSON line, appended and flushed to disk the moment it is known: when its design
check fails (it is never simulated), and when its simulation finishes. A resumed tune asks the same
candidates again (the search is deterministic for its seed) and takes every answer the file holds
instead of computing it, so an interruption loses no finished evaluation.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from zswarm.errors import UsageError
from zswarm.files import check_writable, out_dir, write_json

#: Fields of tune.json that may change between a tune and its resumption.
MAY_CHANGE = ("budget", "finalists", "validation")  # the last two only choose among what was searched


class History:
    def __init__(self, folder: Path, config: dict[str, Any]) -> None:
        self.folder = folder
        self.path = folder / "history.jsonl"
        self.records: dict[tuple[int, int], dict[str, Any]] = {}
        config_path = folder / "tune.json"
        out_dir(folder)
        check_writable(config_path)
        config = json.loads(json.dumps(config))  # as it reads back (tuples become lists)
        if config_path.exists():
            old = json.loads(config_path.read_text())
            differ = sorted(k for k in set(old) | set(config) if k not in MAY_CHANGE and old.get(k) != config.get(k))
            if differ:
                raise UsageError(f"{folder} holds a different tune (it differs in {', '.join(differ)}); "
                                 "give another --out, or the same settings to resume it")
        write_json(config_path, config)
        if self.path.exists():
            self._load()
        self._file = open(self.path, "a")

    def _load(self) -> None:
        lines = self.path.read_text().splitlines()
        for number, line in enumerate(lines, 1):
            try:
                record = json.loads(line)
            except json.JSONDecodeError:
                if number == len(lines):  # a line cut short by the interruption: drop it
                    continue
                raise UsageError(f"{self.path}:{number} is not JSON; remove the line or give another --out") from None
            self.records[(record["gen"], record["slot"])] = record

    def get(self, gen: int, slot: int) -> dict[str, Any] | None:
        return self.records.get((gen, slot))

    def add(self, record: dict[str, Any]) -> None:
        self.records[(record["gen"], record["slot"])] = record
        self._file.write(json.dumps(record) + "\n")
        self._file.flush()
        os.fsync(self._file.fileno())

    def close(self) -> None:
        self._file.close()
