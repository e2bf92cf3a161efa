"""SimLog and results.npz I/O (humanoid_sim.interfaces.log): rows and columns, the save/load round trip with its
units, and the atomic write."""

from __future__ import annotations

import json
import os
import stat

import numpy as np
import pytest

from humanoid_sim.interfaces.log import SIGNALS, SimLog, atomic_write_bytes, load_results


def _row(i: int) -> dict[str, np.ndarray]:
    """A row whose every entry is a known function of the step index and the signal name (shapes of a real
    walk for a few signals, scalars elsewhere)."""
    shapes = {"q": (33,), "v": (32,), "hip_p": (3,), "hip_R": (3, 3), "T": (26,), "saturated": (26,),
              "foot_wrench": (2, 6), "in_contact": (2,)}
    row = {}
    for j, name in enumerate(SIGNALS):
        shape = shapes.get(name, ())
        value = np.full(shape, 1000.0 * i + j)
        if name in ("saturated", "in_contact"):
            value = np.full(shape, (i + j) % 2 == 0)
        row[name] = value
    return row


def test_append_stacks_rows_with_step_first() -> None:
    log = SimLog()
    rows = [_row(i) for i in range(4)]
    for r in rows:
        log.append(**r)
    assert len(log) == 4
    a = log.arrays()
    assert set(a) == set(SIGNALS)
    assert a["q"].shape == (4, 33) and a["hip_R"].shape == (4, 3, 3) and a["foot_wrench"].shape == (4, 2, 6)
    for name in SIGNALS:
        np.testing.assert_array_equal(a[name], np.stack([r[name] for r in rows]), err_msg=name)


def test_append_copies_its_inputs() -> None:
    log = SimLog()
    r = _row(0)
    log.append(**r)
    r["q"][:] = -1.0  # a caller reusing its buffer must not change the logged row
    assert log.arrays()["q"][0, 0] == 1000.0 * 0 + list(SIGNALS).index("q")


def test_rows_must_name_every_signal_and_no_other() -> None:
    log = SimLog()
    r = _row(0)
    del r["t"]
    with pytest.raises(KeyError, match=r"missing \['t'\]"):
        log.append(**r)
    with pytest.raises(KeyError, match=r"unknown \['speed'\]"):
        log.append(**_row(0), speed=1.0)
    assert len(log) == 0


def test_from_columns_checks_names_and_lengths_then_appends() -> None:
    cols = {k: np.stack([_row(i)[k] for i in range(3)]) for k in SIGNALS}
    log = SimLog.from_columns(cols)
    assert len(log) == 3
    np.testing.assert_array_equal(log.arrays()["t"], cols["t"])
    a = log.arrays()  # a copy: the caller may change it
    a["q"][:] = 7.0
    assert not np.any(log.arrays()["q"] == 7.0)
    log.append(**_row(3))  # columns then rows: one log of 4 steps
    assert len(log) == 4
    np.testing.assert_array_equal(log.arrays()["hip_p"][3], _row(3)["hip_p"])
    bad = dict(cols, t=cols["t"][:2])
    with pytest.raises(ValueError, match="different lengths"):
        SimLog.from_columns(bad)
    with pytest.raises(KeyError, match="missing"):
        SimLog.from_columns({k: v for k, v in cols.items() if k != "zmp"})


def test_save_load_round_trip_with_units(tmp_path) -> None:
    log = SimLog()
    for i in range(5):
        log.append(**_row(i))
    path = tmp_path / "out" / "results.npz"
    log.save(path, ["LFFSSP", "RFFDSP"], extra={"my_extra": np.arange(3.0)})
    back = load_results(path)
    for name in SIGNALS:
        np.testing.assert_array_equal(back[name], np.stack([_row(i)[name] for i in range(5)]), err_msg=name)
        assert back[name].dtype == np.stack([_row(0)[name]]).dtype, name
    np.testing.assert_array_equal(back["my_extra"], [0.0, 1.0, 2.0])
    assert back["phase_names"].tolist() == ["LFFSSP", "RFFDSP"]
    units = json.loads(str(back["signal_units"]))
    assert set(units) == set(SIGNALS)
    # the SI units a reader needs, written out by hand
    assert {k: units[k]["unit"] for k in ("t", "hip_p", "hip_v", "T", "theta", "theta_dot", "theta_ddot",
                                          "body_force", "dynamics_residual")} == {
        "t": "s", "hip_p": "m", "hip_v": "m/s", "T": "N m", "theta": "rad", "theta_dot": "rad/s",
        "theta_ddot": "rad/s^2", "body_force": "N", "dynamics_residual": "N m"}
    assert all(units[k]["meaning"] for k in units)


def test_atomic_write_leaves_no_temporary_and_the_umask_mode(tmp_path) -> None:
    target = tmp_path / "a.bin"
    old = os.umask(0o027)
    try:
        atomic_write_bytes(target, b"abc")
    finally:
        os.umask(old)
    assert target.read_bytes() == b"abc"
    assert stat.S_IMODE(target.stat().st_mode) == 0o640  # 0666 less the umask 027, as open() would give
    assert [p.name for p in tmp_path.iterdir()] == ["a.bin"]


def test_atomic_write_failure_keeps_the_old_file(tmp_path) -> None:
    target = tmp_path / "a.bin"
    target.write_bytes(b"old")
    with pytest.raises(TypeError):
        atomic_write_bytes(target, "not bytes")  # the write fails after the temporary file was made
    assert target.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["a.bin"]
