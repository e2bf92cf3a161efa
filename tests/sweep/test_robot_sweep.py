"""A sweep over the robot itself: trunk payload x shank length on sim3_zmp, on MuJoCo (scripts/sweeps/
robot_payload_shank.yaml)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import yaml

from humanoid_sim.cli import sweep as cli
from humanoid_sim.robot.model import DEFAULT_SPEC
from humanoid_sim.sweep.table import read_rows
from tests.conftest import ROOT

SWEEP = ROOT / "scripts" / "sweeps" / "robot_payload_shank.yaml"


@pytest.fixture(scope="module")
def rows(tmp_path_factory):
    out = tmp_path_factory.mktemp("robot_sweep")
    assert cli.main([str(SWEEP), "--out", str(out), "--workers", "2", "--engine", "mujoco", "--quiet",
                     "--no-plots"]) == 0
    return pd.DataFrame(read_rows(out))


@pytest.mark.slow
def test_every_variant_walks_and_its_row_gives_its_mass(rows):
    """Nine walks complete on MuJoCo.  Each row's model mass is the body table's (summed from the YAML here) plus
    its payload, exactly: the masses enter the URDF as printed numbers and Pinocchio sums them (1e-12 kg)."""
    table = yaml.safe_load(DEFAULT_SPEC.read_text())
    thesis = sum(float(b["mass"]["value"]) for b in table["bodies"] if not b.get("virtual"))
    assert len(rows) == 9 and rows["completed"].all(), rows[["reason"]]
    np.testing.assert_allclose(rows["robot_mass_kg"], thesis + rows["robot.payload.mass_kg"], rtol=0, atol=1e-12)
    assert sorted(set(rows["robot.length_scale.shank"])) == [0.9, 1.0, 1.1]


@pytest.mark.slow
@pytest.mark.parametrize("joint", ["theta11", "theta12", "theta15", "theta16"])   # knees, hip pitch
def test_knee_and_hip_pitch_peaks_rise_with_payload(rows, joint):
    """At every shank length, the peak torque of the knees and the hip pitch axes (every 1 ms MuJoCo step) grows
    with the trunk's payload: 0 < 5 < 10 kg.  Measured rises are 2.5-7.6 N m per 5 kg (a 5 kg payload is 9 % of
    the robot), each peak taken over every 1 ms MuJoCo step of a deterministic walk."""
    col = f"design_joints_{joint}_torque_peak_Nm"
    for shank, group in rows.groupby("robot.length_scale.shank"):
        peaks = group.sort_values("robot.payload.mass_kg")[col].to_numpy()
        assert np.all(np.diff(peaks) > 0.0), (shank, peaks)
