"""The precheck of ``ccm run``: before Hydra creates a run directory, every override
combination of the run or sweep is composed and every component built once, so a bad override
ends with one line naming the key and what is allowed (exit code 2), and nothing is written.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from pathlib import Path

from omegaconf import DictConfig

from ccm.experiment import user_configs
from ccm.experiment.composer import Composer, job_config
from ccm.experiment.trust import check_no_env, check_targets
from ccm.experiment.user_configs import GROUPS


def _combos(overrides: Sequence[str], multirun: bool) -> list[list[str]]:
    """Override lists to pre-check: the base combination, then each sweep value in turn."""
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from hydra.errors import HydraException

    parser = OverridesParser.create()
    parsed = []
    for text in overrides:  # one at a time, so a syntax error names its override
        try:
            parsed += parser.parse_overrides([text])
        except HydraException as exc:  # OverrideParseException: the grammar's message only
            raise ValueError(f"{text}: {_one_line(exc)}") from None
    base: list[str] = []
    variants: list[tuple[int, list[str]]] = []
    for i, ov in enumerate(parsed):
        if ov.key_or_group.startswith("hydra"):
            base.append("")
            continue
        if ov.is_sweep_override():
            if not multirun:
                raise ValueError(f"{ov.input_line}: sweeps need `ccm run -m`")
            prefix = ov.input_line.split(ov.key_or_group, 1)[0]
            values = [f"{prefix}{ov.get_key_element()}={v}" for v in ov.sweep_string_iterator()]
            if not values:  # e.g. range(0,0): Hydra would launch no job
                raise ValueError(f"{ov.input_line}: the sweep is empty; give at least one value")
            base.append(values[0])
            variants.append((i, values[1:]))
        else:
            base.append(ov.input_line)
    combos = [[o for o in base if o]]
    for i, values in variants:
        for v in values:
            c = list(base)
            c[i] = v
            combos.append([o for o in c if o])
    return combos


def _check_groups(overrides: Sequence[str], dirs: Sequence[Path] = ()) -> str | None:
    for ov in overrides:
        key, _, value = ov.lstrip("+~").partition("=")
        if key in GROUPS and value not in user_configs.group_options(key, dirs):
            allowed = ", ".join(user_configs.group_options(key, dirs))
            return f"{key}={value}: unknown option; allowed: {allowed}"
    return None


def precheck(
    overrides: Sequence[str], multirun: bool, dirs: Sequence[Path] = (), trusted: bool = False
) -> str | None:
    """Compose each override combination and build its components, then check Hydra's own
    settings (output directory, launcher, the callables it will call: ``trusted`` lifts that
    check, :mod:`ccm.experiment.trust`); return an error line. ``dirs``: the user's config
    directories (:mod:`ccm.experiment.user_configs`), searched before the package's."""
    from hydra import initialize_config_dir
    from hydra.errors import HydraException

    try:
        combos = _combos(overrides, multirun)
    except (HydraException, ValueError) as exc:
        return _one_line(exc)
    planned: set[tuple[str, ...]] = set()
    with initialize_config_dir(str(user_configs.config_dir()), version_base="1.3", job_name="ccm"):
        for combo in combos:
            bad = _check_groups(combo, dirs)
            if bad:
                return bad
        first: list[tuple[DictConfig, Composer]] = []  # the first combination's
        err = _guarded(lambda: first.append(_first_combo(overrides, combos[0], dirs)))
        if err:
            return err
        full, combos_from_first = first[0]
        for combo in combos:
            err = _guarded(
                lambda c=combo: _check_combo(c, combos[0], combos_from_first, planned, dirs)
            )
            if err:
                return err
        return _guarded(lambda: _check_hydra(overrides, full, multirun, dirs, trusted))


def _hydra_overrides(overrides: Sequence[str]) -> list[str]:
    """The ``hydra.*`` overrides that are not sweeps (``hydra.searchpath`` left out: ``dirs``
    carries it)."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    return [
        ov.input_line for ov in OverridesParser.create().parse_overrides(list(overrides))
        if ov.key_or_group.startswith("hydra") and not ov.is_sweep_override()
        and ov.key_or_group != user_configs.SEARCHPATH
    ]  # fmt: skip


def _first_combo(
    overrides: Sequence[str], combo: list[str], dirs: Sequence[Path]
) -> tuple[DictConfig, Composer]:
    """The first combination composed once, with its ``hydra`` node and the run's own
    ``hydra.*`` overrides (Hydra's settings are checked on it), and a
    :class:`ccm.experiment.composer.Composer` that derives the other combinations from it:
    a combination that changes a value (a seed) is the first's config with that value; one
    that changes a config group (``task=…``) is composed in full."""
    own = _hydra_overrides(overrides)

    def compose_combo(changed: Sequence[str]) -> DictConfig:
        keys = {o.partition("=")[0] for o in changed}
        others = [o for o in combo if o.partition("=")[0] not in keys]
        return compose_extra([*others, *own], changed, dirs, hydra_node=True)

    full = compose_combo([])
    return full, Composer(compose_combo, job_config(full), full.hydra.runtime.choices)


def _check_combo(
    combo: list[str],
    first: list[str],
    from_first: Composer,
    planned: set[tuple[str, ...]],
    dirs: Sequence[Path],
) -> None:
    """Derive one override combination's config from the first's and build its plan (once
    per set of overrides other than the seed, which changes no component); raise on bad
    input."""
    from ccm.experiment.components import check_experiment, plan_experiment
    from ccm.experiment.config_check import check_trial_steps
    from ccm.metrics.trial import check_extra_metrics

    cfg, choices = from_first.derive([o for o in combo if o not in first])
    check_no_env(cfg, combo)  # before anything resolves a value into a message
    settings = check_experiment(cfg)
    check_extra_metrics(cfg)
    unseeded = tuple(o for o in combo if o.partition("=")[0].lstrip("+~") != "seed")
    if unseeded in planned:
        return
    planned.add(unseeded)
    conditions = Composer(lambda x: compose_extra(combo, x, dirs, hydra_node=True), cfg, choices)
    plan = plan_experiment(cfg, conditions, settings["trials"])
    if cfg.experiment.get("kind", "trials") == "trials":
        check_trial_steps(plan, settings)


def _check_hydra(
    overrides: Sequence[str],
    cfg: DictConfig,
    multirun: bool,
    dirs: Sequence[Path] = (),
    trusted: bool = False,
) -> None:
    """Check the first combination's ``hydra`` settings (composed with the run's own
    ``hydra.*`` overrides, sweeps left out): the run or sweep directory, the job name, the
    launcher and the callables Hydra will call."""
    from hydra import compose
    from hydra.core.override_parser.overrides_parser import OverridesParser

    from ccm.core.errors import ConfigError
    from ccm.experiment import run_record
    from ccm.experiment.config_check import check_hydra

    check_no_env(cfg, list(overrides))
    check_hydra(cfg.hydra, multirun)
    check_targets(cfg.hydra, trusted)
    if multirun:  # the sweep's config: the overrides but the sweeps (as Hydra's multirun.yaml)
        parsed = OverridesParser.create().parse_overrides(list(overrides))
        unswept = [ov.input_line for ov in parsed if not ov.is_sweep_override()]
        search = user_configs.searchpath_override(dirs)
        sweep = compose("config", overrides=[*unswept, *search])
        try:
            run_record.check_sweep_record(Path(cfg.hydra.sweep.dir), sweep, run_record.forced())
        except run_record.RecordRefused as exc:
            raise ConfigError("hydra.sweep.dir", str(exc)) from None


def _guarded(check: Callable[[], None]) -> str | None:
    """Run ``check``; a user error becomes its one line (a bug too, unless --verbose)."""
    import yaml
    from hydra.errors import HydraException
    from omegaconf.errors import OmegaConfBaseException

    from ccm.core.errors import ConfigError

    try:
        check()
    except ConfigError as exc:
        return str(exc)
    except (HydraException, OmegaConfBaseException, ValueError, TypeError) as exc:
        return _one_line(exc)
    except yaml.YAMLError as exc:
        if os.environ.get("HYDRA_FULL_ERROR") == "1":
            raise
        return yaml_line(exc)
    except Exception as exc:  # a bug, not a user error: one line unless --verbose
        if os.environ.get("HYDRA_FULL_ERROR") == "1":
            raise
        return f"{type(exc).__name__}: {_one_line(exc)}"
    return None


def yaml_line(exc: BaseException) -> str:
    """``<file>:<line>:<col>: <problem>`` for a YAML syntax error in a config file."""
    mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
    problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
    context = getattr(exc, "context", None)
    where = f"{mark.name}:{mark.line + 1}:{mark.column + 1}" if mark else "config"
    return f"{where}: YAML syntax error: {problem}" + (f" ({context})" if context else "")


def compose_extra(  # noqa: ANN202
    base: Sequence[str],
    extra: Sequence[str],
    dirs: Sequence[Path] | None = None,
    hydra_node: bool = False,
):
    """Compose ``base`` plus a condition's ``extra`` overrides (``dirs``: the user's config
    directories; None inside a Hydra job, where Hydra's own sources say), with the ``hydra``
    node if ``hydra_node`` (its group choices: :class:`ccm.experiment.composer.Composer`)."""
    from hydra import compose

    if dirs is None:
        dirs = user_configs.job_dirs(user_configs.config_dir())
    bad = _check_groups(extra, dirs)
    if bad:
        from ccm.core.errors import ConfigError

        key, _, _ = bad.partition(":")
        raise ConfigError(f"experiment.conditions ({key})", bad.split(": ", 1)[1])
    overrides = [*base, *extra, *user_configs.searchpath_override(dirs)]
    return compose("config", overrides=overrides, return_hydra_config=hydra_node)


def _one_line(exc: BaseException) -> str:
    """A single line from a Hydra/OmegaConf exception message."""
    text = " ".join(str(exc).split())
    if "is not in struct" in text or "Could not override" in text:
        key = text.split("'")[1] if "'" in text else text
        return f"{key}: unknown key (see `ccm run --cfg job` for the keys; `+{key}=…` adds one)"
    return text.split(". ", 1)[0] if len(text) > 300 else text
