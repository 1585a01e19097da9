"""``python -m adaptive_rig layout``: prints the payload layout as JSON (size, alignment, the
offset of every field, the type name), for comparison with the Rust structs."""

import json
import sys

from .contract import layout


def main(argv: list) -> int:
    """Runs the command in ``argv``; returns the exit status."""
    if argv[1:] == ["layout"]:
        print(json.dumps(layout(), indent=1))
        return 0
    print("usage: python -m adaptive_rig layout", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv))
