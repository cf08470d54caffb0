"""The package's layers (issue #21): every module imports only its own layer or the layers
below it, and no import cycle exists, counting imports inside functions.

The layers, bottom to top (``|`` separates siblings, which must not import each other)::

    core  <-  sim | tasks | learn  <-  control  <-  metrics | checks  <-  plots  <-  experiment
          <-  analyses | suite  <-  envs | reporting  <-  cli, bench

Plots sit above metrics rather than beside them: a figure draws what a metric computes (the
motion-subspace error, the mode decisions, the rail distances) and reuses that code instead
of repeating it. The imports are read from the source (``ast``), so a function-level import
counts as much as one at the top of a module.

Inside a layer, the subfolders are siblings too: ``sim.pymunk`` and ``sim.pybullet``, or
``control.adaptive``, ``control.baselines`` and ``control.mpc``, may import the modules at
their folder's top (``sim.base``, ``control.impedance``) but not each other.
"""

from __future__ import annotations

import ast
import fnmatch
from collections.abc import Iterable, Mapping
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "ccm"

#: (layer, sibling group, module patterns), bottom to top; the first matching pattern wins
LAYERS: list[tuple[int, str, tuple[str, ...]]] = [
    (0, "core", ("ccm.core", "ccm.core.*")),
    (1, "sim", ("ccm.sim", "ccm.sim.*")),
    (1, "tasks", ("ccm.tasks", "ccm.tasks.*")),
    (1, "learn", ("ccm.learn", "ccm.learn.*")),
    (2, "control", ("ccm.control", "ccm.control.*")),
    (3, "metrics", ("ccm.metrics", "ccm.metrics.*")),
    (3, "checks", ("ccm.checks", "ccm.checks.*")),
    (4, "plots", ("ccm.plots", "ccm.plots.*")),
    (5, "experiment", ("ccm.experiment", "ccm.experiment.*")),
    (6, "analyses", ("ccm.analyses", "ccm.analyses.*")),
    (6, "suite", ("ccm.suite", "ccm.suite.*")),
    (7, "envs", ("ccm.envs", "ccm.envs.*")),
    (7, "reporting", ("ccm.reporting", "ccm.reporting.*")),
    (8, "cli", ("ccm.cli", "ccm.bench", "ccm.bench.*")),
]  # fmt: skip


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(path: Path, known: Iterable[str]) -> set[str]:
    """The ccm modules ``path`` imports anywhere in its source (``from ccm.x import y`` is
    ``ccm.x.y`` if that is a module, else ``ccm.x``)."""
    known = set(known)
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            if node.module.split(".")[0] == "ccm":
                for alias in node.names:
                    sub = f"{node.module}.{alias.name}"
                    out.add(sub if sub in known else node.module)
        elif isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name.split(".")[0] == "ccm"}
    return out


def import_graph() -> dict[str, set[str]]:
    files = {module_name(p): p for p in PACKAGE.rglob("*.py")}
    return {m: imports(p, files) - {m, "ccm"} for m, p in files.items()}  # "ccm": __version__


def layer_of(module: str) -> tuple[int, str] | None:
    for level, group, patterns in LAYERS:
        if any(fnmatch.fnmatchcase(module, pat) for pat in patterns):
            return level, group
    return None


def violations(graph: Mapping[str, Iterable[str]]) -> list[str]:
    """Every import that goes up a layer or across siblings, and every unplaced module."""
    out = []
    for mod, targets in sorted(graph.items()):
        here = layer_of(mod)
        if mod == "ccm":  # imported before any other module: it may import none
            out += [f"ccm (the root package) imports {tgt}" for tgt in sorted(targets)]
            continue
        if here is None:
            out.append(f"{mod}: in no layer (tests/test_layers.py LAYERS)")
            continue
        for tgt in sorted(targets):
            there = layer_of(tgt)
            if there is None:
                continue  # reported as its own module
            if there[0] > here[0] or (there[0] == here[0] and there[1] != here[1]):
                out.append(f"{mod} ({here[1]}) imports {tgt} ({there[1]})")
            elif here == there and None is not _subfolder(mod) != _subfolder(tgt) is not None:
                out.append(f"{mod} ({_subfolder(mod)}) imports {tgt} ({_subfolder(tgt)})")
    return out


def _subfolder(module: str) -> str | None:
    """``sim.pymunk`` for ``ccm.sim.pymunk.backend``; None for a module at a folder's top."""
    parts = module.split(".")
    return ".".join(parts[1:3]) if len(parts) > 3 else None


def cycles(graph: Mapping[str, Iterable[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_the_checks_catch_an_upward_import_a_sibling_import_and_a_cycle() -> None:
    """The checks can fail: a metric importing the runner, the simulator importing a
    learner, one backend importing the other, the root package importing anything, and two
    plots importing each other are each reported."""
    graph = {
        "ccm.metrics.trial": {"ccm.experiment.runner"},
        "ccm.sim.base": {"ccm.learn.mixtures.igmm"},
        "ccm.plots.run": {"ccm.plots.modes"},
        "ccm.plots.modes": {"ccm.plots.run"},
        "ccm.sim.pymunk.backend": {"ccm.sim.pybullet.robot", "ccm.sim.base"},
        "ccm.experiment.runner": set(), "ccm.learn.mixtures.igmm": set(),
        "ccm": {"ccm.reporting.load"},
    }  # fmt: skip
    assert violations(graph) == [
        "ccm (the root package) imports ccm.reporting.load",
        "ccm.metrics.trial (metrics) imports ccm.experiment.runner (experiment)",
        "ccm.sim.base (sim) imports ccm.learn.mixtures.igmm (learn)",
        "ccm.sim.pymunk.backend (sim.pymunk) imports ccm.sim.pybullet.robot (sim.pybullet)",
    ]
    assert cycles(graph) == [["ccm.plots.modes", "ccm.plots.run"]]


def test_every_import_points_down_the_layers() -> None:
    found = violations(import_graph())
    assert not found, "\n".join(found)


@pytest.mark.parametrize("name", ["ccm.metrics.trial", "ccm.plots.run", "ccm.experiment.runner"])
def test_the_graph_sees_the_modules_imports(name: str) -> None:
    """The graph is not empty by mistake: these modules import other ccm modules."""
    assert import_graph()[name]


def test_no_import_cycles() -> None:
    found = cycles(import_graph())
    assert not found, found
