"""``python -m humanoid_sim.outputs.viewer --serve``: the live server's child process (see :mod:`.live`)."""

import sys

from humanoid_sim.outputs.viewer.live import _serve

if __name__ == "__main__":  # pragma: no cover - the live server's child process
    if sys.argv[1:] == ["--serve"]:
        _serve()
    else:
        sys.exit("usage: python -m humanoid_sim.outputs.viewer --serve  (starts a meshcat server on 127.0.0.1)")
