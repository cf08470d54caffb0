"""The ``recording`` pattern segment: P from a demonstration file (seed A §3), its C²
smoothing spline, the round trip of a known path, force targets and the file checks."""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from ccm.core.errors import ConfigError
from ccm.tasks.recording import CUTOFF_HZ
from ccm.tasks.trajectory import build_pattern

DT = 0.002  # a 500 Hz recording
T = 4.0


def _path(t: np.ndarray) -> np.ndarray:
    """A known path that starts and ends at rest: a min-jerk line along x and a sin³ bump in
    y (both with zero velocity and acceleration at the ends, like a demonstration)."""
    tau = t / T
    s = tau**3 * (10.0 - 15.0 * tau + 6.0 * tau**2)
    return np.column_stack([0.1 + 0.2 * s, 0.05 * np.sin(math.pi * tau) ** 3])


def _write(tmp: Path, frame: pd.DataFrame, name: str = "demo.csv") -> str:
    path = tmp / name
    if path.suffix == ".csv":
        frame.to_csv(path, index=False)
    elif path.suffix == ".parquet":
        frame.to_parquet(path)
    elif path.suffix == ".json":
        path.write_text(json.dumps({c: frame[c].tolist() for c in frame.columns}))
    else:
        np.savez(path, **{c: frame[c].to_numpy() for c in frame.columns})
    return str(path)


def _frame(noise_m: float = 0.0, seed: int = 0) -> pd.DataFrame:
    t = np.arange(0.0, T + DT / 2, DT)
    p = _path(t) + np.random.default_rng(seed).normal(0.0, noise_m, (t.size, 2))
    return pd.DataFrame({"t": t + 10.0, "x": p[:, 0], "y": p[:, 1]})  # any time origin


def _pattern(file: str, **extra: object) -> object:
    return build_pattern([{"type": "recording", "file": file, **extra}], [0.1, 0.0], DT)


def test_c2_continuity_everywhere_and_at_the_knots(tmp_path: Path) -> None:
    """Finite differences of position and velocity match the analytic velocity and
    acceleration over the whole recording, and nothing jumps across any knot. The recording
    is noisy (0.5 mm), which is what would show kinks if the spline were not C²."""
    P = _pattern(_write(tmp_path, _frame(noise_m=5e-4)))
    seg = P.segments[0]
    h = 1e-6
    ts = np.linspace(h, P.duration - 2 * h, 2001)  # at the end P holds (velocity 0)
    lo, mid, hi = (P.sample_many(ts + d) for d in (-h, 0.0, h))
    fd_vel = (hi["position"] - lo["position"]) / (2 * h)
    fd_acc = (hi["velocity"] - lo["velocity"]) / (2 * h)
    # truncation ~ h² |third derivative| (< 1e3 m/s³ here) plus rounding ~ 1e-16 / h
    assert np.max(np.abs(fd_vel - mid["velocity"])) < 1e-6
    assert np.max(np.abs(fd_acc - mid["acceleration"])) < 1e-5
    knots = seg._motion.breaks[1:]
    eps = 1e-9
    left, right = (P.sample_many(knots + d) for d in (-eps, eps))
    for name, bound in (("position", 1e-9), ("velocity", 1e-7), ("acceleration", 1e-4)):
        # a jump would be O(1) of the quantity; continuity leaves derivative x 2 eps
        assert np.max(np.abs(right[name] - left[name])) < bound, name


def test_round_trip_of_a_known_path(tmp_path: Path) -> None:
    """A clean analytic path comes back within 20 µm / 1 mm/s / 0.05 m/s², and noise is
    smoothed away.

    Tolerance: the path's content lies below 1 Hz, where the smoothing spline's gain
    1 / (1 + (f / f_c)⁴) differs from 1 by < 2e-3 at f_c = 5 Hz, i.e. < 0.1 mm on 0.05 m
    amplitudes; what is left is the resampling and the end conditions, which start at rest.
    White noise of std σ sampled at 500 Hz keeps about sqrt(5.5 Hz / 250 Hz) ≈ 0.15 σ
    through a 5 Hz smoother, so < 0.3 σ is asserted."""
    P = _pattern(_write(tmp_path, _frame()))
    ts = np.linspace(0.0, T, 4001)
    got = P.sample_many(ts)
    h = 1e-6
    want_vel = (_path(ts + h) - _path(ts - h)) / (2 * h)
    assert np.max(np.abs(got["position"] - _path(ts))) < 2e-5
    assert np.max(np.abs(got["velocity"] - want_vel)) < 1e-3
    want_acc = (_path(ts + 1e-4) - 2 * _path(ts) + _path(ts - 1e-4)) / 1e-8
    assert np.max(np.abs(got["acceleration"] - want_acc)) < 0.05
    assert P.duration == pytest.approx(T)
    noisy = _pattern(_write(tmp_path, _frame(noise_m=2e-4, seed=3), "noisy.csv"))
    err = noisy.sample_many(ts)["position"] - _path(ts)
    assert 0.0 < float(np.sqrt(np.mean(err**2))) < 0.3 * 2e-4


def test_the_cutoff_rule_halves_a_sine_at_the_cutoff(tmp_path: Path) -> None:
    """λ = 1 / (h (2π f_c)⁴) puts the half-amplitude point at f_c (module docstring)."""
    t = np.arange(0.0, 4.0, 0.001)
    ys = {f: 0.001 * np.sin(2 * math.pi * f * t) for f in (1.0, CUTOFF_HZ)}
    for f, y in ys.items():
        frame = pd.DataFrame({"t": t, "x": 0.1 + 0 * t, "y": y})
        P = _pattern(_write(tmp_path, frame, f"sine{f}.csv"))
        mid = (t > 1.0) & (t < 3.0)
        out = P.sample_many(t[mid])["position"][:, 1]
        gain = float(np.std(out) / np.std(y[mid]))
        assert gain == pytest.approx(1.0 / (1.0 + (f / CUTOFF_HZ) ** 4), abs=0.02), f


def test_every_format_reads_the_same(tmp_path: Path) -> None:
    frame = _frame()
    ref = _pattern(_write(tmp_path, frame)).sample(1.3).position
    for name in ("d.parquet", "d.json", "d.npz"):
        got = _pattern(_write(tmp_path, frame, name)).sample(1.3).position
        np.testing.assert_allclose(got, ref, atol=1e-12, err_msg=name)


def test_force_columns_become_the_hybrid_force_target(tmp_path: Path) -> None:
    frame = _frame()
    frame["fx"] = 0.0
    frame["fy"] = np.where(frame["t"] - 10.0 > 2.0, -8.0, 0.0)  # pressing down after 2 s
    P = _pattern(_write(tmp_path, frame))
    early, late = (copy.deepcopy(P.sample(t)) for t in (1.0, 3.0))  # P reuses its sample (#40)
    assert early.force_dir is None and early.force_mag == 0.0
    np.testing.assert_allclose(late.force_dir, [0.0, -1.0], atol=1e-9)
    assert late.force_mag == pytest.approx(8.0, abs=1e-3)
    many = P.sample_many(np.array([1.0, 3.0]))
    assert many["force_active"].tolist() == [False, True]
    assert many["force_mag"][1] == pytest.approx(late.force_mag)
    assert P.sample(T + 1.0).force_mag == pytest.approx(8.0, abs=1e-3)  # held after the end


def test_the_start_is_shifted_onto_the_previous_end_or_refused(tmp_path: Path) -> None:
    file = _write(tmp_path, _frame())
    spec = [{"type": "line", "to": [0.105, 0.0], "duration": 0.5},
            {"type": "recording", "file": file}]  # fmt: skip
    P = build_pattern(spec, [0.0, 0.0], DT)
    np.testing.assert_allclose(P.segments[1].offset, [0.005, 0.0], atol=1e-5)
    np.testing.assert_allclose(
        P.sample(0.5 + T).position, _path(np.array([T]))[0] + [0.005, 0], atol=2e-5
    )
    spec[0]["to"] = [0.2, 0.0]
    with pytest.raises(ConfigError, match=r"demo\.csv: starts at .* from the previous end"):
        build_pattern(spec, [0.0, 0.0], DT)


def _bad(frame: pd.DataFrame, row: int, column: str, value: float) -> pd.DataFrame:
    out = frame.copy()
    out.loc[row - 1, column] = value  # rows count from 1
    return out


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda f: f.drop(columns="y"), r"demo\.csv: missing column\(s\) y \(has: t, x\)"),
        (lambda f: f.drop(columns="t"), r"demo\.csv: missing column t"),
        (lambda f: _bad(f, 7, "t", 10.0), r"demo\.csv: row 7: time does not increase"),
        (lambda f: _bad(f, 5, "x", math.nan), r"demo\.csv: row 5: column x is not a finite"),
        (lambda f: _bad(f, 9, "y", 0.5), r"demo\.csv: row 9: position jumps at .* 1\.7 m/s"),
        (lambda f: f.iloc[:5], r"demo\.csv: 5 rows; a recording needs at least 10"),
        (lambda f: f.assign(theta=np.linspace(0, 1, len(f))), r"demo\.csv: row \d+: orientation"),
        (lambda f: f.assign(fx=0.0), r"demo\.csv: missing column\(s\) fy"),
    ],
)
def test_bad_files_get_one_line_naming_file_and_row(
    tmp_path: Path, change: object, message: str
) -> None:
    file = _write(tmp_path, change(_frame()))  # type: ignore[operator]
    with pytest.raises(ConfigError, match=message) as err:
        _pattern(file)
    assert "\n" not in str(err.value)
    assert str(err.value).startswith("task.pattern[0].file: ")


def test_bad_paths_and_keys(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"nope\.csv: no such file"):
        _pattern(str(tmp_path / "nope.csv"))
    (tmp_path / "d.pkl").write_bytes(b"\x80\x04")
    with pytest.raises(ConfigError, match=r"unknown format '\.pkl'"):
        _pattern(str(tmp_path / "d.pkl"))
    with pytest.raises(ConfigError, match=r"task\.pattern\[0\]\.duration: unknown key"):
        _pattern(_write(tmp_path, _frame()), duration=2.0)
    with pytest.raises(ConfigError, match=r"cutoff_hz: must lie in \(0, 250\)"):
        _pattern(_write(tmp_path, _frame()), cutoff_hz=300.0)
    with pytest.raises(ConfigError, match=r"row 9: position jumps at .* 0\.1 m/s"):
        _pattern(_write(tmp_path, _bad(_frame(), 9, "y", 0.001)), max_speed=0.1)


def test_windows_of_one_file_join_as_the_whole_recording(tmp_path: Path) -> None:
    """``from``/``to`` cut one smoothed spline into named segments: together they are the
    whole recording (the same P to rounding), so the joins are C² too."""
    file = _write(tmp_path, _frame(noise_m=2e-4))
    whole = _pattern(file)
    spec = [{"type": "recording", "file": file, "to": 1.5, "name": "a"},
            {"type": "recording", "file": file, "from": 1.5, "name": "b"}]  # fmt: skip
    split = build_pattern(spec, [0.1, 0.0], DT)
    assert [s.name for s in split.segments] == ["a", "b"]
    assert split.duration == pytest.approx(whole.duration)
    ts = np.linspace(0.0, T - 1e-6, 3001)
    for name in ("position", "velocity", "acceleration"):
        np.testing.assert_allclose(
            split.sample_many(ts)[name], whole.sample_many(ts)[name], atol=1e-12, err_msg=name
        )
    with pytest.raises(ConfigError, match=r"pattern\[0\]\.from: window \[3\.0, 9\.0\] s"):
        _pattern(file, **{"from": 3.0, "to": 9.0})


def test_a_ccm_path_is_inside_the_config_directory() -> None:
    from ccm.experiment.user_configs import config_dir
    from ccm.tasks.recording_file import resolve_path

    assert resolve_path("ccm://demos/x.csv") == config_dir() / "demos" / "x.csv"
    assert resolve_path("demos/x.csv") == Path("demos/x.csv")  # from the working directory


def test_a_force_component_starts_where_the_recording_has_it(tmp_path: Path) -> None:
    """The smoothing spreads a force step over about ±1/f_c; the per-axis gate keeps the
    target's direction on the recorded components until the new one was recorded (a wall
    met at 2 s while pressing on a table): no tilt toward the wall before it is reached."""
    frame = _frame()
    t = frame["t"] - 10.0
    frame["fx"] = np.where(t >= 2.0, 10.0, 0.0)  # the wall, from 2 s on
    frame["fy"] = -12.0  # the table, all along
    P = _pattern(_write(tmp_path, frame))
    before = P.sample_many(np.array([1.9, 1.99]))
    np.testing.assert_allclose(before["force_dir"], [[0.0, -1.0], [0.0, -1.0]], atol=1e-12)
    after = P.sample(2.5)
    assert after.force_dir[0] == pytest.approx(10.0 / math.hypot(10.0, 12.0), abs=0.01)
    raw_smooth = P.segments[0]._force.eval(1.9)[0]  # the spline itself leaks ahead of 2 s
    assert abs(raw_smooth[0]) > 0.05  # (it rings: negative here)
