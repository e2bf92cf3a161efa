#!/usr/bin/env python
"""Run a parameter sweep: ``python scripts/sweep.py SWEEP.yaml [options]`` (see ``--help``)."""

import sys

from humanoid_sim.cli.sweep import main

if __name__ == "__main__":
    sys.exit(main())
