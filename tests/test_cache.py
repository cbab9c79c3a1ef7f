"""Results kept between commands (zswarm.cache): the swarm check's squeeze computed once per set and code."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from zswarm import cache
from zswarm.design import squeeze as squeezing
from zswarm.paper.params import DEFAULT_PARAMS

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@pytest.fixture
def folder(tmp_path, monkeypatch):
    monkeypatch.setenv(cache.ENV, str(tmp_path / "cache"))
    return tmp_path / "cache"


def counting():
    calls = []

    def compute():
        calls.append(1)
        return {"value": len(calls), "far": float("inf")}
    return compute, calls


def test_a_result_is_computed_once_per_key_and_read_back_whole(folder):
    compute, calls = counting()
    first = cache.kept("t", "a", compute)
    assert cache.kept("t", "a", compute) == first == {"value": 1, "far": float("inf")} and len(calls) == 1
    assert cache.kept("t", "b", compute) == {"value": 2, "far": float("inf")} and len(calls) == 2
    assert sorted(p.name.split("-")[0] for p in folder.iterdir()) == ["t", "t"]  # no temporary file left


def test_another_code_never_reads_this_codes_result(folder, monkeypatch):
    compute, calls = counting()
    cache.kept("t", "a", compute)
    monkeypatch.setattr(cache, "code_digest", lambda: "another version of zswarm")
    assert cache.kept("t", "a", compute) == {"value": 2, "far": float("inf")} and len(calls) == 2


def test_a_damaged_or_foreign_entry_is_computed_again(folder):
    compute, calls = counting()
    cache.kept("t", "a", compute)
    (entry,) = folder.iterdir()
    for damage in ("{not json", json.dumps({"key": "another key", "value": {"value": 99}}), "[]"):
        entry.write_text(damage)
        assert cache.kept("t", "a", compute)["value"] == len(calls)  # computed, not the damaged value
    assert json.loads(entry.read_text())["value"]["value"] == len(calls) == 4  # and written right again


def test_off_or_unwritable_the_result_is_computed_and_nothing_fails(tmp_path, monkeypatch):
    compute, calls = counting()
    monkeypatch.setenv(cache.ENV, "off")
    cache.kept("t", "a", compute)
    cache.kept("t", "a", compute)
    assert len(calls) == 2
    (tmp_path / "file").write_text("a file where the folder would be")
    monkeypatch.setenv(cache.ENV, str(tmp_path / "file"))
    assert cache.kept("t", "a", compute)["value"] == 3


def test_the_cache_keeps_at_most_its_bound(folder, monkeypatch):
    monkeypatch.setattr(cache, "MAX_ENTRIES", 8)
    compute, _ = counting()
    for k in range(30):
        cache.kept("t", str(k), compute)
    assert 4 <= len(list(folder.iterdir())) <= 8


def test_the_squeeze_another_process_reads_is_the_one_computed_here(folder):
    """The swarm check's squeeze: computed here, kept, and read back by another command as the same result
    (inf included); nothing of it is computed there (its engine would fail)."""
    squeezing.squeeze.cache_clear()
    params = DEFAULT_PARAMS.with_values({"c_o": 2.75})
    here = squeezing.squeeze(params, 4)
    assert len(list(folder.glob("squeeze-*.json"))) == 1
    code = ("import sys, zswarm.design.squeeze as s; from zswarm.paper.params import DEFAULT_PARAMS as P\n"
            "s._Pressed = None  # a squeeze computed here fails\n"
            "print(repr(s.squeeze(P.with_values({'c_o': 2.75}), 4)))")
    there = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60,
                           env={**os.environ, "PYTHONPATH": ROOT, cache.ENV: str(folder)})
    assert there.returncode == 0, there.stderr[-2000:]
    assert there.stdout.strip() == repr(here)
    squeezing.squeeze.cache_clear()
