#!/usr/bin/env python
"""Search robot and actuator designs: ``python scripts/optimize.py DESIGN.yaml [options]`` (see ``--help``)."""

import sys

from humanoid_sim.cli.optimize import main

if __name__ == "__main__":
    sys.exit(main())
