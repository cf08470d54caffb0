"""Oracle tests of seed A's belief and detection metrics and the Table 1 layout
(``ccm.metrics.contacts``; issue #39 item 1): each value against its definition in the module
docstring, on a controller report whose numbers are known."""

from __future__ import annotations

import numpy as np
import pytest

from ccm.metrics.contact_beliefs import contact_table
from ccm.metrics.contacts import contact_metrics
from tests.test_contact_metrics import PARAMS, TABLE, drop_log

#: the table's belief: before the trial 5 mm off along y (std 8 mm), after it 3 mm (4 mm);
#: the first measured contact 2 mm below the nominal surface and 1 mm aside
REPORT = {"contacts": [
    {"name": "table", "kind": "collision", "source": "config", "mean": [0.0, 0.003, 0.1],
     "std": 0.004, "prior_mean": [0.0, 0.005, 0.1], "prior_std": 0.008,
     "measured": [[0.001, 0.0, 0.098], [0.0, 0.0, 0.5]],
     "approach_velocity": 0.02, "impact_force": 7.5},
]}  # fmt: skip


def _metrics(report: dict | None, contact: dict = TABLE) -> dict:
    return contact_metrics(
        drop_log(), 3, {**PARAMS, "task_contacts": [contact], "controller_report": report}
    )


def test_prior_and_detection_metrics_give_their_definitions_values() -> None:
    m = _metrics(REPORT)
    assert m["contact_prior_error_m_table"] == pytest.approx(0.005)
    assert m["contact_prior_std_m_table"] == pytest.approx(0.008)
    # the first measurement only: ‖(0.001, 0, −0.002)‖, and its depth along −n: 2 mm past
    assert m["detection_error_m_table"] == pytest.approx(np.hypot(0.001, 0.002))
    assert m["detection_depth_m_table"] == pytest.approx(0.002)
    assert m["n_contacts_learned"] == 0.0


def test_the_depth_uses_the_unit_normal_and_none_without_one() -> None:
    scaled = _metrics(REPORT, {**TABLE, "normal": (0.0, 0.0, 4.0)})
    assert scaled["detection_depth_m_table"] == pytest.approx(0.002)
    bare = _metrics(REPORT, {k: v for k, v in TABLE.items() if k != "normal"})
    assert bare["detection_depth_m_table"] is None
    assert bare["detection_error_m_table"] == pytest.approx(np.hypot(0.001, 0.002))


def test_without_beliefs_every_belief_metric_is_none() -> None:
    for report in (None, {}, {"contacts": []}):
        m = _metrics(report)
        keys = ("contact_error_m", "contact_std_m", "contact_prior_error_m", "contact_prior_std_m",
                "approach_velocity_mps", "measured_impact_force_N", "detection_error_m",
                "detection_depth_m")  # fmt: skip
        assert all(m[f"{k}_table"] is None for k in keys), report
    assert _metrics(None)["n_contacts_learned"] is None
    assert _metrics({"contacts": []})["n_contacts_learned"] == 0.0
    no_prior = {"contacts": [{**REPORT["contacts"][0], "prior_mean": None, "measured": []}]}
    m = _metrics(no_prior)
    assert m["contact_prior_error_m_table"] is None and m["detection_error_m_table"] is None
    assert m["contact_error_m_table"] == pytest.approx(0.003)


def test_table_1_row_holds_each_value_in_its_column() -> None:
    trial = {"condition": "full", "trial": 2, "pattern_time_s": 20.0, "transition_time_s": 5.25,
             "contact_prior_error_m_table": 0.005, "contact_prior_std_m_table": 0.008,
             "contact_error_m_table": 0.001, "contact_std_m_table": 0.004,
             "approach_velocity_mps_table": 0.02, "impact_force_N_table": 8.14,
             "measured_impact_force_N_table": 7.96}  # fmt: skip
    text = contact_table([trial, {**trial, "trial": 3, "approach_velocity_mps_table": None}])
    assert text is not None
    lines = text.splitlines()
    assert lines[0].startswith("| condition | trial | contact | error before [m] |")
    assert len(lines) == 4 and text.endswith("\n")
    assert lines[2] == (
        "| full | 2 | table | 0.0050 | 0.0080 | 0.0010 | 0.0040 | 0.0200 | 8.1 | 8.0 "
        "| 20.00 | 5.25 |"
    )
    assert "| 0.0040 | – | 8.1 |" in lines[3]
