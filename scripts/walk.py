#!/usr/bin/env python
"""Walk a scenario: ``python scripts/walk.py [SCENARIO] [options]`` (see ``--help``)."""

import sys

from humanoid_sim.cli.walk import main

if __name__ == "__main__":
    sys.exit(main())
