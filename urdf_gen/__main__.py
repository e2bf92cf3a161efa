"""Command line: ``python -m urdf_gen MODEL.yaml -o OUT.urdf`` (stdout when -o is omitted).

Exit status 2 with a one-line message on invalid input; the output file is written atomically, so a failed
run never leaves a half-written URDF.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

from urdf_gen.emit import emit_urdf
from urdf_gen.spec import SpecError, load_spec


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m urdf_gen", description=__doc__.splitlines()[0])
    parser.add_argument("model", type=Path, help="body-parameter YAML, e.g. models/thesis_humanoid.yaml")
    parser.add_argument("-o", "--output", type=Path, help="URDF file to write (default: stdout)")
    args = parser.parse_args(argv)
    try:
        spec = load_spec(args.model)
        text = emit_urdf(spec)
    except SpecError as exc:
        print(f"urdf_gen: error: {exc}", file=sys.stderr)
        return 2
    if args.output is None:
        sys.stdout.write(text)
        return 0
    args.output.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=args.output.parent, prefix=f".{args.output.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", newline="\n") as fh:
            fh.write(text)
        os.replace(tmp, args.output)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    print(f"wrote {args.output} ({spec.total_mass:.3f} kg, {len(spec.joints)} joints)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
