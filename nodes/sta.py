"""STA as a compositor node group: ``core.techniques.sta.technique`` for one light, out of Math and Vector Math nodes.

Per pixel, exactly the arithmetic of ``core.techniques.sta.technique.sta`` (its docstring has the formulas): the light
direction and irradiance of one light (sun, point, spot or area, as ``core.optics.lights.light_at``),
L_T = normalize(L + distortion N), T_dir = scale max(0, V . -L_T)^power, and
albedo x light colour x (E / pi) x t x (T_dir + ambient) on the mask. Several lights: chain one
group per light (its Image output into the next one's Image input); ``setup.build_chain``
does that for the scene's lights.

Inputs are the passes (Diffuse Color, Normal, Position, the thickness AOV), the mask, STA's
parameters under the names, defaults and descriptions of its spec (``core.techniques.sta.technique.TECHNIQUE``),
the light (the fields of ``core.scene.scene.Light``, prefixed ``light_``) and the camera (for the view
vector). Outputs: ``Image`` = Image + SSS, and ``SSS``, the added translucency.

Not as in NumPy: a pixel with a NaN or infinite input gives NaN here (``core.techniques.sta.technique`` gives 0).
"""

from __future__ import annotations

import math

from ..core.optics.lights import THICKNESS_CONVENTIONS
from ..core.scene.scene import CAMERA_TYPES, LIGHT_TYPES
from ..core.techniques.sta.technique import TECHNIQUE
from . import _graph
from ._graph import Interface, Socket

GROUP_NAME = "SSS Lab STA"
#: Version of the graph below; a group built by another version is rebuilt by ``ensure_sta_group``.
VERSION = 1

_LEN_EPS = 1e-6  # core.techniques.sta.technique._EPS: below this |L + d N| has no direction and the light adds nothing

#: STA's number parameters as group inputs, made from its parameter specs (the other, the
#: falloff, is not modelled by the group: the compositor set-up warns).
PARAM_SOCKETS = [Socket(p.name, "FLOAT", p.default, p.description, p.min) for p in TECHNIQUE.params if p.type is float]

INTERFACE = Interface(
    inputs=[
        Socket("Image", "COLOR", (0.0, 0.0, 0.0, 1.0), "The image to add the translucency to (Combined)"),
        Socket("albedo", "COLOR", (0.8, 0.8, 0.8, 1.0), "Diffuse Color pass"),
        Socket("normal", "VECTOR", (0.0, 0.0, 1.0), "Normal pass (world space)"),
        Socket("position", "VECTOR", (0.0, 0.0, 0.0), "Position pass (world space)"),
        Socket("thickness", "FLOAT", 1.0, "Thickness AOV (see thickness_convention)", 0.0, 1.0),
        Socket("mask", "FLOAT", 1.0, "1 on the pixels that get translucency, 0 elsewhere", 0.0, 1.0),
        *PARAM_SOCKETS,
        Socket(
            "thickness_convention",
            "MENU",
            "translucency",
            "translucency: 1 = thin (STA's); thickness: 1 = thick (read as 1 - t)",
            items=THICKNESS_CONVENTIONS,
        ),
        Socket("light_type", "MENU", "SUN", "Kind of light", items=LIGHT_TYPES),
        Socket("light_direction", "VECTOR", (0.0, 0.0, -1.0), "Direction the light shines in (its local -Z)"),
        Socket("light_position", "VECTOR", (0.0, 0.0, 0.0), "Light position (point, spot, area)"),
        Socket("light_color", "COLOR", (1.0, 1.0, 1.0, 1.0), "Light colour"),
        Socket("light_energy", "FLOAT", 10.0, "Sun: Strength (W/m^2); others: Power (W)", 0.0),
        Socket("light_spot_size", "FLOAT", math.radians(45.0), "Spot cone angle", 0.0, math.pi, subtype="ANGLE"),
        Socket("light_spot_blend", "FLOAT", 0.15, "Spot blend", 0.0, 1.0),
        Socket("camera_type", "MENU", "PERSP", "Perspective or orthographic camera", items=CAMERA_TYPES),
        Socket("camera_position", "VECTOR", (0.0, 0.0, 0.0), "Camera position (perspective view vector)"),
        Socket("camera_forward", "VECTOR", (0.0, 0.0, -1.0), "Camera view direction (orthographic view vector)"),
    ],
    outputs=[
        Socket("Image", "COLOR", description="Image + SSS"),
        Socket("SSS", "COLOR", description="The translucency STA adds"),
    ],
)


def ensure_sta_group(name: str = GROUP_NAME):
    """The STA node group ``name``, built or rebuilt in place (idempotent); returns it."""
    group = _graph.ensure_group(name, INTERFACE, {"technique": "sta", "version": VERSION})
    g = _graph.Graph(group)
    n = g.vmath("NORMALIZE", g.inp("normal"), label="N")
    p = g.inp("position")
    light_dir = g.vmath("NORMALIZE", g.inp("light_direction"), label="light direction")
    view_persp = g.vmath("NORMALIZE", g.vsub(g.inp("camera_position"), p), label="V perspective")
    view_ortho = g.vscale(g.vmath("NORMALIZE", g.inp("camera_forward")), -1.0, label="V orthographic")

    g.column()
    delta = g.vsub(g.inp("light_position"), p, label="to light")
    dist = g.vmath("LENGTH", delta)
    to_point = g.vmath("NORMALIZE", delta, label="L point")
    to_sun = g.vscale(light_dir, -1.0, label="L sun")
    r2 = g.max(g.mul(dist, dist), 1e-12, label="r^2")
    energy = g.inp("light_energy")

    g.column()
    e_point = g.div(energy, g.mul(r2, 4.0 * math.pi), label="E point")
    cos_angle = g.vmath("DOT_PRODUCT", g.vscale(to_point, -1.0), light_dir, label="cos angle")
    half = g.math("COSINE", g.mul(g.inp("light_spot_size"), 0.5), label="cos half cone")
    smooth = g.mul(g.sub(1.0, half), g.inp("light_spot_blend"), label="blend width")
    x = g.clamp01(g.div(g.sub(cos_angle, half), g.max(smooth, 1e-30)))
    cone = g.mul(g.mul(x, x), g.sub(3.0, g.mul(x, 2.0)), label="smoothstep")

    g.column()
    e_spot = g.mul(e_point, cone, label="E spot")
    e_area = g.div(g.mul(energy, g.max(cos_angle, 0.0)), g.mul(r2, math.pi), label="E area")
    kind = g.inp("light_type")
    to_light = g.menu("VECTOR", kind, {"SUN": to_sun, "POINT": to_point, "SPOT": to_point, "AREA": to_point}, "L")
    irradiance = g.menu("FLOAT", kind, {"SUN": energy, "POINT": e_point, "SPOT": e_spot, "AREA": e_area}, "E")
    view = g.menu("VECTOR", g.inp("camera_type"), {"PERSP": view_persp, "ORTHO": view_ortho}, "V")

    g.column()
    bent = g.vadd(to_light, g.vscale(n, g.inp("distortion")), label="L + d N")
    bent_len = g.vmath("LENGTH", bent)
    lt = g.vmath("NORMALIZE", bent, label="L_T")
    vdot = g.mul(g.vmath("DOT_PRODUCT", view, lt), -1.0, label="V . -L_T")
    has_dir = g.math("GREATER_THAN", bent_len, _LEN_EPS, label="has direction")

    g.column()
    lobe = g.mul(g.math("GREATER_THAN", vdot, 0.0), g.math("POWER", g.max(vdot, 0.0), g.inp("power")), label="lobe")
    t_dir = g.mul(g.mul(lobe, g.inp("scale")), has_dir, label="T_dir")
    t = g.clamp01(g.inp("thickness"))
    t = g.menu("FLOAT", g.inp("thickness_convention"), {"translucency": t, "thickness": g.sub(1.0, t)}, "t")

    g.column()
    term = g.mul(g.mul(g.div(irradiance, math.pi), t), g.add(t_dir, g.inp("ambient")), label="E/pi t (T_dir + a)")
    term = g.mul(term, g.inp("mask"), label="on the mask")
    sss = g.vscale(g.vmul(g.inp("albedo"), g.inp("light_color")), term, label="SSS")

    g.column()
    g.out("SSS", sss)
    g.out("Image", g.add_keep_alpha(g.inp("Image"), sss))
    _graph.set_menu_defaults(group, INTERFACE)
    return group
