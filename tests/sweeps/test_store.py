"""The store's small writes (sweeps/store.py): whole or not at all, on a real folder."""

from __future__ import annotations

from pathlib import Path

import pytest

from dse_runner.sweeps import store


def test_a_write_cut_short_leaves_the_old_file_whole_and_no_half_file(tmp_path):
    """Ctrl-C raises wherever the client is, inside a status write too (test_interrupt.py once found a
    status file's half left beside it): the half goes, and the file it was replacing stays as it was."""
    store.write_text(tmp_path, "s.status.json", "old")

    def cut_short(partial: Path) -> None:
        partial.write_bytes(b"half")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        store._replace_whole(str(tmp_path / "s.status.json"), cut_short)
    assert [p.name for p in tmp_path.iterdir()] == ["s.status.json"]
    assert (tmp_path / "s.status.json").read_text() == "old"
