"""`python -m chunkc ...` runs the installed chunkc binary with the same arguments."""

from __future__ import annotations

import os
import subprocess
import sys

from chunkc import find_binary


def main() -> int:
    try:
        binary = find_binary()
    except FileNotFoundError as e:
        print(f"chunkc: {e}", file=sys.stderr)
        return 1
    if os.name == "nt":  # no exec on Windows: run it and pass its exit status on
        return subprocess.run([binary, *sys.argv[1:]]).returncode
    os.execv(binary, [binary, *sys.argv[1:]])
    return 0  # not reached


if __name__ == "__main__":
    sys.exit(main())
