"""Components from outside ccm: by import path, or from installed packages' entry points.

A controller, a simulator or a task's motion segment is named in its config in one of three
ways:

* ``type: <name>`` (controllers, segments) or ``name: <name>`` (simulators): a built-in, or
  a name that an installed package registers under the entry-point group of :data:`GROUPS`,
  e.g. in its ``pyproject.toml``::

      [project.entry-points."ccm.controllers"]
      my_ctrl = "my_pkg.ctrl:MyController"

* ``_target_: my_pkg.ctrl:MyController`` (or Hydra's dotted ``my_pkg.ctrl.MyController``):
  an import path, as Hydra's ``instantiate`` takes it.

Built-ins are ``"module:Class"`` strings too, imported only when used, so that loading ccm
does not import every controller (and the MPC chain). Every problem (an unknown name, a path
that does not import, an object that is not the right kind of class) is a one-line
:class:`ccm.core.errors.ConfigError` that names the config key and the plugin.
"""

from __future__ import annotations

import importlib
import inspect
from collections.abc import Callable, Mapping
from importlib import metadata
from typing import Any

from ccm.core.errors import ConfigError, exception_line

#: component kind -> the entry-point group that installed packages register plugins under
GROUPS: dict[str, str] = {
    "controller": "ccm.controllers",
    "sim": "ccm.simulators",
    "segment": "ccm.segments",  # a task's motion segments: a task itself is YAML (--config-dir)
}


def plugin_entry_points(kind: str) -> dict[str, str]:
    """The plugins that installed packages register for ``kind`` (:data:`GROUPS`): name ->
    ``"module:Class"``, read from the packages' metadata (nothing is imported)."""
    return {ep.name: ep.value for ep in metadata.entry_points(group=GROUPS[kind])}


def available(kind: str, builtins: Mapping[str, str]) -> dict[str, str]:
    """Every name usable for ``kind``: the built-ins, then the installed plugins; a plugin
    that takes a built-in's name is not used (``ccm list`` says so)."""
    plugins = {k: v for k, v in plugin_entry_points(kind).items() if k not in builtins}
    return {**builtins, **plugins}


def load_object(path: Any, key: str) -> Any:
    """The object at ``path``: ``"package.module:Attr"`` or Hydra's ``"package.module.Attr"``.

    Raises:
        ConfigError: ``path`` is not such a string, its module does not import (the error's
            own first line is quoted), or the module has no such attribute.
    """
    if not isinstance(path, str) or not path.strip():
        raise ConfigError(key, f"must be an import path 'module:Class', got {path!r}")
    module_name, sep, attr = path.partition(":")
    if not sep:
        module_name, _, attr = path.rpartition(".")
    if not module_name or not attr:
        raise ConfigError(key, f"{path!r} is not an import path 'module:Class'")
    try:
        module = importlib.import_module(module_name)
    except Exception as exc:  # noqa: BLE001 - a plugin's import may raise anything
        raise ConfigError(
            key, f"plugin {path!r}: importing {module_name!r} failed: {exception_line(exc)}"
        ) from None
    obj = module
    for part in attr.split("."):
        if not hasattr(obj, part):
            raise ConfigError(key, f"plugin {path!r}: {module_name!r} has no attribute {attr!r}")
        obj = getattr(obj, part)
    return obj


def resolve_class(
    kind: str, cfg: Mapping[str, Any], name_key: str, builtins: Mapping[str, str], key: str,
    base: type,
) -> tuple[type, str]:  # fmt: skip
    """The class a ``kind`` config names (module docstring) and how it was named (a registry
    name, or the import path), checked to be a subclass of ``base``.

    Args:
        cfg: the component's config; ``_target_`` wins over ``cfg[name_key]``.
        name_key: the key holding the registry name (``type`` or ``name``).
        builtins: the built-in names -> ``"module:Class"``.
        key: the config prefix for errors (``controller``, ``sim``).
    """
    target = cfg.get("_target_")
    if target is not None:
        label, where = str(target), f"{key}._target_"
        obj = load_object(target, where)
    else:
        names = available(kind, builtins)
        name = cfg.get(name_key)
        if name not in names:
            hint = f" (or {key}._target_: an import path 'module:Class')"
            what = "is not set" if name is None else f"unknown value {name!r}"
            raise ConfigError(f"{key}.{name_key}", f"{what}; allowed: {', '.join(names)}{hint}")
        label, where = str(name), f"{key}.{name_key}"
        obj = load_object(names[name], where)
    if not (inspect.isclass(obj) and issubclass(obj, base)):
        what = f"class {obj.__name__}" if inspect.isclass(obj) else type(obj).__name__
        raise ConfigError(
            where,
            f"plugin {label!r} is a {what}, not a subclass of "
            f"{base.__module__}.{base.__qualname__}",
        )
    if inspect.isabstract(obj):
        missing = ", ".join(sorted(getattr(obj, "__abstractmethods__", ())))
        raise ConfigError(where, f"plugin {label!r} does not implement {missing}")
    return obj, label


def call_plugin(
    label: str, where: str, build: Callable[..., Any], /, *args: Any, **kwargs: Any
) -> Any:
    """``build(*args, **kwargs)``: a plugin's constructor (or ``from_config``) that refuses its
    parameters with any exception is one ConfigError line naming the plugin and ``where``."""
    try:
        return build(*args, **kwargs)
    except ConfigError:
        raise
    except Exception as exc:  # noqa: BLE001 - a plugin may raise anything
        raise ConfigError(
            where, f"plugin {label!r} refused its parameters: {exception_line(exc)}"
        ) from exc


def accepts_key(cls: type) -> bool:
    """Whether ``cls``'s constructor takes ccm's ``key`` argument (the config prefix its
    errors name); a plugin's need not."""
    return "key" in inspect.signature(cls.__init__).parameters
