#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Bake a neural yarn model file into the OSL fallback shader for stock Cycles:

    python3 osl/generate_osl.py models/fleece.json -o fleece_fallback.osl

A command line over the add-on's fallback package (addon/fallback/: the tables' validation, the template,
the generator), which needs neither Blender nor anything beyond Python's standard library. The model file
must carry the view-dependent fallback tables (`neuralyarn bake`, `fit` and `fallback` write them).
"""

from __future__ import annotations

import argparse
import json
import os
import sys

# The add-on directory holds the package; this entry point is the only place that names it.
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir, "addon"))
from fallback.osl import generate_osl  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="Generate the OSL fallback shader of a neural yarn model file.")
    ap.add_argument("model", help="model file (.json) with fallback tables")
    ap.add_argument("-o", "--out", help="OSL file to write (default: standard output)")
    ap.add_argument("--name", help="shader name (default: neural_yarn_fallback_<preset>)")
    args = ap.parse_args(argv)
    try:
        with open(args.model, encoding="utf-8") as f:
            model = json.load(f)
        src = generate_osl(model, shader_name=args.name)
    except (OSError, ValueError) as e:  # json.JSONDecodeError is a ValueError
        print(f"generate_osl: model file '{args.model}': {e}", file=sys.stderr)
        return 1
    if args.out:
        tmp = args.out + ".tmp"
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(src)
        os.replace(tmp, args.out)
        print(f"wrote {args.out}")
    else:
        sys.stdout.write(src)
    return 0


if __name__ == "__main__":
    sys.exit(main())
