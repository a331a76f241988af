# SPDX-License-Identifier: Apache-2.0
"""Runs the add-on's pytest suite inside a real Blender executable (Debian's Blender 3.4.1 in CI):

    blender -b --factory-startup --python-exit-code 1 -P tests/addon/run_in_blender.py -- [pytest args]

Blender's own Python (Debian: the system CPython 3.11) has no pytest; the project's .venv (same CPython
version) has it. Its site-packages go at the END of sys.path, so Blender's bpy (built in) and the numpy
Blender was built against (Debian's python3-numpy) keep precedence; only pure-Python pytest and its
dependencies come from the venv. Exit code: pytest's.
"""
import glob
import os
import sys

REPO = os.path.abspath(os.path.join(os.path.dirname(__file__), os.pardir, os.pardir))
for site in glob.glob(os.path.join(REPO, ".venv", "lib", "python3*", "site-packages")):
    if site not in sys.path:
        sys.path.append(site)
try:
    import pytest
except ImportError as e:
    print(f"run_in_blender: pytest not found ({e}); run scripts/setup.sh first", file=sys.stderr)
    sys.exit(2)

argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else [os.path.join(REPO, "tests", "addon")]
# -p no:cacheprovider: do not write .pytest_cache from inside Blender.
code = pytest.main(["-p", "no:cacheprovider", *argv])
sys.exit(int(code))
