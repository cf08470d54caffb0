"""Figures off the critical path (issue #40): a run writes its numbers before its figures, a
figure that fails leaves the record whole, ``ccm plots RUN_DIR`` draws the same figures from
the run's files, and ``ccm paper`` draws only those of the runs its report shows."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from ccm.cli import main as ccm_main
from ccm.experiment import runner
from ccm.experiment.runner import run_experiment
from ccm.plots.redraw import PLOT_INPUTS, main, redraw, run_dirs
from ccm.reporting import paper

# two conditions, two trials each: figures of the first and the last trial (first_last files)
SMOKE = ["experiment=smoke", "experiment.fast=true", "experiment.fast_trials=2",
         "experiment.fast_time_s=0.4"]  # fmt: skip


def _run(composer, out: Path, extra: tuple[str, ...] = ()) -> dict:
    over = [*SMOKE, *extra]
    cfg = composer(over)
    return run_experiment(cfg, lambda more: composer([*over, *more]), out, show_progress=False)


@pytest.fixture(scope="module")
def smoke_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from hydra import compose, initialize_config_dir

    from ccm.cli import config_dir

    out = tmp_path_factory.mktemp("smoke")
    with initialize_config_dir(str(config_dir()), version_base="1.3", job_name="test"):
        _run(lambda o=(): compose("config", overrides=list(o)), out)
    return out


def _pixels(path: Path) -> np.ndarray:
    return np.asarray(Image.open(path).convert("RGB"), dtype=np.int16)


def test_the_numbers_are_written_before_the_figures(smoke_run: Path) -> None:
    pngs = sorted((smoke_run / "figures").glob("*.png"))
    assert len(pngs) >= 5
    written = (smoke_run / "summary.json").stat().st_mtime_ns
    assert all(p.stat().st_mtime_ns >= written for p in pngs)
    inputs = json.loads((smoke_run / PLOT_INPUTS).read_text())
    assert inputs["dim"] == 2 and inputs["lowpass_hz"] == 30.0 and inputs["chance_bounds"] == {}
    info = json.loads((smoke_run / "run_info.json").read_text())
    assert info["cpu_s"]["figures"] > 0.0 and "figures_error" not in info


def test_ccm_plots_draws_the_runs_figures_again(smoke_run: Path, tmp_path: Path) -> None:
    """From the run's files (float32, 18 mantissa bits) the same figures: the same axes and
    ticks (a different tick or limit moves many pixels far), the curves' anti-aliased edges
    shaded a little differently (measured: <= 1.1 % of the pixels, none by more than 64)."""
    import shutil

    copy = tmp_path / "run"
    shutil.copytree(smoke_run, copy)
    shutil.rmtree(copy / "figures")
    assert main([str(copy), "--jobs", "1"]) == 0
    names = sorted(p.name for p in (smoke_run / "figures").glob("*.png"))
    assert sorted(p.name for p in (copy / "figures").glob("*.png")) == names
    for name in names:
        a, b = _pixels(smoke_run / "figures" / name), _pixels(copy / "figures" / name)
        assert a.shape == b.shape, name
        diff = np.abs(a - b)
        assert np.any(diff > 0, axis=2).mean() < 0.03, name
        assert not np.any(diff > 64), name


def test_a_figure_that_fails_leaves_the_record_whole(
    composer, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    def broken(*args: object, **kwargs: object) -> None:
        raise RuntimeError("a plotting bug")

    monkeypatch.setattr(runner, "write_figures", broken)
    summary = _run(composer, tmp_path)
    assert summary["status"] == "ok"
    assert json.loads((tmp_path / "summary.json").read_text()) == summary
    info = json.loads((tmp_path / "run_info.json").read_text())
    assert info["figures_error"] == "RuntimeError: a plotting bug"
    err = capsys.readouterr().err.strip()
    assert err.startswith("ccm: warning: figures failed (RuntimeError: a plotting bug)")
    assert f"`ccm plots {tmp_path}` draws them again" in err and "\n" not in err
    monkeypatch.undo()
    assert len(redraw(tmp_path)) >= 5  # and they can be drawn afterwards


def test_ccm_plots_refuses_what_it_cannot_draw(
    composer, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    assert ccm_main(["plots", str(tmp_path / "nope")]) == 2
    assert capsys.readouterr().err.strip() == f"ccm plots: {tmp_path / 'nope'}: not a directory"
    assert ccm_main(["plots", str(tmp_path)]) == 2
    assert f"{tmp_path}: no run directory with {PLOT_INPUTS} under it" in capsys.readouterr().err
    run = tmp_path / "run"
    _run(composer, run, ("experiment.timeseries=none", "experiment.figures=false"))
    assert not (run / "figures").exists()
    assert main([str(run)]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"ccm plots: error: {run}: no time series of fixed_low trial 1")
    assert err.endswith("(experiment.timeseries: first_last or all)")
    (run / "summary.json").write_text(json.dumps({"status": "failed", "error": "x"}))
    assert main([str(run)]) == 1
    assert "status 'failed'; only an ok run has figures" in capsys.readouterr().err
    assert main([str(run), "--jobs", "0"]) == 2


def test_a_sweep_directory_is_drawn_run_by_run(smoke_run: Path, tmp_path: Path) -> None:
    import shutil

    for k in (0, 1):
        shutil.copytree(
            smoke_run, tmp_path / "sweep" / str(k), ignore=shutil.ignore_patterns("figures")
        )
    shutil.copytree(smoke_run, tmp_path / "sweep" / "1.replaced-2026")  # moved aside: not drawn
    found = run_dirs(tmp_path / "sweep")
    assert found == [tmp_path / "sweep" / "0", tmp_path / "sweep" / "1"]
    assert main([str(tmp_path / "sweep"), "--jobs", "2"]) == 0
    for d in found:
        assert len(list((d / "figures").glob("*.png"))) >= 5


def test_paper_sweeps_draw_only_the_reports_figures(smoke_run: Path, tmp_path: Path) -> None:
    """Trial-loop sweeps run without figures and the lowest seed's run is drawn after them;
    an analysis sweep keeps its own figures."""
    import shutil

    assert "experiment.figures=false" in paper.sweep_command("h4_collisions", tmp_path, False)
    assert "experiment.figures=false" not in paper.sweep_command("mpc_convexity", tmp_path, False)
    for seed in (2, 1, 3):
        d = tmp_path / "smoke" / f"job{seed}"
        shutil.copytree(smoke_run, d, ignore=shutil.ignore_patterns("figures"))
        summary = json.loads((d / "summary.json").read_text())
        (d / "summary.json").write_text(json.dumps({**summary, "seed": seed}))
    timing = paper.draw_shown_figures(tmp_path, ["smoke"], lanes=1)
    drawn = [d.name for d in sorted((tmp_path / "smoke").iterdir()) if (d / "figures").is_dir()]
    assert drawn == ["job1"]
    assert timing["cpu_s"] > 0.0


def test_no_stiffness_figure_without_a_stiffness() -> None:
    """A run whose controllers log no stiffness (GP-MPC) gets no empty stiffness.png; one
    that logs it gets the figure."""
    from ccm.plots.adaptation import write_stiffness_figure

    t = np.linspace(0.0, 1.0, 50)
    drawn: list[str] = []
    write_stiffness_figure({"gp_mpc": {"t": t}}, [], {}, lambda fig, name: drawn.append(name))
    assert drawn == []
    log = {"t": t, "stiffness_Npm": np.full(50, 300.0)}
    write_stiffness_figure({"avic": log}, [], {}, lambda fig, name: drawn.append(name))
    assert drawn == ["stiffness.png"]
