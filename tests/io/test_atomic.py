from __future__ import annotations

from pathlib import Path

import pytest

from darksynth.io.atomic import atomic_output, write_text_atomic


def test_atomic_output_moves_temp_into_place_on_success(tmp_path: Path) -> None:
    dest = tmp_path / "a" / "b" / "out.png"
    with atomic_output(dest) as tmp:
        assert tmp.parent == dest.parent
        assert tmp.name.startswith(".out.tmp-")
        assert tmp.suffix == ".png"
        assert not dest.exists()
        tmp.write_bytes(b"data")
    assert dest.read_bytes() == b"data"
    assert sorted(p.name for p in dest.parent.iterdir()) == ["out.png"]


def test_atomic_output_removes_temp_and_keeps_old_file_on_error(tmp_path: Path) -> None:
    dest = tmp_path / "out.txt"
    dest.write_text("old")
    with pytest.raises(RuntimeError, match="boom"), atomic_output(dest) as tmp:
        tmp.write_text("half")
        raise RuntimeError("boom")
    assert dest.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["out.txt"]


def test_atomic_output_cleans_up_on_keyboard_interrupt(tmp_path: Path) -> None:
    dest = tmp_path / "out.txt"
    with pytest.raises(KeyboardInterrupt), atomic_output(dest) as tmp:
        tmp.write_text("half")
        raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []


def test_atomic_output_temp_names_are_unique(tmp_path: Path) -> None:
    dest = tmp_path / "out.txt"
    with atomic_output(dest) as first, atomic_output(dest) as second:
        first.write_text("1")
        second.write_text("2")
        assert first != second
    assert dest.read_text() == "1"


def test_write_text_atomic_writes_utf8(tmp_path: Path) -> None:
    dest = tmp_path / "sub" / "manifest.json"
    write_text_atomic(dest, '{"name": "nuit — ночь"}\n')
    assert dest.read_text(encoding="utf-8") == '{"name": "nuit — ночь"}\n'
    write_text_atomic(dest, "second")
    assert dest.read_text(encoding="utf-8") == "second"
