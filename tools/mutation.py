"""Mutation testing of the packages that hold the seeds' equations (issue #39 item 1).

``make mutation`` (or ``python tools/mutation.py [TARGET ...]``) runs mutmut 3 once per
target, each in its own copy of the tracked files under ``outputs/mutation/<target>`` (the
working tree is never touched), and writes ``outputs/mutation/mutation.json`` and a
Markdown table of killed / survived / no-test / timeout counts per target, for
``docs/testing.md``. A target's mutants run only the tests that mutmut's stats pass saw
calling the mutated function, drawn from the target's test files below (the whole default
suite for a mutant of a controller would take hours on 2 cores).

Not part of CI (the issue: "it does not have to run in CI"); it takes minutes for the small
targets and hours for ``control``, whose mutants run closed-loop tests: ``--sample N`` tests a
seeded random sample of N mutants per target and reports the score as an estimate with its
95 % (Wilson) interval.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import re
import shutil
import subprocess
import sys
import time
from collections import Counter
from collections.abc import Mapping
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "outputs" / "mutation"

#: target -> (glob(s) of the files mutated, the test files whose tests may kill its mutants);
#: learn and control are split by subpackage so that each part runs in minutes, not hours
TARGETS: dict[str, tuple[str | list[str], list[str]]] = {
    "reporting-claims": (
        "ccm/reporting/claim*.py",
        ["tests/test_claims.py", "tests/test_report.py", "tests/test_claim_pins.py"],
    ),
    "sensor": (
        "ccm/sim/sensor.py",
        [
            "tests/test_sensor_model.py",
            "tests/test_sensor_faults.py",
            "tests/test_pymunk_physics.py",
            "tests/test_reliability.py",
        ],
    ),  # fmt: skip
    "metrics": (
        "ccm/metrics/*",
        [
            "tests/test_metrics.py",
            "tests/test_contact_metrics.py",
            "tests/test_mode_metrics.py",
            "tests/test_adaptation_metrics.py",
            "tests/test_rail_metrics.py",
            "tests/test_metric_pins.py",
            "tests/test_mpc_metrics_oracle.py",
            "tests/test_contact_metrics_oracle.py",
            "tests/test_trial_metrics_oracle.py",
            "tests/test_metric_contracts.py",
            "tests/test_head_to_head.py",
            "tests/test_contact_measurement.py",
            "tests/test_mpc_contact_claims.py",
            "tests/test_polishing_claims.py",
            "tests/test_mpc_figures.py",
            "tests/test_gp_mpc_experiments.py",
        ],
    ),  # fmt: skip
    "learn-mixtures": (
        "ccm/learn/mixtures/*",
        [
            "tests/test_igmm.py",
            "tests/test_igmm_io.py",
            "tests/test_forward_model.py",
            "tests/test_forward_model_state.py",
            "tests/test_mixture_contracts.py",
            "tests/test_h1_one_step.py",
        ],
    ),  # fmt: skip
    "learn-gp": (
        "ccm/learn/gp/*",
        [
            "tests/test_gp_force.py",
            "tests/test_svm_gp.py",
            "tests/test_gp_contracts.py",
            "tests/test_gp_mpc.py",
        ],
    ),
    "learn-contact": (
        "ccm/learn/contact/*",
        [
            "tests/test_collisions.py",
            "tests/test_contacts.py",
            "tests/test_contact_contracts.py",
            "tests/test_modes.py",
            "tests/test_region_c.py",
            "tests/test_contact_measurement.py",
            "tests/test_anticipation.py",
            "tests/test_contact_regions.py",
        ],
    ),  # fmt: skip
    "control-adaptive": (
        "ccm/control/adaptive/*",
        [
            "tests/test_avic.py",
            "tests/test_modal.py",
            "tests/test_anticipation.py",
            "tests/test_retiming.py",
            "tests/test_contact_regions.py",
            "tests/test_contact_measurement.py",
            "tests/test_region_c.py",
            "tests/test_replan.py",
            "tests/test_controller_state.py",
            "tests/test_adaptive_contracts.py",
            # not test_learned_state.py: the runner's and the CLI's side (init_from), whose
            # runs cost a surviving mutant ~36 s; the controllers' round trips are in
            # test_controller_state.py
        ],
    ),  # fmt: skip
    "control-mpc": (
        "ccm/control/mpc/*",
        [
            "tests/test_mpc_terms.py",
            "tests/test_gp_mpc.py",
            "tests/test_admittance.py",
            "tests/test_disturbance_estimate.py",
            "tests/test_mpc_codegen.py",
            "tests/test_mpc_constraints_on_off.py",
            "tests/test_mpc_terms_on_off.py",
        ],
    ),  # fmt: skip
    "control-baselines": (
        "ccm/control/baselines/*",
        [
            "tests/test_baselines.py",
            "tests/test_baseline_laws.py",
            "tests/test_mrac_kernels.py",
            "tests/test_controller_state.py",
        ],
    ),
    "control-core": (
        ["ccm/control/base.py", "ccm/control/impedance.py", "ccm/control/loop.py"],
        [
            "tests/test_impedance.py",
            "tests/test_controller_contracts.py",
            "tests/test_baselines.py",
            "tests/test_contracts.py",
            # the loop's pinned metrics, the 2-D and cheap 3-D tasks only (the 3-D H4 tasks
            # take 40 s, and a surviving mutant runs every test that covers it)
            *(
                f"tests/test_loop_reference.py::test_fast_run_metrics_match_the_pins[{task}]"
                for task in (
                    "smoke",
                    "avic_porridge",
                    "avic_modes_changing_surface_2d",
                    "table_wall_3d",
                )
            ),
            "tests/test_avic.py",
        ],
    ),  # fmt: skip
}
#: a package name on the command line stands for its parts
GROUPS = {pkg: [t for t in TARGETS if t.startswith(pkg + "-")] for pkg in ("learn", "control")}
#: mutmut forks one child per mutant from a process that has run the tests once: a BLAS or
#: OpenMP thread pool started there deadlocks in the child (scikit-learn's GaussianMixture
#: hung every mutant of the frozen forward model's fit, reported as timeouts), so no pools
_ENV = {**os.environ, **dict.fromkeys(
    ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"), "1"
)}  # fmt: skip
_LINE = re.compile(r"^\s+(?P<name>\S+__mutmut_\d+): (?P<status>.+)$")


def _copy_tree(dest: Path, fresh: bool) -> None:
    """The tracked files of the repository (as the index has them) into ``dest``; ``fresh``
    removes what an earlier run left there (its mutants and their results) first."""
    files = subprocess.run(
        ["git", "ls-files", "-z"], cwd=ROOT, check=True, capture_output=True
    ).stdout.split(b"\0")
    if fresh and dest.exists():
        shutil.rmtree(dest)
    for raw in filter(None, files):
        src = ROOT / raw.decode()
        if src.is_file():
            (dest / raw.decode()).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / raw.decode())


def _configure(dest: Path, glob: str | list[str], tests: list[str]) -> None:
    """Append mutmut's settings to the copy's pyproject.toml."""
    also = ["configs/", "hydra_plugins/", "experiments/", "README.md", "Makefile", "docs/"]
    text = (dest / "pyproject.toml").read_text()
    globs = [glob] if isinstance(glob, str) else glob
    text += (
        "\n[tool.mutmut]\n"
        f'source_paths = ["ccm"]\nonly_mutate = {json.dumps(globs)}\n'
        f"also_copy = {json.dumps(also)}\n"
        f"pytest_add_cli_args_test_selection = {json.dumps(tests)}\n"
        'pytest_add_cli_args = ["-q", "-p", "no:cacheprovider", "-m", "not slow"]\n'
    )
    (dest / "pyproject.toml").write_text(text)


def _statuses(dest: Path) -> dict[str, str]:
    """Every mutant of the copy at ``dest`` and its status (``not checked`` before a verdict)."""
    res = subprocess.run(
        [sys.executable, "-m", "mutmut", "results", "--all", "true"],
        cwd=dest, capture_output=True, text=True, check=False,
    )  # fmt: skip
    return {m["name"]: m["status"] for m in map(_LINE.match, res.stdout.splitlines()) if m}


def run_target(
    name: str, jobs: int, again: list[str] | None = None, sample: int | None = None
) -> dict:
    """Mutate one target and count its mutants by status. ``again``: rerun only these mutants
    of the previous run (kept in place; mutmut collects the stats of new tests first), the
    verdicts of the others stand. ``sample``: test a seeded random sample of this many
    mutants only, and count the sample (an estimate of the whole, with its 95 % interval)."""
    glob, tests = TARGETS[name]
    dest = OUT / name
    _copy_tree(dest, fresh=again is None and sample is None)
    _configure(dest, glob, tests)
    t0 = time.perf_counter()
    run = [sys.executable, "-m", "mutmut", "run", "--max-children", str(jobs)]
    population: list[str] = []
    with open(OUT / f"{name}.log", "a" if again or sample else "w") as log:
        scope: list[str] = []
        scope_todo: list[str] = []
        if sample:  # generate the mutants and the stats; no mutant has this name, so none runs
            subprocess.run([*run, "ccm-list-only"], cwd=dest, stdout=log,
                           stderr=subprocess.STDOUT, check=False, env=_ENV)  # fmt: skip
            before = _statuses(dest)
            population = sorted(before)
            scope = sorted(random.Random(0).sample(population, min(sample, len(population))))
            # the sample's mutants without a verdict (an earlier, stopped run keeps its own)
            scope_todo = [n for n in scope if before[n] == "not checked"]
        names = (scope_todo if sample else []) if again is None else again
        if names or not sample:  # no names: every mutant without a verdict (a sample: none)
            subprocess.run([*run, *names], cwd=dest, stdout=log, stderr=subprocess.STDOUT,
                           check=False, env=_ENV)  # fmt: skip
    status = _statuses(dest)
    if sample:
        status = {k: status[k] for k in scope}
    counts = Counter(status.values())
    return {
        "files": glob, "tests": tests, "wall_s": round(time.perf_counter() - t0, 1),
        "mutants": len(status), "sample_of": len(population) or None, "counts": dict(counts),
        "killed_frac": _killed_frac(counts, len(status)),
        "not_killed": sorted(k for k, v in status.items() if v != "killed"),
    }  # fmt: skip


def _wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """95 % Wilson score interval of a proportion k / n (a sampled score's uncertainty)."""
    p, d = k / n, 1.0 + z * z / n
    half = z * ((p * (1 - p) / n + z * z / (4 * n * n)) ** 0.5) / d
    return (p + z * z / (2 * n)) / d - half, (p + z * z / (2 * n)) / d + half


def _killed_frac(counts: Mapping[str, int], n: int) -> float | None:
    """Killed or timed out (a test that never ends fails) over every mutant, "no tests" and
    equivalent ones included: a lower bound; docs/testing.md lists the equivalent ones."""
    return round((counts.get("killed", 0) + counts.get("timeout", 0)) / n, 4) if n else None


def table(results: dict[str, dict]) -> str:
    """The Markdown table of docs/testing.md."""
    cols = ("killed", "timeout", "survived", "no tests")
    rows = [f"| target | files | mutants | {' | '.join(cols)} | other | killed % |",
            "|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for name, r in results.items():
        c = r["counts"]
        other = r["mutants"] - sum(c.get(k, 0) for k in cols)
        frac = _killed_frac(c, r["mutants"])
        files = r["files"] if isinstance(r["files"], str) else ", ".join(r["files"])
        score = "–" if frac is None else f"{100 * frac:.1f}"
        mutants = r["mutants"]
        if r.get("sample_of") and frac is not None:  # a sample: the estimate and its interval
            lo, hi = _wilson(round(frac * r["mutants"]), r["mutants"])
            score += f" ({100 * lo:.0f}–{100 * hi:.0f})"
            mutants = f"{mutants} of {r['sample_of']}"
        cells = [name, f"`{files}`", mutants, *(c.get(k, 0) for k in cols), other, score]
        rows.append("| " + " | ".join(str(x) for x in cells) + " |")
    return "\n".join(rows)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument(
        "targets",
        nargs="*",
        help=f"default: all of {', '.join(TARGETS)}; learn and control name their parts",
    )
    p.add_argument("--jobs", type=int, default=2, help="parallel mutants (default 2)")
    p.add_argument(
        "--sample",
        type=int,
        default=None,
        metavar="N",
        help="test a seeded random sample of N mutants per target (an estimate)",
    )
    p.add_argument(
        "--again",
        action="store_true",
        help="rerun only the mutants that the target's last run did not kill",
    )
    args = p.parse_args(argv)
    unknown = [t for t in args.targets if t not in TARGETS and t not in GROUPS]
    if unknown:
        allowed = ", ".join([*TARGETS, *GROUPS])
        print(f"mutation: unknown target {unknown[0]!r}; allowed: {allowed}")
        return 2
    names = [n for t in args.targets or list(TARGETS) for n in GROUPS.get(t, [t])]
    OUT.mkdir(parents=True, exist_ok=True)
    path = OUT / "mutation.json"
    results = json.loads(path.read_text()) if path.exists() else {}
    for name in names:
        if args.again and results.get(name, {}).get("tests", TARGETS[name][1]) != TARGETS[name][1]:
            # mutmut resets every verdict when the test selection changes
            print(f"mutation: {name}'s tests changed since its last run; run it without --again")
            return 2
        # --again on a run that never finished: resume it (mutmut keeps each verdict it has)
        again = results.get(name, {}).get("not_killed", []) if args.again else None
        if args.again and not (OUT / name / "mutants").is_dir():
            print(f"mutation: --again needs an earlier run of {name!r}; run it without --again")
            return 2
        sample = args.sample
        if args.again and results.get(name, {}).get("sample_of"):
            sample = results[name]["mutants"]  # the same seeded sample as before
        result = run_target(name, args.jobs, again, sample)
        # read again before writing: another target may have finished meanwhile
        results = json.loads(path.read_text()) if path.exists() else {}
        results[name] = result
        path.write_text(json.dumps(results, indent=1) + "\n")
        print(table({name: result}).splitlines()[-1], flush=True)
    print(table(results))
    return 0


if __name__ == "__main__":
    sys.exit(main())
