"""Hostile input that once lost data or failed silently (issue #39 item 2): each case gets one
line naming the problem, a non-zero exit, and nothing already written is changed."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from ccm.cli import main


def _snapshot(root: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()
    }


def _existing_file(tmp: Path) -> list[str]:
    (tmp / "d.csv").write_text("t,x\n0,1\n")
    return ["demo", "smoke", "--out", str(tmp / "d.csv")]


def _directory(tmp: Path) -> list[str]:
    (tmp / "d.csv").mkdir()
    return ["demo", "smoke", "--out", str(tmp / "d.csv")]


def _under_a_file(tmp: Path) -> list[str]:
    (tmp / "f").write_text("x")
    return ["demo", "smoke", "--out", str(tmp / "f" / "d.csv")]


def _negative_seed(tmp: Path) -> list[str]:
    return ["demo", "smoke", "--out", str(tmp / "d.csv"), "--seed", "-1"]


def _unwritable(tmp: Path) -> list[str]:
    return ["demo", "smoke", "--out", "/proc/ccm-demo.csv"]  # read-only even for root


DEMO_CASES: dict[str, tuple[Callable[[Path], list[str]], str]] = {
    "existing file": (_existing_file, "d.csv exists; pass --force to replace it"),
    "directory": (_directory, "d.csv is a directory"),
    "parent is a file": (_under_a_file, "cannot write in"),
    "negative seed": (_negative_seed, "--seed: must be an integer >= 0, got -1"),
    "read-only place": (_unwritable, "/proc/ccm-demo.csv: cannot write"),
}


@pytest.mark.parametrize("case", list(DEMO_CASES))
def test_demo_refuses_with_one_line_and_overwrites_nothing(
    case: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    make, expected = DEMO_CASES[case]
    argv = make(tmp_path)
    before = _snapshot(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and expected in err, err
    assert _snapshot(tmp_path) == before


def test_demo_force_replaces_an_existing_file(tmp_path: Path) -> None:
    out = tmp_path / "d.csv"
    out.write_text("t,x\n0,1\n")
    assert main(["demo", "smoke", "--out", str(out), "--force"]) == 0
    assert out.read_text().startswith("t,x,y,")
    assert [p.name for p in tmp_path.iterdir()] == ["d.csv"]  # no temporary file left
