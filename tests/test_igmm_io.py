"""Saving and loading the IGMM (``ccm.learn.mixtures.igmm_io``; issue #39 item 1).

Every malformed snapshot is refused with the one line that names what is wrong (the message
is checked whole, so a check that reports the wrong field fails), every well-formed edge case
is accepted, and a round trip keeps the components, their ages and the event counters.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ccm.core.errors import ConfigError
from ccm.learn.mixtures.igmm import IGMM


def _snapshot(**change: Any) -> dict[str, Any]:
    """A valid two-component 2-D snapshot (JSON form) with ``change`` applied."""
    data = IGMM(2, sigma_init=1.0, max_components=3).state_dict()
    data.update(
        means=[[0.0, 0.0], [1.0, 2.0]],
        covariances=[[[1.0, 0.2], [0.2, 2.0]], [[0.5, 0.0], [0.0, 0.5]]],
        support=[3.0, 0.5],  # a support below 1 is allowed (> 0)
        ages=[1.0, 4.7],  # ages are floored; 1 is allowed (>= 1)
        n_seen=0,  # allowed (>= 0)
        stats={"created": 2, "merged": 1},
    )
    data.update(change)
    return data


def test_a_snapshot_round_trips_components_ages_and_counters() -> None:
    model = IGMM.from_state_dict(json.loads(json.dumps(_snapshot())))
    np.testing.assert_array_equal(model.means_, [[0.0, 0.0], [1.0, 2.0]])
    np.testing.assert_array_equal(model.support_, [3.0, 0.5])
    np.testing.assert_array_equal(model.ages_, [1, 4])
    # counters absent from the snapshot start at 0
    assert model.stats_ == {
        "created": 2, "merged": 1, "overflow_pruned": 0, "support_pruned": 0, "jitter": 0
    }  # fmt: skip
    again = IGMM.from_state_dict(json.loads(json.dumps(model.state_dict())))
    assert again.stats_ == model.stats_ and again.n_seen_ == 0
    np.testing.assert_array_equal(again.ages_, model.ages_)


@pytest.mark.parametrize("stats", [None, "garbage", [1, 2]])
def test_missing_or_malformed_counters_start_at_zero(stats: Any) -> None:
    data = _snapshot()
    del data["stats"]
    if stats is not None:
        data["stats"] = stats
    assert set(IGMM.from_state_dict(data).stats_.values()) == {0}


def test_an_empty_snapshot_is_an_empty_model() -> None:
    model = IGMM.from_state_dict(_snapshot(means=[], covariances=[], support=[], ages=[]))
    assert model.n_components_ == 0
    assert model.support_.shape == (0,) and model.ages_.shape == (0,)


_PARAMS = IGMM(2, sigma_init=1.0, max_components=3).get_params()
_BAD: list[tuple[dict[str, Any] | list[int], str]] = [
    ([1, 2], "IGMM data must be a mapping, got list"),
    ({"format": "other"}, "not an IGMM snapshot: format='other'"),
    ({"format_version": 2}, "unsupported IGMM format_version 2 (this code reads 1)"),
    ({"params": {**_PARAMS, "zeta": 1, "alpha": 2}}, "IGMM data: unknown params alpha, zeta"),
    ({"params": {**_PARAMS, "key": "x"}}, "IGMM data: unknown params key"),
    ({"params": {**_PARAMS, "self": 1}}, "IGMM data: unknown params self"),
    ({"params": {"max_components": 3}}, "IGMM data: params is missing n_features, sigma_init"),
    ({"params": [1]}, "IGMM data: params must be a mapping"),
    (
        {"support": [3.0, 0.5, 1.0]},
        "IGMM data: inconsistent shapes means (2, 2), covariances (2, 2, 2), support (3,), "
        "ages (2,)",
    ),
    (
        {"ages": [1.0]},
        "IGMM data: inconsistent shapes means (2, 2), covariances (2, 2, 2), support (2,), "
        "ages (1,)",
    ),
    (
        {"covariances": [[[1.0, 0.0], [0.0, 1.0]]]},
        "IGMM data: inconsistent shapes means (2, 2), covariances (1, 2, 2), support (2,), "
        "ages (2,)",
    ),
    ({"means": [[0.0, 0.0, 0.0]] * 2}, "IGMM data: means must have shape (K<=3, 2), got (2, 3)"),
    ({"means": [[0.0, float("nan")], [1.0, 2.0]]}, "IGMM data: means must be finite"),
    ({"ages": [1.0, float("inf")]}, "IGMM data: ages must be finite"),
    ({"support": [3.0, 0.0]}, "IGMM data: support must be > 0, ages >= 1 and n_seen >= 0"),
    ({"ages": [0.5, 2.0]}, "IGMM data: support must be > 0, ages >= 1 and n_seen >= 0"),
    ({"n_seen": -1}, "IGMM data: support must be > 0, ages >= 1 and n_seen >= 0"),
    (
        {"covariances": [[[1.0, 0.2], [0.2 + 1e-9, 2.0]], [[0.5, 0.0], [0.0, 0.5]]]},
        "IGMM data: covariances must be symmetric",  # 5e-9 relative: beyond rtol 1e-12
    ),
]


@pytest.mark.parametrize(("change", "message"), _BAD)
def test_a_malformed_snapshot_is_refused_with_one_line_naming_it(
    change: dict[str, Any] | list[int], message: str
) -> None:
    data = change if isinstance(change, list) else _snapshot(**change)
    with pytest.raises(ValueError) as info:
        IGMM.from_state_dict(data)
    assert str(info.value) == message


def test_missing_fields_are_listed_in_order() -> None:
    data = _snapshot()
    del data["n_seen"], data["params"]
    with pytest.raises(ValueError) as info:
        IGMM.from_state_dict(data)
    assert str(info.value) == "IGMM data is missing params, n_seen"


def test_non_numeric_arrays_and_bad_settings_name_their_cause() -> None:
    with pytest.raises(ValueError, match=r"^IGMM data: non-numeric component arrays \(.+\)$"):
        IGMM.from_state_dict(_snapshot(means=[["a", "b"], [1.0, 2.0]]))
    bad = _snapshot(params={**_PARAMS, "n_features": 0})
    with pytest.raises(ConfigError, match=r"fm\.igmm\.n_features"):
        IGMM.from_state_dict(bad, key="fm.igmm")  # the caller's key names the setting


def _arrays(path: Path) -> dict[str, np.ndarray]:
    with np.load(path, allow_pickle=False) as npz:
        return {k: npz[k] for k in npz.files}


def test_npz_keeps_counters_and_reads_a_file_without_them(tmp_path: Path) -> None:
    """A file written before the counters were saved (no ``stats_json``) loads with zeros."""
    model = IGMM.from_state_dict(_snapshot())
    path = model.save(tmp_path / "m.npz")
    assert IGMM.load(path).stats_ == model.stats_
    np.testing.assert_array_equal(IGMM.load(path).ages_, [1, 4])
    old = {k: v for k, v in _arrays(path).items() if k != "stats_json"}
    np.savez(tmp_path / "old.npz", **old)
    assert set(IGMM.load(tmp_path / "old.npz").stats_.values()) == {0}


def test_npz_refusals_name_the_file_and_the_cause(tmp_path: Path) -> None:
    path = IGMM.from_state_dict(_snapshot()).save(tmp_path / "m.npz")
    arrays = _arrays(path)
    np.savez(tmp_path / "short.npz", **{k: v for k, v in arrays.items() if k not in
                                          ("params_json", "n_seen")})  # fmt: skip
    with pytest.raises(ValueError) as info:
        IGMM.load(tmp_path / "short.npz")
    assert str(info.value) == (
        f"{tmp_path / 'short.npz'}: not a valid IGMM file "
        "(ValueError: missing arrays params_json, n_seen)"
    )
    np.save(tmp_path / "plain.npy", np.zeros(3))
    with pytest.raises(ValueError) as info:
        IGMM.load(tmp_path / "plain.npy")
    assert str(info.value) == (
        f"{tmp_path / 'plain.npy'}: not a valid IGMM file (ValueError: not an NPZ archive)"
    )
    # a complete file whose means are a pickled object array: never unpickled
    np.savez(tmp_path / "obj.npz", **{**arrays, "means": np.array([{"a": 1}], dtype=object)})
    with pytest.raises(ValueError, match=r"obj\.npz: not a valid IGMM file \(.*allow_pickle"):
        IGMM.load(tmp_path / "obj.npz")
    (tmp_path / "junk.npz").write_bytes(b"PK\x03\x04 not a zip")
    with pytest.raises(ValueError, match=r"junk\.npz: not a valid IGMM file \(BadZipFile: "):
        IGMM.load(tmp_path / "junk.npz")
