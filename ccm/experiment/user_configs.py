"""Config directories of a lab's own, beside the package's (issue #19).

A lab keeps its tasks, controllers and experiments outside the package and names them through
Hydra's own mechanisms: ``ccm run --config-dir DIR`` (or ``-cd DIR``, Hydra's flag) or the
override ``hydra.searchpath=[file:///abs/DIR]``. DIR has the package's layout
(``task/*.yaml``, ``experiment/*.yaml``, …); an option in DIR shadows the package's option of
the same name. Hydra itself searches such directories after the package's, so ``ccm run``
names them in :data:`DIRS_ENV` while it runs and the search-path plugin
``hydra_plugins/ccm_config_dirs.py`` puts them first. ccm's own checks (the precheck,
``ccm list``, the condition overrides of an experiment) look in the same order: the user's
directories, then the package's.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from ccm.core.errors import ConfigError

DIR_FLAGS = ("--config-dir", "-cd")
SEARCHPATH = "hydra.searchpath"

#: the user's config directories while ``ccm run`` runs (``os.pathsep``-separated), for the
#: search-path plugin; sweep workers inherit it
DIRS_ENV = "CCM_CONFIG_DIRS"

#: the config groups a run composes (one option each)
GROUPS = ("sim", "controller", "task", "experiment")


def split_dir_flags(args: Sequence[str]) -> tuple[list[Path], list[str]]:
    """(the ``--config-dir`` / ``-cd`` directories, the other arguments) of a ``ccm run`` or
    ``ccm list`` command line; a flag without a value is a ConfigError."""
    dirs: list[Path] = []
    rest: list[str] = []
    it = iter(args)
    for a in it:
        if a in DIR_FLAGS:
            value = next(it, None)
            if value is None or value.startswith("-"):
                raise ConfigError(a, "needs a directory (ccm run --config-dir DIR …)")
            dirs.append(Path(value))
        elif a.startswith("--config-dir="):
            dirs.append(Path(a.split("=", 1)[1]))
        else:
            rest.append(a)
    return dirs, rest


def searchpath_dirs(overrides: Sequence[str]) -> list[Path]:
    """The ``file://`` (or plain) directories of a ``hydra.searchpath=[…]`` override;
    ``pkg://`` entries are Python packages, left to Hydra."""
    dirs: list[Path] = []
    for ov in overrides:
        key, _, value = ov.partition("=")
        if key.lstrip("+~") != SEARCHPATH:
            continue
        for item in value.strip().strip("[]").split(","):
            item = item.strip().strip("'\"")
            if item and not item.startswith("pkg://"):
                dirs.append(Path(item.removeprefix("file://")))
    return dirs


def check_dirs(dirs: Sequence[Path], key: str = "--config-dir") -> list[Path]:
    """``dirs`` made absolute; a missing one is a ConfigError naming it."""
    out = []
    for d in dirs:
        if not d.is_dir():
            raise ConfigError(key, f"{d} is not a directory (a config directory: task/, "
                              "experiment/, … as in the package's configs)")  # fmt: skip
        out.append(d.resolve())
    return out


def env_dirs() -> list[str]:
    """The directories :data:`DIRS_ENV` names (none when it is unset or empty)."""
    return [d for d in os.environ.get(DIRS_ENV, "").split(os.pathsep) if d]


def searchpath_override(dirs: Sequence[Path]) -> list[str]:
    """The ``hydra.searchpath`` override that puts ``dirs`` on Hydra's search path (none
    when there are no dirs): for compose calls, which see only their own overrides."""
    if not dirs:
        return []
    return [f"{SEARCHPATH}=[{','.join(f'file://{d}' for d in dirs)}]"]


def job_dirs(package_dir: Path) -> list[Path]:
    """Inside a Hydra job: the user's config directories Hydra searched (``--config-dir`` and
    ``hydra.searchpath`` entries, file paths only, the package's own left out)."""
    from hydra.core.hydra_config import HydraConfig

    if not HydraConfig.initialized():
        return []
    hc = HydraConfig.get()
    paths = [f"file://{src.path}" for src in hc.runtime.config_sources  # --config-dir
             if src.schema == "file"]  # fmt: skip
    paths += [str(p) for p in (hc.searchpath or [])]  # hydra.searchpath (not in the sources)
    out: list[Path] = []
    for path in paths:
        d = Path(path.removeprefix("file://"))
        if "://" in path and not path.startswith("file://"):  # pkg://, structured://
            continue
        if d.resolve() != package_dir.resolve() and d not in out:
            out.append(d)
    return out


def options(group: str, dirs: Sequence[Path], package_dir: Path) -> list[str]:
    """Option names of a config group over the user's directories and the package's."""
    return sorted({p.stem for d in (*dirs, package_dir) for p in (d / group).glob("*.yaml")})


def option_file(group: str, option: str, dirs: Sequence[Path], package_dir: Path) -> Path:
    """The file that defines ``group=option``: the first directory holding it."""
    for d in (*dirs, package_dir):
        if (d / group / f"{option}.yaml").is_file():
            return d / group / f"{option}.yaml"
    return package_dir / group / f"{option}.yaml"


def config_dir() -> Path:
    """The package's config directory: shipped in the wheel as ``ccm/_configs``, or
    ``configs/`` in a source checkout (editable install)."""
    pkg = Path(__file__).resolve().parents[1]  # the ccm package
    for candidate in (pkg / "_configs", pkg.parent / "configs"):
        if (candidate / "config.yaml").is_file():
            return candidate
    raise FileNotFoundError(f"ccm configs not found next to {pkg}")


def group_options(group: str, dirs: Sequence[Path] = ()) -> list[str]:
    """Option names of a config group (its YAML files), in the user's config directories
    ``dirs`` and the package's."""
    return options(group, dirs, config_dir())
