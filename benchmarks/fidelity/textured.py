"""Materials built the way assets are, each beside its twin with the same values typed in: a check
that SSS Lab reads what Cycles renders (image and procedural textures, a driven Scale, a Principled
BSDF inside a node group and behind a Mix Shader), scored like the suite.

Built with the suite's conventions (``benchmarks/fidelity/scenes.py``) and scored by the same
runner; their references are stored apart, in ``textured_references/`` (1024 samples x 2 seeds, as
the suite's)::

    nice -n 10 .venv/bin/python -m benchmarks.fidelity.references --scenes-module \\
        benchmarks.fidelity.textured --store benchmarks/fidelity/textured_references
    nice -n 10 .venv/bin/python -m benchmarks.fidelity.run --scenes-module benchmarks.fidelity.textured \\
        --store benchmarks/fidelity/textured_references --out benchmarks/results/fidelity_textured.json \\
        --table docs/fidelity_textured.md --grid docs/images/fidelity_textured.png

Every linked input keeps Blender's default value in its socket (Base Color 0.8 grey, Subsurface
Scale 0.05, Weight 0), as an asset leaves it; the twin types in the value the link gives on
average (the texture's mean colour, the Scale's middle).

The pairs (linked scene / its twin: geometry and light; material and method; what is linked):

- head_image_skin / head_typed_skin: the suite's head, small area light; skin (Random Walk); Base
  Color from an image texture (mottled skin, 128 px).
- ball_noise_marble / ball_typed_marble: a sphere, sun, a bar's shadow; marble (Random Walk); Base
  Color from a noise texture through a colour ramp.
- torus_scale_wax / torus_typed_wax: a torus, spot, a bar's shadow; wax (Random Walk); Subsurface
  Scale from a noise texture through Map Range (0.5x-1.5x).
- ball_grouped_jade / ball_plain_jade: a sphere and a block, area light; jade (Random Walk); the
  Principled BSDF in a node group behind a Mix Shader with a glossy coat, Weight from a Math node,
  Radius and Scale through the group's inputs.
"""

from __future__ import annotations

import math

import numpy as np

from benchmarks import scene_kit as kit

from . import scenes as suite
from .scenes import SuiteScene

#: Blender 5.2's Principled BSDF defaults, left in a linked socket.
DEFAULT_BASE_COLOR = (0.8, 0.8, 0.8, 1.0)
DEFAULT_SCALE = 0.05
SKIN_COLOR = np.array((0.436, 0.227, 0.131))
MARBLE_DARK, MARBLE_LIGHT = (0.62, 0.58, 0.55), (0.9, 0.87, 0.84)
WAX_SCALE = 0.02


def _skin_image(size: int = 128) -> np.ndarray:
    """A mottled skin texture (RGBA, float32, rows bottom to top as Blender stores them): the
    skin colour times smooth variation of +-30 % and a few darker freckles, from a fixed seed."""
    rng = np.random.default_rng(7)
    ys, xs = np.mgrid[0:size, 0:size] / size
    shade = np.zeros((size, size))
    for _ in range(12):  # smooth blotches: a sum of random low-frequency waves
        fx, fy, phase = rng.uniform(1, 6), rng.uniform(1, 6), rng.uniform(0, 2 * math.pi)
        shade += np.sin(2 * math.pi * (fx * xs + fy * ys) + phase)
    shade = 0.3 * shade / np.abs(shade).max()
    freckles = np.zeros((size, size))
    for _ in range(40):
        cx, cy, r = rng.uniform(0, 1), rng.uniform(0, 1), rng.uniform(0.01, 0.025)
        freckles = np.maximum(freckles, np.exp(-((xs - cx) ** 2 + (ys - cy) ** 2) / (r * r)))
    rgb = SKIN_COLOR * (1.0 + shade)[..., None] * (1.0 - 0.35 * freckles)[..., None] * np.array((1.0, 0.92, 0.9))
    rgba = np.concatenate([np.clip(rgb, 0.0, 1.0), np.ones((size, size, 1))], axis=2)
    return rgba.astype(np.float32)


def _image_node(tree, name: str, pixels: np.ndarray):
    """An Image Texture node of a new in-memory image holding ``pixels`` (linear, not packed:
    built again on every build, the same to the bit), mapped by generated coordinates."""
    import bpy

    size = pixels.shape[0]
    image = bpy.data.images.new(name, size, size, alpha=True, float_buffer=True)
    image.colorspace_settings.name = "Non-Color"  # the values are linear reflectances already
    image.pixels.foreach_set(pixels.ravel())
    node = tree.nodes.new("ShaderNodeTexImage")
    node.image = image
    coords = tree.nodes.new("ShaderNodeTexCoord")
    tree.links.new(coords.outputs["Generated"], node.inputs["Vector"])
    return node


def _bsdf(mat):
    return mat.node_tree.nodes["Principled BSDF"]


def head_image_skin():
    """The suite's head under a small area light, its skin's Base Color from an image texture."""

    def material():
        mat = kit.skin(scale=0.012)
        bsdf = _bsdf(mat)
        bsdf.inputs["Base Color"].default_value = DEFAULT_BASE_COLOR
        node = _image_node(mat.node_tree, "SkinAlbedo", _skin_image())
        mat.node_tree.links.new(node.outputs["Color"], bsdf.inputs["Base Color"])
        return mat

    return suite.head_area(material)


def head_typed_skin():
    """``head_image_skin`` with the texture's mean colour typed in."""

    def material():
        mat = kit.skin(scale=0.012)
        _bsdf(mat).inputs["Base Color"].default_value = (*_skin_image()[..., :3].reshape(-1, 3).mean(axis=0), 1.0)
        return mat

    return suite.head_area(material)


def _ball(material):
    scene = kit.reset_scene()
    ball = kit.uv_sphere_mesh("Ball", 0.06, segments=48, rings=24)
    kit.add_object(scene, "Ball", ball, location=(0, 0, 0.06), material=material())
    kit.floor(scene)
    kit.shadow_bar(scene, (0.0, -0.2, 0.14), rotation=(0.0, math.radians(30), 0.0))
    kit.add_camera(scene, (0.0, -0.4, 0.11), (0.0, 0.0, 0.06), lens=50.0)
    kit.add_light(scene, "Sun", "SUN", (-0.3, -0.5, 0.4), (0.0, 0.0, 0.06), 3.0, angle=0.01)
    return scene


def ball_noise_marble():
    """A marble ball under a sun with a bar's hard shadow; Base Color from a Noise Texture through
    a Color Ramp between two marble tones."""

    def material():
        mat = kit.marble(scale=0.0085)
        tree, bsdf = mat.node_tree, _bsdf(mat)
        bsdf.inputs["Base Color"].default_value = DEFAULT_BASE_COLOR
        noise = tree.nodes.new("ShaderNodeTexNoise")
        noise.inputs["Scale"].default_value = 40.0
        noise.inputs["Detail"].default_value = 4.0
        ramp = tree.nodes.new("ShaderNodeValToRGB")
        ramp.color_ramp.elements[0].position, ramp.color_ramp.elements[1].position = 0.35, 0.65
        ramp.color_ramp.elements[0].color = (*MARBLE_DARK, 1.0)
        ramp.color_ramp.elements[1].color = (*MARBLE_LIGHT, 1.0)
        tree.links.new(noise.outputs["Fac"], ramp.inputs["Fac"])
        tree.links.new(ramp.outputs["Color"], bsdf.inputs["Base Color"])
        return mat

    return _ball(material)


def ball_typed_marble():
    """``ball_noise_marble`` with the ramp's middle colour typed in."""

    def material():
        mat = kit.marble(scale=0.0085)
        middle = tuple((a + b) / 2 for a, b in zip(MARBLE_DARK, MARBLE_LIGHT, strict=True))
        _bsdf(mat).inputs["Base Color"].default_value = (*middle, 1.0)
        return mat

    return _ball(material)


def torus_scale_wax():
    """A wax torus under a spot with a bar's hard shadow; Subsurface Scale from a Noise Texture
    through Map Range, 0.5 to 1.5 times ``WAX_SCALE``."""

    def material():
        mat = kit.wax(scale=DEFAULT_SCALE)
        tree, bsdf = mat.node_tree, _bsdf(mat)
        bsdf.inputs["Subsurface Scale"].default_value = DEFAULT_SCALE
        noise = tree.nodes.new("ShaderNodeTexNoise")
        noise.inputs["Scale"].default_value = 15.0
        span = tree.nodes.new("ShaderNodeMapRange")
        span.inputs["From Min"].default_value, span.inputs["From Max"].default_value = 0.3, 0.7
        span.inputs["To Min"].default_value, span.inputs["To Max"].default_value = 0.5 * WAX_SCALE, 1.5 * WAX_SCALE
        tree.links.new(noise.outputs["Fac"], span.inputs["Value"])
        tree.links.new(span.outputs["Result"], bsdf.inputs["Subsurface Scale"])
        return mat

    return suite.torus_spot(material)


def torus_typed_wax():
    """``torus_scale_wax`` with the Scale's middle typed in."""
    return suite.torus_spot(lambda: kit.wax(scale=WAX_SCALE))


#: The jade pair's Subsurface Weight, Scale and the glossy coat's share.
JADE_WEIGHT, JADE_SCALE, COAT = 0.8, 0.008, 0.15


def _coat(mat, shader_output):
    """Put a Mix Shader between ``shader_output`` and the material output: (1 - COAT) of it and
    COAT of a glossy BSDF."""
    tree = mat.node_tree
    mix, gloss = tree.nodes.new("ShaderNodeMixShader"), tree.nodes.new("ShaderNodeBsdfGlossy")
    gloss.inputs["Roughness"].default_value = 0.15
    mix.inputs["Fac"].default_value = COAT
    tree.links.new(shader_output, mix.inputs[1])
    tree.links.new(gloss.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], tree.nodes["Material Output"].inputs["Surface"])


def ball_grouped_jade():
    """Jade whose Principled BSDF sits in a node group behind a Mix Shader with a glossy coat."""
    return suite.jade_ball_and_block(_grouped_jade, pillar=False)


def _grouped_jade():
    """Jade whose Principled BSDF sits in a node group (an asset library's wrapper) behind a Mix
    Shader with a glossy coat; its Weight from a Math node (0.5 + 0.3) inside the group, its Radius
    and Scale from the group node's inputs; every socket of the inner BSDF at Blender's default."""
    import bpy

    reference = kit.jade(scale=JADE_SCALE)
    values = _bsdf(reference)
    group = bpy.data.node_groups.new("JadeAsset", "ShaderNodeTree")
    group.interface.new_socket("Radius", in_out="INPUT", socket_type="NodeSocketVector")
    group.interface.new_socket("Scale", in_out="INPUT", socket_type="NodeSocketFloat")
    group.interface.new_socket("Shader", in_out="OUTPUT", socket_type="NodeSocketShader")
    inside, outside = group.nodes.new("NodeGroupInput"), group.nodes.new("NodeGroupOutput")
    bsdf = group.nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.subsurface_method = values.subsurface_method
    for name in ("Base Color", "Roughness", "IOR"):
        bsdf.inputs[name].default_value = values.inputs[name].default_value
    add = group.nodes.new("ShaderNodeMath")
    add.inputs[0].default_value, add.inputs[1].default_value = 0.5, JADE_WEIGHT - 0.5
    group.links.new(add.outputs[0], bsdf.inputs["Subsurface Weight"])
    group.links.new(inside.outputs["Radius"], bsdf.inputs["Subsurface Radius"])
    group.links.new(inside.outputs["Scale"], bsdf.inputs["Subsurface Scale"])
    group.links.new(bsdf.outputs[0], outside.inputs["Shader"])
    mat = bpy.data.materials.new("Jade Asset")
    from sss_lab.blender import compat

    compat.ensure_node_tree(mat)
    tree = mat.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    node = tree.nodes.new("ShaderNodeGroup")
    node.node_tree = group
    node.inputs["Radius"].default_value = tuple(values.inputs["Subsurface Radius"].default_value)
    node.inputs["Scale"].default_value = values.inputs["Subsurface Scale"].default_value
    bpy.data.materials.remove(reference)
    _coat(mat, node.outputs["Shader"])
    return mat


def ball_plain_jade():
    """``ball_grouped_jade`` with the Principled BSDF at the top of the tree and its values typed in."""

    def material():
        mat = kit.jade(scale=JADE_SCALE)
        _bsdf(mat).inputs["Subsurface Weight"].default_value = JADE_WEIGHT
        _coat(mat, _bsdf(mat).outputs[0])
        return mat

    return suite.jade_ball_and_block(material, pillar=False)


def _scene(name, build, kind="diffusion"):
    return name, SuiteScene(name, kind, build, (build.__doc__ or "").split("\n")[0])


SCENES: dict[str, SuiteScene] = dict(
    _scene(n, b)
    for n, b in (
        ("head_image_skin", head_image_skin),
        ("head_typed_skin", head_typed_skin),
        ("ball_noise_marble", ball_noise_marble),
        ("ball_typed_marble", ball_typed_marble),
        ("torus_scale_wax", torus_scale_wax),
        ("torus_typed_wax", torus_typed_wax),
        ("ball_grouped_jade", ball_grouped_jade),
        ("ball_plain_jade", ball_plain_jade),
    )
)
#: Each linked scene's twin with the values typed in.
TWINS = {
    "head_image_skin": "head_typed_skin",
    "ball_noise_marble": "ball_typed_marble",
    "torus_scale_wax": "torus_typed_wax",
    "ball_grouped_jade": "ball_plain_jade",
}
