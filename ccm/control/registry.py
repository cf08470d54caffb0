"""Controller registry: the ``type`` (or ``_target_``) of a ``controller`` config picks the
class (:mod:`ccm.core.plugins`: built-ins, installed plugins and import paths)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ccm.control.base import Controller
from ccm.core.plugins import call_plugin, resolve_class

#: built-in controllers: ``type`` -> "module:Class", imported when used. Presets of a class
#: (AVIC with Algorithm 1: ``configs/controller/avic_modes.yaml``) are configs, not names.
CONTROLLERS: dict[str, str] = {
    "fixed_impedance": "ccm.control.impedance:FixedImpedance",
    "mrac": "ccm.control.baselines.mrac:MRAC",
    "aic": "ccm.control.baselines.aic:AIC",
    "bac": "ccm.control.baselines.bac:BAC",
    "avic": "ccm.control.adaptive.avic:AVIC",
    "avic_anticipation": "ccm.control.adaptive.anticipation:AnticipatoryAVIC",
    "gp_mpc": "ccm.control.mpc.gp_mpc:GPMPC",
}


def controller_class(cfg: Mapping[str, Any], key: str = "controller") -> type[Controller]:
    """The class of a controller config: its ``_target_`` import path, or its ``type`` (a
    built-in or a ``ccm.controllers`` entry point)."""
    return resolve_class("controller", cfg, "type", CONTROLLERS, key, Controller)[0]


def make_controller(cfg: Mapping[str, Any], key: str = "controller") -> Controller:
    """Build a controller from a plain config mapping (:func:`controller_class`; the class's
    ``from_config`` gets the rest of the mapping). A plugin's constructor that refuses its
    parameters with any exception is one :class:`ConfigError` line naming the plugin."""
    cls, label = resolve_class("controller", cfg, "type", CONTROLLERS, key, Controller)
    return call_plugin(label, key, cls.from_config, cfg, key=key)
