"""The numba decorator of every compiled module, and where numba caches their machine code.

numba's disk cache is keyed on the source file holding a jitted function and on nothing it imports: a function
compiled against a helper of another module keeps running the helper's old code after that file is edited.  So
the cache folder here is keyed on a SHA-256 of every compiled source file (:data:`COMPILED_SOURCES`, plus this
file, which holds the compile options): editing any of them moves every compiled function to a fresh folder,
where it is compiled anew.  The folder is set in ``numba.config.CACHE_DIR`` when this module is imported, which
every compiled module does before its first ``@njit``:

- ``$NUMBA_CACHE_DIR/humanoid_sim/<hash>`` when the user set NUMBA_CACHE_DIR (taken as the parent),
- else ``$XDG_CACHE_HOME/humanoid_sim/numba/<hash>`` (``~/.cache/humanoid_sim/numba/<hash>`` by default).

Stale folders of older sources are left in place (a few MB each); deleting them is always safe.

The functions Python calls with the records of :mod:`humanoid_sim.kernel.records` (NamedTuples of arrays) are
compiled by :func:`entry` instead of :func:`njit`: numba types every argument of every call, and a NamedTuple costs
its dispatcher about three times what the same values cost as a plain tuple, so the records cross into numba as
plain tuples (see :func:`entry`).

This is a root module on purpose: the compiled twins live in several layers (``references``, ``kernel``,
``controllers``, ``engines``) and all of them may import it.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path
from typing import Any

try:
    import numba as _numba
    from numba import njit as _numba_njit
except ImportError:  # pragma: no cover - the simulator then takes the NumPy reference paths
    _numba = None
    _numba_njit = None

AVAILABLE = _numba_njit is not None
"""Whether numba is installed."""

PACKAGE = Path(__file__).resolve().parent
COMPILED_SOURCES = (
    "jit.py",
    "kernel/linalg.py",
    "kernel/kinematics.py",
    "kernel/contact.py",
    "kernel/actuators.py",
    "kernel/log.py",
    "kernel/projection.py",
    "references/chapter3/compiled.py",
    "controllers/thesis/compiled.py",
    "controllers/balance/compiled.py",
    "engines/mujoco/compiled.py",
)
"""Every module of the package that defines ``@njit`` functions (paths relative to the package), and this one.
A new compiled module must be added here, or an edit of it would not move the cache (``tests/test_kernel.py``
checks that every module calling :func:`njit` is listed)."""


def source_hash(package: Path = PACKAGE, sources: tuple[str, ...] = COMPILED_SOURCES) -> str:
    """SHA-256 (hex, first 16 characters) over the names and bytes of ``sources`` under ``package``."""
    h = hashlib.sha256()
    for rel in sources:
        h.update(rel.encode())
        h.update(b"\0")
        h.update((package / rel).read_bytes())
        h.update(b"\0")
    return h.hexdigest()[:16]


def cache_root(environ: os._Environ | dict | None = None) -> Path:
    """The folder holding one cache folder per source hash (see the module docstring)."""
    env = os.environ if environ is None else environ
    if env.get("NUMBA_CACHE_DIR"):
        return Path(env["NUMBA_CACHE_DIR"]) / "humanoid_sim"
    base = Path(env["XDG_CACHE_HOME"]) if env.get("XDG_CACHE_HOME") else Path.home() / ".cache"
    return base / "humanoid_sim" / "numba"


CACHE_DIR = cache_root() / source_hash()
"""numba's cache folder of this source tree."""

if _numba is not None:
    _numba.config.CACHE_DIR = str(CACHE_DIR)


_OPTIONS: dict[str, Any] = {"nogil": True, "error_model": "numpy"}
"""numba's options of every compiled function (besides nopython and the disk cache)."""


def njit(fn):
    """Compile ``fn`` with numba (nopython, cached on disk in :data:`CACHE_DIR`, no fastmath: IEEE operations in the
    written order, NumPy's error model: a division by zero gives inf / nan as in the reference paths instead of
    raising), or return it unchanged when numba is missing."""
    if _numba_njit is None:
        return fn
    return _numba_njit(cache=True, **_OPTIONS)(fn)


if _numba is not None:
    from numba.core.registry import CPUDispatcher

    class RecordDispatcher(CPUDispatcher):
        """numba's dispatcher of an :func:`entry` function: every tuple argument of a call from Python (a record of
        :mod:`humanoid_sim.kernel.records`, or a plain tuple) goes on as a plain tuple, and :meth:`typeof_pyval`
        types it as one (``humanoid_sim.sim.builds`` compiles a call's signature from it without running the call).
        Inside compiled code the dispatcher is numba's own: an entry point calling another one passes its plain
        tuples on, and both share one compilation."""

        def __call__(self, *args):
            return super().__call__(*[tuple(a) if isinstance(a, tuple) else a for a in args])

        def typeof_pyval(self, val):
            return super().typeof_pyval(tuple(val) if isinstance(val, tuple) else val)


def entry(fn):
    """Compile ``fn`` as :func:`njit` does, as an entry point: a function Python calls with records (NamedTuples of
    arrays and scalars, :mod:`humanoid_sim.kernel.records`).

    numba's dispatcher types each argument of each call in C, from a key it writes for the value; a NamedTuple's key
    spells its class and field names, which makes it about three times as costly as the same values in a plain tuple
    (ten arrays: 1.3 us against 0.7 us a call; the thesis stage's eleven arguments, 77 arrays and scalars in nine
    records: 10 us against 4 us, measured; ``docs/notes/2026-11-26-speed.md``).  So the records cross into numba as
    plain tuples in ``_fields`` order (:class:`RecordDispatcher` converts them; callers keep passing records), and
    ``fn`` rebuilds them on its first lines (``st = State(*st)``, which costs nothing in the compiled code).  Returns
    ``fn`` unchanged when numba is missing (the rebuild then unpacks the records themselves)."""
    if _numba is None or getattr(_numba.config, "DISABLE_JIT", False):
        return fn
    disp = RecordDispatcher(py_func=fn, locals={}, targetoptions={"nopython": True, "boundscheck": None, **_OPTIONS})
    disp.enable_caching()
    return disp


def cache_present() -> bool:
    """Whether numba's disk cache of this source tree seems to exist (index files in :data:`CACHE_DIR`): when not, the
    first use compiles it.  A heuristic for a progress message only."""
    return CACHE_DIR.is_dir() and any(CACHE_DIR.rglob("*.nbi"))
