"""Controller registry: the ``type`` field of a ``controller`` config picks the class."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ccm.control.adaptive.anticipation import AnticipatoryAVIC
from ccm.control.adaptive.avic import AVIC
from ccm.control.base import Controller
from ccm.control.baselines.aic import AIC
from ccm.control.baselines.bac import BAC
from ccm.control.baselines.mrac import MRAC
from ccm.control.impedance import FixedImpedance
from ccm.control.mpc.gp_mpc import GPMPC
from ccm.core.errors import check_choice

CONTROLLERS: dict[str, type[Controller]] = {
    "fixed_impedance": FixedImpedance,
    "mrac": MRAC,
    "aic": AIC,
    "bac": BAC,
    "avic": AVIC,
    "avic_modes": AVIC,  # with Algorithm 1 (its modes block): AVIC.from_config
    "avic_anticipation": AnticipatoryAVIC,
    "gp_mpc": GPMPC,
}


def make_controller(cfg: Mapping[str, Any], key: str = "controller") -> Controller:
    """Build a controller from a plain config mapping with a ``type`` field."""
    kind = check_choice(f"{key}.type", cfg.get("type"), CONTROLLERS)
    return CONTROLLERS[kind].from_config(cfg, key=key)
