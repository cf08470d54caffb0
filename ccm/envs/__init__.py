"""Gymnasium environments over ccm's changing-contact tasks (issue #41, part 4).

``import ccm.envs`` registers ``ccm/<Name>-v0`` for each entry of :data:`ENVS`; then
``gymnasium.make("ccm/MultiSpring-v0", action="variable_impedance")``. Each takes its task,
simulator and sensor settings from the experiment that reproduces the paper's result on it
(:class:`ccm.envs.env.ChangingContactEnv` documents the spaces and the reward). Needs the
``gym`` extra: ``pip install -e '.[gym]'``.
"""

from __future__ import annotations

from gymnasium.envs.registration import register, registry

#: environment name -> the experiment config it takes its setting from
ENVS: dict[str, str] = {
    "MultiSpring": "h1_adaptive_control",  # seed A Fig. 1c: three springs (2-D)
    "PorridgeStirring": "h1_forward_model",  # seed A §4.1: viscosity that changes (2-D)
    "ChangingSurface": "h2_changing_surface",  # seed A Fig. 8: three frictions (Panda)
    "Collisions": "h4_collisions",  # seed A Fig. 16: contacts met at speed (Panda)
    "TableWall": "h3_long_horizon",  # seed A §4.4: a table, then a wall (Panda)
    "Contact": "mpc_contact",  # seed B Fig. 6: soft, uncertain and stiff contact
    "Polishing": "mpc_polishing",  # seed B Table 3: polishing with a disturbance
}

for _name, _experiment in ENVS.items():
    if f"ccm/{_name}-v0" not in registry:
        register(id=f"ccm/{_name}-v0", entry_point="ccm.envs.env:ChangingContactEnv",
                 kwargs={"experiment": _experiment})  # fmt: skip
