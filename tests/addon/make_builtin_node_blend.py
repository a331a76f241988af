# SPDX-License-Identifier: Apache-2.0
"""Writes tests/data/builtin_neural_yarn_node.blend, the fixture of a file saved in a patched Blender with its
built-in Neural Yarn BSDF node (a plane whose material is that node, with a stand-in Text as its model). Run
in the patched Blender (scripts/build_blender.sh):

    build/blender-full/blender -b --factory-startup --python tests/addon/make_builtin_node_blend.py -- \
        tests/data/builtin_neural_yarn_node.blend
"""
import os
import sys

import bpy

OUT = sys.argv[sys.argv.index("--") + 1]
bpy.ops.wm.read_factory_settings(use_empty=True)
mat = bpy.data.materials.new("built-in yarn")
mat.use_nodes = True
t = mat.node_tree
for n in list(t.nodes):
    t.nodes.remove(n)
node = t.nodes.new("ShaderNodeBsdfNeuralYarn")
out = t.nodes.new("ShaderNodeOutputMaterial")
t.links.new(node.outputs["BSDF"], out.inputs["Surface"])
txt = bpy.data.texts.new("NY model stand-in.json")
txt.from_string("{}\n")
node.model = txt
bpy.ops.mesh.primitive_plane_add()
bpy.context.active_object.data.materials.append(mat)
bpy.ops.wm.save_as_mainfile(filepath=OUT, compress=True)
os._exit(0)
