"""The ``disturbances:`` section: what it parses to, the message of every bad field, and the command line's exit 2
with nothing written."""

from __future__ import annotations

import copy
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from humanoid_sim.scenario.disturbances import resolve_start
from humanoid_sim.scenario.schema import ScenarioError, load_scenario, parse_scenario, read_scenario_doc

ROOT = Path(__file__).resolve().parents[2]
PARAMS = ROOT / "scripts" / "params"
WALK = ROOT / "scripts" / "walk.py"


@pytest.fixture(scope="module")
def doc() -> dict:
    return read_scenario_doc(PARAMS / "sim3_zmp_push.yaml")


def test_shipped_examples_parse() -> None:
    push = load_scenario(PARAMS / "sim3_zmp_push.yaml").disturbances
    assert push is not None and len(push.pushes) == 1 and not push.terrain and push.sensing is None
    p = push.pushes[0]
    # 11 N s over 0.1 s along 90 deg of the heading frame: 110 N to the left (cos 90 deg in floating point: 6e-15)
    np.testing.assert_allclose(p.force, [0.0, 110.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(p.impulse, [0.0, 11.0, 0.0], atol=1e-12)
    assert (p.body, p.frame, p.start.phase, p.start.fraction, p.given) == (17, "heading", 8, 0.5, "impulse_Ns")
    terrain = load_scenario(PARAMS / "sim3_zmp_terrain.yaml").disturbances
    assert terrain is not None and [t.kind for t in terrain.terrain] == ["slope", "slope", "bar"]
    assert load_scenario(PARAMS / "sim3_zmp.yaml").disturbances is None


def test_forms_of_force_direction_and_start(doc: dict) -> None:
    d = copy.deepcopy(doc)
    d["disturbances"] = {"pushes": [
        {"force_N": [1.0, 2.0, 3.0], "frame": "world", "start": {"time_s": 2.5}, "duration_s": 0.2, "body": "O_17"},
        {"force_N": 50, "direction": [0.6, 0.8, 0.0], "start": {"phase": 3}, "duration_s": 0.05},
        {"impulse_Ns": [0.0, -3.0, 0.0], "start": {"phase": 4, "fraction": 1}, "duration_s": 0.3}],
        "sensing": {"base_linear_velocity_mps": 0.02, "delay_s": 0.02, "seed": 3}}
    dist = parse_scenario(d, "x.yaml").disturbances
    a, b, c = dist.pushes
    assert a.force == (1.0, 2.0, 3.0) and a.body == "O_17" and a.start.time_s == 2.5
    np.testing.assert_allclose(b.force, [30.0, 40.0, 0.0], rtol=1e-15)   # 50 N along a unit vector: round-off
    assert b.frame == "heading" and b.start.fraction == 0.0
    np.testing.assert_allclose(c.force, [0.0, -10.0, 0.0], rtol=1e-15)   # 3 N s / 0.3 s
    s = dist.sensing
    assert (s.base_linear_velocity_mps, s.joint_position_rad, s.seed, s.delay_s) == (0.02, 0.0, 3, 0.02)


class _Phase:
    def __init__(self, t_start: float, t_end: float) -> None:
        self.t_start, self.t_end = t_start, t_end


def test_resolve_start_is_the_nominal_window() -> None:
    """{phase: k, fraction: f} -> t_start + f (t_end - t_start) of the k-th phase, numbered from 1."""
    d = {"pushes": [{"force_N": 1, "direction_deg": 0, "start": {"phase": 2, "fraction": 0.3}, "duration_s": 1}]}
    from humanoid_sim.scenario.disturbances import parse_disturbances

    p = parse_disturbances("x", d).pushes[0]
    phases = [_Phase(0.0, 1.0), _Phase(1.0, 1.7), _Phase(1.7, 1.8)]
    assert resolve_start(p, phases) == 1.0 + 0.3 * (1.7 - 1.0)
    with pytest.raises(ScenarioError, match=r"start\.phase: expected a phase number in \[1, 1\]"):
        resolve_start(p, phases[:1])


PUSH = {"force_N": 100, "direction_deg": 90, "start": {"phase": 8, "fraction": 0.5}, "duration_s": 0.1}
BAD = [
    # (what replaces disturbances, the message's tail)
    ({"pushes": [{**PUSH, "duration_s": -0.1}]},
     "disturbances.pushes[0].duration_s: expected a duration in s > 0, got -0.1"),
    ({"pushes": [{**PUSH, "impulse_Ns": 3}]}, "disturbances.pushes[0]: expected exactly one of force_N and "
                                              "impulse_Ns, got force_N and impulse_Ns"),
    ({"pushes": [{k: v for k, v in PUSH.items() if k != "direction_deg"}]},
     "disturbances.pushes[0].direction: missing; force_N = 100 is a magnitude"),
    ({"pushes": [{**PUSH, "direction": [1, 1, 0]}]}, "both direction and direction_deg given"),
    ({"pushes": [{**{k: v for k, v in PUSH.items() if k != "direction_deg"}, "direction": [1, 1, 0]}]},
     "disturbances.pushes[0].direction: expected a unit vector [x, y, z] (norm 1 within 0.001), got [1, 1, 0]"),
    ({"pushes": [{**PUSH, "frame": "body"}]}, "disturbances.pushes[0].frame: expected one of heading, world, got "
                                             "'body'"),
    ({"pushes": [{**PUSH, "start": {"phase": 0}}]}, "disturbances.pushes[0].start.phase: expected a phase number >= 1"),
    ({"pushes": [{**PUSH, "start": {"phase": 2, "fraction": 1.5}}]},
     "disturbances.pushes[0].start.fraction: expected a fraction of the phase's nominal duration in [0, 1], got 1.5"),
    ({"pushes": [{**PUSH, "start": {"time_s": 1, "phase": 2}}]}, "time_s given with phase"),
    ({"pushes": [{**PUSH, "start": 3.0}]}, "disturbances.pushes[0].start: expected {time_s: t} or"),
    ({"pushes": [{**PUSH, "body": True}]}, "disturbances.pushes[0].body: expected a thesis body number"),
    ({"pushes": [{**PUSH, "forse_N": 3}]}, "disturbances.pushes[0].forse_N: unknown key; did you mean 'force_N'?"),
    ({"pushes": [{**PUSH, "force_N": [0, 100, 0]}]}, "pushes[0]: force_N is a vector, which has its own direction"),
    ({"pushes": [{**{k: v for k, v in PUSH.items() if k != "direction_deg"}, "force_N": [0, 0, 0]}]},
     "disturbances.pushes[0].force_N: expected a non-zero vector, got [0, 0, 0]"),
    ({"pushes": {"a": 1}}, "disturbances.pushes: expected a list"),
    ({"terrain": [{"kind": "hill", "centre": [0, 0, 0], "size": [1, 1, 1]}]},
     "disturbances.terrain[0].kind: expected one of box, step, bar, tile, slope, got 'hill'"),
    ({"terrain": [{"kind": "bar", "centre": [0, 0], "size": [1, 1, 1]}]},
     "disturbances.terrain[0].centre: expected 3 entries"),
    ({"terrain": [{"kind": "tile", "centre": [0, 0, 0], "size": [1, 0, 1]}]},
     "disturbances.terrain[0].size[1]: expected a length in m in (0, 100], got 0"),
    ({"terrain": [{"kind": "slope", "centre": [0, 0], "size": [1, 1], "angle_deg": 60, "direction": "up"}]},
     "disturbances.terrain[0].angle_deg: expected a slope angle in deg in (0, 45], got 60"),
    ({"terrain": [{"kind": "slope", "centre": [0, 0], "size": [1, 1], "angle_deg": 3, "direction": "left"}]},
     "disturbances.terrain[0].direction: expected one of up, down, sideways"),
    ({"terrain": [{"kind": "slope", "centre": [0, 0], "size": [1, 1], "normal": [1, 0, 0.2]}]},
     "disturbances.terrain[0].normal: expected an upward normal at most 45 deg from z"),
    ({"terrain": [{"kind": "step", "centre": [0, 0, 0], "size": [1, 1, 1], "friction": -1}]},
     "disturbances.terrain[0].friction: expected a friction coefficient in (0, 5], got -1"),
    ({"sensing": {"base_linear_velocity_mps": -0.1}},
     "disturbances.sensing.base_linear_velocity_mps: expected a standard deviation in m/s in [0, 10], got -0.1"),
    ({"sensing": {"seed": 1.5}}, "disturbances.sensing.seed: expected an integer >= 0, got 1.5"),
    ({"sensing": {"delay_s": "20ms"}}, "disturbances.sensing.delay_s: expected a delay in s in [0, 1], got '20ms'"),
    ({"sensing": {"joint_noise": 0.1}}, "disturbances.sensing.joint_noise: unknown key"),
    ({"model": {"payload_kg": 5}}, "disturbances.model.payload_kg: unknown key; did you mean 'payload'"),
    ([1, 2], "disturbances: expected a mapping of keys to values, got list"),
]


@pytest.mark.parametrize("section, message", BAD, ids=[m[:50] for _, m in BAD])
def test_bad_field_named_with_value_and_expectation(doc: dict, section, message) -> None:
    d = copy.deepcopy(doc)
    d["disturbances"] = section
    with pytest.raises(ScenarioError) as exc:
        parse_scenario(d, "scenario.yaml")
    assert str(exc.value).startswith("scenario.yaml: ") and message in str(exc.value), str(exc.value)


def _walk(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(WALK), *args], capture_output=True, text=True, cwd=ROOT, timeout=300)


@pytest.mark.slow
def test_cli_bad_entry_exits_2_and_writes_nothing(tmp_path: Path) -> None:
    scen = tmp_path / "bad.yaml"
    scen.write_text(yaml.safe_dump({"base": str(PARAMS / "sim3_zmp.yaml"), "disturbances": {"pushes": [
        {**PUSH, "duration_s": -0.1}]}}))
    out = tmp_path / "out"
    r = _walk(str(scen), "--engine", "mujoco", "--out", str(out), "--quiet")
    assert r.returncode == 2, r.stderr
    assert r.stderr == f"walk.py: error: {scen}: disturbances.pushes[0].duration_s: expected a duration in s > 0, " \
                       "got -0.1\n"
    assert r.stdout == "" and not out.exists()


@pytest.mark.slow
@pytest.mark.parametrize("example, engine, needle", [
    ("sim3_zmp_terrain.yaml", "pinocchio", "disturbances.terrain: the 'pinocchio' engine welds the feet"),
    ("sim3_zmp_push.yaml", "thesis", "disturbances.pushes: the 'thesis' engine welds the feet")])
def test_cli_refuses_pushes_and_terrain_on_welds(tmp_path: Path, example, engine, needle) -> None:
    out = tmp_path / "out"
    r = _walk(str(PARAMS / example), "--engine", engine, "--out", str(out), "--quiet", "--figures", "none")
    assert r.returncode == 2, r.stderr
    assert r.stderr.startswith(f"walk.py: error: {PARAMS / example}: ") and needle in r.stderr, r.stderr
    assert "Traceback" not in r.stderr and not out.exists()


@pytest.mark.slow
def test_cli_phase_beyond_the_walk_exits_2(tmp_path: Path) -> None:
    scen = tmp_path / "late.yaml"
    scen.write_text(yaml.safe_dump({"base": str(PARAMS / "sim3_zmp.yaml"), "disturbances": {"pushes": [
        {**PUSH, "start": {"phase": 40, "fraction": 0.5}}]}}))
    out = tmp_path / "out"
    r = _walk(str(scen), "--engine", "mujoco", "--out", str(out), "--quiet", "--figures", "none")
    assert r.returncode == 2, r.stderr
    assert "disturbances.pushes[0].start.phase: expected a phase number in [1, 17]" in r.stderr, r.stderr
    assert not out.exists()


def test_angle_direction_is_about_z_from_x(doc: dict) -> None:
    d = copy.deepcopy(doc)
    d["disturbances"] = {"pushes": [{**PUSH, "direction_deg": 30}]}
    f = parse_scenario(d, "x.yaml").disturbances.pushes[0].force
    # cos / sin of 30 deg times 100 N: one rounding each
    np.testing.assert_allclose(f, [100 * math.cos(math.pi / 6), 100 * math.sin(math.pi / 6), 0.0], rtol=1e-15)
