"""Gymnasium environments over ccm's changing-contact tasks (issue #41, part 4).

``import ccm.envs`` registers ``ccm/<Name>-v0`` for each task of the benchmark suite
(:data:`ENVS`, ``ccm suite --list``); then ``gymnasium.make("ccm/MultiSpring-v0",
action="variable_impedance")``. Each is its suite task: the simulator, scene, sensor and plan
``ccm suite`` scores controllers on (:class:`ccm.envs.env.ChangingContactEnv` documents the
spaces and the reward). Needs the ``gym`` extra: ``pip install -e '.[gym]'``.
"""

from __future__ import annotations

from gymnasium.envs.registration import register, registry

#: environment name -> the task of the benchmark suite (changing_contact_v1) it is
ENVS: dict[str, str] = {
    "MultiSpring": "multi_spring",  # seed A Fig. 1c: three springs (2-D)
    "PorridgeStirring": "porridge",  # seed A §4.1: viscosity that changes (2-D)
    "ChangingSurface": "changing_surface",  # seed A Fig. 8: three frictions (Panda)
    "Collisions": "collisions",  # seed A Fig. 16: contacts met at speed (Panda)
    "TableWall": "table_wall",  # seed A §4.4: a table, then a wall (Panda)
    "Contact": "contact",  # seed B Fig. 6: into a compliant wall and a 10 N push
    "ContactLatency": "contact_latency",  # the same, the F/T reading 4 ms late
    "Polishing": "polishing",  # seed B Table 3: polishing with a disturbance
}

for _name, _task in ENVS.items():
    if f"ccm/{_name}-v0" not in registry:
        register(id=f"ccm/{_name}-v0", entry_point="ccm.envs.env:ChangingContactEnv",
                 kwargs={"task": _task})  # fmt: skip
