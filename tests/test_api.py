"""The public API (humanoid_sim.api, exported by humanoid_sim): run a walk, read its log, write its outputs."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import humanoid_sim as hs
from humanoid_sim.interfaces.log import SIGNALS
from humanoid_sim.robot.actuators import T_NAMES
from humanoid_sim.robot.model import THETA_NAMES


@pytest.fixture(scope="module")
def short_run() -> hs.Run:
    return hs.run_walk("sim1", until=0.2)


def test_a_short_walk_stops_where_asked(short_run: hs.Run) -> None:
    assert short_run.status is hs.RunStatus.STOPPED and short_run.status.reached_end
    assert short_run.summary["status"] == "stopped" and not short_run.summary["completed"]
    assert len(short_run.log) == 20                       # 0.2 s of 10 ms steps
    assert short_run.result.error is None and short_run.result.traceback is None


def test_the_dataframe_names_every_component_by_joint_and_unit(short_run: hs.Run) -> None:
    log, hm = short_run.log, short_run.hm
    df = log.to_pandas()
    assert df.index.name == "t [s]" and np.array_equal(df.index.to_numpy(), log["t"])
    n_columns = sum(int(np.prod(a.shape[1:])) for k, a in log.arrays.items() if k != "t") + 1   # + phase_name
    assert df.shape == (len(log), n_columns)
    # actuators by the thesis's names (eq. 4.69 order), joint angles by theirs
    assert np.array_equal(df["T.T3 [N m]"], log["T"][:, T_NAMES.index("T3")])
    assert np.array_equal(df["theta.theta9 [rad]"], log["theta"][:, THETA_NAMES.index("theta9")])
    # Pinocchio's coordinates by joint name, read through Pinocchio's own index of the joint
    for name in ("theta9", "theta18"):
        j = hm.model.getJointId(name)
        assert np.array_equal(df[f"q.{name} [rad]"], log["q"][:, hm.model.joints[j].idx_q])
        assert np.array_equal(df[f"v.{name} [rad/s]"], log["v"][:, hm.model.joints[j].idx_v])
    assert np.array_equal(df["foot_wrench.L_fz [N]"], log["foot_wrench"][:, 1, 2])
    assert np.array_equal(df["hip_p.z [m]"], log["hip_p"][:, 2])
    names = short_run.result.phase_names
    assert list(df["phase_name"]) == [names[int(k)] for k in log["phase"]]
    # every single-unit signal's columns carry that signal's unit
    for col in df.columns:
        sig = col.split(".")[0].split(" ")[0]
        if sig in SIGNALS and "," not in SIGNALS[sig][0] and sig not in ("q", "v", "tau", "foot_wrench"):
            assert col.endswith(f"[{SIGNALS[sig][0]}]"), col


def test_write_puts_the_summary_and_the_log_on_disk(short_run: hs.Run, tmp_path: Path) -> None:
    written = short_run.write(tmp_path / "out", figures=False, playback=False)
    assert [p.name for p in written] == ["results.npz", "summary.json", "design.csv", "fatigue.csv", "load_cases.json"]
    assert json.loads((tmp_path / "out" / "summary.json").read_text()) == json.loads(json.dumps(short_run.summary))
    with np.load(tmp_path / "out" / "results.npz") as z:
        assert np.array_equal(z["T"], short_run.log["T"])
        # the transmitted joint wrenches: their moment about each joint's axis is the joint's applied torque
        # (1e-6 N m: the weld engine's dynamics close to round-off, ~1e-11)
        hm = short_run.hm
        from humanoid_sim.dynamics.joint_loads import joint_axes

        axes = joint_axes(hm.model, [hm.model.getJointId(n) for n in z["theta_names"]])
        torsion = np.einsum("nmk,mk->nm", z["joint_wrench"][:, :, 3:], axes)
        assert np.abs(torsion - z["tau"][:, hm.theta_v_idx]).max() < 1e-6


@pytest.mark.parametrize("kwargs, match", [
    ({"scenario": "sim9"}, r"'sim9' is neither a YAML file nor a shipped scenario; expected a path or one of .*sim1"),
    ({"scenario": "sim1", "engine": "bullet"}, r"engine: 'bullet' is not one of pinocchio, thesis, mujoco"),
    ({"scenario": "sim1", "until": -1.0}, r"until: expected a positive time in s, got -1.0"),
])
def test_bad_input_is_an_input_error_naming_the_field(kwargs: dict, match: str) -> None:
    with pytest.raises(hs.InputError, match=match):
        hs.run_walk(**kwargs)


def _deep_helper(x: np.ndarray) -> np.ndarray:
    return x[[99]]                                        # IndexError, two frames below the controller


class _Raises:
    name = "raises"

    def setup(self, ctx) -> None:
        pass

    def __call__(self, obs) -> np.ndarray:
        return _deep_helper(np.zeros(26))


def test_a_failing_controller_ends_the_run_with_its_status_and_traceback() -> None:
    run = hs.run_walk("sim1", until=0.05, controller=_Raises())
    assert run.status is hs.RunStatus.FAILED and not run.status.reached_end
    assert isinstance(run.result.error, hs.ControllerError)
    assert "IndexError" in run.result.reason
    assert "_deep_helper" in run.result.traceback and "test_api.py" in run.result.traceback


def test_the_shipped_scenarios_are_listed_and_found_by_name() -> None:
    names = hs.scenario_names()
    assert {"sim1", "sim2", "sim3", "sim1_zmp", "sim3_zmp"} <= set(names)
    for n in names:
        assert (hs.SCENARIOS_DIR / f"{n}.yaml").is_file()
        assert hs.load_scenario(hs.SCENARIOS_DIR / f"{n}.yaml").name == n


def test_the_public_names_are_exported() -> None:
    for name in hs.__all__:
        assert getattr(hs, name) is not None, name


@pytest.mark.slow
def test_the_first_walk_example_runs_as_a_newcomer_would(tmp_path: Path) -> None:
    """scripts/examples/first_walk.py (<= 10 lines, the documented API only): a MuJoCo walk, its DataFrame, a PNG."""
    import subprocess
    import sys

    script = Path(__file__).resolve().parents[1] / "scripts" / "examples" / "first_walk.py"
    assert len(script.read_text().splitlines()) <= 10
    proc = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    png = tmp_path / "first_walk_T3.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000
