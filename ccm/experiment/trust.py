"""What a config may make ccm run or reveal (issue #39). Configs are code: Hydra instantiates
every ``_target_`` under ``hydra.callbacks``, ``hydra.launcher`` and ``hydra.sweeper``, and
``logging.config`` every handler ``class`` or ``()`` factory under ``hydra.job_logging``,
arguments included. A user config could so run any callable (``builtins.open``,
``shutil.copyfile``) before ccm's first line of its own.

* :func:`check_targets`: those callables must be ccm's own (the ``_target_`` values of the
  package's configs), Hydra's own plugins (``hydra._internal.core_plugins.*``, installed
  ``hydra_plugins.*`` launchers), or standard ``logging`` handlers, formatters and filters;
  anything else needs ``ccm run --trust-configs``. Arguments of allowed callables are not
  inspected: a config from someone you do not trust is still code you are running.
* :func:`check_no_env`: ``${oc.env:…}`` would write an environment variable's value into the
  run's records (``.hydra/config.yaml``, ``summary.json``) and into error lines; it is refused
  wherever it appears, naming the key and never the value.
"""

from __future__ import annotations

import functools
import logging
import logging.handlers
import re
from typing import Any

from omegaconf import OmegaConf

from ccm.core.errors import ConfigError, leaves
from ccm.experiment.user_configs import config_dir

#: the ``hydra`` nodes whose callables Hydra or ``logging.config`` calls
CALLING_NODES = ("callbacks", "launcher", "sweeper", "job_logging", "hydra_logging")
#: keys whose string value names a callable
CALLABLE_KEYS = ("_target_", "class", "()")
TRUST_FLAG = "--trust-configs"
_PLUGIN_PREFIXES = ("hydra._internal.core_plugins.", "hydra_plugins.")
_ENV = re.compile(r"oc\.env\s*:")


@functools.cache
def package_targets() -> frozenset[str]:
    """The ``_target_`` values written in ccm's own config files."""
    pattern = re.compile(r"^\s*_target_:\s*['\"]?([\w.]+)", re.MULTILINE)
    return frozenset(
        m for path in config_dir().rglob("*.yaml")
        for m in pattern.findall(path.read_text(encoding="utf-8"))
    )  # fmt: skip


def _logging_class(name: str) -> bool:
    """A handler, formatter or filter class of the standard ``logging`` package."""
    module, _, attr = name.rpartition(".")
    owner = {"logging": logging, "logging.handlers": logging.handlers}.get(module)
    obj = getattr(owner, attr, None) if owner is not None else None
    bases = (logging.Handler, logging.Formatter, logging.Filter)
    return isinstance(obj, type) and issubclass(obj, bases)


def allowed_callable(name: str) -> bool:
    """Whether ccm calls ``name`` from a config without ``--trust-configs``."""
    return name in package_targets() or name.startswith(_PLUGIN_PREFIXES) or _logging_class(name)


def check_targets(hydra: Any, trusted: bool) -> None:
    """Refuse a callable outside ccm, Hydra's plugins and ``logging`` (module docstring)."""
    if trusted:
        return
    for name in CALLING_NODES:
        node = OmegaConf.select(hydra, name, default=None)
        plain = OmegaConf.to_container(node, resolve=False) if node is not None else None
        for key, leaf, value in leaves(plain, f"hydra.{name}"):
            if leaf in CALLABLE_KEYS and isinstance(value, str) and not allowed_callable(value):
                raise ConfigError(
                    key, f"{value!r} is not one of ccm's or Hydra's own callables; a config "
                    f"that runs other code needs ccm run {TRUST_FLAG} (configs are code: "
                    "docs/user-guide/configs.md, 'Trusting a config')",
                )  # fmt: skip


def check_no_env(cfg: Any, overrides: list[str]) -> None:
    """Refuse ``${oc.env:…}`` in an override or anywhere in the composed config (unresolved),
    naming the key, never the value."""
    for ov in overrides:
        key, _, value = ov.partition("=")
        if _ENV.search(value):
            _env_refused(key.lstrip("+~"))
    for key, _, value in leaves(OmegaConf.to_container(cfg, resolve=False)):
        if isinstance(value, str) and _ENV.search(value):
            _env_refused(key)


def _env_refused(key: str) -> None:
    raise ConfigError(
        key, "reads an environment variable (${oc.env:...}), whose value would be written to "
        "the run's records and messages; give the value itself",
    )  # fmt: skip
