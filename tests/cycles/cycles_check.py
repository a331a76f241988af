# SPDX-License-Identifier: Apache-2.0
"""What the Cycles CTest scripts of this directory share: scripts/ on the import path (the harness's `evaluate`,
`garment`, `images`), the command line `SCRIPT.py OUT_DIR`, and how a script reports what it found wrong."""
from __future__ import annotations

import os
import sys
from typing import Callable

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "scripts"))


def report(name: str, problems: list[str]) -> int:
    """Each problem on stderr under the script's name; the exit status: 1 if there were any, else 0."""
    for p in problems:
        print(f"{name}: {p}", file=sys.stderr)
    return 1 if problems else 0


def run(main: Callable[[str], int], doc: str) -> None:
    """Exits with `main(OUT_DIR)` for the command line `SCRIPT.py OUT_DIR`, or with 2 and the usage (`doc`)."""
    if len(sys.argv) != 2:
        print(doc, file=sys.stderr)
        sys.exit(2)
    sys.exit(main(sys.argv[1]))
