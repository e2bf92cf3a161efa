"""The compiled modules as a whole: numba's cache folder is keyed on every compiled source file, every module
defining compiled functions is in that key, entry points take grouped arguments, and the packed vectors' named
layouts (the stage log, the balance controller's targets) match what the compiled code writes and reads."""

from __future__ import annotations

import inspect
import re
import shutil
from pathlib import Path

import numpy as np

import humanoid_sim
from humanoid_sim import jit

PACKAGE = Path(humanoid_sim.__file__).resolve().parent


def test_the_cache_key_changes_with_any_compiled_source(tmp_path):
    """source_hash over a temporary copy of the compiled sources: stable, and different after a one-character edit
    of any one of them (a helper edited in one module moves the cache of every module that calls it)."""
    copy = tmp_path / "pkg"
    for rel in jit.COMPILED_SOURCES:
        (copy / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(PACKAGE / rel, copy / rel)
    base = jit.source_hash(copy)
    assert base == jit.source_hash(PACKAGE) == jit.CACHE_DIR.name
    for rel in jit.COMPILED_SOURCES:
        f = copy / rel
        text = f.read_text()
        f.write_text(text + "\n")
        assert jit.source_hash(copy) != base, rel
        f.write_text(text)
    assert jit.source_hash(copy) == base


def test_the_cache_folder_honours_numba_cache_dir(tmp_path):
    """NUMBA_CACHE_DIR, when set, is the parent of the per-hash folders; else the user cache folder."""
    assert jit.cache_root({"NUMBA_CACHE_DIR": str(tmp_path)}) == tmp_path / "humanoid_sim"
    assert jit.cache_root({"XDG_CACHE_HOME": str(tmp_path)}) == tmp_path / "humanoid_sim" / "numba"
    if jit.AVAILABLE:
        import numba

        assert Path(numba.config.CACHE_DIR) == jit.CACHE_DIR


def test_every_compiled_module_is_in_the_cache_key():
    """Every module of the package that decorates a function with @njit or @entry is listed in
    jit.COMPILED_SOURCES."""
    found = {str(p.relative_to(PACKAGE)) for p in PACKAGE.rglob("*.py")
             if re.search(r"^@(njit|entry)\b", p.read_text(), re.M)}
    assert found, "no compiled module found"
    assert found <= set(jit.COMPILED_SOURCES), found - set(jit.COMPILED_SOURCES)


def test_entry_points_take_grouped_arguments():
    """The functions Python calls take at most 12 parameters (records of arrays, not dozens of positionals)."""
    from humanoid_sim.sim import builds

    for name, module in builds.HOME.items():
        import importlib

        fn = getattr(importlib.import_module(module), name)
        py = getattr(fn, "py_func", fn)
        assert len(inspect.signature(py).parameters) <= 12, name


def test_the_stage_log_layout():
    """The log's named fields tile its 45 floats; StageLog reads them as views of the vector."""
    from humanoid_sim.kernel.log import LOG_FIELDS, LOG_SIZE, LOG_SLICES, StageLog

    assert LOG_SIZE == sum(n for _, n in LOG_FIELDS) == 45
    assert LOG_SLICES["status"] == slice(0, 1) and LOG_SLICES["hip_p"] == slice(4, 7)
    assert LOG_SLICES["R_2"] == slice(34, 43)
    lg = np.arange(float(LOG_SIZE))
    r = StageLog(lg)
    assert r.status == 0.0 and r.weld_position_error == 1.0 and r.residual == 3.0
    np.testing.assert_array_equal(r.R_17, np.arange(10.0, 19.0).reshape(3, 3))
    np.testing.assert_array_equal(r.toe_L_p, [22.0, 23.0, 24.0])
    assert np.shares_memory(r.hip_v, lg)


def test_the_balance_target_layout():
    """The target vector's named fields tile its 51 floats; pack_hip / pack_swing write them where the compiled
    stage reads them."""
    from humanoid_sim.controllers.balance import targets as T

    assert T.TARGET_SIZE == 51
    tgt = np.zeros(T.TARGET_SIZE)
    R = np.arange(9.0).reshape(3, 3)
    T.pack_hip(tgt, np.ones(3), np.full(6, 2.0), R, np.full(6, 3.0))
    T.pack_swing(tgt, np.full(3, 4.0), np.full(6, 5.0), R + 10, np.full(6, 6.0), 0.5, 0.2, -1.0)
    assert (tgt[T.T_HIP_P:T.T_HIP_P + 3] == 1).all() and (tgt[T.T_HIP_A:T.T_HIP_A + 6] == 3).all()
    np.testing.assert_array_equal(tgt[T.T_HIP_R:T.T_HIP_R + 9], R.ravel())
    np.testing.assert_array_equal(tgt[T.T_SWING_R:T.T_SWING_R + 9], (R + 10).ravel())
    assert (tgt[T.T_SWING_V:T.T_SWING_V + 6] == 5).all() and (tgt[T.T_SWING_A:T.T_SWING_A + 6] == 6).all()
    assert (tgt[T.T_RETURN_X], tgt[T.T_RETURN_TIME], tgt[T.T_LIFT0]) == (0.5, 0.2, -1.0)
    assert T.T_HEEL_ANGLE == 24 and T.T_LIFT0 == 50


def test_every_twin_names_its_reference():
    """Each compiled twin's module docstring names the reference it mirrors."""
    refs = {"kernel/kinematics.py": "Pinocchio", "kernel/contact.py": "humanoid_sim.dynamics.contact",
            "kernel/actuators.py": "Actuators.thesis_torques", "kernel/projection.py": "project_on_support",
            "kernel/log.py": "_stage0_record", "references/chapter3/compiled.py": "chapter3.generator",
            "controllers/thesis/compiled.py": "controllers.thesis.command",
            "controllers/balance/compiled.py": "qp_numpy", "engines/mujoco/compiled.py": "mujoco.contact"}
    import ast

    for rel, name in refs.items():
        doc = ast.get_docstring(ast.parse((PACKAGE / rel).read_text()))
        assert doc and name in doc.replace("\n", " "), rel


def test_entry_points_take_records_as_plain_tuples(hm):
    """The functions Python calls are jit.entry dispatchers: records cross into numba as plain tuples (numba types a
    NamedTuple about three times slower), so a call with records and one with the same values as plain tuples use
    one compilation, whose signature holds no NamedTuple; inside compiled code the entry points rebuild the
    records."""
    import importlib

    from numba import types

    from humanoid_sim.dynamics.contact.constraints import record_anchors
    from humanoid_sim.kernel.projection import project_on_support
    from humanoid_sim.kernel.support import SupportKernel
    from humanoid_sim.references.initial import initial_configuration
    from humanoid_sim.robot.phases import Phase
    from humanoid_sim.scenario.schema import load_scenario
    from humanoid_sim.sim import builds

    if not jit.AVAILABLE:
        return
    home = {**builds.HOME, "ssp_controller": builds.HOME["ssp_stage"]}
    for name in set(builds.ENTRY_POINTS) | {"ssp_controller", "ssp_dynamics"}:
        fn = getattr(importlib.import_module(home[name]), name)
        assert isinstance(fn, jit.RecordDispatcher), name
    sup = SupportKernel(hm)
    q = initial_configuration(hm, load_scenario(PACKAGE.parent / "scripts" / "params" / "sim1.yaml").path)
    v = np.zeros(hm.model.nv)
    anchors = record_anchors(hm.model, q, Phase.LFFSSP.contacts)
    anchor, foot, tree = sup.anchor(Phase.LFFSSP, anchors), sup._feet[Phase.LFFSSP], sup.tree.record
    qa, va = sup.project(Phase.LFFSSP, anchors, q, v)                 # records
    qb, vb = np.empty_like(q), np.empty_like(v)
    project_on_support(q, v, tuple(anchor), tuple(foot), tuple(tree), qb, vb)   # the same values, plain tuples
    assert qa.tobytes() == qb.tobytes() and va.tobytes() == vb.tobytes()
    sigs = [s for s in project_on_support.signatures if len(s) == 7]
    assert len(sigs) == 1, sigs
    assert not any(isinstance(a, types.NamedTuple) for a in sigs[0]), sigs[0]
    assert project_on_support.typeof_pyval(anchor) == project_on_support.typeof_pyval(tuple(anchor))
    assert isinstance(project_on_support.typeof_pyval(tree), types.BaseTuple)
    assert not isinstance(project_on_support.typeof_pyval(tree), types.NamedTuple)
