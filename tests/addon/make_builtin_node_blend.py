# SPDX-License-Identifier: Apache-2.0
"""Writes tests/data/builtin_neural_yarn_node.blend, the fixture of a file saved in a patched Blender with its
built-in Neural Yarn BSDF node (a plane whose material is that node, with a stand-in Text as its model, and a
second plane whose material holds it inside a node group). Run
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
# The same node inside a node group, which a second material uses.
group = bpy.data.node_groups.new("yarn group", "ShaderNodeTree")
group.interface.new_socket("BSDF", in_out="OUTPUT", socket_type="NodeSocketShader")
inner = group.nodes.new("ShaderNodeBsdfNeuralYarn")
inner.model = txt
g_out = group.nodes.new("NodeGroupOutput")
group.links.new(inner.outputs["BSDF"], g_out.inputs["BSDF"])
mat2 = bpy.data.materials.new("grouped yarn")
mat2.use_nodes = True
t2 = mat2.node_tree
for n in list(t2.nodes):
    t2.nodes.remove(n)
g = t2.nodes.new("ShaderNodeGroup")
g.node_tree = group
out2 = t2.nodes.new("ShaderNodeOutputMaterial")
t2.links.new(g.outputs["BSDF"], out2.inputs["Surface"])
bpy.ops.mesh.primitive_plane_add(location=(3.0, 0.0, 0.0))
bpy.context.active_object.data.materials.append(mat2)
bpy.ops.wm.save_as_mainfile(filepath=OUT, compress=True)
os._exit(0)
