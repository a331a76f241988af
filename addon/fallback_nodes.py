# SPDX-License-Identifier: GPL-3.0-or-later
"""The inside of the Neural Yarn BSDF node group: the fallbacks that stock Cycles can render.

Two interchangeable bodies, both driven by the model file's view-dependent "fallback" tables
(docs/file_formats.md, osl/README.md):

* OSL: a Script node holding the shader that fallback/osl.py makes from the model (CPU, or OptiX);
* NODES: the same computation in stock shader nodes, for SVM (GPU, or Blender without OSL): the view
  direction in the yarn frame from the Geometry node, the tables as four small float images looked up
  bilinearly between cell centres (Linear + Extend, exactly the OSL shader's lookup), and the same
  built-in closures with the same weights and roughnesses:

      P_T transparent + Tint sum_k W_k lobe_k,  transparent on back faces,

with the lobes GGX reflections about the surface fibers' tangent (Glossy BSDF, GGX, anisotropic),
diffuse and translucent, and their RGB weights W_k fitted per view to the model (model/fallback.h).
Both return, under uniform light, the model's albedo for every view (tests/addon/). The native closure of
a patched Cycles replaces the whole group (cycles_patch/).
"""

from __future__ import annotations

import dataclasses
import glob
import hashlib
import math
import os
import sys

import bpy

from . import model_io
from .fallback import lobes as fallback_lobes
from .fallback import osl as fallback_osl

FALLBACK_MODES = ("OSL", "NODES")
GROUP_INPUT_TINT = "Tint"
GROUP_OUTPUT = "BSDF"


# ---------------------------------------------------------------------------------------------------------
# Group interface (Blender 4.0 replaced tree.inputs/outputs by tree.interface)


def ensure_interface(tree) -> None:
    """Gives a group tree its Tint input and BSDF output (once)."""
    if hasattr(tree, "interface"):
        names = {(item.in_out, item.name) for item in tree.interface.items_tree if item.item_type == "SOCKET"}
        if ("INPUT", GROUP_INPUT_TINT) not in names:
            s = tree.interface.new_socket(GROUP_INPUT_TINT, in_out="INPUT", socket_type="NodeSocketColor")
            s.default_value = (1.0, 1.0, 1.0, 1.0)
        if ("OUTPUT", GROUP_OUTPUT) not in names:
            tree.interface.new_socket(GROUP_OUTPUT, in_out="OUTPUT", socket_type="NodeSocketShader")
    else:  # Blender 3.x
        if GROUP_INPUT_TINT not in tree.inputs:
            s = tree.inputs.new("NodeSocketColor", GROUP_INPUT_TINT)
            s.default_value = (1.0, 1.0, 1.0, 1.0)
        if GROUP_OUTPUT not in tree.outputs:
            tree.outputs.new("NodeSocketShader", GROUP_OUTPUT)


# ---------------------------------------------------------------------------------------------------------
# Data blocks shared by every material that uses the same model


def _key(model: model_io.YarnModel) -> str:
    """The name stem of a model's images and OSL texts: a hash of the whole model file, so that two models
    share data blocks only when everything they are made of (fallback tables included) is the same."""
    return f"NY {model.preset_name} {hashlib.sha1(model.text.encode('utf-8')).hexdigest()[:12]}"


def table_image(name: str, values: list, theta_bins: int, phi_bins: int, channels: int):
    """A float image of phi_bins x theta_bins pixels (row i = theta cell i) holding a table; a scalar
    table goes into all three colour channels. Packed into the .blend (as OpenEXR: floats survive)."""
    img = bpy.data.images.get(name)
    if img is not None and tuple(img.size) == (phi_bins, theta_bins):
        return img
    if img is not None:
        bpy.data.images.remove(img)
    img = bpy.data.images.new(name, phi_bins, theta_bins, alpha=False, float_buffer=True)
    # Colour space first: changing it regenerates a generated image's pixels.
    img.colorspace_settings.name = "Non-Color"
    img.alpha_mode = "NONE"
    px = [1.0] * (theta_bins * phi_bins * 4)
    for k in range(theta_bins * phi_bins):
        for c in range(3):
            px[4 * k + c] = values[k * channels + (c if channels == 3 else 0)]
    img.pixels.foreach_set(px)
    img.file_format = "OPEN_EXR"  # packed as 32-bit float OpenEXR
    img.pack()
    return img


def osl_text(model: model_io.YarnModel, tilt: float):
    """The Text data block holding the model's OSL fallback for a twist tilt (radians)."""
    tables = dataclasses.replace(model.fallback, twist_tilt_rad=tilt)
    source = fallback_osl.shader_source(tables, model.preset_name, str(model.data.get("code_version", "?")))
    name = f"{_key(model)} {math.degrees(tilt):.2f}.osl"
    text = bpy.data.texts.get(name) or bpy.data.texts.new(name)
    if text.as_string() != source:
        text.from_string(source)
    return text


# ---------------------------------------------------------------------------------------------------------
# A small node-graph builder: sockets or constants in, sockets out


class _Graph:
    def __init__(self, tree):
        self.tree, self.nodes, self.links = tree, tree.nodes, tree.links
        self.column = 0

    def node(self, kind: str, x: float | None = None, y: float = 0.0, **props):
        n = self.nodes.new(kind)
        for k, v in props.items():
            setattr(n, k, v)
        n.location = (x if x is not None else 200.0 * self.column, y)
        return n

    def feed(self, socket_in, value) -> None:
        if isinstance(value, bpy.types.NodeSocket):
            self.links.new(value, socket_in)
        else:
            socket_in.default_value = value

    def math(self, op: str, a, b=None, y=0.0):
        n = self.node("ShaderNodeMath", y=y, operation=op)
        self.feed(n.inputs[0], a)
        if b is not None:
            self.feed(n.inputs[1], b)
        return n.outputs[0]

    def vmath(self, op: str, a, b=None, *, scale=None, y=0.0):
        n = self.node("ShaderNodeVectorMath", y=y, operation=op)
        self.feed(n.inputs[0], a)
        if b is not None:
            self.feed(n.inputs[1], b)
        if scale is not None:
            self.feed(n.inputs["Scale"], scale)
        return n.outputs["Value"] if op == "DOT_PRODUCT" else n.outputs["Vector"]

    def bsdf(self, kind: str, color, y=0.0, **inputs):
        n = self.node(kind, y=y)
        self.feed(n.inputs["Color"], color)
        for k, v in inputs.items():
            self.feed(n.inputs[k], v)
        return n

    def add(self, a, b, y=0.0):
        n = self.node("ShaderNodeAddShader", y=y)
        self.links.new(a, n.inputs[0])
        self.links.new(b, n.inputs[1])
        return n.outputs[0]


def _clear(tree) -> tuple:
    for n in list(tree.nodes):
        tree.nodes.remove(n)
    g_in = tree.nodes.new("NodeGroupInput")
    g_out = tree.nodes.new("NodeGroupOutput")
    g_in.location = (-400.0, 0.0)
    return g_in, g_out


def _ensure_oslquery() -> None:
    """Cycles compiles Script nodes with the `oslquery` module; Blender puts its own site-packages on
    sys.path, the bpy wheel does not (it ships the module there all the same)."""
    try:
        import oslquery  # noqa: F401
        return
    except ImportError:
        pass
    root = bpy.utils.system_resource("PYTHON")
    for path in sorted(glob.glob(os.path.join(root, "lib", "python3*", "site-packages"))):
        if path not in sys.path:
            sys.path.append(path)


def build_osl(tree, model: model_io.YarnModel, tilt: float) -> None:
    """Fills the group with the Script node of the model's OSL fallback. Compiles it when this Blender
    has OSL (so that the node gets its sockets now, not at the first render)."""
    if bpy.app.build_options.cycles_osl:
        _ensure_oslquery()  # before the script is set: setting it makes Cycles compile it
    ensure_interface(tree)
    g_in, g_out = _clear(tree)
    script = tree.nodes.new("ShaderNodeScript")
    script.mode = "INTERNAL"
    script.script = osl_text(model, tilt)
    script.location = (0.0, 0.0)
    g_out.location = (300.0, 0.0)
    if bpy.app.build_options.cycles_osl:
        import cycles.osl  # Cycles' own add-on module

        reports = []
        if not cycles.osl.update_script_node(script, lambda kind, msg: reports.append(msg)):
            raise RuntimeError("the generated OSL fallback did not compile: " + "; ".join(map(str, reports)))
    if "Tint" in script.inputs:
        tree.links.new(g_in.outputs[GROUP_INPUT_TINT], script.inputs["Tint"])
    if "BSDF" in script.outputs:
        tree.links.new(script.outputs["BSDF"], g_out.inputs[GROUP_OUTPUT])


def build_nodes(tree, model: model_io.YarnModel, tilt: float) -> None:
    """Fills the group with the stock-node fallback (the OSL template's computation, node for node)."""
    ensure_interface(tree)
    g_in, g_out = _clear(tree)
    fb = model.fallback
    key = _key(model)
    K = len(fb.lobes)
    cells = fb.theta_bins * fb.phi_bins
    p_t = table_image(f"{key} P_T", fb.P_T, fb.theta_bins, fb.phi_bins, 1)
    weights = [table_image(f"{key} W{k}", [fb.W[(c * K + k) * 3 + ch] for c in range(cells) for ch in range(3)],
                           fb.theta_bins, fb.phi_bins, 3) for k in range(K)]

    g = _Graph(tree)
    geo = g.node("ShaderNodeNewGeometry", x=-200.0)
    n = geo.outputs["Normal"]
    wv = geo.outputs["Incoming"]  # toward the viewer, like OSL's I
    # Yarn frame: x = tangent (dPdu made perpendicular to n), z = n, y = n x t.
    g.column = 1
    dpdu = geo.outputs["Tangent"]
    t = g.vmath("NORMALIZE", g.vmath("SUBTRACT", dpdu, g.vmath("SCALE", n, scale=g.vmath("DOT_PRODUCT", dpdu, n))))
    y = g.vmath("CROSS_PRODUCT", n, t, y=-200.0)
    g.column = 2
    wx = g.vmath("DOT_PRODUCT", wv, t)
    wy = g.vmath("DOT_PRODUCT", wv, y, y=-200.0)
    wz = g.vmath("DOT_PRODUCT", wv, n, y=-400.0)
    g.column = 3
    theta = g.math("ARCSINE", g.math("MINIMUM", g.math("MAXIMUM", wx, -1.0), 1.0))
    phi = g.math("ARCTAN2", wy, wz, y=-200.0)
    # Texture coordinates: s = phi / pi + 1/2 (columns), t = theta / pi + 1/2 (rows): cell centres at texel
    # centres, so Linear + Extend is the OSL shader's bilinear lookup (ny_cell) with edge clamping.
    g.column = 4
    uv = g.node("ShaderNodeCombineXYZ")
    g.feed(uv.inputs[0], g.math("ADD", g.math("MULTIPLY", phi, 1.0 / math.pi), 0.5))
    g.feed(uv.inputs[1], g.math("ADD", g.math("MULTIPLY", theta, 1.0 / math.pi), 0.5))
    g.column = 5
    tex = []
    for k, img in enumerate([p_t] + weights):
        node = g.node("ShaderNodeTexImage", y=-300.0 * k, image=img, interpolation="Linear", extension="EXTEND")
        g.feed(node.inputs["Vector"], uv.outputs[0])
        tex.append(node.outputs["Color"])

    # The surface fibers' tangent t_f = cos(tilt) t - sin(tilt) y: the GGX lobes' alpha_x runs along it.
    ct, st = math.cos(tilt), math.sin(tilt)
    g.column = 6
    t_f = g.vmath("NORMALIZE", g.vmath("SUBTRACT", g.vmath("SCALE", t, scale=ct), g.vmath("SCALE", y, scale=st)),
                  y=-300.0 * (K + 1))
    tint = g_in.outputs[GROUP_INPUT_TINT]
    body = None
    for k, lobe in enumerate(fb.lobes):
        g.column = 7
        color = g.vmath("MULTIPLY", tint, tex[k + 1], y=-300.0 * k)
        g.column = 8
        if lobe["closure"] == "ggx":
            roughness, anisotropy = fallback_lobes.glossy_node_inputs(lobe["alpha_x"], lobe["alpha_y"])
            node = g.bsdf("ShaderNodeBsdfAnisotropic", color, y=-300.0 * k, Roughness=roughness,
                          Anisotropy=anisotropy, Rotation=0.0, Tangent=t_f)
            node.distribution = "GGX"
        else:
            node = g.bsdf("ShaderNodeBsdfDiffuse" if lobe["closure"] == "diffuse" else "ShaderNodeBsdfTranslucent",
                          color, y=-300.0 * k)
        g.column = 9
        body = node.outputs[0] if body is None else g.add(body, node.outputs[0], y=-300.0 * k)
    g.column = 10
    clear = g.bsdf("ShaderNodeBsdfTransparent", tex[0], y=-300.0 * K)
    front = g.add(body, clear.outputs[0])
    # The thick curve's inside is transparent, as in the native closure.
    back = g.node("ShaderNodeBsdfTransparent", y=-400.0)
    g.column = 11
    mix = g.node("ShaderNodeMixShader")
    g.feed(mix.inputs["Fac"], geo.outputs["Backfacing"])
    tree.links.new(front, mix.inputs[1])
    tree.links.new(back.outputs[0], mix.inputs[2])
    g_out.location = (200.0 * 12, 0.0)
    tree.links.new(mix.outputs[0], g_out.inputs[GROUP_OUTPUT])


def build(tree, model: model_io.YarnModel, mode: str, tilt: float) -> None:
    if mode == "OSL":
        build_osl(tree, model, tilt)
    elif mode == "NODES":
        build_nodes(tree, model, tilt)
    else:
        raise ValueError(f"unknown fallback mode {mode!r} (one of {', '.join(FALLBACK_MODES)})")
