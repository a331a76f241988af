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


def plane_with_surface(material: str, make_node):
    """A plane (one more along x) whose material's surface is the BSDF output of `make_node(tree)`."""
    mat = bpy.data.materials.new(material)
    mat.use_nodes = True
    mat.node_tree.nodes.clear()
    bsdf = make_node(mat.node_tree).outputs["BSDF"]
    mat.node_tree.links.new(bsdf, mat.node_tree.nodes.new("ShaderNodeOutputMaterial").inputs["Surface"])
    bpy.ops.mesh.primitive_plane_add(location=(3.0 * len(bpy.data.materials), 0.0, 0.0))
    bpy.context.active_object.data.materials.append(mat)


def builtin_node(tree):
    node = tree.nodes.new("ShaderNodeBsdfNeuralYarn")
    node.model = txt
    return node


def group_node(tree):
    node = tree.nodes.new("ShaderNodeGroup")
    node.node_tree = group
    return node


bpy.ops.wm.read_factory_settings(use_empty=True)
txt = bpy.data.texts.new("NY model stand-in.json")
txt.from_string("{}\n")
plane_with_surface("built-in yarn", builtin_node)
# The same node inside a node group, which a second material uses.
group = bpy.data.node_groups.new("yarn group", "ShaderNodeTree")
group.interface.new_socket("BSDF", in_out="OUTPUT", socket_type="NodeSocketShader")
group.links.new(builtin_node(group).outputs["BSDF"], group.nodes.new("NodeGroupOutput").inputs["BSDF"])
plane_with_surface("grouped yarn", group_node)
bpy.ops.wm.save_as_mainfile(filepath=OUT, compress=True)
os._exit(0)
