# SPDX-License-Identifier: Apache-2.0
"""Makes the add-on's pure-Python `geometry` subpackage importable without Blender.

`addon/__init__.py` imports bpy, so the add-on itself cannot be imported here. Its `geometry` subpackage
only uses relative imports, the standard library and numpy, so putting `<repo>/addon` on sys.path and
importing it as the top-level package `geometry` runs exactly the code Blender runs as
`neural_yarn.geometry`.
"""
import os
import sys

ADDON_DIR = os.path.abspath(os.path.join(os.path.dirname(__file__), os.pardir, os.pardir, "addon"))
if ADDON_DIR not in sys.path:
    sys.path.insert(0, ADDON_DIR)

import glob  # noqa: E402
import importlib.util  # noqa: E402

import pytest  # noqa: E402


def _in_blender_executable(module) -> bool:
    """True inside a Blender executable (tests/addon/run_in_blender.py), False for the bpy wheel."""
    return bool(module.app.binary_path)  # the wheel has none


@pytest.fixture(scope="session")
def bpy():
    """Blender: the bpy wheel (4.5 as a module, .venv/bin/python), which must have OSL in Cycles, or a
    Blender executable running tests/addon/run_in_blender.py (Debian's 3.4.1, no OSL)."""
    try:
        import bpy as module
    except ImportError as e:
        if os.environ.get("NY_REQUIRE_BPY"):
            pytest.fail(f"NY_REQUIRE_BPY is set but bpy cannot be imported ({e})")
        pytest.skip(f"the bpy wheel is not installed in this interpreter ({e}); run it with the bpy wheel's interpreter, .venv/bin/python")
    if not module.app.build_options.cycles_osl and not _in_blender_executable(module):
        pytest.fail("this bpy build has no OSL in Cycles (bpy.app.build_options.cycles_osl is False)")
    # The Cycles add-on compiles Script nodes with `oslquery`, which the wheel ships in Blender's own
    # site-packages rather than on sys.path.
    for path in glob.glob(os.path.join(module.utils.system_resource("PYTHON"), "lib", "python3*", "site-packages")):
        if path not in sys.path:
            sys.path.append(path)
    return module


@pytest.fixture(scope="session")
def has_osl(bpy) -> bool:
    return bool(bpy.app.build_options.cycles_osl)


@pytest.fixture
def needs_osl(has_osl, bpy):
    """Skips a test that needs Cycles OSL, which only a Blender executable without it may lack (the bpy
    wheel without OSL already failed in the `bpy` fixture)."""
    if not has_osl:
        pytest.skip(f"Blender {bpy.app.version_string} has no OSL in Cycles")


@pytest.fixture
def empty(bpy, addon):
    """An empty factory scene with the add-on registered."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return bpy.context.scene


@pytest.fixture(scope="session")
def addon(bpy):
    """The add-on, loaded from addon/ as the package `neural_yarn` and registered (as Blender would)."""
    if "neural_yarn" in sys.modules:
        return sys.modules["neural_yarn"]
    spec = importlib.util.spec_from_file_location("neural_yarn", os.path.join(ADDON_DIR, "__init__.py"),
                                                  submodule_search_locations=[ADDON_DIR])
    module = importlib.util.module_from_spec(spec)
    sys.modules["neural_yarn"] = module
    spec.loader.exec_module(module)
    module.register()
    yield module
    # Free every node of ours before its class goes (Blender 3.4 crashes at exit on nodes whose Python
    # class was unregistered while they existed).
    bpy.ops.wm.read_factory_settings(use_empty=True)
    module.unregister()
