# SPDX-License-Identifier: GPL-3.0-or-later
"""The "Neural Yarn" panel in the 3D viewport's sidebar: make or import yarns, twist plies, assign a
preset. Drawing only; the work is in operators.py."""

from __future__ import annotations

import bpy

from . import level_of_detail, nodes


class VIEW3D_PT_neural_yarn(bpy.types.Panel):
    bl_label = "Neural Yarn"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Neural Yarn"

    def draw(self, context):
        layout = self.layout
        col = layout.column(align=True)
        col.label(text="Yarn Curves")
        col.operator("neural_yarn.add_knit", icon="OUTLINER_OB_CURVES")
        col.operator("neural_yarn.add_weave", icon="OUTLINER_OB_CURVES")
        col.operator("neural_yarn.import_bcc", icon="IMPORT")
        col.operator("neural_yarn.import_leaf", icon="IMPORT")
        col = layout.column(align=True)
        col.label(text="Plies and Material")
        col.operator("neural_yarn.make_plies", icon="MOD_SCREW")
        col.operator_menu_enum("neural_yarn.assign_preset", "preset", icon="MATERIAL")
        self.draw_level_of_detail(context, layout)
        col = layout.column(align=True)
        col.label(text="Render")
        col.operator("neural_yarn.frame_render", icon="CAMERA_DATA")
        obj = context.active_object
        mat = obj.active_material if obj is not None else None
        if mat is not None and mat.node_tree is not None:
            found = nodes.unrenderable_builtin_nodes([mat])
            if found:
                box = layout.box()
                box.label(text=f"'{mat.name}': built-in Neural Yarn node of a patched Blender", icon="ERROR")
                box.label(text="It renders black here: convert it to the add-on's node there")
            for node in mat.node_tree.nodes:
                if node.bl_idname == nodes.NODE_IDNAME:
                    box = layout.box()
                    shown = {"NODES": "stock nodes", "OSL": "OSL script", "ERROR": "error"}.get(node.built, "not built")
                    box.label(text=f"Material '{mat.name}' (in stock Blender: {shown})")
                    box.context_pointer_set("node", node)
                    node.draw_buttons(context, box)
                    break
                if node.bl_idname == nodes.BUILTIN_IDNAME:
                    box = layout.box()
                    box.label(text=f"Material '{mat.name}' (built-in node: a patched Blender only)")
                    box.prop(node, "model", text="")
                    box.context_pointer_set("node", node)
                    box.operator("neural_yarn.convert_node", text="Convert to Add-on Node").to = "ADDON"
                    break
        scene = context.scene
        if scene.render.engine == "CYCLES" and bpy.app.build_options.cycles_osl and not scene.cycles.shading_system:
            layout.label(text="Tip: Open Shading Language (CPU) gives the OSL fallback", icon="INFO")


    @staticmethod
    def draw_level_of_detail(context, layout):
        col = layout.column(align=True)
        col.label(text="Level of Detail")
        col.prop(context.scene, "neural_yarn_lod", text="Scene")
        obj = context.active_object
        obj = level_of_detail.yarn_object_of(obj, context.scene) if obj is not None else None  # plies, surface: yarns
        if obj is not None and obj.type == "CURVES":
            row = col.row(align=True)
            row.active = context.scene.neural_yarn_lod == "OBJECT"
            row.prop(obj.neural_yarn, "level", text=obj.name)
            col.prop(obj.neural_yarn, "plies")
            col.prop(obj.neural_yarn, "split")  # Auto's (the object's or the scene's)
            if obj.neural_yarn.chosen:
                col.label(text=f"Applied: {obj.neural_yarn.chosen}", icon="INFO")
        col.operator("neural_yarn.apply_lod", icon="MOD_DECIM")


def register():
    bpy.utils.register_class(VIEW3D_PT_neural_yarn)


def unregister():
    bpy.utils.unregister_class(VIEW3D_PT_neural_yarn)
