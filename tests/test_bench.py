"""``make bench`` pieces (issue #20) on tiny sizes: the raw engine loops beside ccm's loop,
the ratio, and the CPU-minutes read from a paper run's timing file. Speeds are not asserted
(these machines are noisy); the rows' bookkeeping is."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from ccm.bench.components import components
from ccm.bench.engines import raw_loop
from ccm.bench.loop import bench_task, paper_cpu, print_paper_cpu


@pytest.mark.parametrize(
    ("task", "sim"),
    [("multi_spring", None), ("changing_surface", "pybullet3d"), ("changing_surface", "mujoco3d")],
)
def test_raw_loop_runs_the_engine_and_moves_time_on(task: str, sim: str | None) -> None:
    comp = components(task, "fixed_impedance", sim)
    try:
        wall = raw_loop(comp.sim, comp.task.pattern, 50)
        assert wall > 0.0
        obs, _ = comp.sim.step(comp.controller.step(*_first(comp)))
        assert obs.t > 0.0  # the simulator still works after the raw loop
    finally:
        comp.sim.close()


def _first(comp):  # noqa: ANN001, ANN202
    obs, _ = comp.sim.reset(seed=0)
    comp.controller.reset(comp.task.dim, comp.sim.control_dt)
    return obs, comp.task.pattern.sample(obs.t)


def test_raw_loop_refuses_an_unknown_simulator() -> None:
    class Other:
        control_dt = 0.001

        def reset(self, seed: int = 0) -> tuple:
            return type("Obs", (), {"t": 0.0})(), None

    with pytest.raises(TypeError, match="no raw loop for Other"):
        raw_loop(Other(), components("smoke", "fixed_impedance").task.pattern, 10)


def test_a_loop_row_has_the_raw_loop_and_the_ratio() -> None:
    row = bench_task("smoke", repeats=2)
    assert row["raw_us_per_control_step"] > 0.0
    assert row["ratio_vs_raw"] > 0.0
    assert row["x_realtime"] == pytest.approx(row["sim_time_s"] / row["median_wall_s"], rel=1e-12)
    # the ceiling: the raw loop plus ccm's per-step interface alone, timed in each repeat
    raw, iface = row["raw_s_per_repeat"], row["interface_s_per_repeat"]
    assert len(raw) == len(iface) == 2 and min(iface) > 0.0
    ceilings = [row["sim_time_s"] / (r + i) for r, i in zip(raw, iface, strict=True)]
    assert row["ceiling_x_realtime"] == pytest.approx(sum(ceilings) / 2, rel=1e-12)
    assert row["objects_us_per_control_step"] > 0.0
    assert row["interface_us_per_control_step"] == pytest.approx(
        1e6 * sum(iface) / 2 / row["control_steps"], rel=1e-12
    )


def test_the_interface_cost_records_the_rows_objects() -> None:
    """It times whole passes that build and record the objects (more steps take longer;
    a 3D row's objects are built from its own observation without error)."""
    from ccm.bench.interface import interface_cost

    comp = components("smoke", "fixed_impedance")
    assert (
        0.0
        < interface_cost(comp.sim, comp.controller, 10)
        < interface_cost(comp.sim, comp.controller, 20_000)
    )
    assert interface_cost(comp.sim, comp.controller, 1_000, record=False) > 0.0
    comp3 = components("changing_surface", "avic_modes", "pybullet3d")
    try:
        assert interface_cost(comp3.sim, comp3.controller, 50, repeats=1) > 0.0
    finally:
        comp3.sim.close()


def test_paper_cpu_minutes(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert paper_cpu(tmp_path) is None
    print_paper_cpu(None, tmp_path)
    assert "run make reproduce-paper" in capsys.readouterr().out
    timing = {"wall_s": 600.0, "quick": False, "sweeps_s": {"a": 300.0, "b": 120.0},
              "sweeps_cpu_s": {"a": 540.0, "b": 120.0}, "earlier": []}  # fmt: skip
    (tmp_path / "paper_timing.json").write_text(json.dumps(timing))
    res = paper_cpu(tmp_path)
    print_paper_cpu(res, tmp_path)
    out = capsys.readouterr().out
    assert "wall 10.0 min" in out
    lines = {ln.split()[0]: ln.split()[1:] for ln in out.splitlines()[2:]}
    assert lines["a"] == ["5.0", "9.0"] and lines["b"] == ["2.0", "2.0"]
    assert lines["total"] == ["7.0", "11.0"]
