"""Compiled IPOPT solvers (ccm.control.mpc.codegen): same solution, disk cache, fallback."""

from __future__ import annotations

import shutil
import sys

import casadi as ca
import numpy as np
import pytest

from ccm.control.mpc import codegen as mc

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc")

OPTS = {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes", "expand": True}


def _rosenbrock() -> dict[str, ca.MX]:
    """A tiny parametric NLP (MX, as GPMPCProblem builds it) with an active constraint."""
    x, p = ca.MX.sym("x", 2), ca.MX.sym("p", 2)
    f = (p[0] - x[0]) ** 2 + p[1] * (x[1] - x[0] ** 2) ** 2
    return {"x": x, "p": p, "f": f, "g": x[0] ** 2 + x[1] ** 2}


def _solve(solver: ca.Function, p: list[float]) -> dict[str, np.ndarray]:
    sol = solver(x0=[0.5, 0.5], p=p, lbg=-np.inf, ubg=1.5)
    assert solver.stats()["success"]
    return {k: np.asarray(v).ravel() for k, v in sol.items() if k in ("x", "f", "lam_g")}


def test_compiled_matches_uncompiled_and_is_cached(tmp_path):
    nlp = _rosenbrock()
    plain = mc.make_solver("rb", nlp, OPTS)
    n0 = mc.compile_count
    compiled = mc.make_solver("rb", nlp, OPTS, codegen="-O1", cache_dir=tmp_path)
    info = mc.last_build()
    assert info is not None and info.compiled and not info.cached and info.error is None
    assert mc.compile_count == n0 + 1
    assert info.path is not None and info.path.parent == tmp_path and info.path.is_file()
    assert info.generate_s > 0.0 and info.compile_s > 0.0 and info.source_bytes > 0
    for p in ([1.0, 100.0], [0.3, 10.0]):
        a, b = _solve(plain, p), _solve(compiled, p)
        for k in a:
            np.testing.assert_allclose(b[k], a[k], rtol=1e-10, atol=1e-10)
    mtime = info.path.stat().st_mtime_ns
    # the same problem again: loaded from the cache, nothing compiled, file untouched
    again = mc.make_solver("rb", nlp, OPTS, codegen="-O1", cache_dir=tmp_path)
    info2 = mc.last_build()
    assert info2 is not None and info2.compiled and info2.cached and info2.compile_s == 0.0
    assert info2.path == info.path and info2.path.stat().st_mtime_ns == mtime
    assert mc.compile_count == n0 + 1
    np.testing.assert_allclose(_solve(again, [1.0, 100.0])["x"], _solve(plain, [1.0, 100.0])["x"])
    assert [f.name for f in tmp_path.iterdir()] == [info.path.name]  # no temp files left
    # other flags -> another key and library
    mc.make_solver("rb", nlp, OPTS, codegen="-O0", cache_dir=tmp_path)
    assert mc.last_build().key != info.key and mc.compile_count == n0 + 2


def test_cache_dir_from_environment(tmp_path, monkeypatch):
    monkeypatch.setenv(mc.CACHE_ENV, str(tmp_path / "env_cache"))
    assert mc.default_cache_dir() == tmp_path / "env_cache"
    mc.make_solver("rb", _rosenbrock(), OPTS, codegen="-O1")
    assert mc.last_build().path.parent == tmp_path / "env_cache"
    monkeypatch.delenv(mc.CACHE_ENV)
    assert mc.default_cache_dir() == mc.DEFAULT_CACHE_DIR.expanduser()


@pytest.mark.parametrize("compiler", ["/nonexistent/ccm-cc", "false"])
def test_failing_compiler_falls_back_with_a_warning(tmp_path, monkeypatch, compiler):
    monkeypatch.setattr(mc, "COMPILER", compiler)
    nlp = _rosenbrock()
    with pytest.warns(RuntimeWarning, match="uncompiled") as rec:
        solver = mc.make_solver("rb", nlp, OPTS, codegen="-O1", cache_dir=tmp_path)
    assert len(rec) == 1 and "\n" not in str(rec[0].message)
    if compiler == "false":  # exits 1 silently: the line names the program and its code
        assert str(rec[0].message) == (
            "ccm: compiled MPC solver unavailable (false failed: 1); using the uncompiled one"
        )
    info = mc.last_build()
    assert info is not None and not info.compiled and info.error
    assert not list(tmp_path.glob("*.so"))
    plain = mc.make_solver("rb", nlp, OPTS)
    np.testing.assert_allclose(_solve(solver, [1.0, 100.0])["x"], _solve(plain, [1.0, 100.0])["x"])


def test_limited_memory_hessian_compiles_without_hessian(tmp_path):
    opts = {**OPTS, "ipopt.hessian_approximation": "limited-memory"}
    solver = mc.make_solver("rb", _rosenbrock(), opts, codegen="-O1", cache_dir=tmp_path)
    assert mc.last_build().compiled
    plain = mc.make_solver("rb", _rosenbrock(), opts)
    np.testing.assert_allclose(_solve(solver, [1.0, 100.0])["x"], _solve(plain, [1.0, 100.0])["x"])


def test_gp_mpc_compiled_same_solution_along_a_closed_loop(tmp_path, monkeypatch):
    """GPMPCProblem with codegen gives the uncompiled solutions (to 1e-8) over warm starts."""
    monkeypatch.setenv(mc.CACHE_ENV, str(tmp_path))
    from ccm.control.mpc.admittance import system_matrices
    from ccm.control.mpc.problem import GPMPCProblem
    from ccm.control.mpc.settings import Weights
    from ccm.learn.gp.gp_force_models import GPForceModels

    rng = np.random.default_rng(3)
    n, pts = 2, 8
    X = rng.uniform(-0.02, 0.02, (pts, n))
    X[:, 0] = np.linspace(-0.03, 0.004, pts)
    F = rng.normal(0.0, 0.3, (pts, n))
    F[:, 0] += 5.0 - 15000.0 * np.maximum(0.0, X[:, 0])
    gp = GPForceModels(n, mean="hinge").fit(X, F)
    kw = dict(
        horizon=3, ts=0.01, f_ref_target=[-10.0, 0.0], well_damped={"zeta": 1.2},
        weights=Weights(vel=1.0, f_ref_target=0.01, delta_mass=1e-3, delta_damping=1e-6),
    )  # fmt: skip
    plain = GPMPCProblem([gp.casadi_functions()], n, **kw)
    compiled = GPMPCProblem(
        [gp.casadi_functions()], n, codegen="-O1", **kw
    )  # a new casadi graph of the same fit
    assert mc.last_build().compiled and mc.last_build().path.parent == tmp_path
    xi, m, d, fr = np.array([-0.01, 0.0, 0.0, 0.0]), np.full(n, 5.0), np.full(n, 500.0), np.zeros(n)
    for _ in range(6):
        s1 = plain.solve(xi, [1.0], m, d, fr)
        s2 = compiled.solve(xi, [1.0], m, d, fr)
        assert s1.success and s2.success
        for a, b in ((s1.f_ref, s2.f_ref), (s1.mass, s2.mass), (s1.damping, s2.damping)):
            np.testing.assert_allclose(b, a, rtol=1e-8, atol=1e-8)
        np.testing.assert_allclose(s2.predicted, s1.predicted, rtol=1e-8, atol=1e-10)
        m, d, fr = s1.mass, s1.damping, s1.f_ref
        a, b = system_matrices(m, d, 0.01)
        xi = a @ xi + b @ (np.array([5.0 - 15000.0 * max(0.0, xi[0]), 0.0]) - fr)


def test_a_failing_build_step_is_named_with_its_last_error_line() -> None:
    """The compiler's last stderr line (its error) names why the build fell back."""
    script = (
        "import sys; sys.stdout.write('noise\\n'); sys.stderr.write('a\\nboom\\n'); sys.exit(3)"
    )
    with pytest.raises(RuntimeError) as err:
        mc._run([sys.executable, "-c", script])
    assert str(err.value) == f"{sys.executable} failed: boom"
