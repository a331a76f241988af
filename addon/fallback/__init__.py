# SPDX-License-Identifier: GPL-3.0-or-later
"""The stock-Blender fallback of a neural yarn model, without bpy.

* schema: the one validation of a model file's "fallback" object (docs/file_formats.md), its lobes
  included, as strict as the C++ loader (cpp_core/src/model/fallback.cpp);
* lobes: what a validated built-in lobe becomes: its OSL closure and its Glossy-node inputs;
* osl: the OSL shader made from the tables (the template neural_yarn_fallback.osl.in lies beside it).

The add-on's stock-node body (fallback_nodes.py, bpy) and the command line osl/generate_osl.py use them.
"""
