"""IPOPT solvers whose NLP functions are generated as C, compiled once and cached on disk.

:func:`make_solver` is a drop-in for ``ca.nlpsol(name, "ipopt", nlp, opts)``. With
``codegen`` set (the C compiler's flags, e.g. ``"-O1"``) it

1. expands the NLP to an SX graph (as ``expand=True`` does) and removes common
   subexpressions (``ca.cse``: the GP kernels that the mean, its gradient and the variance
   share are computed once; about 35 % fewer operations in the Hessian of the Lagrangian);
2. builds the IPOPT solver on that graph and generates C for the functions IPOPT calls
   (``nlp_f``, ``nlp_g``, ``nlp_grad_f``, ``nlp_jac_g``, ``nlp_hess_l``) and for the oracle
   ``nlp`` that casadi needs to load them, one translation unit each;
3. compiles them with ``gcc`` in parallel (one job per core) into one shared library, stored
   under ``<cache>/<name>_<key>.so`` where ``key`` hashes the C sources, the flags, the
   compiler name, the casadi version and the machine type. The library is written to a
   temporary file and renamed into place, so concurrent runs never see half a file; a
   second build of the same problem (same GP fit, horizon, options) loads it without
   compiling;
4. builds the IPOPT solver from the library (``ca.nlpsol(name, "ipopt", "<lib>.so", …)``).

The compiled solver solves the same problem with the same IPOPT options: the generated code
performs the same floating-point operations as casadi's virtual machine (3-D, horizon 10:
solutions equal to 1.5e-12 relative, same iteration counts; the tests check 1e-8). Two
casadi options differ: ``calc_lam_p=False`` and
``no_nlp_grad=True``, since the parametric sensitivity ``lam_p`` would need one more large
compiled function and :class:`ccm.control.mpc.problem.GPMPCProblem` does not use it.
The oracle ``nlp`` is compiled with ``-O0``: IPOPT never evaluates it (it only provides
sparsity patterns), and it is a sixth of the code.

GP training data, ``alpha`` and ``L⁻¹`` are constants in the generated code, so every new
GP fit compiles a new library; re-running a seeded experiment reproduces the fit and hits
the cache. Compile time grows with the terms that use the GP (measured on 2 cores, 3-D, 30
points: horizon 5 with the well-damped constraint ~10 s, horizon 10 ~16 s; the variance
terms, chance constraint and a second mode add up to 2-3x; ``make bench`` prints it). At
~4-5 ms saved per horizon-10 solve, a compile pays off after a few thousand solves.
If the compiler is missing or anything in code generation, compilation or loading fails,
:func:`make_solver` emits a one-line RuntimeWarning and returns the uncompiled solver: a run
never fails because of it.

Cache directory: the ``cache_dir`` argument, else ``$CCM_CACHE_DIR``, else
``~/.cache/ccm/casadi``. Entries are never removed automatically (one library per fit,
~1-3 MB each for 3-D, horizon 5-10, 30 GP points); deleting the directory is safe.
"""

from __future__ import annotations

import hashlib
import os
import platform
import resource
import shlex
import subprocess
import tempfile
import time
import warnings
from collections.abc import Mapping
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import casadi as ca

#: the C compiler (a command on PATH); tests replace it to exercise the fallback
COMPILER = "gcc"
#: environment variable overriding the default cache directory
CACHE_ENV = "CCM_CACHE_DIR"
DEFAULT_CACHE_DIR = Path("~/.cache/ccm/casadi")
#: compile time limit per translation unit [s]; beyond it the uncompiled solver is used
COMPILE_TIMEOUT_S = 900.0
#: functions IPOPT evaluates, generated and compiled with the requested flags
_NLP_FUNCTIONS = ("nlp_f", "nlp_g", "nlp_grad_f", "nlp_jac_g", "nlp_hess_l")
_ORACLE_FLAGS = ("-O0",)  # the oracle "nlp" only provides sparsity (module docstring)
#: casadi options of the solver built from the compiled library (module docstring)
_COMPILED_OPTS = {"calc_lam_p": False, "no_nlp_grad": True}


@dataclass(frozen=True)
class BuildInfo:
    """What the last :func:`make_solver` call with ``codegen`` did.

    Attributes:
        compiled: the solver runs compiled code (False: fell back to the uncompiled one).
        cached: the library came from the cache (no compilation in this call).
        path: the shared library, or None after a fallback.
        key: hash of C sources, flags, compiler name, casadi version and machine type.
        generate_s: expansion, solver set-up and C generation [s].
        compile_s: compilation and linking [s], wall time (0 on a cache hit).
        compile_cpu_s: CPU time of the compiler processes [s].
        load_s: building the IPOPT solver from the library [s].
        source_bytes: size of the generated C.
        error: why it fell back, else None.
    """

    compiled: bool
    cached: bool
    path: Path | None
    key: str | None
    generate_s: float
    compile_s: float
    compile_cpu_s: float
    load_s: float
    source_bytes: int
    error: str | None = None


_last_build: BuildInfo | None = None
#: number of compilations in this process (tests check that a cache hit adds none)
compile_count = 0


def last_build() -> BuildInfo | None:
    """Information on the most recent :func:`make_solver` call that asked for codegen."""
    return _last_build


def default_cache_dir() -> Path:
    """``$CCM_CACHE_DIR`` if set, else ``~/.cache/ccm/casadi``."""
    env = os.environ.get(CACHE_ENV)
    return Path(env).expanduser() if env else DEFAULT_CACHE_DIR.expanduser()


def make_solver(
    name: str,
    nlp: Mapping[str, Any],
    opts: Mapping[str, Any],
    codegen: str | None = None,
    cache_dir: Path | str | None = None,
) -> ca.Function:
    """An IPOPT solver for ``nlp`` = {"x", "p", "f", "g"} (casadi MX or SX).

    Args:
        name: the solver's name.
        nlp: the problem, as for ``ca.nlpsol``.
        opts: ``ca.nlpsol`` options (``"expand"`` is implied with ``codegen``).
        codegen: None: ``ca.nlpsol(name, "ipopt", nlp, opts)``, nothing compiled. Otherwise
            the C compiler flags, e.g. ``"-O1"`` (see the module docstring).
        cache_dir: where compiled libraries are kept (default: :func:`default_cache_dir`).
    """
    global _last_build
    if codegen is None:
        return ca.nlpsol(name, "ipopt", dict(nlp), dict(opts))
    flags = shlex.split(codegen)
    t0 = time.perf_counter()
    gen_s = comp_s = comp_cpu = 0.0
    nbytes = 0
    key = None
    try:
        sx_nlp = _expanded(nlp)
        sx_opts = {k: v for k, v in opts.items() if k != "expand"}
        sx_opts.update(_COMPILED_OPTS)
        solver = ca.nlpsol(name, "ipopt", sx_nlp, sx_opts)
        sources = _generate(solver, _exact_hessian(opts))
        nbytes = sum(len(s) for s in sources.values())
        key = _key(sources, flags)
        gen_s = time.perf_counter() - t0
        folder = Path(cache_dir).expanduser() if cache_dir is not None else default_cache_dir()
        lib = folder / f"{name}_{key[:24]}.so"
        cached = lib.is_file()
        if not cached:
            t1, c1 = time.perf_counter(), _children_cpu()
            _compile(sources, flags, lib)
            comp_s, comp_cpu = time.perf_counter() - t1, _children_cpu() - c1
        t2 = time.perf_counter()
        compiled = ca.nlpsol(name, "ipopt", str(lib), sx_opts)
        load_s = time.perf_counter() - t2
        _last_build = BuildInfo(True, cached, lib, key, gen_s, comp_s, comp_cpu, load_s, nbytes)
        return compiled
    except Exception as err:  # noqa: BLE001 - any failure falls back (module docstring)
        reason = " ".join(str(err).split())[:200] or type(err).__name__
        warnings.warn(
            f"ccm: compiled MPC solver unavailable ({reason}); using the uncompiled one",
            RuntimeWarning,
            stacklevel=2,
        )
        _last_build = BuildInfo(
            False, False, None, key, gen_s, comp_s, comp_cpu, 0.0, nbytes, reason
        )
        return ca.nlpsol(name, "ipopt", dict(nlp), dict(opts))


# ----------------------------------------------------------------------------- helpers
def _expanded(nlp: Mapping[str, Any]) -> dict[str, ca.SX]:
    """The NLP as SX (what ``expand=True`` does) with common subexpressions removed."""
    x = nlp["x"]
    sym = type(x)
    p = nlp.get("p", sym(0, 1))
    f = nlp.get("f", sym(0))
    g = nlp.get("g", sym(0, 1))
    fun = ca.Function("nlp", [x, p], [f, g], ["x", "p"], ["f", "g"])
    if not fun.is_a("SXFunction"):
        fun = fun.expand()
    xs, ps = fun.sx_in()
    fs, gs = ca.cse(fun(xs, ps))
    return {"x": xs, "p": ps, "f": fs, "g": gs}


def _exact_hessian(opts: Mapping[str, Any]) -> bool:
    nested = opts.get("ipopt", {})
    approx = opts.get("ipopt.hessian_approximation", nested.get("hessian_approximation"))
    return approx in (None, "exact")


def _generate(solver: ca.Function, exact_hessian: bool) -> dict[str, str]:
    """C source per function: the oracle "nlp" and what IPOPT evaluates."""
    names = [f for f in _NLP_FUNCTIONS if exact_hessian or f != "nlp_hess_l"]
    funs = {"nlp": solver.oracle(), **{f: solver.get_function(f) for f in names}}
    sources = {}
    for fname, fun in funs.items():
        # avoid_stack: intermediates in the work vector instead of thousands of locals;
        # same run time, gcc's register allocation then scales better (-40 % compile time)
        cg = ca.CodeGenerator(f"ccm_{fname}", {"with_header": False, "avoid_stack": True})
        cg.add(fun)
        sources[fname] = cg.dump()
    return sources


def _key(sources: Mapping[str, str], flags: list[str]) -> str:
    h = hashlib.sha256()
    meta = [COMPILER, *flags, "|", *_ORACLE_FLAGS, ca.__version__, platform.machine()]
    h.update("\0".join(meta).encode())
    for fname, code in sources.items():
        h.update(f"\0{fname}\0".encode())
        h.update(code.encode())
    return h.hexdigest()


def _children_cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def _n_jobs() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def _run(cmd: list[str]) -> None:
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=COMPILE_TIMEOUT_S)
    if res.returncode != 0:
        msg = (res.stderr or res.stdout).strip().splitlines()
        raise RuntimeError(f"{cmd[0]} failed: {msg[-1] if msg else res.returncode}")


def _compile(sources: Mapping[str, str], flags: list[str], lib: Path) -> None:
    """Compile each source to an object file (in parallel), link, and rename into place."""
    global compile_count
    lib.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="ccm-codegen-") as tmp:
        jobs, objs = [], []
        # largest first, so the Hessian does not start last
        for fname, code in sorted(sources.items(), key=lambda kv: -len(kv[1])):
            src = Path(tmp) / f"{fname}.c"
            src.write_text(code, encoding="utf-8")
            obj = src.with_suffix(".o")
            fl = list(_ORACLE_FLAGS) if fname == "nlp" else flags
            jobs.append([COMPILER, "-c", "-fPIC", *fl, str(src), "-o", str(obj)])
            objs.append(str(obj))
        with ThreadPoolExecutor(max_workers=min(_n_jobs(), len(jobs))) as pool:
            list(pool.map(_run, jobs))
        fd, part = tempfile.mkstemp(prefix=f".{lib.name}.", suffix=".part", dir=lib.parent)
        os.close(fd)
        try:
            _run([COMPILER, "-shared", *objs, "-o", part, "-lm"])
            os.replace(part, lib)
        finally:
            if os.path.exists(part):
                os.unlink(part)
    compile_count += 1
