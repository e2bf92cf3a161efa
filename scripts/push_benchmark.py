#!/usr/bin/env python
"""Run the push-recovery benchmark: ``python scripts/push_benchmark.py SCENARIO [options]`` (see ``--help``)."""

import sys

from humanoid_sim.cli.push import main

if __name__ == "__main__":
    sys.exit(main())
