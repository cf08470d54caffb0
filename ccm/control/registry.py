"""Controller registry: the ``type`` field of a ``controller`` config picks the class."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ccm.control.aic import AIC
from ccm.control.anticipation import AnticipatoryAVIC
from ccm.control.avic import AVIC
from ccm.control.bac import BAC
from ccm.control.base import Controller
from ccm.control.gp_mpc import GPMPC
from ccm.control.impedance import FixedImpedance
from ccm.control.modal import ModalAVIC
from ccm.control.mrac import MRAC
from ccm.errors import check_choice

CONTROLLERS: dict[str, type[Controller]] = {
    "fixed_impedance": FixedImpedance,
    "mrac": MRAC,
    "aic": AIC,
    "bac": BAC,
    "avic": AVIC,
    "avic_modes": ModalAVIC,
    "avic_anticipation": AnticipatoryAVIC,
    "gp_mpc": GPMPC,
}


def make_controller(cfg: Mapping[str, Any], key: str = "controller") -> Controller:
    """Build a controller from a plain config mapping with a ``type`` field."""
    kind = check_choice(f"{key}.type", cfg.get("type"), CONTROLLERS)
    return CONTROLLERS[kind].from_config(cfg, key=key)
